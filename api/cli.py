"""``ris-planner serve``: run the REST service with uvicorn (127.0.0.1:8000 by default).

The command's arguments are declared in :mod:`ris_planner.cli.app`, which imports this module only
when ``serve`` runs (the package never imports the service at import time).
"""

from __future__ import annotations

import argparse

from ris_planner.core.errors import RisPlannerError


def run_serve(args: argparse.Namespace) -> int:
    """Start uvicorn with the app of :func:`api.main.create_app` (arguments already checked)."""
    import uvicorn

    from api.main import create_app
    from api.settings import Settings

    overrides = {"db": args.db, "workers": args.workers}
    settings = Settings(**{k: v for k, v in overrides.items() if v is not None})
    try:
        uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level=args.log_level)
    except SystemExit as exc:  # uvicorn's own exit (port in use, lifespan failure): logged above
        if exc.code not in (0, None):
            raise RisPlannerError(
                f"the service could not run on {args.host}:{args.port} (uvicorn exited with"
                f" {exc.code}; its message is above)"
            ) from None
    return 0
