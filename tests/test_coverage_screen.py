"""The screen of the compiled scorer (``_crb_jit.screen_chunk``, ``Scorer.loss``): a
sub-problem CRB is a lower bound on the full one, so screening never changes a coverage
decision or a capped mean; checked against numpy inverses and against the unscreened scorer
(which in turn equals the numpy reference, blind pairs left out of the factorisation)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ris_planner.environment import Scene
from ris_planner.inversion._crb_jit import CHUNK, SCREEN_MAX_STATES, screen_chunk
from ris_planner.inversion.ldl import pack
from ris_planner.planning import PlanDocument
from ris_planner.planning.inputs.presets import plan_preset
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.scoring.scorer import Scorer, loss_from_metric
from ris_planner.planning.scoring.site_cache import build_site_cache
from ris_planner.planning.scoring.visibility import pair_visibility

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


def hall_scorer(objective: dict[str, Any]) -> Scorer:
    raw = plan_preset("hall") | {"pairs": {"sample": 300, "seed": 2}}
    raw["objective"] = objective
    d = PlanDocument.model_validate(raw)
    sites = expand_sites(d)
    pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
    vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, d.system.los)
    cache = build_site_cache(d.system, sites, pairs, visibility=vis, known=tuple(d.known))
    return Scorer(cache, pairs.weights, d.objective, tuple(d.known))


def check_screen(sc: Scorer, lays: Any, limit: float) -> float:
    """The screened metric differs from the full one only where both exceed ``limit`` (and
    the screened value is a lower bound; a singular FIM's ``inf`` may get a finite bound), and
    the loss is the unscreened one exactly; returns the fraction of the pairs that are not
    blind (``inf`` both ways) that the screen settled."""
    full = sc.metric(lays)
    np.testing.assert_array_equal(full, sc.metric_reference(lays))  # blind pairs left out alike
    screened = sc.metric(lays, screen=True)
    moved = screened != full
    assert np.all(screened[moved] > limit) and np.all(full[moved] > limit)
    assert np.all(screened[moved] <= full[moved])
    np.testing.assert_array_equal(
        sc.loss(lays), loss_from_metric(sc.objective, full, sc.metric_weights)
    )
    return float(moved.sum() / max(1, (np.isfinite(full) | np.isfinite(screened)).sum()))


def test_screened_losses_equal_the_full_ones() -> None:
    """Hall preset (fields of view: per-pair presence masks). 2 RISs + LOS is the smallest
    identifiable count of every present pair (7 channel parameters for 7 states); at 3 RISs
    only the pairs that see just two of them are screened. Coverage at two thresholds and
    the capped mean: the screened metric moves only above the threshold or cap, and every
    loss is the unscreened one exactly."""
    objectives: list[tuple[dict[str, Any], float]] = [
        ({"kind": "coverage", "metric": "rx", "threshold_m": 0.5}, 0.5),
        ({"kind": "coverage", "metric": "rx", "threshold_m": 2.0}, 2.0),
        ({"kind": "mean_capped", "metric": "rx", "cap_m": 1.0}, 1.0),
    ]
    for objective, limit in objectives:
        sc = hall_scorer(objective)
        rng = np.random.default_rng(4)
        n = sc.cache.n_sites
        lays = np.array([np.sort(rng.choice(n, 2, replace=False)) for _ in range(300)])
        # the screen is taken (5–9 % of the values here: many pairs are blind)
        assert check_screen(sc, lays, limit) > 0.02
        lays3 = np.array([np.sort(rng.choice(n, 3, replace=False)) for _ in range(100)])
        assert check_screen(sc, lays3, limit) > 0.0


def test_no_screen_for_a_quantile_or_above_the_smallest_count_in_free_space() -> None:
    """A quantile objective is never screened (its value depends on the PEBs themselves);
    without presence masks the screen needs the whole layout at the smallest identifiable
    count."""
    sc = hall_scorer({"kind": "quantile", "metric": "rx", "q": 0.9})
    assert sc._screen_limit(2) == 0.0
    sc = hall_scorer({"kind": "coverage", "metric": "rx", "threshold_m": 1.0})
    assert sc._screen_limit(2) == sc._screen_limit(3) > 1.0
    free = Scorer(
        replace(sc.cache, present=None, los_present=None),
        sc.weights,
        sc.objective,
        sc.known,
    )
    assert free._screen_limit(2) > 1.0 and free._screen_limit(3) == 0.0


def test_extra_candidates_screened_while_they_settle(monkeypatch: Any) -> None:
    """A cap far below every PEB: nearly every pair that sees more RISs than it needs is
    settled, so the kernel keeps screening those too (``_crb_jit.SCREEN_KEEP``), and the
    losses, computed one small kernel block at a time, are still the unscreened ones."""
    import ris_planner.planning.scoring.scorer as objectives

    sc = hall_scorer({"kind": "mean_capped", "metric": "rx", "cap_m": 0.02})
    rng = np.random.default_rng(5)
    n = sc.cache.n_sites
    monkeypatch.setattr(objectives, "KERNEL_MATRICES", 7 * sc.cache.n_pairs)  # 7 layouts a call
    for n_ris in (3, 4):
        lays = np.array([np.sort(rng.choice(n, n_ris, replace=False)) for _ in range(60)])
        assert check_screen(sc, lays, 0.02) > 0.95


def test_masks_with_every_path_present_need_no_counting() -> None:
    """Presence masks that are all true (a hall whose walls see every UE) make the kernel skip
    the per-pair count: the layout-wide rule says the same, so the metric still equals the
    numpy reference, which counts every pair (``objectives.underdetermined``)."""
    sc = hall_scorer({"kind": "coverage", "metric": "rx", "threshold_m": 1.0})
    assert sc.cache.counts_paths  # the preset's walls hide some UEs
    los = sc.cache.los_present
    assert los is not None and sc.cache.present is not None
    cache = replace(sc.cache, present=np.ones_like(sc.cache.present), los_present=np.ones_like(los))
    full = Scorer(cache, sc.weights, sc.objective, sc.known)
    assert not cache.counts_paths and full._kernel_inputs["present"].size == 0
    rng = np.random.default_rng(6)
    for n_ris in (1, 2, 3):
        lays = np.array(
            [np.sort(rng.choice(cache.n_sites, n_ris, replace=False)) for _ in range(40)]
        )
        np.testing.assert_array_equal(full.metric(lays), full.metric_reference(lays))
        check_screen(full, lays, 1.0)
