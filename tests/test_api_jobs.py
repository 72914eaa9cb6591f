"""Job store (SQLite) and job runner (worker processes): life cycle, progress, failure,
crash, cancellation, restart recovery; and the job routes over them."""

from __future__ import annotations

import json
import os
import sqlite3
import time
from pathlib import Path

import pytest
from api_helpers import api_client, wait_for
from api_job_kinds import TEST_KINDS
from waits import HANG_S

from api.store import INTERRUPTED_MESSAGE, JobStore


def submit(client, kind: str, document: dict) -> str:  # type: ignore[no-untyped-def]
    """Queue a job of a test kind directly (the product's kinds have POST routes)."""
    app = client.app
    job = app.state.store.create(kind, document)
    app.state.runner.submit(job.id)
    return job.id


# -- store ---------------------------------------------------------------------------------


def test_store_schema_and_transitions(tmp_path: Path) -> None:
    store = JobStore(tmp_path / "sub" / "j.db")
    job = store.create("count", {"steps": 3})
    assert (job.status, job.progress, job.result, job.figures) == ("queued", 0.0, None, {})
    assert store.start(job.id) and not store.start(job.id)  # queued → running only once
    assert store.set_progress(job.id, 0.25, "quarter")
    assert store.get(job.id).progress == 0.25  # type: ignore[union-attr]
    assert store.set_progress(job.id, 7.0, "clipped") and store.get(job.id).progress == 1.0  # type: ignore[union-attr]
    assert store.succeed(job.id, {"x": 1}, {"f": "f.png"})
    assert not store.cancel(job.id) and not store.fail(job.id, "late")  # ended: no change
    done = store.get(job.id)
    assert done is not None and done.status == "succeeded" and done.result == {"x": 1}
    assert done.finished_at is not None and done.started_at is not None
    # the schema rejects impossible rows (a CHECK constraint, not just the Python code)
    with pytest.raises(sqlite3.IntegrityError), sqlite3.connect(store.path) as con:
        con.execute("UPDATE jobs SET status = 'lost' WHERE id = ?", (job.id,))


def test_store_cancelled_job_is_not_finished_by_a_late_worker(tmp_path: Path) -> None:
    store = JobStore(tmp_path / "j.db")
    job = store.create("count", {"steps": 1})
    store.start(job.id)
    assert store.cancel(job.id)
    assert not store.set_progress(job.id, 0.5, "late")
    assert not store.succeed(job.id, {"late": True}, {})
    assert store.get(job.id).status == "cancelled"  # type: ignore[union-attr]


def test_store_recover_fails_running_and_returns_queued(tmp_path: Path) -> None:
    store = JobStore(tmp_path / "j.db")
    a, b, c = (store.create("count", {"steps": i}) for i in range(3))
    store.start(b.id)
    store.start(c.id)
    store.succeed(c.id, {}, {})
    reopened = JobStore(tmp_path / "j.db")  # a new process opening the same file
    assert reopened.recover() == [a.id]
    got = reopened.get(b.id)
    assert got is not None and got.status == "failed" and got.error == INTERRUPTED_MESSAGE
    assert reopened.get(c.id).status == "succeeded"  # type: ignore[union-attr]


def test_store_paging_newest_first(tmp_path: Path) -> None:
    store = JobStore(tmp_path / "j.db")
    ids = [store.create("count" if i % 2 else "fail", {"i": i}).id for i in range(5)]
    page, total = store.list_jobs(limit=2, offset=1)
    assert total == 5 and [j.id for j in page] == [ids[3], ids[2]]
    page, total = store.list_jobs(limit=10, kind="count")
    assert total == 2 and [j.id for j in page] == [ids[3], ids[1]]


# -- runner through the routes ----------------------------------------------------------------


def test_job_runs_in_a_worker_with_progress_and_figure(tmp_path: Path) -> None:
    with api_client(tmp_path, kinds=TEST_KINDS, workers=1) as client:
        job_id = submit(client, "count", {"steps": 12, "sleep_s": 0.1, "figure": True})
        seen = set()
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            view = client.get(f"/v1/jobs/{job_id}").json()
            seen.add(view["progress"])
            if view["status"] == "succeeded":
                break
            time.sleep(0.03)
        assert view["status"] == "succeeded" and view["progress"] == 1.0
        assert view["result"] == {"steps": 12, "sum": 66}
        assert any(0 < p < 1 for p in seen), seen  # progress written back while it ran
        assert view["figures"] == {"curve": f"/v1/jobs/{job_id}/figures/curve"}
        png = client.get(view["figures"]["curve"])
        assert png.status_code == 200 and png.headers["content-type"] == "image/png"
        assert png.content[:8] == b"\x89PNG\r\n\x1a\n"
        missing = client.get(f"/v1/jobs/{job_id}/figures/heatmap")
        assert missing.status_code == 404 and "curve" in missing.json()["message"]


