"""Fault injection against a real server (uvicorn on 127.0.0.1, a temporary SQLite file): a
database lock held past the busy timeout while a job runs and finishes, the database file
removed mid-job, SIGKILL of the server and of a worker. After each: no process outlives its
server (checked by pid in /proc), every job reaches a final state, the next job runs."""

from __future__ import annotations

import os
import signal
import sqlite3
import sys
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
from test_api_plans import small_plan_doc
from waits import HANG_S

from api.launch import served

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")

FINAL = ("succeeded", "failed", "cancelled")
ENV = {"RIS_PLANNER_DB_BUSY_TIMEOUT_S": "0.2", "RIS_PLANNER_DB_RETRY_S": "60"}
"""A short busy timeout: a lock of a few seconds is far past it (the store must retry)."""


def long_plan() -> dict[str, Any]:
    """A plan of a few seconds (long enough to be hit by a fault while it runs)."""
    doc = small_plan_doc(pairs={"sample": 60000, "seed": 1}, max_pairs=60000, ris_count=[2, 3, 4])
    doc["tx_map"] = doc["rx_map"] = {"grid": {"x": [-3, 3, 0.2], "y": [-3, 3, 0.2], "z": [0, 0, 1]}}
    return doc


def children(pid: int) -> list[int]:
    """Direct children of a process (from /proc/*/stat)."""
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(entry))
    return out


def descendants(pid: int) -> list[int]:
    found, todo = [], [pid]
    while todo:
        for child in children(todo.pop()):
            found.append(child)
            todo.append(child)
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def wait_gone(pids: list[int], timeout_s: float = HANG_S) -> None:
    deadline = time.monotonic() + timeout_s
    while any(alive(p) for p in pids):
        assert time.monotonic() < deadline, f"still alive: {[p for p in pids if alive(p)]}"
        time.sleep(0.1)


def poll(
    url: str, job_id: str, statuses: tuple[str, ...], timeout_s: float = HANG_S
) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        view: dict[str, Any] = httpx.get(f"{url}/v1/jobs/{job_id}", timeout=HANG_S).json()
        if view["status"] in statuses:
            return view
        assert time.monotonic() < deadline, f"job {job_id} still {view['status']}"
        time.sleep(0.05)


def submit(url: str, doc: dict[str, Any]) -> str:
    r = httpx.post(f"{url}/v1/plans", json=doc, timeout=HANG_S)
    assert r.status_code == 202, r.text
    job_id: str = r.json()["id"]
    return job_id


def next_job_runs(url: str) -> None:
    view = poll(url, submit(url, small_plan_doc()), FINAL)
    assert view["status"] == "succeeded", view["error"]


def worker_pids(server_pid: int) -> list[int]:
    """The job workers: children of the server's forkserver (a child of the server) that lead
    their own process group (the parse processes, its other children, do not)."""
    return [w for fs in children(server_pid) for w in children(fs) if _group_leader(w)]


def _group_leader(pid: int) -> bool:
    try:
        return os.getpgid(pid) == pid
    except ProcessLookupError:
        return False


def hold_lock(
    db: Path, until: float | threading.Event, ready: threading.Event | None = None
) -> str:
    """An exclusive transaction on the database (writers wait, readers go on) for ``until``
    seconds – the fault – or until that event is set; ``ready`` is set once it holds. The UTC
    time it ended."""
    from api.store import utc_now

    con = sqlite3.connect(db, isolation_level=None, timeout=HANG_S)
    try:
        con.execute("BEGIN EXCLUSIVE")  # every write of the workers and the dispatcher waits
        if ready is not None:
            ready.set()
        if isinstance(until, threading.Event):
            until.wait(HANG_S)
        else:
            time.sleep(until)
        con.execute("ROLLBACK")
    finally:
        con.close()
    return utc_now()


def test_lock_past_the_busy_timeout_while_a_job_finishes(tmp_path: Path) -> None:
    """A lock of 5 s (25 busy timeouts) within the retry time: the job waits and succeeds."""
    db = tmp_path / "jobs.db"
    with served(db, env=ENV, log=tmp_path / "server.log") as server:
        job_id = submit(server.url, long_plan())
        poll(server.url, job_id, ("running",))
        released = hold_lock(db, 5.0)
        view = poll(server.url, job_id, FINAL)
        assert view["status"] == "succeeded", view["error"]
        assert view["finished_at"] >= released  # its last writes waited for the lock
        next_job_runs(server.url)
        pids = descendants(server.process.pid)
    wait_gone([server.process.pid, *pids])


