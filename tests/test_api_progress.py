"""A REST plan job's progress is honest (tests/test_progress_honest.py's rules, seen through
``GET /v1/jobs/{id}``): it never goes back, is below 1 while the job runs, reaches 1 only with
the result, and no stretch of most of the run leaves the bar standing."""

from __future__ import annotations

import time
from pathlib import Path

from api_helpers import api_client

from tests.test_progress_honest import STALL_MOVE, STALL_WALL_SHARE, small_plan


def test_plan_job_progress_is_honest(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/plans", json=small_plan())
        assert r.status_code == 202
        job_id = r.json()["id"]
        seen: list[tuple[float, str, str, float]] = []
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            view = client.get(f"/v1/jobs/{job_id}").json()
            seen.append((view["progress"], view["message"], view["status"], time.monotonic()))
            if view["status"] in ("succeeded", "failed"):
                break
            time.sleep(0.03)
    assert seen[-1][2] == "succeeded", seen[-1]
    fractions = [p for p, _, _, _ in seen]
    assert fractions == sorted(fractions)
    assert all(p < 1.0 for p, _, status, _ in seen if status != "succeeded")
    assert seen[-1][0] == 1.0
    running = [(p, t) for p, _, status, t in seen if status == "running"] + [
        (seen[-1][0], seen[-1][3])
    ]
    wall = running[-1][1] - running[0][1]
    # the longest stretch over which the bar stood still (to within STALL_MOVE)
    start = 0
    for i in range(1, len(running)):
        while running[i][0] - running[start][0] >= STALL_MOVE:
            start += 1
        stood = running[i][1] - running[start][1]
        assert stood <= STALL_WALL_SHARE * wall, (stood, wall, running[start][0], running[i][0])
    stages = {m.split(":")[0] for _, m, status, _ in seen if status == "running" and m}
    assert {"fields", "figures"} & stages or len(running) < 10, stages
