"""Imported once by the job runner's forkserver, after the engine's modules
(:data:`api.worker.PRELOAD_MODULES`): :func:`ris_planner.planning.warmup.prepare_process`
–
matplotlib and numba's runtime set up once, so that each plan job, a fork of the forkserver,
starts without paying ≈ 1 s for them (docs/guides/service-operations.md, "Job processes").
Nothing else imports this module: the server process itself never loads numba or matplotlib."""

from ris_planner.planning.warmup import prepare_process

prepare_process()
