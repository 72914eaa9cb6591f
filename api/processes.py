"""What the service's worker processes (job workers, parse processes) share about their own
life: the modules the forkserver preloads, closing the forkserver's inherited pipe, and exiting
when the server is gone (docs/guides/service-operations.md)."""

from __future__ import annotations

import contextlib
import multiprocessing.forkserver
import os
import time

WORKER_MODULES = (
    "api.routes.plans",
    "api.routes.cities",
    "api.routes.web",
    "api.routes.imports",
    "api.routes.power",
)
"""Modules a worker process imports once at start (the routes' parse and job functions)."""

ORPHAN_CHECK_S = 1.0
"""A worker checks this often whether its server (and its parent) are gone, and exits if so."""


def close_inherited_alive_pipe() -> None:
    """A forkserver child inherits the write end of the forkserver's "alive" pipe; holding it
    keeps the forkserver running after its server died, so the worker closes it."""
    fs = multiprocessing.forkserver._forkserver
    fd = getattr(fs, "_forkserver_alive_fd", None)
    if fd is not None:
        with contextlib.suppress(OSError):
            os.close(fd)
        fs._forkserver_alive_fd = None  # type: ignore[attr-defined]


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def exit_when_orphaned(server_pid: int) -> None:
    """Daemon thread: a worker whose server (or parent, the forkserver) is gone stops instead
    of computing on; the restarted server marks its job failed."""
    parent = os.getppid()
    while True:
        if os.getppid() != parent or not _pid_alive(server_pid):
            os._exit(1)
        time.sleep(ORPHAN_CHECK_S)
