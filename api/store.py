"""The persistent job store: one SQLite file (stdlib ``sqlite3``), shared by the server process
and its worker processes.

Every call opens its own short-lived connection (WAL journal, 10 s busy timeout), so the store
is safe to use from the event loop's thread pool and from worker processes at once. Status
changes are conditional updates (``... WHERE status IN (...)``): a job that was cancelled is
never turned into "succeeded" by a worker that finishes late.

Life cycle: ``queued`` → ``running`` → ``succeeded`` | ``failed``; ``queued``/``running`` →
``cancelled``. On start-up (:meth:`JobStore.recover`) a job found ``running`` is marked
``failed`` – the server died while it ran, and re-running a job that may have caused the crash
could crash again – and ``queued`` jobs are handed back to be run. A graceful shutdown instead
puts its running jobs back to ``queued`` (:meth:`JobStore.requeue`): they were not at fault and
run again on the next start.

Faults (README "Fault behaviour"): every call is retried with exponential backoff while SQLite
reports a transient error (locked, busy, I/O) for up to ``retry_s`` seconds, then raises
:class:`StoreUnavailableError`. Every failing call records its fault by class (:func:`fault_kind`:
locked, read-only, full, corrupt, …) in :attr:`JobStore.faults`; a fault met by a write lasts
until a write succeeds (a read-only file still reads), one met by a read until any call does.
:meth:`JobStore.write_fault` has one row written, at most every :data:`PROBE_EVERY_S` and on a
thread of its own, for ``/healthz``: a read-only or full database is seen even when nobody
submits.

The store remembers the identity (device, inode) of its file:
a call that finds the file removed or replaced raises :class:`StoreGoneError` – a worker's
store never creates a file – except in the server's store (``recreate=True``), which creates a
fresh empty database at the same path, records the fault and tells its listener (the job runner
fails the jobs that were lost with the old file). One server per database: the server holds an
exclusive ``flock`` on the database file itself, so two paths to one file (a symlink, ``./x``
and an absolute path) collide.
"""

from __future__ import annotations

import fcntl
import json
import logging
import math
import os
import sqlite3
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal, get_args

JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]
JOB_STATUSES: tuple[JobStatus, ...] = get_args(JobStatus)

INTERRUPTED_MESSAGE = "interrupted: the server stopped while this job was running; submit it again"
LOST_MESSAGE = (
    "lost: the job database was removed or replaced while this job was {status}; a new empty"
    " database was created; submit the job again"
)

BUSY_TIMEOUT_S = 10.0
"""SQLite's wait for a lock held by another connection, per attempt."""
RETRY_S = 60.0
"""Total time a store call keeps retrying transient errors before it gives up."""
BACKOFF_S = (0.05, 2.0)
"""First and largest pause between two attempts (doubling)."""

log = logging.getLogger("api.store")

CALL_BUDGET_S: ContextVar[float | None] = ContextVar("store_call_budget_s", default=None)
"""The longest a store call may wait (lock waits and retries together) in the current context:
set per HTTP request by the service (``Settings.request_store_wait_s``), so that a request
answers 503 within a known bound while the job workers keep their longer ``retry_s``."""

_SCHEMA = """
CREATE TABLE IF NOT EXISTS jobs (
    id          TEXT PRIMARY KEY,
    kind        TEXT NOT NULL,
    status      TEXT NOT NULL CHECK (status IN
                    ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    progress    REAL NOT NULL DEFAULT 0 CHECK (progress >= 0 AND progress <= 1),
    message     TEXT NOT NULL DEFAULT '',
    request     TEXT NOT NULL,
    result      TEXT,
    error       TEXT,
    figures     TEXT NOT NULL DEFAULT '{}',
    seq         INTEGER NOT NULL,
    created_at  TEXT NOT NULL,
    started_at  TEXT,
    finished_at TEXT
);
CREATE INDEX IF NOT EXISTS jobs_seq ON jobs (seq);
CREATE INDEX IF NOT EXISTS jobs_status ON jobs (status);
CREATE TABLE IF NOT EXISTS health_probe (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    at TEXT NOT NULL
);
"""

_ADDED_COLUMNS = {"owner": "TEXT", "idempotency_key": "TEXT", "estimate": "TEXT"}
"""Columns added after the first schema (added to an older database when it is opened)."""

