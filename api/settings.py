"""Service settings, read from the environment (prefix ``RIS_PLANNER_``).

======================== ============================== =========================================
variable                 default                        meaning
======================== ============================== =========================================
RIS_PLANNER_DB           ``ris_planner_jobs.sqlite3``   SQLite job database (a file; created)
RIS_PLANNER_DATA_DIR     ``<DB>.data``                  job figures (PNG files), one folder a job
RIS_PLANNER_WORKERS      2                              job worker processes (1–64)
RIS_PLANNER_BLAS_THREADS 1                              BLAS threads per request / job worker
RIS_PLANNER_BOUNDS_CONCURRENCY 4                        bounds computations at once (others wait)
RIS_PLANNER_BOUNDS_INLINE_WORK 1000000                  small bounds requests on the event loop
RIS_PLANNER_MAX_PAIRS    10000                          TX–RX pairs per ``POST /v1/bounds``
RIS_PLANNER_MAX_ARRAY_ELEMENTS 20000000                 largest engine array of a request [elements]
RIS_PLANNER_MAX_WORK     1000000000                     Σ_ℓ 3·G̃·N_ℓ·pairs; legs × obstacle edges
RIS_PLANNER_MAX_BODY_BYTES 10000000                     request body limit [bytes]
RIS_PLANNER_API_KEY      (unset: no authentication)     the admin key (sees every job) on /v1
RIS_PLANNER_API_KEYS     (unset)                        more keys: ``name:sha256hex,...``
RIS_PLANNER_API_KEYS_FILE (unset)                       more keys: one ``name:sha256hex`` a line
RIS_PLANNER_ALLOWED_ORIGINS (unset)                     other origins whose pages may write
RIS_PLANNER_ALLOWED_HOSTS (unset)                       host names a loopback server answers too
RIS_PLANNER_REQUEST_STORE_WAIT_S 10                     a request's longest wait for the DB [s]
RIS_PLANNER_PARSE_CONCURRENCY 4                         request bodies parsed/validated at once
RIS_PLANNER_DB_BUSY_TIMEOUT_S 10                        SQLite lock wait per attempt [s]
RIS_PLANNER_DB_RETRY_S   60                             retries of a failing store call [s]
RIS_PLANNER_JOB_MEMORY_MB 4096                          memory budget of one job worker [MiB]
RIS_PLANNER_PLAN_WORKERS 0                              a plan job's pool processes (0: one a core)
RIS_PLANNER_DASK_SCHEDULER (unset: in the job worker)   Dask scheduler (tcp://host:8786) for plans
======================== ============================== =========================================
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, SecretStr
from pydantic_settings import BaseSettings, SettingsConfigDict

from api.security import OriginPolicy, parse_list
from ris_planner.model.limits import (
    JOB_MEMORY_MB_DEFAULT,
    MAX_ARRAY_ELEMENTS,
    MAX_REQUEST_PAIRS,
    MAX_WORK,
    RequestLimits,
)

API_KEY_HEADER = "X-API-Key"

BOUNDS_INLINE_WORK = 1_000_000
"""Default ``bounds_inline_work``: 26 × Table I's 38 400 products (a batch of a few dozen
such pairs), about a millisecond of the event loop per request. Answering Table I on the
loop instead of a worker thread took the server's CPU per request from 3.8–4.0 to 2.5–2.6 ms
and the 50-request bursts from 232–241 to 334–353 requests/s on the quiet machine
(docs/validation/speed-guard.md): the thread hand-off and its GIL switches cost more than the
work."""
INLINE_MAX_BODY_BYTES = 64 * 1024
"""A bounds body is parsed and validated on the event loop only up to this size."""


class Settings(BaseSettings):
    """Configuration of one service instance (see the module docstring for the variables)."""

    model_config = SettingsConfigDict(env_prefix="RIS_PLANNER_", extra="ignore", frozen=True)

    db: Path = Field(Path("ris_planner_jobs.sqlite3"), description="SQLite job database file")
    data_dir: Path | None = Field(
        None, description="Folder for job figures; default: the DB path with suffix '.data'"
    )
    workers: int = Field(2, ge=1, le=64, description="Job worker processes")
    blas_threads: int = Field(
        1,
        ge=1,
        le=256,
        description="BLAS threads per computation: requests and jobs run side by side, so one"
        " thread each avoids oversubscribing the cores (Table I bounds: 1.5 ms vs 16 ms)",
    )
    bounds_concurrency: int = Field(
        4,
        ge=1,
        le=256,
        description="POST /v1/bounds computations running at once (threads); others wait, so"
        " memory stays bounded under a burst of large batches",
    )
    bounds_inline_work: int = Field(
        BOUNDS_INLINE_WORK,
        ge=0,
        le=10**9,
        description="POST /v1/bounds requests of at most this much work (planar complex"
        " products Σ 3·G̃·N·pairs, ×32 for the spherical model, plus visibility tests) and a"
        " body of at most 64 KiB are answered on the event loop instead of a worker thread"
        " (≈ 1 ms each: the thread hand-off cost more than the work); 0: always a thread",
    )
    max_pairs: int = Field(MAX_REQUEST_PAIRS, ge=1, description="TX–RX pairs per bounds request")
    max_array_elements: int = Field(
        MAX_ARRAY_ELEMENTS,
        ge=1000,
        description="Largest engine array per request: max over RISs of pairs·N, 3G̃·N, 3G̃·pairs",
    )
    max_work: int = Field(
        MAX_WORK,
        ge=1000,
        description="Complex products per request: Σ_ℓ 3·G̃·N_ℓ·pairs; also the visibility tests"
        " (legs × obstacle edges) of a request with an environment",
    )
    max_body_bytes: int = Field(10_000_000, ge=1024, description="Request body limit [bytes]")
    db_busy_timeout_s: float = Field(
        10.0, gt=0, le=600, description="SQLite lock wait per attempt [s]"
    )
    db_retry_s: float = Field(
        60.0,
        ge=0,
        le=3600,
        description="How long a store call retries a locked/busy database before the job is"
        " failed with a message (and /healthz reports degraded) [s]",
    )
    job_memory_mb: int = Field(
        JOB_MEMORY_MB_DEFAULT,
        ge=64,
        le=1 << 22,
        description="Memory budget of one job worker [MiB]: the size estimate of a submitted"
        " document must fit it (413 otherwise) and the worker's address space is capped at it",
    )
    api_key: SecretStr | None = Field(
        None,
        description="The admin key: if set (or api_keys are), /v1 routes require a key; this"
        " one sees and cancels every job",
    )
    api_keys: str | None = Field(
        None,
        description="Further API keys, comma-separated 'name:sha256hex' (the SHA-256 of the"
        " key, hex); each key sees only the jobs it created",
    )
    api_keys_file: Path | None = Field(
        None, description="A file of further API keys, one 'name:sha256hex' a line (# comments)"
    )
    allowed_origins: str | None = Field(
        None,
        max_length=10_000,
        description="Origins besides the server's own whose browser pages may send it writes"
        " (POST, DELETE), comma-separated 'scheme://host[:port]': a page served elsewhere that"
        " uses this service; without them a write whose Origin is another is refused (403)",
    )
    allowed_hosts: str | None = Field(
        None,
        max_length=10_000,
        description="Host names a server listening on a loopback address answers besides"
        " localhost and IP addresses, comma-separated (a name of this machine, a local proxy's"
        " name); any other Host is refused (403: a page of another site resolving its own name"
        " to 127.0.0.1)",
    )
    request_store_wait_s: float = Field(
        10.0,
        gt=0,
        le=600,
        description="Longest wait of one HTTP request for the job database (locks and retries"
        " together); then 503 with Retry-After [s]",
    )
    parse_concurrency: int = Field(
        4,
        ge=1,
        le=256,
        description="Request bodies parsed and validated at once (threads); others wait",
    )
    plan_workers: int = Field(
        0,
        ge=0,
        le=256,
        description="Processes of a plan job's local pool (its layout search and checks, as"
        " `ris-planner plan --workers`); 0: one per core, as the command line",
    )
    dask_scheduler: str | None = Field(
        None,
        pattern=r"^(tcp|tls|inproc|ucx)://\S+$",
        description="Dask scheduler address; plan jobs send their layout search there",
    )

    @property
    def origin_policy(self) -> OriginPolicy:
        """Which hosts and origins may send what (:class:`api.security.OriginPolicy`)."""
        return OriginPolicy(parse_list(self.allowed_origins), parse_list(self.allowed_hosts))

    @property
    def request_limits(self) -> RequestLimits:
        """The limits of one bounds or power request, as the engine checks them."""
        return RequestLimits(self.max_pairs, self.max_array_elements, self.max_work)

    @property
    def figures_dir(self) -> Path:
        """Where job figures are written (``data_dir`` or ``<db>.data``)."""
        return self.data_dir if self.data_dir is not None else Path(f"{self.db}.data")
