"""The job kinds: kind name → module-level function ``(document, progress, out_dir) ->
JobOutput`` run in a worker process (:mod:`api.worker`). Each kind's POST route validates the
document first, so a job starts from a valid document."""

from __future__ import annotations

from api.worker import JobFunction

JOB_KINDS: dict[str, JobFunction] = {}
