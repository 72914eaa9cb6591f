"""Job functions that exercise the job runner itself (progress, failure, crash, cancellation).

They are imported by the worker processes by module name (tests/ is on sys.path), like the
product's own kinds in ``api.kinds``.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from api.worker import JobOutput
from ris_planner.core.errors import RisPlannerError
from ris_planner.runtime.progress import ProgressCallback


def counting_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    """``steps`` steps of ``sleep_s`` each, reporting progress; optional PNG figure 'curve'."""
    steps, total = int(document["steps"]), 0
    for i in range(steps):
        time.sleep(float(document.get("sleep_s", 0.0)))
        total += i
        progress((i + 1) / steps, f"step {i + 1} of {steps}")
    figures = {}
    if document.get("figure"):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        out_dir.mkdir(parents=True, exist_ok=True)
        fig, ax = plt.subplots(figsize=(2, 2))
        ax.plot(range(steps))
        figures["curve"] = out_dir / "curve.png"
        fig.savefig(figures["curve"])
        plt.close(fig)
    return JobOutput({"steps": steps, "sum": total}, figures)


def failing_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    raise RisPlannerError(f"cannot do {document.get('what', 'this')}")


def crashing_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    os._exit(3)


def sleeping_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    progress(0.5, "sleeping")
    time.sleep(float(document.get("sleep_s", 60)))
    return JobOutput({"slept": True})


def hogging_job(document: dict[str, Any], progress: ProgressCallback, out_dir: Path) -> JobOutput:
    """Allocates ``mb`` MiB at once (beyond a small job memory budget)."""
    import numpy as np

    block = np.ones(int(document["mb"]) << 17)  # 8 B each
    return JobOutput({"sum": float(block.sum())})


def figure_then_sleep_job(
    document: dict[str, Any], progress: ProgressCallback, out_dir: Path
) -> JobOutput:
    """Writes a figure file, then sleeps (cancelled meanwhile: no figure may remain)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "partial.png").write_bytes(b"\x89PNG partial")
    for _ in range(600):
        time.sleep(0.05)
        progress(0.5, "sleeping")
    return JobOutput({}, {"partial": out_dir / "partial.png"})


TEST_KINDS = {
    "hog": hogging_job,
    "figure_sleep": figure_then_sleep_job,
    "count": counting_job,
    "fail": failing_job,
    "crash": crashing_job,
    "sleep": sleeping_job,
}
