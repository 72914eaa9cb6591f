"""Start the service as a real uvicorn process on 127.0.0.1 (end-to-end tests, benchmarks).

``served(db)`` runs ``python -m ris_planner.cli serve`` (or ``python -m uvicorn api.main:app``)
on a free loopback port with its own database, waits until ``/healthz`` answers, and stops the
server gracefully (SIGINT) on exit.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

HOST = "127.0.0.1"


def free_port() -> int:
    """A TCP port that was free on 127.0.0.1 a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((HOST, 0))
        port: int = s.getsockname()[1]
        return port


@dataclass(frozen=True)
class Server:
    """A running server: its base URL and process."""

    url: str
    process: subprocess.Popen[bytes]


@contextmanager
def served(
    db: Path,
    *,
    workers: int = 1,
    via: str = "serve",
    env: dict[str, str] | None = None,
    startup_timeout_s: float = 600.0,
    log: Path | None = None,
    log_level: str = "warning",
) -> Iterator[Server]:
    """A server on a free port with job database ``db``; ``via`` is ``"serve"`` (the CLI) or
    ``"uvicorn"`` (``uvicorn api.main:app``, settings from the environment); ``log_level``:
    its ``--log-level``. ``startup_timeout_s`` ends a start that hangs: a busy machine may
    take minutes to import the service."""
    port = free_port()
    environ = dict(os.environ) | {"RIS_PLANNER_DB": str(db), "RIS_PLANNER_WORKERS": str(workers)}
    environ |= env or {}
    if via == "serve":
        cmd = [sys.executable, "-m", "ris_planner.cli", "serve", "--port", str(port)]
        cmd += ["--log-level", log_level]
    elif via == "uvicorn":
        cmd = [sys.executable, "-m", "uvicorn", "api.main:app", "--host", HOST]
        cmd += ["--port", str(port), "--log-level", log_level]
    else:
        raise ValueError(f"via must be 'serve' or 'uvicorn', got {via!r}")
    out = open(log, "ab") if log is not None else subprocess.DEVNULL  # noqa: SIM115
    proc = subprocess.Popen(cmd, env=environ, stdout=out, stderr=out)
    url = f"http://{HOST}:{port}"
    try:
        deadline = time.monotonic() + startup_timeout_s
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"server exited with code {proc.returncode} at start-up")
            try:
                with urllib.request.urlopen(f"{url}/healthz", timeout=1.0) as answer:
                    if answer.status == 200:
                        break
            except (urllib.error.URLError, ConnectionError, TimeoutError):
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"server not ready after {startup_timeout_s} s")
            time.sleep(0.1)
        yield Server(url, proc)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if log is not None:
            out.close()  # type: ignore[union-attr]
