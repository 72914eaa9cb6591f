"""End to end: a real uvicorn process on 127.0.0.1 (free port, temporary SQLite file), a plan
job polled to completion, a restart on the same database, the same job read back; and a job
that was running when the server was killed is failed at the next start."""

from __future__ import annotations

import signal
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
from test_api_plans import small_plan_doc
from waits import HANG_S

from api.launch import served
from api.store import INTERRUPTED_MESSAGE
from ris_planner import preset_document
from ris_planner.model.paper import fig10_pairs


def poll(url: str, job_id: str, timeout_s: float = HANG_S) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        view: dict[str, Any] = httpx.get(f"{url}/v1/jobs/{job_id}", timeout=HANG_S).json()
        if view["status"] in ("succeeded", "failed", "cancelled"):
            return view
        assert time.monotonic() < deadline, f"job still {view['status']}"
        time.sleep(0.1)


def healthz_answers_during_bounds(url: str) -> int:
    """Send 8 bounds requests of 9000 pairs each (seconds of work in total) from threads and
    count the /healthz answers that arrive while they are in flight."""
    tx, rx = fig10_pairs()
    doc = preset_document("2-ris-L") | {"tx": tx[:4500].tolist() * 2, "rx": rx[:4500].tolist() * 2}
    with ThreadPoolExecutor(8) as pool:
        futures = [
            pool.submit(httpx.post, f"{url}/v1/bounds", json=doc, timeout=HANG_S) for _ in range(8)
        ]
        answered = 0
        while not all(f.done() for f in futures):
            if httpx.get(f"{url}/healthz", timeout=HANG_S).status_code == 200:
                answered += 1
            time.sleep(0.02)
        assert all(f.result().status_code == 200 for f in futures)
    return answered


def test_plan_job_survives_a_restart(tmp_path: Path) -> None:
    db = tmp_path / "jobs.db"
    with served(db, via="uvicorn", log=tmp_path / "server.log") as server:
        r = httpx.post(f"{server.url}/v1/plans", json=small_plan_doc(), timeout=HANG_S)
        assert r.status_code == 202
        job_id = r.json()["id"]
        first = poll(server.url, job_id)
        assert first["status"] == "succeeded", first["error"]
        png = httpx.get(f"{server.url}{first['figures']['cdf']}", timeout=HANG_S)
        assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
        # the bounds computations run beside the event loop, which keeps answering
        assert healthz_answers_during_bounds(server.url) >= 3
    assert server.process.returncode == 0  # graceful stop on SIGINT
    with served(db, via="serve", log=tmp_path / "server.log") as server:
        again = httpx.get(f"{server.url}/v1/jobs/{job_id}", timeout=HANG_S).json()
        assert again == first
        listed = httpx.get(f"{server.url}/v1/jobs", timeout=HANG_S).json()
        assert [j["id"] for j in listed["items"]] == [job_id]
        png2 = httpx.get(f"{server.url}{first['figures']['cdf']}", timeout=HANG_S)
        assert png2.content == png.content


def test_killed_server_running_job_is_failed_on_restart(tmp_path: Path) -> None:
    """SIGKILL while a (large) plan job runs and reports progress: nothing can update the job,
    so the next start-up marks it failed rather than leaving it 'running' forever."""
    db = tmp_path / "jobs.db"
    big = small_plan_doc(  # about 7 s of work
        pairs={"sample": 200000, "seed": 1}, max_pairs=200000, ris_count=[2, 3, 4, 5]
    )
    big["tx_map"] = big["rx_map"] = {"grid": {"x": [-3, 3, 0.1], "y": [-3, 3, 0.1], "z": [0, 0, 1]}}
    with served(db, log=tmp_path / "server.log") as server:
        job_id = httpx.post(f"{server.url}/v1/plans", json=big, timeout=HANG_S).json()["id"]
        deadline = time.monotonic() + HANG_S
        while True:  # the plan's own progress reaches SQLite while it runs
            view = httpx.get(f"{server.url}/v1/jobs/{job_id}", timeout=HANG_S).json()
            if view["status"] == "running" and 0 < view["progress"] < 1:
                break
            assert view["status"] in ("queued", "running") and time.monotonic() < deadline
            time.sleep(0.05)
        server.process.send_signal(signal.SIGKILL)
        server.process.wait()
    with served(db, log=tmp_path / "server.log") as server:
        view = httpx.get(f"{server.url}/v1/jobs/{job_id}", timeout=HANG_S).json()
        assert view["status"] == "failed" and view["error"] == INTERRUPTED_MESSAGE
        time.sleep(1.5)  # the orphaned worker (if still alive) cannot overwrite the verdict
        assert httpx.get(f"{server.url}/v1/jobs/{job_id}", timeout=HANG_S).json() == view
