"""The malloc thresholds of :mod:`ris_planner.runtime.allocator`: never set by importing the
package;
set by the entry points (the command line, the service) and by an explicit opt-in on glibc,
followed by the local pool's workers, left alone when the user opts out or chose glibc's own
variables (fresh interpreters: the setting is process-wide and made once)."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest
from waits import HANG_S

GLIBC = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"

FAULTS = """
import resource, sys, numpy as np, ris_planner
from ris_planner.runtime import allocator
if sys.argv[1:] == ["tune"]:
    allocator.tune_malloc()
def cycle():
    live = [np.ones(750_000) for _ in range(3)]  # three 6 MB temporaries, then all freed
    del live
cycle()
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):
    cycle()
print(allocator.tuned(), resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def run(code: str | Path, *args: str, **env: str) -> list[str]:
    """Run code (a string, or a script file) in a fresh interpreter; its stdout words."""
    full = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    full.pop("RIS_PLANNER_MALLOC_TUNING", None)
    source = [str(code)] if isinstance(code, Path) else ["-c", code]
    out = subprocess.run(
        [sys.executable, *source, *args],
        env=full | env,
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


CLI_PROBE = """
import sys
from ris_planner.runtime import allocator
from ris_planner.cli import app as cli
cli.main(["schema"])
print(allocator.tuned(), file=sys.stderr)
"""

POOL_PROBE = """
from ris_planner.runtime import allocator
from ris_planner.runtime.executor import LocalExecutor
def probe(shared, chunk):
    from ris_planner.runtime import allocator
    return allocator.tuned()
if __name__ == "__main__":
    import sys
    if sys.argv[1:] == ["tune"]:
        allocator.tune_malloc()
    with LocalExecutor(2, share_memory=False) as ex:
        print(all(ex.map(probe, None, [0, 1])))
"""


@pytest.mark.skipif(not GLIBC, reason="mallopt thresholds are glibc's")
def test_import_changes_nothing_entry_points_and_opt_in_tune() -> None:
    probe = "import ris_planner.bounds.compute; from ris_planner.runtime import allocator;"
    probe += "print(allocator.tuned())"
    assert run(probe) == ["False"]  # importing the library leaves the host process alone
    tune = "from ris_planner.runtime import allocator;"
    tune += "print(allocator.tune_malloc(), allocator.tuned())"
    assert run(tune) == ["True", "True"]  # the opt-in
    assert run(tune, RIS_PLANNER_MALLOC_TUNING="0") == ["False", "False"]
    assert run(tune, MALLOC_MMAP_THRESHOLD_="131072") == ["False", "False"]  # the user's choice
    out = subprocess.run(
        [sys.executable, "-c", CLI_PROBE], capture_output=True, text=True, timeout=HANG_S
    )
    assert out.returncode == 0 and out.stderr.split()[-1] == "True"  # the command line tunes


@pytest.mark.skipif(not GLIBC, reason="mallopt thresholds are glibc's")
def test_pool_workers_follow_the_process_that_started_them(tmp_path: Path) -> None:
    script = tmp_path / "pool_probe.py"
    script.write_text(POOL_PROBE)
    assert run(script, "tune")[-1] == "True"
    assert run(script)[-1] == "False"


@pytest.mark.skipif(not GLIBC, reason="mallopt thresholds are glibc's")
def test_freed_temporaries_are_reused_without_page_faults() -> None:
    """Twenty rounds of three live 6 MB arrays: with the thresholds their pages stay mapped
    and are reused (no minor faults after the first round); with glibc's heuristic alone
    (opted out) the heap is trimmed and every round faults its 18 MB in again (≈ 17 500 faults
    measured on the 2-core machine)."""
    tuned, faults = run(FAULTS, "tune")
    assert tuned == "True" and int(faults) <= 50
    untuned, faults_default = run(FAULTS)
    assert untuned == "False" and int(faults_default) > 20 * int(faults) + 1000
