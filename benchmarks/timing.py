"""Timing helpers shared by the benchmark scripts (their folder is on ``sys.path`` when run as
``python benchmarks/<script>.py``)."""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any


def median_time(fn: Callable[..., Any], repeats: int) -> float:
    """Median wall time [s] of ``repeats`` calls of ``fn`` after one warm-up call."""
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def run_in_tree(tree: Path, worker: str, *args: str, timeout: float = 600) -> dict[str, Any]:
    """``python -c WORKER ARGS`` in a fresh process that imports ``tree``'s code (its
    ``PYTHONPATH`` and working directory); the JSON object on its last line of output."""
    env = dict(os.environ) | {"PYTHONPATH": str(tree)}
    out = subprocess.run(
        [sys.executable, "-c", worker, *args],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=True,
        timeout=timeout,
    )
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result