_ADDED_INDEXES = """
CREATE UNIQUE INDEX IF NOT EXISTS jobs_idempotency_key
    ON jobs (COALESCE(owner, ''), idempotency_key) WHERE idempotency_key IS NOT NULL;
CREATE INDEX IF NOT EXISTS jobs_owner ON jobs (owner, seq);
"""
"""Indexes added after the first schema. An Idempotency-Key is unique per owner, the keyless
owner (NULL) included: SQLite takes NULLs as distinct in a unique index, so the index is on
``COALESCE(owner, '')`` (an API key's name is never empty)."""

SCHEMA_VERSION = 2
"""``PRAGMA user_version`` of the current schema. 0 or 1: the unique index was on
``(owner, idempotency_key)`` and held nothing without API keys; :func:`_migrate` keeps the key
on the first job of each duplicate (the others stay, without a key) before the new index."""


class DatabaseInUseError(RuntimeError):
    """Another server process holds the database's lock."""


class StoreUnavailableError(RuntimeError):
    """The database did not answer within the retry time (locked, busy, I/O errors); ``kind``:
    the fault's class (:func:`fault_kind`)."""

    def __init__(self, message: str, kind: FaultKind = "error") -> None:
        super().__init__(message)
        self.kind = kind


class StoreGoneError(StoreUnavailableError):
    """The database file was removed or replaced since the store opened it."""


FileIdentity = tuple[int, int]
"""(st_dev, st_ino) of a database file."""


