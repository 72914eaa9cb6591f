"""The coverage screen of the compiled scorer (``_crb_jit.screen_chunk``, ``Scorer.loss``): a
sub-problem CRB is a lower bound on the full one, so screening never changes a coverage
decision; checked against numpy inverses and against the unscreened scorer."""

from __future__ import annotations

from typing import Any

import numpy as np

from ris_planner._crb_jit import CHUNK, SCREEN_MAX_STATES, screen_chunk
from ris_planner.environment import Scene
from ris_planner.ldl import pack
from ris_planner.planning import PlanDocument
from ris_planner.planning.maps import build_map, build_pairs
from ris_planner.planning.objectives import Scorer, loss_from_metric
from ris_planner.planning.presets import plan_preset
from ris_planner.planning.site_cache import build_site_cache
from ris_planner.planning.sites import expand_sites
from ris_planner.planning.visibility import pair_visibility

SCREEN_RTOL = 1e-9
"""screen_chunk's trace against numpy's inverse of the same sub-matrix (cond ≲ 1e4 here: a
few hundred roundings of relative size ε, far below 1e-9)."""


def run_screen(f: Any, sub: list[int], m: int) -> Any:
    """screen_chunk on the [t, 7, 7] matrices f (t ≤ CHUNK)."""
    t = f.shape[0]
    a = np.zeros((28, CHUNK))
    a[:, :t] = pack(f)
    out = np.empty(CHUNK)
    mat = np.empty((SCREEN_MAX_STATES, SCREEN_MAX_STATES, CHUNK))
    rows = np.empty((SCREEN_MAX_STATES + 3, CHUNK))
    screen_chunk(a, t, np.array(sub, dtype=np.int64), m, mat, rows, out)
    return out[:t]


def test_screen_bound_is_the_sub_problem_crb_and_below_the_full_one() -> None:
    rng = np.random.default_rng(11)
    j = rng.normal(size=(40, 9, 7)) * np.logspace(0, 2, 7)
    f = j.transpose(0, 2, 1) @ j  # [40, 7, 7] positive definite
    sub = [2, 6, 3, 4, 5]  # z_T and the clock, then p_R
    got = run_screen(f, sub, 3)
    m_sub = f[:, sub][:, :, sub]
    want = np.trace(np.linalg.inv(m_sub)[:, 2:, 2:], axis1=1, axis2=2)
    np.testing.assert_allclose(got, want, rtol=SCREEN_RTOL)
    full = np.trace(np.linalg.inv(f)[:, 3:6, 3:6], axis1=1, axis2=2)
    assert np.all(got <= full * (1 + 1e-12))
    assert np.mean(got < 0.99 * full) > 0.5  # a bound, not the CRB itself
    # a singular sub-matrix (the clock row a copy of z_T's) is never screened
    f[0, 6, :], f[0, :, 6] = f[0, 2, :], f[0, :, 2]
    f[0, 6, 6] = f[0, 2, 2]
    assert run_screen(f[:1], sub, 3)[0] == -1.0


def hall_scorer(threshold: float) -> Scorer:
    raw = plan_preset("hall") | {"pairs": {"sample": 300, "seed": 2}}
    raw["objective"] = {"kind": "coverage", "metric": "rx", "threshold_m": threshold}
    d = PlanDocument.model_validate(raw)
    sites = expand_sites(d)
    pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
    vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, d.system.los)
    cache = build_site_cache(d.system, sites, pairs, visibility=vis, known=tuple(d.known))
    return Scorer(cache, pairs.weights, d.objective, tuple(d.known))


def test_screened_losses_equal_the_full_ones() -> None:
    """Hall preset, 2 RISs + LOS (7 channel parameters for 7 states: the screened count):
    the screened metric differs only where it proves a pair above the threshold, and every
    loss is the unscreened one exactly."""
    for threshold in (0.5, 2.0):
        sc = hall_scorer(threshold)
        rng = np.random.default_rng(4)
        n = sc.cache.n_sites
        lays = np.array([np.sort(rng.choice(n, 2, replace=False)) for _ in range(300)])
        full = sc.metric(lays)
        screened = sc.metric(lays, screen=True)
        moved = screened != full
        assert moved.mean() > 0.02  # the screen is taken (9 % / 5 % here: many pairs are blind)
        assert np.all(screened[moved] > threshold) and np.all(full[moved] > threshold)
        assert np.all(screened[moved] <= full[moved])
        np.testing.assert_array_equal(
            sc.loss(lays), loss_from_metric(sc.objective, full, sc.metric_weights)
        )
        # 3 RISs: more parameters than states, no screen (the LDLᵀ is as cheap there)
        lays3 = np.array([np.sort(rng.choice(n, 3, replace=False)) for _ in range(50)])
        np.testing.assert_array_equal(sc.metric(lays3, screen=True), sc.metric(lays3))
