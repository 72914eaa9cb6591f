"""Honest progress: over a whole plan with its figures and exports the fractions never go back,
stay below 1 until the last call, the last call comes after the files are written, and no
stage holds most of the work while the bar stands still
(ris_planner.planning.resources.time_estimate). The work is the plan's CPU time in its own
process (``time.process_time``): another process's load does not stretch it, as it stretches
the wall time."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from ris_planner.io.geoplan import plan_document
from ris_planner.planning import SerialExecutor
from ris_planner.runtime.progress import LAST_BEFORE_END, Stages

STALL_WALL_SHARE = 0.6
"""No stretch of the run longer than this share of its CPU time …"""
STALL_MOVE = 0.05
"""… may move the bar less than this."""


def small_plan() -> dict[str, Any]:
    ring = [
        {
            "position": [6 * math.cos(a), 6 * math.sin(a), 2.0],
            "orientation": [a + math.pi, 0.3, 0.0],
        }
        for a in (2 * math.pi * k / 6 for k in range(6))
    ]
    grid = {"grid": {"x": [-4, 4, 1], "y": [-4, 4, 1], "z": [0, 0, 1]}}
    return {
        "candidates": ring,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 300, "seed": 1},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [2, 3],
    }


def check_honest(calls: list[tuple[float, str, float]], t_start: float, t_end: float) -> None:
    """The rules of the module docstring on recorded (fraction, message, time) calls."""
    fractions = [f for f, _, _ in calls]
    assert fractions == sorted(fractions), "progress went back"
    assert all(f < 1.0 for f in fractions[:-1]) and fractions[-1] == 1.0
    span = t_end - t_start
    # the stretch from one call to the next (and from the start to the first call)
    times = [t_start] + [t for _, _, t in calls]
    fr = [0.0, *fractions]
    for i in range(1, len(times)):
        if times[i] - times[i - 1] > STALL_WALL_SHARE * span:
            assert fr[i] - fr[i - 1] >= STALL_MOVE, (
                f"{times[i] - times[i - 1]:.2f} s of {span:.2f} s moved the bar"
                f" {fr[i] - fr[i - 1]:.3f} (to {calls[i - 1][1]!r})"
            )


def test_stages_monotone_and_below_one_until_finish() -> None:
    seen: list[float] = []
    st = Stages(lambda f, m: seen.append(f), {"a": 1.0, "b": 3.0})
    st.report("b", 0.5)
    st.report("a", 1.0)  # an earlier stage after a later one: never back
    st.report("b", 1.0)
    assert seen == sorted(seen) and max(seen) == LAST_BEFORE_END
    st.finish()
    assert seen[-1] == 1.0
    inner: list[tuple[float, str]] = []
    outer = Stages(lambda f, m: inner.append((f, m)), {"x": 1.0, "y": 1.0})
    nested = Stages(outer.callback("x"), {"p": 1.0, "q": 1.0})
    nested.report("q", 0.5, "half")
    nested.finish()
    assert inner[-2] == (0.375, "x: q: half") and inner[-1] == (0.5, "x: done")


def test_plan_progress_is_honest(tmp_path: Path) -> None:
    calls: list[tuple[float, str, float]] = []
    written: list[float] = []

    def record(f: float, m: str) -> None:
        calls.append((f, m, time.process_time()))
        if f == 1.0:  # the files are there by the last call
            written.append(sum(1 for p in tmp_path.iterdir() if p.suffix == ".png"))

    t0 = time.process_time()
    done = plan_document(small_plan(), tmp_path, record, SerialExecutor())
    t1 = time.process_time()
    check_honest(calls, t0, t1)
    assert written == [len([p for p in done.files.values() if p.suffix == ".png"])] and written[0]
    assert t1 - calls[-1][2] < 0.05 * (t1 - t0)  # the last call is at the end
    stages = {m.split(":")[0] for _, m, _ in calls[:-1]}
    assert stages == {"plan", "fields", "report", "figures", "exports"}


def test_progress_bar_redraws_at_a_new_stage() -> None:
    import io

    from ris_planner.runtime.progress import ProgressBar

    out = io.StringIO()
    bar = ProgressBar("plan", stream=out)
    bar(0.1, "plan: cache")
    bar(0.2, "plan: search")  # within 0.1 s, same stage: not drawn
    bar(0.6, "figures")  # a new stage: drawn
    text = out.getvalue()
    assert "cache" in text and "search" not in text and "figures" in text
