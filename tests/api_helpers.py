"""Helpers for the service tests: an app on a temporary database, job polling."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient
from waits import HANG_S

from api.main import create_app
from api.settings import Settings
from api.worker import JobFunction

JSON = {"Content-Type": "application/json"}
GEOJSON = {"Content-Type": "application/geo+json"}
OCTETS = {"Content-Type": "application/octet-stream"}
"""Request headers of a body of each media type (a body must say its type: 415 otherwise)."""


@contextmanager
def api_client(
    tmp_path: Path, kinds: dict[str, JobFunction] | None = None, **settings: Any
) -> Iterator[TestClient]:
    """A TestClient (lifespan run: store opened, workers started) on ``tmp_path/jobs.db``."""
    app = create_app(Settings(db=tmp_path / "jobs.db", **settings), kinds=kinds)
    with TestClient(app, raise_server_exceptions=False) as client:
        yield client


def wait_for(
    client: Any, job_id: str, statuses: tuple[str, ...], timeout_s: float = HANG_S
) -> dict[str, Any]:
    """Poll GET /v1/jobs/{id} until its status is one of ``statuses``; the last view
    (``timeout_s`` ends a hang: tests/waits.py)."""
    deadline = time.monotonic() + timeout_s
    while True:
        view: dict[str, Any] = client.get(f"/v1/jobs/{job_id}").json()
        if view["status"] in statuses:
            return view
        if time.monotonic() > deadline:
            raise AssertionError(f"job {job_id} still {view['status']} after {timeout_s} s")
        time.sleep(0.05)
