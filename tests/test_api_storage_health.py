"""Storage faults of every class against a real server (uvicorn on 127.0.0.1, stopped by its
PID): the job database made read-only (the file immutable: ``chattr +i``, which binds root
too), its disk full (the database on a small tmpfs, filled up), locked (a connection of the
test holding it exclusively) and corrupt (its header overwritten in place, the same file).
While each lasts, a write answers 503 and ``/healthz`` names the fault's class; once it is
cleared ``/healthz`` is ``ok`` again with the fault on record, and a job runs
(docs/guides/service-operations.md, "Storage faults").

The read-only and full cases need root (``chattr``, ``mount``); they are skipped where the
test cannot make the fault."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from test_api_attacks import wait_until
from test_api_faults import FINAL, poll
from test_api_hardening import lock_database
from test_api_plans import small_plan_doc
from waits import HANG_S

from api.launch import served

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")

ENV = {"RIS_PLANNER_REQUEST_STORE_WAIT_S": "1.5", "RIS_PLANNER_DB_BUSY_TIMEOUT_S": "0.2"}


def _run(*cmd: str) -> bool:
    return subprocess.run(cmd, capture_output=True, check=False).returncode == 0


@contextlib.contextmanager
def read_only(db: Path) -> Iterator[None]:
    if not _run("chattr", "+i", str(db)):
        pytest.skip("chattr +i is not permitted here (needs root and a file system with it)")
    try:
        yield
    finally:
        _run("chattr", "-i", str(db))


@contextlib.contextmanager
def small_disk(folder: Path) -> Iterator[Path]:
    """A 32 MiB tmpfs mounted at ``folder`` (unmounted on exit)."""
    folder.mkdir()
    if not _run("mount", "-t", "tmpfs", "-o", "size=32m", "tmpfs", str(folder)):
        pytest.skip("mounting a tmpfs is not permitted here (needs root)")
    try:
        yield folder
    finally:
        if not _run("umount", str(folder)):
            _run("umount", "-l", str(folder))


@contextlib.contextmanager
def full(db: Path) -> Iterator[None]:
    """Every free byte of the database's file system taken by one file (removed on exit)."""
    filler = db.parent / "filler"
    with open(filler, "wb", buffering=0) as f, contextlib.suppress(OSError):
        while True:
            f.write(b"\0" * (1 << 16))
    try:
        yield
    finally:
        filler.unlink()


@contextlib.contextmanager
def locked(db: Path) -> Iterator[None]:
    ready, release = threading.Event(), threading.Event()
    holder = threading.Thread(target=lock_database, args=(db, ready, release))
    holder.start()
    try:
        assert ready.wait(10)
        yield
    finally:
        release.set()
        holder.join(30)


@contextlib.contextmanager
def corrupt(db: Path) -> Iterator[None]:
    """The database header overwritten in place (the same file), then restored."""
    with open(db, "r+b") as f:
        header = f.read(100)
        f.seek(0)
        f.write(b"\xff" * 100)
    try:
        yield
    finally:
        with open(db, "r+b") as f:
            f.write(header)


FAULTS = {"read-only": read_only, "full": full, "locked": locked, "corrupt": corrupt}


def health(url: str) -> dict[str, Any]:
    answer: dict[str, Any] = httpx.get(f"{url}/healthz", timeout=HANG_S).json()
    return answer


@pytest.mark.parametrize("fault", list(FAULTS))
def test_health_reports_a_storage_fault_while_it_lasts_and_after(
    tmp_path: Path, fault: str
) -> None:
    with contextlib.ExitStack() as stack:
        folder = stack.enter_context(small_disk(tmp_path / "disk")) if fault == "full" else tmp_path
        db = folder / "jobs.db"
        server = stack.enter_context(served(db, env=ENV, log=tmp_path / "server.log"))
        url = server.url
        first = httpx.post(f"{url}/v1/plans", json=small_plan_doc(), timeout=HANG_S).json()["id"]
        poll(url, first, FINAL)
        assert health(url)["status"] == "ok"
        with FAULTS[fault](db):
            r = httpx.post(f"{url}/v1/plans", json=small_plan_doc(), timeout=HANG_S)
            assert r.status_code == 503 and r.headers["retry-after"].isdigit(), r.text[:300]
            during = wait_until(
                lambda: (h := health(url)).get("fault") == fault and h,
                lambda: f"/healthz does not name {fault}: {health(url)}",
            )
            assert during["status"] in ("degraded", "unavailable"), during
            assert fault in during["reason"], during
        after = wait_until(
            lambda: (h := health(url))["status"] == "ok" and h,
            lambda: f"/healthz not ok: {health(url)}",
        )
        assert after["fault"] is None and fault in after["last_fault"], after
        job = httpx.post(f"{url}/v1/plans", json=small_plan_doc(), timeout=HANG_S)
        assert job.status_code == 202, job.text[:300]
        assert poll(url, job.json()["id"], FINAL)["status"] == "succeeded"
    text = (tmp_path / "server.log").read_text()
    assert "Traceback" not in text and "internal_error" not in text, text[-3000:]
