"""Request dependencies: the app's settings, store and runner, and the API-key check."""

from __future__ import annotations

import hmac

from fastapi import HTTPException, Request, Security
from fastapi.security import APIKeyHeader

from api.settings import API_KEY_HEADER, Settings
from api.store import JobStore
from api.worker import JobRunner

api_key_header = APIKeyHeader(
    name=API_KEY_HEADER,
    auto_error=False,
    description="API key; required on every /v1 route when the server sets RIS_PLANNER_API_KEY",
)


def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def get_store(request: Request) -> JobStore:
    store: JobStore = request.app.state.store
    return store


def get_runner(request: Request) -> JobRunner:
    runner: JobRunner = request.app.state.runner
    return runner


def require_api_key(request: Request, key: str | None = Security(api_key_header)) -> None:
    """401 unless no key is configured or the header matches it (constant-time comparison)."""
    expected = get_settings(request).api_key
    if expected is None:
        return
    if key is None or not hmac.compare_digest(
        key.encode("utf-8"), expected.get_secret_value().encode("utf-8")
    ):
        raise HTTPException(
            401,
            f"missing or wrong API key: send it in the {API_KEY_HEADER} header",
            headers={"WWW-Authenticate": "ApiKey"},
        )
