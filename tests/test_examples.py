"""Every script in ``examples/`` runs: each one's ``--smoke`` mode (tiny sizes, output in a
temporary folder) as a subprocess, parametrised over the files, so a new example without a
smoke mode fails here (docs/guides/examples.md)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from waits import HANG_S

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))
SMOKE_S = HANG_S
"""An example's smoke run that has not ended by then hangs (they take seconds; tests/waits.py)."""


def test_the_examples_are_found() -> None:
    assert len(EXAMPLES) >= 11 and (ROOT / "examples" / "plan_helsinki.py") in EXAMPLES


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.stem)
def test_example_smoke_mode_runs(script: Path, tmp_path: Path) -> None:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env |= {"MPLBACKEND": "Agg", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    env["TMPDIR"] = str(tmp_path)  # the smoke output goes to a temporary folder under it
    proc = subprocess.run(
        [sys.executable, str(script), "--smoke"],
        capture_output=True,
        text=True,
        timeout=SMOKE_S,
        env=env,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip(), "an example prints its results"
    assert "Traceback" not in proc.stderr
    # nothing written outside the temporary folder
    assert not (tmp_path / "out").exists()
