"""A REST plan job's progress events are honest (tests/test_progress_honest.py's rules, seen
through ``GET /v1/jobs/{id}/events``): the fraction never goes back, stays below 1 while the job
runs, reaches 1 only with the result, and the stages are named on the way. That no stretch of
the run leaves the bar standing is tested on the job's own function in its process
(tests/test_progress_honest.py, on its CPU time): the events' arrival times here are the
machine's load as much as the job's."""

from __future__ import annotations

import json
from pathlib import Path

from api_helpers import api_client
from test_progress_honest import small_plan


def test_plan_job_progress_events_are_honest(tmp_path: Path) -> None:
    events: list[tuple[str, dict[str, object]]] = []  # (name, summary)
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/plans", json=small_plan())
        assert r.status_code == 202
        job_id = r.json()["id"]
        with client.stream("GET", f"/v1/jobs/{job_id}/events") as stream:
            assert stream.status_code == 200
            name = "message"
            for line in stream.iter_lines():
                if line.startswith("event:"):
                    name = line[6:].strip()
                elif line.startswith("data:"):
                    events.append((name, json.loads(line[5:])))
    assert events[-1][0] == "end" and events[-1][1]["status"] == "succeeded"
    progress = [float(d["progress"]) for _, d in events]  # type: ignore[arg-type]
    assert progress == sorted(progress)
    assert progress[-1] == 1.0
    assert all(
        p < 1.0 for p, (_, d) in zip(progress, events, strict=True) if d["status"] != "succeeded"
    )
    messages = [str(d["message"]) for _, d in events if d["status"] == "running"]
    assert any(m.startswith("figures") for m in messages), messages


class _Recorder:
    """A job store stand-in that records progress writes."""

    def __init__(self) -> None:
        self.writes: list[tuple[float, str]] = []

    def set_progress(self, job_id: str, fraction: float, message: str) -> bool:
        self.writes.append((fraction, message))
        return True


def test_store_progress_throttles_within_a_stage_but_writes_every_new_stage() -> None:
    from api.worker import StoreProgress
    from ris_planner.runtime.progress import LAST_BEFORE_END

    rec = _Recorder()
    progress = StoreProgress(rec, "job", interval_s=60.0)  # type: ignore[arg-type]
    progress(0.1, "plan: cache")
    progress(0.2, "plan: search")  # same stage, within the interval: dropped
    progress(0.6, "figures")  # a new stage: written at once
    progress(0.7, "figures: more")  # same stage again: dropped
    progress(1.0, "done")  # the end: always
    # the job's 1.0 comes with its result (JobStore.succeed), not from the job function
    assert rec.writes == [
        (0.1, "plan: cache"),
        (0.6, "figures"),
        (LAST_BEFORE_END, "storing the result"),
    ]
