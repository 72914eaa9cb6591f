"""Service hardening against real servers (uvicorn on 127.0.0.1, each stopped by its PID via
``api.launch.served``): storage faults answer 503 with Retry-After within the request bound and
health recovers; security headers on every answer; a client that disconnects mid-body leaves
no traceback; one error class per failure kind; list sizes refused before validation; API keys
owning their jobs; Idempotency-Key; DELETE removes a job (docs/guides/service-operations.md).

Storage fault injection: a connection of the test process holds the database in SQLite's
``locking_mode=EXCLUSIVE`` with an open write transaction, so that no other connection (the
server's, its workers') can read or write the file – the store's real failure path (every
attempt fails with "database is locked" until the request's bound). Root ignores file
permissions, so a read-only file would not fail; the lock fails for every user.
"""

from __future__ import annotations

import json
import socket
import sqlite3
import sys
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
from api_helpers import JSON
from test_api_faults import FINAL, poll, wait_gone
from test_api_plans import small_plan_doc
from waits import HANG_S

from api.auth import key_digest
from api.launch import served

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")

WAIT_S = 1.5
"""The request bound of the fault tests (RIS_PLANNER_REQUEST_STORE_WAIT_S)."""


def lock_database(db: Path, ready: threading.Event, release: threading.Event) -> None:
    """Hold ``db`` exclusively (no reader nor writer gets in) until ``release`` is set."""
    con = sqlite3.connect(db, isolation_level=None, timeout=HANG_S)
    try:
        con.execute("PRAGMA locking_mode=EXCLUSIVE")
        con.execute("BEGIN EXCLUSIVE")
        con.execute("UPDATE jobs SET message = message WHERE 0")
        ready.set()
        release.wait(60)
        con.execute("COMMIT")
    finally:
        con.close()


def test_storage_fault_is_503_with_retry_after_and_health_recovers(tmp_path: Path) -> None:
    db = tmp_path / "jobs.db"
    log = tmp_path / "server.log"
    env = {"RIS_PLANNER_REQUEST_STORE_WAIT_S": str(WAIT_S), "RIS_PLANNER_DB_BUSY_TIMEOUT_S": "0.2"}
    with served(db, env=env, log=log) as server:
        url = server.url
        first = httpx.post(f"{url}/v1/plans", json=small_plan_doc(), timeout=HANG_S)
        assert first.status_code == 202
        poll(url, first.json()["id"], FINAL)
        ready, release = threading.Event(), threading.Event()
        holder = threading.Thread(target=lock_database, args=(db, ready, release))
        holder.start()
        try:
            assert ready.wait(10)
            # each request gives up after the wait and answers 503 while the database is
            # still locked (the lock is released only below): none waits for the lock
            for method, path, body in [
                ("POST", "/v1/plans", small_plan_doc()),
                ("GET", "/v1/jobs", None),
                ("GET", f"/v1/jobs/{first.json()['id']}", None),
                ("DELETE", f"/v1/jobs/{first.json()['id']}", None),
            ]:
                r = httpx.request(method, f"{url}{path}", json=body, timeout=HANG_S)
                assert r.status_code == 503, (path, r.status_code, r.text)
                assert r.headers["retry-after"].isdigit(), r.headers
                assert r.json()["error"] == "unavailable" and "job database" in r.json()["message"]
                assert holder.is_alive(), path
            health = httpx.get(f"{url}/healthz", timeout=HANG_S)
            assert health.status_code == 503 and health.json()["status"] == "unavailable"
        finally:
            release.set()
            holder.join(30)
        deadline = time.monotonic() + HANG_S
        while (h := httpx.get(f"{url}/healthz", timeout=HANG_S).json())["status"] != "ok":
            assert time.monotonic() < deadline, h  # back to ok once the store answers
            time.sleep(0.2)
        assert h["last_fault"], h  # the fault stays on record
        assert httpx.get(f"{url}/v1/jobs", timeout=HANG_S).status_code == 200
        pids = [server.process.pid]
    wait_gone(pids)
    text = log.read_text()
    assert "Traceback" not in text and "internal_error" not in text and "unexpected" not in text


