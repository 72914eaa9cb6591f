"""The headline workloads, one asv benchmark each (docs/validation/benchmarks.md).

* ``Bounds.time_table1_single_pair``: ``compute_bounds`` of the paper's Table I (one pair);
* ``Bounds.time_fig10_layout``: the Fig. 10 workload of the 4-RIS layout, ``random``
  codebook (4753 pairs, :func:`ris_planner.model.paper.fig10_pairs`);

The workloads are the benchmarks' own (``benchmarks/fixtures.py``); the district search and the
Kamppi block are in ``planning.py`` beside this file.
* ``Planning.time_hall_plan``: a small hall plan (``run_plan``, serial executor);
* ``Planning.time_hall_site_cache``: the hall's site cache (every site × pair);
* ``Estimation.time_estimate``: one run of the estimator (Alg. 1 + 2) on a Table I signal;
* ``Rest.time_bounds_burst``: 50 concurrent ``POST /v1/bounds`` of Table I against
  ``ris-planner serve`` on 127.0.0.1 (started in ``setup``, stopped by PID in ``teardown``),
  on 50 keep-alive connections opened in ``setup``.

Only the public API that every benchmarked commit has is used (asv runs these suites of the
working copy against each commit's code). ``asv continuous --factor 1.3 BASE HEAD`` flags a
workload that became more than 1.3× slower.
"""

from __future__ import annotations

import asyncio
import os
import sys
import tempfile
from contextlib import ExitStack
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: the fixtures

from fixtures import fig10_document, fig10_pairs, small_hall, table1_document

from ris_planner import compute_bounds, load_scenario


class Bounds:
    """The bounds engine: one pair (per-call overheads) and a whole Fig. 10 layout."""

    timeout = 120.0

    def setup(self) -> None:
        self.table1 = load_scenario(table1_document())
        self.fig10 = load_scenario(fig10_document("4-ris", "random"))
        self.tx, self.rx = fig10_pairs()
        compute_bounds(self.table1)  # imports and first-call work outside the timing

    def time_table1_single_pair(self) -> None:
        compute_bounds(self.table1)

    def time_fig10_layout(self) -> None:
        compute_bounds(self.fig10, tx=self.tx, rx=self.rx)


class Planning:
    """A hall plan end to end, and the site cache that dominates larger ones."""

    timeout = 600.0
    number = 1
    repeat = (1, 5, 60.0)

    def setup(self) -> None:
        from ris_planner.environment import Scene
        from ris_planner.planning import PlanDocument
        from ris_planner.planning.inputs.sites import expand_sites
        from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
        from ris_planner.planning.scoring.visibility import pair_visibility

        self.plan_doc = small_hall()
        d = PlanDocument.model_validate(small_hall(spacing_m=5.0, pairs=1600))
        self.system = d.system
        self.sites = expand_sites(d)
        self.pairs = build_pairs(
            build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6
        )
        scene = Scene.from_environment(d.environment)
        self.visibility = pair_visibility(scene, self.sites, self.pairs, d.system.los)
        self.time_hall_plan()  # compiled kernels loaded (or compiled) outside the timing

    def time_hall_plan(self) -> None:
        from ris_planner.planning import SerialExecutor, run_plan

        run_plan(self.plan_doc, executor=SerialExecutor())

    def time_hall_site_cache(self) -> None:
        from ris_planner.planning.scoring.site_cache import build_site_cache

        build_site_cache(self.system, self.sites, self.pairs, visibility=self.visibility, known=())


class Estimation:
    """One estimator run (Alg. 1 + 2) on a simulated Table I signal (seeded)."""

    timeout = 300.0
    number = 1

    def setup(self) -> None:
        from ris_planner.estimation.pipeline import Estimator
        from ris_planner.estimation.signal import (
            realisation_paths,
            received_signal,
            separate_paths,
            signal_setup,
        )
        from ris_planner.model.simulation import EstimatorSettings, Multipath

        doc = table1_document()
        doc["system"]["noise_figure_db"] = 0.0
        sc = load_scenario(doc)
        setup = signal_setup(sc)
        settings = EstimatorSettings()
        self.estimator = Estimator(setup, settings, settings.search_area.candidates(sc.tx_array[0]))
        rng = np.random.default_rng(0)
        paths = realisation_paths(setup, Multipath(), rng)
        self.signal = separate_paths(setup, received_signal(setup, paths, rng))
        self.estimator.estimate(self.signal)  # first-call work outside the timing

    def time_estimate(self) -> None:
        self.estimator.estimate(self.signal)


class Rest:
    """A burst of 50 concurrent ``POST /v1/bounds`` (Table I) against a real server, on 50
    keep-alive connections opened in ``setup`` (as ``benchmarks/service/bench_api.py``: a new
    connection per request costs the client about as much CPU as the server's work)."""

    timeout = 300.0
    number = 1
    repeat = (3, 10, 60.0)
    concurrency = 50

    def setup(self) -> None:
        import httpx

        from api.launch import served

        self.stack = ExitStack()
        tmp = Path(self.stack.enter_context(tempfile.TemporaryDirectory()))
        here = Path.cwd()
        os.chdir(tmp)  # ``python -m`` puts the working folder first on the server's path
        try:
            self.server = self.stack.enter_context(
                served(tmp / "jobs.db", env={"RIS_PLANNER_BLAS_THREADS": "1"})
            )
        except BaseException:
            self.stack.close()
            raise
        finally:
            os.chdir(here)
        self.doc = table1_document()
        self.loop = asyncio.new_event_loop()  # the clients' connections live on this loop
        self.stack.callback(self.loop.close)
        self.clients = [
            httpx.AsyncClient(base_url=self.server.url, timeout=60.0)
            for _ in range(self.concurrency)
        ]
        self.stack.callback(lambda: self.loop.run_until_complete(self._close_clients()))
        try:
            self.loop.run_until_complete(self._burst())  # warm-up: opens the connections
        except BaseException:
            self.stack.close()  # the server too, by its PID
            raise

    def teardown(self) -> None:
        self.stack.close()  # stops the server by its PID (api.launch.served)

    async def _close_clients(self) -> None:
        await asyncio.gather(*(c.aclose() for c in self.clients))

    async def _burst(self) -> None:
        answers = await asyncio.gather(*(c.post("/v1/bounds", json=self.doc) for c in self.clients))
        bad = [a.status_code for a in answers if a.status_code != 200]
        if bad:
            raise RuntimeError(f"non-200 answers: {bad}")

    def time_bounds_burst(self) -> None:
        self.loop.run_until_complete(self._burst())
