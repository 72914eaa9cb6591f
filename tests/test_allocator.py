"""The malloc thresholds of :mod:`ris_planner.allocator`: set at import on glibc, left alone
when the user opts out or chose glibc's own variables (fresh interpreters: the setting is
process-wide and made once)."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

GLIBC = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"

FAULTS = """
import resource, numpy as np, ris_planner
def cycle():
    live = [np.ones(750_000) for _ in range(3)]  # three 6 MB temporaries, then all freed
    del live
cycle()
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):
    cycle()
print(ris_planner.allocator.TUNED, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def run(code: str, **env: str) -> list[str]:
    full = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    full.pop("RIS_PLANNER_MALLOC_TUNING", None)
    out = subprocess.run(
        [sys.executable, "-c", code], env=full | env, capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


@pytest.mark.skipif(not GLIBC, reason="mallopt thresholds are glibc's")
def test_thresholds_set_at_import_unless_opted_out() -> None:
    probe = "import ris_planner; print(ris_planner.allocator.TUNED)"
    assert run(probe) == ["True"]
    assert run(probe, RIS_PLANNER_MALLOC_TUNING="0") == ["False"]
    assert run(probe, MALLOC_MMAP_THRESHOLD_="131072") == ["False"]  # the user's own choice


@pytest.mark.skipif(not GLIBC, reason="mallopt thresholds are glibc's")
def test_freed_temporaries_are_reused_without_page_faults() -> None:
    """Twenty rounds of three live 6 MB arrays: with the thresholds their pages stay mapped
    and are reused (no minor faults after the first round); with glibc's heuristic alone
    (opted out) the heap is trimmed and every round faults its 18 MB in again (≈ 17 500 faults
    measured on the 2-core machine)."""
    tuned, faults = run(FAULTS)
    assert tuned == "True" and int(faults) <= 50
    untuned, faults_default = run(FAULTS, RIS_PLANNER_MALLOC_TUNING="0")
    assert untuned == "False" and int(faults_default) > 20 * int(faults) + 1000