def test_headers_on_every_answer(tmp_path: Path) -> None:
    with served(tmp_path / "jobs.db") as server:
        url = server.url
        answers = {
            path: httpx.get(f"{url}{path}", timeout=HANG_S)
            for path in ("/", "/static/index.html", "/docs", "/redoc", "/docs/oauth2-redirect")
        }
        for path in ("/healthz", "/openapi.json", "/static/app.js", "/v1/nothing", "/v1/jobs/x"):
            r = httpx.get(f"{url}{path}", timeout=HANG_S)
            assert r.headers["x-content-type-options"] == "nosniff", path
        r = httpx.post(f"{url}/v1/bounds", content=b"x" * 20_000_000, timeout=HANG_S)
        assert r.status_code == 413 and r.headers["x-content-type-options"] == "nosniff"
        for path, r in answers.items():
            assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
            csp = r.headers["content-security-policy"]
            assert "frame-ancestors 'none'" in csp and "default-src 'self'" in csp, path
            assert "unsafe-inline" not in csp.split("script-src")[1].split(";")[0], path
            assert r.headers["x-frame-options"] == "DENY", path
            assert r.headers["x-content-type-options"] == "nosniff", path
        # Swagger UI's inline start-up script is admitted by its hash (ReDoc has none)
        assert "'sha256-" in answers["/docs"].headers["content-security-policy"]
        for path in ("/docs", "/redoc"):
            assert "cdn" not in answers[path].text.lower(), path


def test_client_disconnect_mid_body_is_no_error(tmp_path: Path) -> None:
    log = tmp_path / "server.log"
    with served(tmp_path / "jobs.db", log=log) as server:
        host, port = server.url.removeprefix("http://").split(":")
        for path in ("/v1/plans", "/v1/bounds", "/v1/import", "/v1/plans/validate"):
            with socket.create_connection((host, int(port)), timeout=HANG_S) as s:
                head = f"POST {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n"
                s.sendall(f"{head}Content-Length: 1000\r\n\r\n".encode() + b'{"a": 1')
            time.sleep(0.3)
        assert httpx.get(f"{server.url}/healthz", timeout=HANG_S).status_code == 200
        pids = [server.process.pid]
    wait_gone(pids)
    text = log.read_text()
    assert "Traceback" not in text and "ClientDisconnect" not in text, text[-2000:]
    assert "unexpected error" not in text


def test_terminated_parse_executor_leaves_nothing_for_the_exit_hook() -> None:
    """The interpreter's exit hook writes to every live executor's wake-up pipe while that
    executor's manager thread may be closing it (Python 3.11: EBADF, a traceback in the
    server's log at shutdown). A terminated executor's manager thread is joined and its pipe
    closed before ``_terminate`` returns – both were forgotten by ``shutdown`` before."""
    from api.offload import ParsePool, _ready

    pool = ParsePool._new_executor()
    assert pool.submit(_ready).result(timeout=HANG_S) > 0
    manager = getattr(pool, "_executor_manager_thread", None)  # typeshed types it wrongly
    wakeup = pool._executor_manager_thread_wakeup
    assert manager is not None and wakeup is not None
    ParsePool._terminate(pool, HANG_S)
    assert not manager.is_alive()
    assert wakeup._closed


def nested(depth: int) -> str:
    return "[" * depth + "]" * depth


def test_one_error_class_per_failure_kind(tmp_path: Path) -> None:
    with served(tmp_path / "jobs.db") as server:
        url = server.url
        routes = ["/v1/bounds", "/v1/plans", "/v1/plans/validate", "/v1/power-allocations"]
        routes += ["/v1/sites", "/v1/import?format=geojson", "/v1/import?format=sites"]
        huge = '{"a": ' + "7" * 100_000 + "}"
        for route in routes:
            for body in (nested(10_000), '{"x": ' + nested(100) + "}", "{not json"):
                r = httpx.post(f"{url}{route}", content=body, headers=JSON, timeout=HANG_S)
                assert r.status_code == 400 and r.json()["error"] == "bad_request", (route, r.text)
            r = httpx.post(f"{url}{route}", content=huge, headers=JSON, timeout=HANG_S)
            assert r.status_code == 413, (route, r.status_code, r.text[:300])
            assert "digits" in r.json()["message"] and "sys." not in r.text, route
            r = httpx.post(f"{url}{route}", content=b"x" * 20_000_000, timeout=HANG_S)
            assert r.status_code == 413 and r.json()["limit"] == 10_000_000, route


