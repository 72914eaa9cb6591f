"""Every stage of a plan is timed: plan.json's ``timing_s`` names each stage of the
pipeline – inputs to the GIS exports – and its sum is the plan's wall time, on the command line
(measured around the CLI's ``main`` in this process, and around the command's own process
with its ``startup``) and for a REST job (its ``started_at`` to
``finished_at``); the benchmark's smoke mode runs."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import Any

from api_helpers import api_client, wait_for
from waits import HANG_S

from ris_planner.cli import main

ROOT = Path(__file__).resolve().parents[1]

WALL_SHARE = 0.05
"""The stages sum to the wall time within 5 %. What no stage holds is the command
line's own work around the plan (parsing the arguments, reading the document, writing
plan.json, printing the summary) and, for a job, storing its result: milliseconds against
the ≥ 0.5 s of the plan below, which is sized so that they stay well inside the 5 %."""

STAGES = {
    "inputs",
    "visibility",
    "cache",
    "search",
    "branch_and_bound",
    "checks",
    "rollout",
    "diagnosis",
    "fields",
    "report",
    "figures",
    "exports",
}
"""The stages of every plan (docs/concepts/planning.md, "Pipeline"); beams, sweep and sizing
add theirs when the document asks for them."""


def timed_plan() -> dict[str, Any]:
    """Eight candidates on a ring, 11 × 11 grids, 600 pairs, 2–3 RISs of 16 × 16: a plan of
    about a second (more under load: every stage grows with it)."""
    ring = [
        {
            "position": [7 * math.cos(a), 7 * math.sin(a), 2.0 + (k % 2)],
            "orientation": [a + math.pi, 0.3, 0.0],
        }
        for k, a in enumerate(2 * math.pi * k / 8 + 0.1 for k in range(8))
    ]
    grid = {"grid": {"x": [-5, 5, 1], "y": [-5, 5, 1], "z": [0, 0, 1]}}
    return {
        "ris": {"rows": 16, "cols": 16},
        "candidates": ring,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 600, "seed": 1},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 0.5},
        "ris_count": [2, 3],
    }


def check_sum(timing: dict[str, float], wall: float) -> None:
    assert set(timing) >= STAGES, sorted(STAGES - set(timing))
    assert all(v >= 0 for v in timing.values())
    total = sum(timing.values())
    assert abs(total - wall) <= WALL_SHARE * wall, (total, wall, timing)


def test_cli_stage_times_sum_to_the_wall_time(tmp_path: Path) -> None:
    doc = tmp_path / "plan.json"
    doc.write_text(json.dumps(timed_plan()))
    out = tmp_path / "out"
    argv = ["plan", str(doc), "--out", str(out), "--workers", "1"]
    main(argv)  # warm: the kernels and matplotlib load once per process
    t0 = time.perf_counter()
    assert main(argv) == 0
    wall = time.perf_counter() - t0
    timing = json.loads((out / "plan.json").read_text())["timing_s"]
    assert "workers_close" in timing  # the command line's own stage
    check_sum(timing, wall)


def test_cli_process_stage_times_sum_to_its_wall_time(tmp_path: Path) -> None:
    """The command as a process: ``startup`` (the interpreter, the imports, reading the
    document) and the stages account for the process's wall time up to writing plan.json,
    measured outside it – from the launch to plan.json's modification time, on the same
    system clock; only the process runs the clock from its start (in-process calls above
    have none). What follows plan.json – the summary lines and the interpreter's exit,
    0.02–0.1 s, more on a busy machine – cannot be in the file it has written
    (docs/concepts/planning.md, "Output")."""
    doc = tmp_path / "plan.json"
    doc.write_text(json.dumps(timed_plan()))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ris_planner.cli", "plan", str(doc), "--out", str(out)]
    t0 = time.time()
    proc = subprocess.run([*cmd, "--workers", "1"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    wall = (out / "plan.json").stat().st_mtime - t0
    timing = json.loads((out / "plan.json").read_text())["timing_s"]
    assert timing["startup"] > 0
    check_sum(timing, wall)


def test_process_age_counts_from_the_process_start() -> None:
    code = (
        "import time; time.sleep(0.4)\n"
        "from ris_planner.runtime.process import process_age_s; print(process_age_s())"
    )
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    age = float(proc.stdout)
    # the kernel's start time has a clock tick's resolution (10 ms)
    assert 0.4 <= age <= wall + 0.02, (age, wall)


def test_rest_job_stage_times_sum_to_the_job_time(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/plans", json=timed_plan())
        assert r.status_code == 202
        job_id = r.json()["id"]
        view = wait_for(client, job_id, ("succeeded", "failed"))
        assert view["status"] == "succeeded", view["error"]
        # a second job of the same plan: the worker's kernels are warm (the forkserver's
        # preload does not compile every kernel)
        r = client.post("/v1/plans", json=timed_plan())
        view = wait_for(client, r.json()["id"], ("succeeded", "failed"))
        assert view["status"] == "succeeded", view["error"]
    start = datetime.fromisoformat(view["started_at"])
    end = datetime.fromisoformat(view["finished_at"])
    timing = view["result"]["timing_s"]
    assert timing["job"] > 0  # the worker's own bookkeeping, timed (api.worker.JOB_STAGE)
    check_sum(timing, (end - start).total_seconds())


def test_bench_interactive_smoke() -> None:
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "planning" / "bench_interactive.py"), "--smoke"],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "sum(timing_s) / wall" in proc.stdout


def test_reports_between_stages_are_timed_once() -> None:
    """A progress report made between stages is timed as ``progress``; one made inside a
    stage only by that stage (a service job writes each report to its store)."""
    from ris_planner.runtime.progress import BETWEEN_STAGES, StageClock, Stages

    def slow_report(fraction: float, message: str) -> None:
        time.sleep(0.02)

    t0 = time.perf_counter()
    clock = StageClock()
    stages = Stages(slow_report, {"a": 1.0, "b": 1.0}, clock)
    on_a = stages.callback("a")  # before the stage's timer: between stages
    with clock.stage("a"):
        on_a(0.5, "half")  # inside: the stage's own time
    stages.finish()
    wall = time.perf_counter() - t0
    assert clock.seconds[BETWEEN_STAGES] >= 0.04  # the start and the end
    assert clock.seconds["a"] >= 0.02
    # nothing counted twice: the timed stretches fit in the time they all took together
    assert sum(clock.seconds.values()) <= wall, (clock.seconds, wall)
