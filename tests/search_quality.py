"""Random small placement problems checked against exhaustive search (search
quality): the instances and the comparison shared by tests/test_search_quality.py (a few seeded
instances) and benchmarks/planning/bench_search_quality.py (the table over many)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from test_planning import GRID, plan_doc, setup

from ris_planner.model.plan import SearchSpec
from ris_planner.planning import SerialExecutor
from ris_planner.planning.scoring.scorer import Scorer
from ris_planner.planning.search.layouts import Layout, SearchOutcome, exhaustive

COUNTS = (2, 3, 4)

GreedyFn = Callable[..., SearchOutcome]


def quality_objective(rng: np.random.Generator) -> dict[str, Any]:
    """A random objective: a median or upper quantile (blind pairs make it infinite), a capped
    mean or a coverage, of PEB_R, PEB_T or their maximum."""
    metric = str(rng.choice(["rx", "tx", "max"]))
    kind = int(rng.integers(4))
    if kind == 0:
        return {"kind": "quantile", "metric": metric, "q": 0.5}
    if kind == 1:
        return {"kind": "quantile", "metric": metric, "q": float(rng.choice([0.8, 0.9]))}
    if kind == 2:
        return {"kind": "mean_capped", "metric": metric, "cap_m": float(rng.uniform(0.2, 3.0))}
    return {"kind": "coverage", "metric": metric, "threshold_m": float(rng.uniform(0.05, 0.6))}


BLIND_GRID = {"grid": {"x": [-8, 8, 2], "y": [-8, 8, 2], "z": [0, 0.5, 0.5]}}
"""The UE grid of the blind-prone instances: wider than the candidates' fields of view."""


def quality_instance(seed: int) -> dict[str, Any]:
    """A random plan document: 12–20 candidates around a UE grid (random positions, heights,
    orientations; some facing away), 40–120 random pairs, a random objective, LOS path or
    not, random known parts. Every third instance is blind-prone: a 16 × 16 m UE grid, no LOS
    path, nothing known and candidates facing anywhere, so a pair needs three RISs in view and
    many layouts have an infinite median or quantile."""
    rng = np.random.default_rng(10_000 + seed)
    n = int(rng.integers(12, 21))
    blind = seed % 3 == 2
    cands = []
    for _ in range(n):
        phi = rng.uniform(0, 2 * math.pi)
        r = rng.uniform(3.5, 7.0) if not blind else rng.uniform(2.0, 9.0)
        turn = rng.uniform(-1.2, 1.2) if not blind else rng.uniform(-2.0, 2.0)
        cands.append(
            {
                "position": [r * math.cos(phi), r * math.sin(phi), rng.uniform(1.0, 4.0)],
                "orientation": [phi + math.pi + turn, rng.uniform(0, 0.8), 0],
            }
        )
    obj = quality_objective(rng)
    known: list[str] = []
    if obj["metric"] == "rx" and not blind:
        known = [["clock"], [], ["height"], ["tx"]][int(rng.integers(4))]
    if blind:
        return plan_doc(
            candidates=cands,
            tx_map=BLIND_GRID,
            rx_map=BLIND_GRID,
            pairs={"sample": int(rng.integers(40, 121)), "seed": seed},
            objective=obj,
            known=known,
            system={"los": False},
            ris_count=list(COUNTS),
        )
    return plan_doc(
        candidates=cands,
        tx_map=GRID,
        rx_map=GRID,
        pairs={"sample": int(rng.integers(40, 121)), "seed": seed},
        objective=obj,
        known=known,
        system={"los": bool(rng.integers(2))},
        ris_count=list(COUNTS),
    )


@dataclass(frozen=True)
class Comparison:
    """One (instance, RIS count): the search's best loss against exhaustive search's."""

    seed: int
    kind: str
    n_ris: int
    optimum: float
    found: float
    evaluated: int
    total: int

    @property
    def gap(self) -> float:
        """Relative distance of the found loss from the optimum (0: optimal; ``inf``: an
        infinite loss where a finite one exists)."""
        if self.found == self.optimum:
            return 0.0
        if not math.isfinite(self.found):
            return math.inf
        return (self.found - self.optimum) / max(abs(self.optimum), 1e-300)

    @property
    def infinite_when_finite(self) -> bool:
        return math.isfinite(self.optimum) and not math.isfinite(self.found)


def compare(
    seed: int, greedy_fn: GreedyFn, spec: SearchSpec | None = None
) -> tuple[list[Comparison], float]:
    """The instance's counts 2–4 searched by ``greedy_fn`` (each count seeded with the best
    layouts of the smaller ones, as ``run_plan`` does) against exhaustive search; also the
    seconds the searches took."""
    rows, spent = compare_many(seed, [(greedy_fn, spec)])
    return rows[0], spent[0]


def compare_many(
    seed: int, searches: list[tuple[GreedyFn, SearchSpec | None]]
) -> tuple[list[list[Comparison]], list[float]]:
    """:func:`compare` for several searches on one instance (its site cache and exhaustive
    optima computed once)."""
    import time

    d, sites, _, scorer = setup(quality_instance(seed))
    optima = {
        n: float(exhaustive(scorer, len(sites), n, SerialExecutor()).ranked(1)[0][1])
        for n in COUNTS
    }
    total = {n: math.comb(len(sites), n) for n in COUNTS}
    rows: list[list[Comparison]] = []
    spent: list[float] = []
    for greedy_fn, spec in searches:
        spec = spec or d.search
        out: list[Comparison] = []
        seeds: list[Layout] = []
        t_all = 0.0
        for n_ris in COUNTS:
            t0 = time.perf_counter()
            res = greedy_fn(scorer, len(sites), n_ris, spec, SerialExecutor(), None, tuple(seeds))
            t_all += time.perf_counter() - t0
            best, loss = res.ranked(1)[0]
            seeds.append(best)
            label = _label(scorer)
            out.append(
                Comparison(
                    seed, label, n_ris, optima[n_ris], float(loss), res.evaluated, total[n_ris]
                )
            )
        rows.append(out)
        spent.append(t_all)
    return rows, spent


def _label(scorer: Scorer) -> str:
    obj = scorer.objective
    if obj.kind == "quantile":
        return f"quantile {obj.q:g}"
    return str(obj.kind)