def test_list_sizes_refused_before_validation(tmp_path: Path) -> None:
    prism = {"kind": "prism", "footprint": [[0, 0], [1, 0], [1, 1]], "height": 3}
    doc = small_plan_doc()
    doc["environment"] = {"obstacles": [prism] * 100_001}
    body = json.dumps(doc)
    with served(tmp_path / "jobs.db", env={"RIS_PLANNER_MAX_BODY_BYTES": "20000000"}) as server:
        # the parse processes started (they boot with the server, in the background)
        small = httpx.post(f"{server.url}/v1/plans/validate", json=small_plan_doc(), timeout=HANG_S)
        assert small.status_code == 200, small.text[:300]
        for route in ("/v1/plans", "/v1/plans/validate", "/v1/bounds"):
            r = httpx.post(f"{server.url}{route}", content=body, headers=JSON, timeout=HANG_S)
            # counted, never validated: every prism is invalid ("height" is not a field), so a
            # validation would have answered 422
            assert r.status_code == 413 and r.json()["limit"] == 100_000, r.text[:300]
            assert "100001 obstacles exceed the limit of 100000" in r.json()["message"]


def headers(key: str, **more: str) -> dict[str, str]:
    return {"X-API-Key": key, **more}


def test_api_keys_own_their_jobs_and_idempotent_submissions(tmp_path: Path) -> None:
    keys_file = tmp_path / "keys"
    keys_file.write_text(f"# name:sha256\nbob:{key_digest('bob-key')}\n")
    env = {
        "RIS_PLANNER_API_KEY": "admin-key",
        "RIS_PLANNER_API_KEYS": f"alice:{key_digest('alice-key')}",
        "RIS_PLANNER_API_KEYS_FILE": str(keys_file),
    }
    with served(tmp_path / "jobs.db", env=env) as server:
        url = server.url
        doc = small_plan_doc()
        assert httpx.get(f"{url}/v1/jobs", timeout=HANG_S).status_code == 401
        assert (
            httpx.get(f"{url}/v1/jobs", headers=headers("alice"), timeout=HANG_S).status_code == 401
        )
        assert httpx.get(f"{url}/healthz", timeout=HANG_S).status_code == 200
        alice = headers("alice-key", **{"Idempotency-Key": "run-1"})
        r1 = httpx.post(f"{url}/v1/plans", json=doc, headers=alice, timeout=HANG_S)
        r2 = httpx.post(f"{url}/v1/plans", json=doc, headers=alice, timeout=HANG_S)
        assert r1.status_code == r2.status_code == 202
        job = r1.json()["id"]
        assert r2.json()["id"] == job and r2.headers["idempotent-replayed"] == "true"
        other = small_plan_doc(description="another")
        r3 = httpx.post(f"{url}/v1/plans", json=other, headers=alice, timeout=HANG_S)
        assert r3.status_code == 409 and r3.json()["error"] == "conflict"
        bob = headers("bob-key", **{"Idempotency-Key": "run-1"})  # same key, other owner
        rb = httpx.post(f"{url}/v1/plans", json=doc, headers=bob, timeout=HANG_S)
        assert rb.status_code == 202 and rb.json()["id"] != job
        bob_job = rb.json()["id"]
        for h, own, other_job in ((alice, job, bob_job), (bob, bob_job, job)):
            page = httpx.get(f"{url}/v1/jobs", headers=h, timeout=HANG_S).json()
            assert [j["id"] for j in page["items"]] == [own] and page["total"] == 1
            for method, path in [
                ("GET", f"/v1/jobs/{other_job}"),
                ("GET", f"/v1/jobs/{other_job}/events"),
                ("GET", f"/v1/jobs/{other_job}/figures/topview"),
                ("POST", f"/v1/jobs/{other_job}/cancel"),
                ("DELETE", f"/v1/jobs/{other_job}"),
            ]:
                r = httpx.request(method, f"{url}{path}", headers=h, timeout=HANG_S)
                assert r.status_code == 404 and r.json()["error"] == "not_found", (method, path)
        admin = headers("admin-key")
        page = httpx.get(f"{url}/v1/jobs", headers=admin, timeout=HANG_S).json()
        assert {j["id"] for j in page["items"]} == {job, bob_job}
        # DELETE removes (the admin may remove any job); POST .../cancel of an ended job: 409
        view = poll_key(url, job, admin)
        r = httpx.post(f"{url}/v1/jobs/{job}/cancel", headers=admin, timeout=HANG_S)
        assert r.status_code == 409 and view["status"] in FINAL
        assert (
            httpx.delete(f"{url}/v1/jobs/{job}", headers=admin, timeout=HANG_S).status_code == 204
        )
        for h in (admin, alice):
            assert httpx.get(f"{url}/v1/jobs/{job}", headers=h, timeout=HANG_S).status_code == 404
        assert (
            httpx.delete(f"{url}/v1/jobs/{job}", headers=admin, timeout=HANG_S).status_code == 404
        )


