"""Plan jobs on the local process pool: a job's worker starts the same pool as
``ris-planner plan`` (so the same results), and cancelling the job or stopping the server stops
every process of it – checked by PID."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
from api_helpers import api_client, wait_for
from test_api_plans import GRID, without_timing
from tolerance import BOUND_ACCURACY, assert_close
from waits import HANG_S

from api.launch import served

ROOT = Path(__file__).resolve().parent.parent


def pool_doc(n_sites: int = 12, pairs: int = 1500, counts: tuple[int, ...] = (2, 3)) -> dict:
    """A plan big enough that the search splits its batches over 2 workers
    (``plan.needs_workers``: C(12, 3) · 1500 ≥ 2 · 250 000 layout-pairs), on its workers
    whatever its size (``search.pool_min_work`` 0)."""
    candidates = []
    for k in range(n_sites):
        phi = 2 * math.pi * k / n_sites + 0.1
        candidates.append(
            {
                "position": [4.5 * math.cos(phi), 4.5 * math.sin(phi), 2.0 + (k % 2)],
                "orientation": [phi + math.pi, math.pi / 6, 0.0],
            }
        )
    return {
        "candidates": candidates,
        "tx_map": GRID,
        "rx_map": GRID,
        "pairs": {"sample": pairs, "seed": 1},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": list(counts),
        "search": {"max_exhaustive": 10_000, "pool_min_work": 0},
    }


def children(pid: int) -> set[int]:
    """Every live descendant of ``pid`` (from /proc)."""
    parent_of: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            parent_of[int(entry)] = int(stat.rsplit(")", 1)[1].split()[1])
    found: set[int] = set()
    frontier = {pid}
    while frontier:
        frontier = {c for c, p in parent_of.items() if p in frontier} - found
        found |= frontier
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def spawned_children(pid: int) -> set[int]:
    """The children of ``pid`` that are multiprocessing spawn workers (by their command line);
    a child that exits between the listing and the read is none of them."""
    found = set()
    for c in children(pid):
        try:
            if b"spawn_main" in Path(f"/proc/{c}/cmdline").read_bytes():
                found.add(c)
        except OSError:  # gone meanwhile
            continue
    return found


def pool_of(client: Any, timeout_s: float = HANG_S) -> tuple[int, set[int]]:
    """(the running job's worker pid, its pool's processes) once the pool has 2 workers."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        pids = client.app.state.runner.worker_pids()
        if pids and len(spawned_children(pids[0])) >= 2:
            return pids[0], children(pids[0])
        time.sleep(0.05)
    raise AssertionError("the plan job started no process pool")


def wait_gone(pids: set[int], timeout_s: float = HANG_S) -> set[int]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.05)
    return {p for p in pids if alive(p)}


def test_cancelling_a_plan_job_stops_its_pool(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=1, plan_workers=2) as client:
        job = client.post("/v1/plans", json=pool_doc(counts=(2, 3, 4))).json()["id"]
        worker, pool = pool_of(client)
        assert client.post(f"/v1/jobs/{job}/cancel").status_code == 200
        assert wait_gone({worker} | pool) == set()
        assert wait_for(client, job, ("cancelled",))["status"] == "cancelled"


def test_stopping_the_server_stops_a_running_plan_pool(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=1, plan_workers=2) as client:
        client.post("/v1/plans", json=pool_doc(counts=(2, 3, 4)))
        worker, pool = pool_of(client)
    assert wait_gone({worker} | pool) == set()


def test_plan_job_on_the_pool_equals_the_command_line(tmp_path: Path) -> None:
    """The job (its worker's pool of 2) and ``ris-planner plan --workers 2``: the same plan.json
    to the bounds' accuracy (other processes), the same decisions."""
    doc = pool_doc()
    with api_client(tmp_path, workers=1, plan_workers=2) as client:
        job = client.post("/v1/plans", json=doc).json()["id"]
        view = wait_for(client, job, ("succeeded", "failed"))
    assert view["status"] == "succeeded", view["error"]
    src = tmp_path / "doc.json"
    src.write_text(json.dumps(doc))
    out = tmp_path / "cli"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "ris_planner.cli",
            "plan",
            str(src),
            "--out",
            str(out),
            "--workers",
            "2",
        ],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        env=env,
    )
    assert run.returncode == 0, run.stderr
    cli = json.loads((out / "plan.json").read_text())
    assert_close(without_timing(view["result"]), without_timing(cli), accuracy=BOUND_ACCURACY)
    sites = [b["sites"] for b in view["result"]["by_count"]]
    assert sites == [b["sites"] for b in cli["by_count"]]


@pytest.mark.parametrize("stop", ["sigint", "sigkill"])
def test_no_process_outlives_a_real_server(tmp_path: Path, stop: str) -> None:
    """``ris-planner serve`` with a plan job on its pool and the parse processes: after the
    server stops (SIGINT: its shutdown; SIGKILL: nothing runs in it) every process it started
    – forkserver, job worker, the job's pool, parse processes – is gone, by PID."""
    env = {"RIS_PLANNER_PLAN_WORKERS": "2", "RIS_PLANNER_PARSE_CONCURRENCY": "2"}
    with served(tmp_path / "jobs.db", env=env) as server:
        r = httpx.post(f"{server.url}/v1/plans", json=pool_doc(counts=(2, 3, 4)), timeout=HANG_S)
        assert r.status_code == 202
        deadline = time.monotonic() + HANG_S
        while True:
            if len(spawned_children(server.process.pid)) >= 2:
                break
            assert time.monotonic() < deadline, "the plan job started no process pool"
            time.sleep(0.05)
        started = children(server.process.pid)
        assert len(started) >= 5  # forkserver, 2 parse processes, the job, its 2 workers
        if stop == "sigkill":
            server.process.kill()
            server.process.wait()
    assert wait_gone(started) == set()