def test_engine_error_and_worker_crash_end_as_failed(tmp_path: Path) -> None:
    with api_client(tmp_path, kinds=TEST_KINDS, workers=2) as client:
        bad = submit(client, "fail", {"what": "the impossible"})
        crash = submit(client, "crash", {})
        view = wait_for(client, bad, ("failed",))
        assert view["error"] == "cannot do the impossible" and view["result"] is None
        view = wait_for(client, crash, ("failed",))
        assert view["error"] == "worker process exited with code 3"


def test_unknown_kind_fails_instead_of_hanging(tmp_path: Path) -> None:
    with api_client(tmp_path, kinds=TEST_KINDS) as client:
        job_id = submit(client, "teleport", {})
        view = wait_for(client, job_id, ("failed",))
        assert "unknown job kind 'teleport'" in view["error"]


def test_cancel_running_and_queued_jobs(tmp_path: Path) -> None:
    with api_client(tmp_path, kinds=TEST_KINDS, workers=1) as client:
        running = submit(client, "sleep", {"sleep_s": 60})
        queued = submit(client, "count", {"steps": 1})
        wait_for(client, running, ("running",))
        assert client.get(f"/v1/jobs/{queued}").json()["status"] == "queued"  # 1 worker busy
        r = client.post(f"/v1/jobs/{queued}/cancel")
        assert r.status_code == 200 and r.json()["status"] == "cancelled"
        t0 = time.monotonic()
        r = client.post(f"/v1/jobs/{running}/cancel")
        assert r.status_code == 200 and r.json()["status"] == "cancelled"
        # the worker process is terminated, the slot frees, and nothing overwrites the state
        while client.app.state.runner.running() and time.monotonic() - t0 < HANG_S:
            time.sleep(0.05)
        assert client.app.state.runner.running() == 0
        assert client.get(f"/v1/jobs/{running}").json()["status"] == "cancelled"
        again = client.post(f"/v1/jobs/{running}/cancel")
        assert again.status_code == 409 and "already ended (cancelled)" in again.json()["message"]


def test_restart_keeps_jobs_requeues_interrupted_ones(tmp_path: Path) -> None:
    """Graceful shutdown puts a running job back in the queue; the next start runs it. A job
    found 'running' at start-up (the process died) is marked failed."""
    with api_client(tmp_path, kinds=TEST_KINDS, workers=1) as client:
        done = submit(client, "count", {"steps": 2})
        wait_for(client, done, ("succeeded",))
        interrupted = submit(client, "count", {"steps": 20, "sleep_s": 0.1})
        wait_for(client, interrupted, ("running",))
    store = JobStore(tmp_path / "jobs.db")
    assert store.get(interrupted).status == "queued"  # type: ignore[union-attr]
    crashed = store.create("count", {"steps": 1})
    store.start(crashed.id)  # as if a server had died while running it
    with api_client(tmp_path, kinds=TEST_KINDS, workers=1) as client:
        listed = {j["id"]: j for j in client.get("/v1/jobs").json()["items"]}
        assert set(listed) == {done, interrupted, crashed.id}
        assert listed[crashed.id]["status"] == "failed"
        assert listed[crashed.id]["error"] == INTERRUPTED_MESSAGE
        view = wait_for(client, interrupted, ("succeeded",))
        assert view["result"] == {"steps": 20, "sum": 190}
        assert client.get(f"/v1/jobs/{done}").json()["result"] == {"steps": 2, "sum": 1}


def test_job_listing_pages_and_filters(tmp_path: Path) -> None:
    with api_client(tmp_path, kinds=TEST_KINDS, workers=2) as client:
        ids = [submit(client, "count", {"steps": 1}) for _ in range(3)]
        failed = submit(client, "fail", {})
        for job_id in ids:
            wait_for(client, job_id, ("succeeded",))
        wait_for(client, failed, ("failed",))
        page = client.get("/v1/jobs", params={"limit": 2}).json()
        assert page["total"] == 4 and page["next_offset"] == 2
        assert [j["id"] for j in page["items"]] == [failed, ids[2]]
        assert "result" not in page["items"][0]  # summaries only
        last = client.get("/v1/jobs", params={"limit": 2, "offset": 2}).json()
        assert [j["id"] for j in last["items"]] == [ids[1], ids[0]] and last["next_offset"] is None
        only = client.get("/v1/jobs", params={"status": "failed"}).json()
        assert [j["id"] for j in only["items"]] == [failed]
        bad = client.get("/v1/jobs", params={"limit": 0, "status": "lost"})
        assert bad.status_code == 422
        assert {f["field"] for f in bad.json()["fields"]} == {"limit", "status"}
        assert {f["location"] for f in bad.json()["fields"]} == {"query"}


