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
"""

from __future__ import annotations

import fcntl
import json
import sqlite3
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal, get_args

JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]
JOB_STATUSES: tuple[JobStatus, ...] = get_args(JobStatus)

INTERRUPTED_MESSAGE = "interrupted: the server stopped while this job was running; submit it again"

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
"""


class DatabaseInUseError(RuntimeError):
    """Another server process holds the database's lock."""


@contextmanager
def server_lock(db_path: Path | str) -> Iterator[None]:
    """Hold ``<db>.lock`` exclusively while a server runs: a second server (e.g. ``uvicorn
    --workers 2``) on the same database would re-queue and fail the first one's jobs at its
    start-up, so it is refused. The kernel releases the lock when the process dies."""
    path = Path(f"{db_path}.lock")
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise DatabaseInUseError(
                f"another server process uses the job database {db_path}; run one server per"
                " database (one uvicorn process)"
            ) from None
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


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

    @classmethod
    def from_row(cls, row: sqlite3.Row) -> JobHead:
        return cls(**{name: row[name] for name in HEAD_COLUMNS})


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


class JobStore:
    """Jobs in one SQLite file; the schema is created when the store is opened."""

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self._connect() as con:
            con.execute("PRAGMA journal_mode=WAL")
            con.executescript(_SCHEMA)

    @contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        con = sqlite3.connect(self.path, timeout=10.0)
        con.row_factory = sqlite3.Row
        try:
            with con:  # one transaction: commit on success, roll back on error
                yield con
        finally:
            con.close()

    # -- creation and reading -------------------------------------------------------------

    def create(self, kind: str, request: dict[str, Any]) -> Job:
        """A new ``queued`` job holding the (validated) request document."""
        job_id = uuid.uuid4().hex
        created_at = utc_now()
        with self._connect() as con:  # one statement: seq is unique under concurrent inserts
            con.execute(
                "INSERT INTO jobs (id, kind, status, request, seq, created_at)"
                " SELECT ?, ?, 'queued', ?, COALESCE(MAX(seq), 0) + 1, ? FROM jobs",
                (job_id, kind, json.dumps(request, allow_nan=False), created_at),
            )
        return Job(
            id=job_id,
            kind=kind,
            status="queued",
            progress=0.0,
            message="",
            error=None,
            created_at=created_at,
            started_at=None,
            finished_at=None,
            request=request,
            result=None,
            figures={},
        )

    def get(self, job_id: str) -> Job | None:
        with self._connect() as con:
            row = con.execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return None if row is None else Job.from_row(row)

    def head(self, job_id: str) -> JobHead | None:
        """The job's state without decoding its request and result."""
        with self._connect() as con:
            row = con.execute(f"SELECT {_HEAD_SELECT} FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return None if row is None else JobHead.from_row(row)

    def list_jobs(
        self,
        *,
        limit: int,
        offset: int = 0,
        status: JobStatus | None = None,
        kind: str | None = None,
    ) -> tuple[list[JobHead], int]:
        """A page of jobs (without their documents), newest first, and the total count
        matching the filters."""
        where: list[str] = []
        args: list[str] = []
        if status is not None:
            where.append("status = ?")
            args.append(status)
        if kind is not None:
            where.append("kind = ?")
            args.append(kind)
        clause = f"WHERE {' AND '.join(where)}" if where else ""
        with self._connect() as con:
            total = con.execute(f"SELECT COUNT(*) FROM jobs {clause}", args).fetchone()[0]
            rows = con.execute(
                f"SELECT {_HEAD_SELECT} FROM jobs {clause} ORDER BY seq DESC LIMIT ? OFFSET ?",
                [*args, limit, offset],
            ).fetchall()
        return [JobHead.from_row(r) for r in rows], int(total)

    def ids_with_status(self, status: JobStatus) -> list[str]:
        """Ids of all jobs with this status, oldest first."""
        with self._connect() as con:
            rows = con.execute(
                "SELECT id FROM jobs WHERE status = ? ORDER BY seq", (status,)
            ).fetchall()
        return [r["id"] for r in rows]

    def counts(self) -> dict[str, int]:
        """Number of jobs per status (every status present, 0 if none)."""
        with self._connect() as con:
            rows = con.execute("SELECT status, COUNT(*) AS n FROM jobs GROUP BY status")
            found = {r["status"]: int(r["n"]) for r in rows}
        return {s: found.get(s, 0) for s in JOB_STATUSES}

    # -- transitions (conditional: each returns whether it applied) ------------------------

    def _update(self, job_id: str, sql: str, args: tuple[Any, ...]) -> bool:
        with self._connect() as con:
            cur = con.execute(sql, (*args, job_id))
            return cur.rowcount == 1

    def start(self, job_id: str) -> bool:
        """queued → running (False if the job was cancelled or taken meanwhile)."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'running', started_at = ?, message = 'started'"
            " WHERE status = 'queued' AND id = ?",
            (utc_now(),),
        )

    def set_progress(self, job_id: str, fraction: float, message: str) -> bool:
        """Progress of a running job (fraction clipped to [0, 1]); False if no longer running."""
        frac = min(max(float(fraction), 0.0), 1.0) if fraction == fraction else 0.0
        return self._update(
            job_id,
            "UPDATE jobs SET progress = ?, message = ? WHERE status = 'running' AND id = ?",
            (frac, str(message)[:500]),
        )

    def succeed(self, job_id: str, result: dict[str, Any], figures: dict[str, str]) -> bool:
        """running → succeeded with the result document and its figures (name → file name in
        the job's figure folder)."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'succeeded', progress = 1, message = 'done', result = ?,"
            " figures = ?, finished_at = ? WHERE status = 'running' AND id = ?",
            (json.dumps(result, allow_nan=False), json.dumps(figures), utc_now()),
        )

    def fail(self, job_id: str, error: str) -> bool:
        """queued/running → failed with a one-line error message."""
        return self._update(
            job_id,
            "UPDATE jobs SET status = 'failed', message = 'failed', error = ?, finished_at = ?"
            " WHERE status IN ('queued', 'running') AND id = ?",
            (error, utc_now()),
        )

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
        with self._connect() as con:
            con.execute(
                "UPDATE jobs SET status = 'failed', message = 'failed', error = ?,"
                " finished_at = ? WHERE status = 'running'",
                (INTERRUPTED_MESSAGE, utc_now()),
            )
        return self.ids_with_status("queued")
