"""The REST service of ris_planner: FastAPI routes over the same JSON documents as the CLI.

Long work (placement plans, power allocation) runs as jobs in worker processes and persists in
SQLite (:mod:`api.store`); :func:`api.main.create_app` builds the application.
"""