def file_identity(path: Path) -> FileIdentity | None:
    """The file's (device, inode), None when it does not exist."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    return (st.st_dev, st.st_ino)


class DatabaseLock:
    """An exclusive ``flock`` on the database file itself (created empty if missing: SQLite
    takes an empty file as a new database). ``flock`` locks are separate from SQLite's POSIX
    record locks; the descriptor is closed only after the store's last connection (closing an
    fd of a file drops the process's POSIX locks on it). The kernel releases the lock when the
    process dies."""

    def __init__(self, db_path: Path | str) -> None:
        self.db_path = Path(db_path)
        self._fd: int | None = None

    def acquire(self) -> None:
        self.db_path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.db_path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise DatabaseInUseError(
                f"another server process uses the job database {self.db_path.name}; run one"
                " server per database (one uvicorn process)"
            ) from None
        self.release()
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None


@contextmanager
def server_lock(db_path: Path | str) -> Iterator[DatabaseLock]:
    """Hold the database's lock while a server runs: a second server (e.g. ``uvicorn
    --workers 2``) on the same database would re-queue and fail the first one's jobs at its
    start-up, so it is refused."""
    lock = DatabaseLock(db_path)
    lock.acquire()
    try:
        yield lock
    finally:
        lock.release()


def _migrate(con: sqlite3.Connection) -> None:
    """Create the schema, or bring an older database to :data:`SCHEMA_VERSION` (in the
    caller's transaction)."""
    for statement in _SCHEMA.split(";"):
        if statement.strip():
            con.execute(statement)
    have = {row[1] for row in con.execute("PRAGMA table_info(jobs)")}
    for name, sql_type in _ADDED_COLUMNS.items():
        if name not in have:
            con.execute(f"ALTER TABLE jobs ADD COLUMN {name} {sql_type}")
    if int(con.execute("PRAGMA user_version").fetchone()[0]) < SCHEMA_VERSION:
        con.execute("DROP INDEX IF EXISTS jobs_idempotency")
        con.execute(  # duplicates made while the old index held nothing: the first keeps it
            "UPDATE jobs SET idempotency_key = NULL WHERE idempotency_key IS NOT NULL AND seq >"
            " (SELECT MIN(seq) FROM jobs AS first WHERE first.idempotency_key ="
            " jobs.idempotency_key AND COALESCE(first.owner, '') = COALESCE(jobs.owner, ''))"
        )
    for statement in _ADDED_INDEXES.split(";"):
        if statement.strip():
            con.execute(statement)
    con.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")


def _transient(exc: sqlite3.Error) -> bool:
    """Errors worth another attempt: locks and busy databases, I/O hiccups."""
    text = str(exc).lower()
    return isinstance(exc, sqlite3.OperationalError) and any(
        word in text for word in ("locked", "busy", "disk i/o", "unable to open")
    )


FaultKind = Literal["locked", "read-only", "full", "corrupt", "io", "missing", "gone", "error"]
"""The class of a storage fault: the database locked or busy, read-only, its disk full, its
file corrupt (or not a database), an I/O error, the file missing or unopenable, replaced or
removed under the server, any other SQLite error."""


def _no_space(path: Path) -> bool:
    """Whether the file system of ``path`` has no free block left (a full disk shows up in
    SQLite as an I/O error as often as SQLITE_FULL: its shared-memory file cannot grow)."""
    try:
        return os.statvfs(path.parent).f_bavail == 0
    except OSError:
        return False


def fault_kind(exc: BaseException, path: Path) -> FaultKind:
    """The class of a store error (SQLite's error name where Python gives it, else its text)."""
    if isinstance(exc, StoreGoneError):
        return "gone"
    if isinstance(exc, StoreUnavailableError):
        return exc.kind
    name = str(getattr(exc, "sqlite_errorname", "") or "")
    text = str(exc).lower()
    if name.startswith(("SQLITE_BUSY", "SQLITE_LOCKED")) or "locked" in text or "busy" in text:
        return "locked"
    if name.startswith("SQLITE_READONLY") or "readonly" in text:
        return "read-only"
    if name.startswith("SQLITE_FULL") or "is full" in text:
        return "full"
    if name.startswith(("SQLITE_CORRUPT", "SQLITE_NOTADB")) or "malformed" in text:
        return "corrupt"
    if "not a database" in text:
        return "corrupt"
    io = name.startswith("SQLITE_IOERR") or "disk i/o" in text
    unopened = name.startswith("SQLITE_CANTOPEN") or "unable to open" in text
    if (io or unopened) and _no_space(path):
        return "full"
    return "io" if io else "missing" if unopened else "error"


@dataclass
class Fault:
    """One fault the store met (README "Fault behaviour")."""

    at: str
    reason: str
    kind: FaultKind = "error"
    mono: float = field(default_factory=time.monotonic)


@dataclass
class FaultLog:
    """The last faults, and the one the store has now (``current``: its reason, ``kind``: its
    class, ``by_write``: whether a write met it – only a write that succeeds ends it then)."""

    current: str | None = None
    kind: FaultKind | None = None
    by_write: bool = False
    recent: list[Fault] = field(default_factory=list)

    def record(self, reason: str, kind: FaultKind = "error", write: bool = False) -> None:
        self.current, self.kind, self.by_write = reason, kind, write
        if not self.recent or self.recent[-1].reason != reason:
            self.recent = [*self.recent[-9:], Fault(utc_now(), reason, kind)]

    def clear(self, write: bool = True) -> None:
        """A call succeeded: a write ends any fault, a read one that a read met."""
        if write or not self.by_write:
            self.current, self.kind, self.by_write = None, None, False


def fault_reason(kind: FaultKind, exc: BaseException) -> str:
    """A fault's line: its class and SQLite's words (``job database read-only: attempt to
    write a readonly database``)."""
    return f"job database {kind}: {exc}"


PROBE_EVERY_S = 1.0
"""``/healthz`` has its probe row written at most this often (:meth:`JobStore.write_fault`)."""
PROBE_LOCK_WAIT_S = 1.0
"""The probe's wait for the write lock (a lock held longer is not a fault of its own)."""


def utc_now() -> str:
    """ISO 8601 UTC timestamp with microseconds."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


@dataclass(frozen=True)
class JobHead:
    """A job's state without its documents (listings, the dispatcher): no JSON to decode."""

    id: str
    kind: str
    status: JobStatus
    progress: float
    message: str
    error: str | None
    created_at: str
    started_at: str | None
    finished_at: str | None
    owner: str | None
    estimate: str | None
    """The job's resource estimate as JSON text (a plan's: ``{"time_s", "memory_mib",
    "budget_mib"}``, made at submission), or None; :attr:`estimate_json` decodes it."""

    @classmethod
    def from_row(cls, row: sqlite3.Row) -> JobHead:
        return cls(**{name: row[name] for name in HEAD_COLUMNS})

    @property
    def estimate_json(self) -> dict[str, Any] | None:
        """The decoded :attr:`estimate`."""
        return None if self.estimate is None else dict(json.loads(self.estimate))


HEAD_COLUMNS = tuple(JobHead.__dataclass_fields__)
_HEAD_SELECT = ", ".join(HEAD_COLUMNS)


@dataclass(frozen=True)
class Job(JobHead):
    """One row of the job table, JSON columns decoded."""

    request: dict[str, Any]
    result: dict[str, Any] | None
    figures: dict[str, str]

    @classmethod
    def from_row(cls, row: sqlite3.Row) -> Job:
        return cls(
            **{name: row[name] for name in HEAD_COLUMNS},
            request=json.loads(row["request"]),
            result=None if row["result"] is None else json.loads(row["result"]),
            figures=json.loads(row["figures"]),
        )


class JsonText(str):
    """A request document as its JSON text (what the store keeps), for :meth:`JobStore.
    create_once`."""


class JobStore:
    """Jobs in one SQLite file; the schema is created when the store is opened.

    ``expect``: the file identity the store must find (a worker checks that it writes to the
    server's database); ``recreate``: the server's store, which creates a fresh database when
    the file was removed (and calls ``on_recreated``)."""

    def __init__(
        self,
        path: Path | str,
        *,
        expect: FileIdentity | None = None,
        recreate: bool = False,
        busy_timeout_s: float = BUSY_TIMEOUT_S,
        retry_s: float = RETRY_S,
    ) -> None:
        self.path = Path(path)
        self.recreate = recreate
        self.busy_timeout_s = busy_timeout_s
        self.retry_s = retry_s
        self.faults = FaultLog()
        self.on_recreated: Callable[[], None] | None = None
        self._reopen_lock = threading.Lock()
        self._probe_lock = threading.Lock()
        self._probe: tuple[float, BaseException | None] = (-math.inf, None)
        self._probing = False
        if expect is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._create_schema()
            identity = file_identity(self.path)
            assert identity is not None
            self.identity: FileIdentity = identity
        else:
            self.identity = expect
            self._check_identity()

    def _create_schema(self) -> None:
        con = sqlite3.connect(self.path, timeout=self.busy_timeout_s, isolation_level=None)
        try:
            con.execute("PRAGMA journal_mode=WAL")
            con.execute("BEGIN IMMEDIATE")  # one schema change at a time, all or nothing
            try:
                _migrate(con)
            except BaseException:
                con.execute("ROLLBACK")
                raise
            con.execute("COMMIT")
        finally:
            con.close()

    def _check_identity(self) -> None:
        """Raise :class:`StoreGoneError` when the file is not the one this store opened; the
        server's store recreates it instead."""
        if file_identity(self.path) == self.identity:
            return
        if not self.recreate:
            raise StoreGoneError(f"the job database {self.path.name} was removed or replaced")
        with self._reopen_lock:
            if file_identity(self.path) == self.identity:
                return  # another thread recreated it meanwhile
            for suffix in ("-wal", "-shm"):  # stale journal files of the removed database
                Path(f"{self.path}{suffix}").unlink(missing_ok=True)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._create_schema()
            identity = file_identity(self.path)
            assert identity is not None
            self.identity = identity
            reason = (
                f"the job database {self.path.name} was removed or replaced while the server"
                " ran; a new empty database was created (jobs it held are lost)"
            )
            log.error(reason)
            self.faults.record(reason, "gone")
            self.faults.clear()
        if self.on_recreated is not None:
            self.on_recreated()

    @contextmanager
    def _connect(self, timeout_s: float | None = None) -> Iterator[sqlite3.Connection]:
        """One attempt: a connection in one transaction (commit on success)."""
        self._check_identity()
        timeout = self.busy_timeout_s if timeout_s is None else timeout_s
        # mode=rw: never create a file behind the store's back (a removed database)
        con = sqlite3.connect(f"file:{self.path}?mode=rw", uri=True, timeout=timeout)
        con.row_factory = sqlite3.Row
        try:
            with con:  # one transaction: commit on success, roll back on error
                yield con
        finally:
            con.close()

    def _run(
        self, work: Callable[[sqlite3.Connection], Any], *, retry: bool = True, write: bool = False
    ) -> Any:
        """``work(con)`` in one transaction, retried with backoff on transient errors for up
        to ``retry_s`` (README "Fault behaviour"); :class:`StoreUnavailableError` after that.
        Within an HTTP request (:data:`CALL_BUDGET_S` set) lock waits and retries together end
        after that budget (docs/guides/service-operations.md). Every error is recorded in
        :attr:`faults` by its class; ``write``: the call writes (see :class:`FaultLog`)."""
        budget = CALL_BUDGET_S.get()
        retry_s = self.retry_s if budget is None else min(self.retry_s, budget)
        start = time.monotonic()
        deadline = start + (retry_s if retry else 0.0)
        pause = BACKOFF_S[0]
        while True:
            timeout_s = None if retry else min(self.busy_timeout_s, 1.0)
            if budget is not None:  # each attempt's lock wait within what is left
                left = max(0.05, start + budget - time.monotonic())
                timeout_s = min(timeout_s or self.busy_timeout_s, left)
            try:
                with self._connect(timeout_s) as con:
                    out = work(con)
                if self.faults.current is not None:
                    self.faults.clear(write)
                return out
            except StoreGoneError:
                raise
            except sqlite3.Error as exc:
                kind = fault_kind(exc, self.path)
                self.faults.record(fault_reason(kind, exc), kind, write)
                if not _transient(exc) and file_identity(self.path) == self.identity:
                    raise
                if time.monotonic() + pause > deadline:
                    waited = time.monotonic() - start
                    raise StoreUnavailableError(
                        f"the job database did not answer for {waited:.1f} s ({kind}: {exc})",
                        kind,
                    ) from None
                time.sleep(pause)
                pause = min(2 * pause, BACKOFF_S[1])

    # -- creation and reading -------------------------------------------------------------

    def create(self, kind: str, request: dict[str, Any], *, owner: str | None = None) -> Job:
        """A new ``queued`` job holding the (validated) request document."""
        return self.create_once(kind, request, owner=owner)[0]

    def create_once(
        self,
        kind: str,
        request: dict[str, Any] | JsonText,
        *,
        owner: str | None = None,
        idempotency_key: str | None = None,
        estimate: dict[str, Any] | None = None,
    ) -> tuple[Job, bool]:
        """A new ``queued`` job holding the (validated) request document, owned by ``owner``
        (an API key's name; None without keys); ``(job, True)``. With an ``idempotency_key``
        already used by the same owner, the job created then and ``False`` (nothing new).
        ``request`` may be the document's JSON text already (:class:`JsonText`, rendered by a
        parse process: the server never holds the parsed document); the new job's ``request``
        is then empty (the caller has the document). ``estimate``: its resource estimate (a
        plan's), kept with it."""
        job_id = uuid.uuid4().hex
        created_at = utc_now()
        text = request if isinstance(request, JsonText) else json.dumps(request, allow_nan=False)
        est = None if estimate is None else json.dumps(estimate, allow_nan=False)

        def work(con: sqlite3.Connection) -> sqlite3.Row | None:
            if idempotency_key is not None:
                # the write lock first: the look-up and the insert are one transaction, so of
                # concurrent retries the first creates the job and the others find it
                con.execute("BEGIN IMMEDIATE")
                row: sqlite3.Row | None = con.execute(
                    "SELECT * FROM jobs WHERE COALESCE(owner, '') = COALESCE(?, '')"
                    " AND idempotency_key = ?",
                    (owner, idempotency_key),
                ).fetchone()
                if row is not None:
                    return row
            con.execute(  # one statement: seq is unique under concurrent inserts
                "INSERT INTO jobs (id, kind, status, request, seq, created_at, owner,"
                " idempotency_key, estimate) SELECT ?, ?, 'queued', ?, COALESCE(MAX(seq), 0) + 1,"
                " ?, ?, ?, ? FROM jobs",
                (job_id, kind, text, created_at, owner, idempotency_key, est),
            )
            return None

        existing: sqlite3.Row | None = self._run(work, write=True)
        if existing is not None:
            return Job.from_row(existing), False
        job = Job(
            id=job_id,
            kind=kind,
            status="queued",
            progress=0.0,
            message="",
            error=None,
            created_at=created_at,
            started_at=None,
            finished_at=None,
            owner=owner,
            estimate=est,
            request={} if isinstance(request, JsonText) else request,
            result=None,
            figures={},
        )
        return job, True

    def delete(self, job_id: str) -> bool:
        """Remove the job's row (True if it existed)."""
        changed: int = self._run(
            lambda con: con.execute("DELETE FROM jobs WHERE id = ?", (job_id,)).rowcount,
            write=True,
        )
        return changed == 1

    def _row(self, sql: str, args: tuple[Any, ...]) -> sqlite3.Row | None:
        row: sqlite3.Row | None = self._run(lambda con: con.execute(sql, args).fetchone())
        return row

    def get(self, job_id: str) -> Job | None:
        row = self._row("SELECT * FROM jobs WHERE id = ?", (job_id,))
        return None if row is None else Job.from_row(row)

    def head(self, job_id: str) -> JobHead | None:
        """The job's state without decoding its request and result."""
        row = self._row(f"SELECT {_HEAD_SELECT} FROM jobs WHERE id = ?", (job_id,))
        return None if row is None else JobHead.from_row(row)

    def list_jobs(
        self,
        *,
        limit: int,
        offset: int = 0,
        status: JobStatus | None = None,
        kind: str | None = None,
        owner: str | None = None,
    ) -> tuple[list[JobHead], int]:
        """A page of jobs (without their documents), newest first, and the total count
        matching the filters (``owner``: only that owner's jobs)."""
        where: list[str] = []
        args: list[str] = []
        if owner is not None:
            where.append("owner = ?")
            args.append(owner)
        if status is not None:
            where.append("status = ?")
            args.append(status)
        if kind is not None:
            where.append("kind = ?")
            args.append(kind)
        clause = f"WHERE {' AND '.join(where)}" if where else ""

        def work(con: sqlite3.Connection) -> tuple[int, list[sqlite3.Row]]:
            total = con.execute(f"SELECT COUNT(*) FROM jobs {clause}", args).fetchone()[0]
            rows = con.execute(
                f"SELECT {_HEAD_SELECT} FROM jobs {clause} ORDER BY seq DESC LIMIT ? OFFSET ?",
                [*args, limit, offset],
            ).fetchall()
            return int(total), rows

        total, rows = self._run(work)
        return [JobHead.from_row(r) for r in rows], total

    def ids_with_status(self, status: JobStatus) -> list[str]:
        """Ids of all jobs with this status, oldest first."""
        rows = self._run(
            lambda con: con.execute(
                "SELECT id FROM jobs WHERE status = ? ORDER BY seq", (status,)
            ).fetchall()
        )
        return [r["id"] for r in rows]

    def counts(self, *, retry: bool = True) -> dict[str, int]:
        """Number of jobs per status (every status present, 0 if none); ``retry=False``: one
        attempt (``/healthz`` answers at once)."""
        rows = self._run(
            lambda con: con.execute(
                "SELECT status, COUNT(*) AS n FROM jobs GROUP BY status"
            ).fetchall(),
            retry=retry,
        )
        found = {r["status"]: int(r["n"]) for r in rows}
        return {s: found.get(s, 0) for s in JOB_STATUSES}

    def write_fault(self) -> BaseException | None:
        """What the last write probe met (None: it wrote, or none has run yet), for
        ``/healthz``; a new probe starts on a thread of its own when the last is older than
        :data:`PROBE_EVERY_S` – the health check never waits for a write (under a burst of
        submissions the write lock and its disk sync can take a while)."""
        with self._probe_lock:
            at, error = self._probe
            if time.monotonic() - at >= PROBE_EVERY_S and not self._probing:
                self._probing = True
                threading.Thread(target=self._probe_once, name="store-probe", daemon=True).start()
        return error

    def _probe_once(self) -> None:
        """One attempt to write the probe row of ``health_probe``: a read-only or full
        database, a corrupt one, is recorded as a fault met by a write; a lock held by other
        writers is not a fault (their own calls record one when it lasts)."""
        error: BaseException | None = None
        try:
            with self._connect(PROBE_LOCK_WAIT_S) as con:
                con.execute(
                    "INSERT OR REPLACE INTO health_probe (id, at) VALUES (1, ?)", (utc_now(),)
                )
        except StoreGoneError as exc:
            error = exc
        except sqlite3.Error as exc:
            kind = fault_kind(exc, self.path)
            if kind != "locked":
                error = exc
                self.faults.record(fault_reason(kind, exc), kind, write=True)
        else:
            if self.faults.current is not None:
                self.faults.clear(write=True)
        finally:
            with self._probe_lock:
                self._probe = (time.monotonic(), error)
                self._probing = False

    # -- transitions (conditional: each returns whether it applied) ------------------------

    def _update(self, job_id: str, sql: str, args: tuple[Any, ...]) -> bool:
        changed: int = self._run(lambda con: con.execute(sql, (*args, job_id)).rowcount, write=True)
        return changed == 1

    def start(self, job_id: str, at: str | None = None) -> bool:
        """queued → running (False if the job was cancelled or taken meanwhile); ``at``: the
        start's timestamp (:func:`utc_now` when it is written, by default)."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'running', started_at = ?, message = 'started'"
            " WHERE status = 'queued' AND id = ?",
            (at or utc_now(),),
        )

    def set_progress(self, job_id: str, fraction: float, message: str) -> bool:
        """Progress of a running job (fraction clipped to [0, 1]); False if no longer running."""
        frac = min(max(float(fraction), 0.0), 1.0) if fraction == fraction else 0.0
        return self._update(
            job_id,
            "UPDATE jobs SET progress = ?, message = ? WHERE status = 'running' AND id = ?",
            (frac, str(message)[:500]),
        )

    def succeed(
        self, job_id: str, result: dict[str, Any], figures: dict[str, str], at: str | None = None
    ) -> bool:
        """running → succeeded with the result document and its figures (name → file name in
        the job's figure folder); ``at``: the end's timestamp (:func:`utc_now` by default)."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'succeeded', progress = 1, message = 'done', result = ?,"
            " figures = ?, finished_at = ? WHERE status = 'running' AND id = ?",
            (json.dumps(result, allow_nan=False), json.dumps(figures), at or utc_now()),
        )

    def fail(self, job_id: str, error: str) -> bool:
        """queued/running → failed with a one-line error message."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'failed', message = 'failed', error = ?, finished_at = ?"
            " WHERE status IN ('queued', 'running') AND id = ?",
            (error, utc_now()),
        )

    def record_lost(self, job_id: str, kind: str, status: str) -> bool:
        """A failed row for a job whose row was lost with a removed database (no-op if the id
        exists): the job's URL keeps answering, with the reason."""
        now = utc_now()
        error = LOST_MESSAGE.format(status=status)
        changed: int = self._run(
            lambda con: (
                con.execute(
                    "INSERT OR IGNORE INTO jobs (id, kind, status, message, request, error, seq,"
                    " created_at, finished_at) SELECT ?, ?, 'failed', 'failed', '{}', ?,"
                    " COALESCE(MAX(seq), 0) + 1, ?, ? FROM jobs",
                    (job_id, kind, error, now, now),
                ).rowcount
            ),
            write=True,
        )
        return changed == 1

    def cancel(self, job_id: str) -> bool:
        """queued/running → cancelled."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'cancelled', message = 'cancelled', finished_at = ?"
            " WHERE status IN ('queued', 'running') AND id = ?",
            (utc_now(),),
        )

    def requeue(self, job_id: str) -> bool:
        """running → queued (progress reset): used when the server shuts down gracefully while
        the job runs, so that the next start runs it again."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'queued', progress = 0, started_at = NULL,"
            " message = 're-queued: the server shut down while this job was running'"
            " WHERE status = 'running' AND id = ?",
            (),
        )

    def recover(self) -> list[str]:
        """Start-up repair: ``running`` jobs become ``failed`` (the process that ran them is
        gone); returns the ids of ``queued`` jobs, oldest first, to be run again."""
        self._run(
            lambda con: con.execute(
                "UPDATE jobs SET status = 'failed', message = 'failed', error = ?,"
                " finished_at = ? WHERE status = 'running'",
                (INTERRUPTED_MESSAGE, utc_now()),
            ),
            write=True,
        )
        return self.ids_with_status("queued")