def poll_key(url: str, job_id: str, h: dict[str, str], timeout_s: float = HANG_S) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        view: dict[str, Any] = httpx.get(
            f"{url}/v1/jobs/{job_id}", headers=h, timeout=HANG_S
        ).json()
        if view["status"] in FINAL:
            return view
        assert time.monotonic() < deadline, view
        time.sleep(0.05)


def test_delete_of_a_running_job_cancels_and_removes_it(tmp_path: Path) -> None:
    from test_api_faults import long_plan, worker_pids

    db = tmp_path / "jobs.db"
    with served(db) as server:
        url = server.url
        job = httpx.post(f"{url}/v1/plans", json=long_plan(), timeout=HANG_S).json()["id"]
        poll(url, job, ("running",))
        workers = worker_pids(server.process.pid)
        assert httpx.delete(f"{url}/v1/jobs/{job}", timeout=HANG_S).status_code == 204
        wait_gone(workers)  # its worker process was terminated
        time.sleep(0.5)  # the dispatcher reaps it: no row comes back
        assert httpx.get(f"{url}/v1/jobs/{job}", timeout=HANG_S).status_code == 404
        assert httpx.get(f"{url}/v1/jobs", timeout=HANG_S).json()["total"] == 0
        assert not (Path(f"{db}.data") / job).exists()


def test_healthz_answers_under_load() -> None:
    """A bounded version of ``benchmarks/service/bench_service_liveness.py`` on one server: 30
    concurrent plan submissions, a plan of 20 000 prisms (1.6 MB), the validation of 10 000,
    a GeoJSON import of 40 000 vertices and 20 open event streams; ``/healthz`` answers 200
    throughout each (the documents are parsed in the parse processes, api.offload). How fast it
    answers is the benchmark's figure (docs/validation/measured-times.md, "Service"), not a
    bound here: a busy machine slows every answer alike."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks" / "service"))
    from bench_service_liveness import measure

    loads = ("idle", "concurrent", "prisms", "import", "streams")
    figures = measure(smoke=True, only=loads)
    assert len(figures) == 6
    for load in figures:
        assert set(load["health_statuses"]) == {200}, load


def test_every_sqlite_error_is_503(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A full disk or a read-only database (SQLite errors that are not retried) answer 503 with
    Retry-After through the same handler (in-process: the store's call raises as SQLite
    would)."""
    from api_helpers import api_client

    from api.store import JobStore

    def full(*args: Any, **kwargs: Any) -> Any:
        raise sqlite3.OperationalError("database or disk is full")

    with api_client(tmp_path) as client:
        monkeypatch.setattr(JobStore, "create_once", full)
        monkeypatch.setattr(JobStore, "list_jobs", full)
        for r in (client.post("/v1/plans", json=small_plan_doc()), client.get("/v1/jobs")):
            assert r.status_code == 503 and r.headers["retry-after"] == "5", r.text
            assert "disk is full" in r.json()["message"]


def _niceness(pid: int) -> int:
    """The process's nice value (field 19 of /proc/PID/stat)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[16])


def test_job_processes_run_nicer_than_the_server(tmp_path: Path) -> None:
    """A job's process yields the CPU to the server and its parse processes (liveness)."""
    from test_api_faults import long_plan, worker_pids

    from api.worker import JOB_NICENESS

    with served(tmp_path / "jobs.db") as server:
        url = server.url
        job = httpx.post(f"{url}/v1/plans", json=long_plan(), timeout=HANG_S).json()["id"]
        poll(url, job, ("running",))
        workers = worker_pids(server.process.pid)
        assert workers
        base = _niceness(server.process.pid)
        assert all(_niceness(w) == min(19, base + JOB_NICENESS) for w in workers)
        assert httpx.delete(f"{url}/v1/jobs/{job}", timeout=HANG_S).status_code == 204
        wait_gone(workers)