def test_lock_past_the_retry_time_fails_the_job_and_degrades_health(tmp_path: Path) -> None:
    """A lock longer than the retry time: the worker gives up, the dispatcher keeps the job's
    failure until the database answers, /healthz says degraded with the reason meanwhile – it
    answers while the lock is held (it does not wait for the database)."""
    db = tmp_path / "jobs.db"
    env = ENV | {"RIS_PLANNER_DB_RETRY_S": "1"}
    with served(db, env=env, log=tmp_path / "server.log") as server:
        job_id = submit(server.url, long_plan())
        poll(server.url, job_id, ("running",))
        ready, release = threading.Event(), threading.Event()
        holder = threading.Thread(target=hold_lock, args=(db, release, ready))
        holder.start()
        try:
            assert ready.wait(HANG_S)
            # the dispatcher and the worker give up after the retry time: degraded, and why
            deadline = time.monotonic() + HANG_S
            while True:
                health = httpx.get(f"{server.url}/healthz", timeout=HANG_S).json()
                if health["status"] == "degraded" and "did not answer" in health["reason"]:
                    break
                assert time.monotonic() < deadline, health
                time.sleep(0.1)
            assert holder.is_alive()  # answered with the database still locked
        finally:
            release.set()
            holder.join(HANG_S)
        view = poll(server.url, job_id, FINAL)
        assert view["status"] == "failed" and "did not answer" in view["error"], view
        next_job_runs(server.url)
        pids = descendants(server.process.pid)
    wait_gone([server.process.pid, *pids])


def test_database_removed_mid_job(tmp_path: Path) -> None:
    db = tmp_path / "jobs.db"
    with served(db, env=ENV, log=tmp_path / "server.log") as server:
        job_id = submit(server.url, long_plan())
        poll(server.url, job_id, ("running",))
        old_workers = worker_pids(server.process.pid)
        for suffix in ("", "-wal", "-shm"):
            Path(f"{db}{suffix}").unlink(missing_ok=True)
        view = poll(server.url, job_id, FINAL)
        assert view["status"] == "failed" and "database was removed" in view["error"]
        assert str(tmp_path) not in view["error"]  # no server paths in job messages
        wait_gone(old_workers)  # its worker was stopped: its result has nowhere to go
        deadline = time.monotonic() + HANG_S  # the store answers again: ok, the fault on record
        while (health := httpx.get(f"{server.url}/healthz", timeout=HANG_S).json())[
            "status"
        ] != "ok":
            assert time.monotonic() < deadline, health
            time.sleep(0.1)
        assert "removed" in health["last_fault"], health
        assert db.exists()  # recreated empty, and the next job runs in it
        next_job_runs(server.url)
        pids = descendants(server.process.pid)
    wait_gone([server.process.pid, *pids])


def test_sigkill_of_the_server_ends_its_workers(tmp_path: Path) -> None:
    db = tmp_path / "jobs.db"
    with served(db, env=ENV, log=tmp_path / "server.log") as server:
        job_id = submit(server.url, long_plan())
        poll(server.url, job_id, ("running",))
        pids = descendants(server.process.pid)
        assert worker_pids(server.process.pid), "a worker runs the job"
        server.process.send_signal(signal.SIGKILL)
        server.process.wait(timeout=HANG_S)
        wait_gone(pids)  # forkserver and worker end with their server
    with served(db, env=ENV, log=tmp_path / "server.log") as server:
        view = poll(server.url, job_id, FINAL)
        assert view["status"] == "failed" and view["error"].startswith("interrupted")
        next_job_runs(server.url)
        pids = descendants(server.process.pid)
    wait_gone([server.process.pid, *pids])


def test_sigkill_of_a_worker_fails_its_job(tmp_path: Path) -> None:
    db = tmp_path / "jobs.db"
    with served(db, env=ENV, log=tmp_path / "server.log") as server:
        job_id = submit(server.url, long_plan())
        poll(server.url, job_id, ("running",))
        (worker,) = worker_pids(server.process.pid)
        os.kill(worker, signal.SIGKILL)
        view = poll(server.url, job_id, FINAL)
        assert view["status"] == "failed" and "SIGKILL" in view["error"]
        next_job_runs(server.url)
        pids = descendants(server.process.pid)
    wait_gone([server.process.pid, *pids])
