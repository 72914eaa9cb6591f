"""A command-line plan's figures drawn by a helper process (interactive planning of a city block):
the same files as drawn in-process, the parent draws them itself when the helper cannot, and
the helper never outlives its plan."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread
from test_plan_timing import timed_plan
from waits import HANG_S

from ris_planner.io.geoplan import plan_document
from ris_planner.planning import figure_process
from ris_planner.planning.figure_process import FigureProcess
from ris_planner.runtime.executor import SerialExecutor

FIGURES = {"topview", "heatmap", "cdf"}


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def _ended(pid: int, within_s: float = HANG_S) -> bool:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        if not _alive(pid):
            return True
        time.sleep(0.05)
    return False


def _pixels(path: Path) -> np.ndarray:
    return np.asarray(imread(path))


def test_the_helper_draws_the_in_process_figures(tmp_path: Path) -> None:
    doc = timed_plan()
    here = plan_document(doc, tmp_path / "here", executor=SerialExecutor())
    with FigureProcess() as figures:
        pid = figures.pid
        assert pid is not None
        there = plan_document(doc, tmp_path / "there", executor=SerialExecutor(), figures=figures)
        assert figures.note is None, figures.note
    assert _ended(pid)
    assert set(here.files) >= FIGURES and set(there.files) >= FIGURES
    assert list(there.files)[:3] == list(here.files)[:3]  # the figures first, as before
    for name in FIGURES:
        assert there.files[name].parent == tmp_path / "there"
        a, b = _pixels(here.files[name]), _pixels(there.files[name])
        # the same code on the same data, rasterised by the same Agg in two processes
        assert a.shape == b.shape, name
        assert np.count_nonzero(np.any(a != b, axis=-1)) <= 1e-4 * a.shape[0] * a.shape[1], name
    # the stages still sum to the wall time: the wait for the helper is "figures"
    assert "figures" in there.plan["timing_s"]


def test_the_parent_draws_when_the_helper_does_not_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(figure_process.sys, "executable", str(tmp_path / "no-python"))
    with FigureProcess() as figures:
        assert figures.pid is None and figures.note is not None
        done = plan_document(timed_plan(), tmp_path, executor=SerialExecutor(), figures=figures)
    assert "did not start" in (figures.note or "")
    assert set(done.files) >= FIGURES and all(done.files[n].is_file() for n in FIGURES)


def test_the_parent_draws_when_the_helper_dies(tmp_path: Path) -> None:
    with FigureProcess() as figures:
        pid = figures.pid
        assert pid is not None
        os.kill(pid, 9)
        deadline = time.monotonic() + HANG_S
        while figures.pid is not None and time.monotonic() < deadline:  # reaped by its poll
            time.sleep(0.05)
        assert figures.pid is None
        done = plan_document(timed_plan(), tmp_path, executor=SerialExecutor(), figures=figures)
    assert figures.note is not None and "figure process" in figures.note
    assert set(done.files) >= FIGURES and all(done.files[n].is_file() for n in FIGURES)


def test_the_helper_stops_with_a_failed_plan(tmp_path: Path) -> None:
    with pytest.raises(ValueError), FigureProcess() as figures:  # an invalid document
        pid = figures.pid
        assert pid is not None
        plan_document({"not": "a plan"}, tmp_path, executor=SerialExecutor(), figures=figures)
    assert _ended(pid, 2 * figure_process.STOP_TIMEOUT_S)


def test_the_helper_exits_when_its_parent_goes(tmp_path: Path) -> None:
    parent = (
        "from ris_planner.planning.figure_process import FigureProcess\n"
        "import os\n"
        "f = FigureProcess()\n"
        "print(f.pid, flush=True)\n"
        "os._exit(0)\n"  # no clean-up: the helper sees its stdin close
    )
    done = subprocess.run(
        [sys.executable, "-c", parent], capture_output=True, text=True, timeout=HANG_S, check=True
    )
    pid = int(done.stdout.strip())
    assert _ended(pid, 30.0), "the helper outlived its parent"


def test_cli_plan_draws_with_the_helper(tmp_path: Path) -> None:
    import json

    doc = tmp_path / "plan.json"
    doc.write_text(json.dumps(timed_plan()))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ris_planner.cli", "plan", str(doc), "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=HANG_S, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "figures drawn in this process" not in done.stderr
    assert all((out / f"{name}.png").is_file() for name in FIGURES)


def test_the_hand_over_leaves_the_site_cache_behind() -> None:
    """The helper gets what the figures read, not the scorer's site cache (hundreds of MB for a
    large plan): the hand-over's size follows the maps and fields."""
    import pickle

    from ris_planner.planning.pipeline import run_plan

    result = run_plan(timed_plan(), executor=SerialExecutor())
    job = figure_process.figure_job(result)
    data = pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL)
    assert b"SiteCache" not in data and b"planning.scoring.scorer" not in data  # no Scorer
    assert len(data) < result.scorer.cache.blocks.nbytes  # type: ignore[attr-defined]
    weights = result.pairs.weights
    near = job.scorer.near_field_by_site(weights)
    assert np.array_equal(near, result.scorer.near_field_by_site(weights))
    assert np.array_equal(job.metric_weights, result.metric_weights)


def test_the_hand_over_leaves_the_sizing_state_behind(tmp_path: Path) -> None:
    """A district plan with sizing keeps its search's state for the sizing (the problem, the
    search view, the relaxation: hundreds of MB for a district); the helper gets none of it,
    and draws every figure of the plan from what it gets – the sizing and district ones too."""
    import pickle

    from district_site import street_doc

    from ris_planner.planning.pipeline import run_plan

    doc = street_doc(counts=(2, 3))
    doc["sizing"] = {"target": {"objective": 0.5}}
    result = run_plan(doc, executor=SerialExecutor())
    assert result.sizing is not None and result.sizing_state is not None
    job = figure_process.figure_job(result)
    assert job.sizing_state is None
    data = pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL)
    kept = pickle.dumps(result.sizing_state, protocol=pickle.HIGHEST_PROTOCOL)
    assert b"DistrictRelaxation" not in data and len(data) < len(kept)
    files = figure_process._draw(job, tmp_path)
    assert {"sizing", "district"} <= set(files) and all(p.is_file() for p in files.values())
