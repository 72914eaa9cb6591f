"""``ris-planner serve``: run the REST service with uvicorn (127.0.0.1:8000 by default).

The command's arguments are declared in :mod:`ris_planner.cli`, which imports this module only
when ``serve`` runs (the package never imports the service at import time).
"""

from __future__ import annotations

import argparse


def run_serve(args: argparse.Namespace) -> int:
    """Start uvicorn with the app of :func:`api.main.create_app` (arguments already checked)."""
    import uvicorn

    from api.main import create_app
    from api.settings import Settings

    overrides = {"db": args.db, "workers": args.workers}
    settings = Settings(**{k: v for k, v in overrides.items() if v is not None})
    uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level=args.log_level)
    return 0