def test_job_request_is_stored_as_json(tmp_path: Path) -> None:
    store = JobStore(tmp_path / "j.db")
    job = store.create("count", {"steps": 2, "nested": {"a": [1.5, None]}})
    with sqlite3.connect(store.path) as con:
        raw = con.execute("SELECT request FROM jobs WHERE id = ?", (job.id,)).fetchone()[0]
    assert json.loads(raw) == {"steps": 2, "nested": {"a": [1.5, None]}}


def test_concurrent_submissions_get_distinct_order(tmp_path: Path) -> None:
    from concurrent.futures import ThreadPoolExecutor

    store = JobStore(tmp_path / "j.db")
    with ThreadPoolExecutor(8) as pool:
        ids = list(pool.map(lambda i: store.create("count", {"i": i}).id, range(40)))
    with sqlite3.connect(store.path) as con:
        seqs = [r[0] for r in con.execute("SELECT seq FROM jobs")]
    assert sorted(seqs) == list(range(1, 41)) and len(set(ids)) == 40


def test_describe_error_is_one_line() -> None:
    from pydantic import ValidationError

    from api.worker import describe_error
    from ris_planner.core.errors import RisPlannerError
    from ris_planner.model.scenario import Scenario

    try:
        Scenario.model_validate({"ris": [], "tx": [0, 0, 0]})
    except ValidationError as exc:
        text = describe_error(exc)
    assert "\n" not in text and text.startswith("invalid document: ris: ")
    assert "; rx: Field required" in text
    assert describe_error(RisPlannerError("too many sites")) == "too many sites"
    assert describe_error(KeyError("x")) == "KeyError: 'x'"


def test_second_server_on_the_same_database_is_refused(tmp_path: Path) -> None:
    from api.store import DatabaseInUseError

    with api_client(tmp_path) as client:
        assert client.get("/healthz").status_code == 200
        with pytest.raises(DatabaseInUseError, match="one server per"), api_client(tmp_path):
            pass
    with api_client(tmp_path) as client:  # released at shutdown
        assert client.get("/healthz").status_code == 200


def test_job_beyond_its_memory_budget_fails_with_a_message(tmp_path: Path) -> None:
    with api_client(tmp_path, kinds=TEST_KINDS, workers=1, job_memory_mb=256) as client:
        job_id = submit(client, "hog", {"mb": 2048})
        view = wait_for(client, job_id, ("succeeded", "failed"))
        assert view["status"] == "failed" and "out of memory" in view["error"], view
        ok = wait_for(client, submit(client, "hog", {"mb": 16}), ("succeeded", "failed"))
        assert ok["status"] == "succeeded", ok["error"]


def partial_figures(data: Path) -> list[str]:
    """The partial.png files under ``data``; a folder the server removes while it is walked is
    skipped (os.walk ignores it), where Path.glob would raise FileNotFoundError."""
    return [d for d, _, files in os.walk(data) if "partial.png" in files]


def test_cancelled_job_leaves_no_partial_figures(tmp_path: Path) -> None:
    with api_client(tmp_path, kinds=TEST_KINDS, workers=1) as client:
        job_id = submit(client, "figure_sleep", {})
        data = client.app.state.settings.figures_dir
        deadline = time.monotonic() + 30
        while not partial_figures(data):
            assert time.monotonic() < deadline, "the job never wrote its figure"
            time.sleep(0.05)
        assert client.post(f"/v1/jobs/{job_id}/cancel").status_code == 200
        view = wait_for(client, job_id, ("cancelled",))
        deadline = time.monotonic() + 10
        while partial_figures(data):
            assert time.monotonic() < deadline, "partial figures remain"
            time.sleep(0.05)
        assert view["figures"] == {}


def test_job_messages_carry_no_server_paths() -> None:
    from api.worker import describe_error, redact_paths

    err = describe_error(PermissionError(13, "Permission denied", "/srv/ris/data/jobs.db"))
    assert "/srv" not in err and "jobs.db" in err
    assert redact_paths("cannot read /home/u/maps/a.csv (x)") == "cannot read a.csv (x)"
    assert redact_paths("ratio 1/2 and 0.5/s") == "ratio 1/2 and 0.5/s"


def test_database_lock_is_on_the_file_not_the_path(tmp_path: Path) -> None:
    """Two spellings of one database file (a symlink, a relative path) are the same database."""
    import os

    from api.store import DatabaseInUseError, server_lock

    db = tmp_path / "real" / "jobs.db"
    link = tmp_path / "link.db"
    db.parent.mkdir()
    JobStore(db)
    link.symlink_to(db)
    with server_lock(db):
        with pytest.raises(DatabaseInUseError, match="one server per"), server_lock(link):
            pass
        cwd = os.getcwd()
        try:
            os.chdir(db.parent)
            with pytest.raises(DatabaseInUseError), server_lock(Path("./jobs.db")):
                pass
        finally:
            os.chdir(cwd)
    with server_lock(link):  # released
        pass
