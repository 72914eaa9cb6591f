"""The site cache's storage (its memory budget): square-root rows recomputed on demand equal the
stored ones bit for bit, float32 storage keeps every score within its rounding bound and the
decisions of float64, and the re-scored finalists of a float32 cache are float64-exact."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from ris_planner.bounds.compute import (
    compute_bounds,
    los_gradient,
    los_path_information,
    ris_path_information,
    stand_ins,
    to_los_reference,
    ue_on_ris,
)
from ris_planner.environment import Scene
from ris_planner.inversion.ldl import unpack
from ris_planner.model.limits import CacheLayout
from ris_planner.model.plan import PlanDocument
from ris_planner.model.scenario import Scenario
from ris_planner.physics import fim
from ris_planner.planning import SerialExecutor, run_plan
from ris_planner.planning.inputs.presets import plan_preset
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.scoring.scorer import Scorer, select_metric
from ris_planner.planning.scoring.site_cache import build_site_cache
from ris_planner.planning.scoring.visibility import pair_visibility
from ris_planner.planning.search.layouts import all_layouts

UNIT_ROUNDOFF_F32 = 2.0**-24
"""float32 unit roundoff: each stored entry F_s,ij carries a relative error ≤ u."""

F64_SLACK = 64 * np.finfo(float).eps
"""The float64 inversions' own rounding (relative, per unit of trace(F̂⁻¹)): both routes are
backward stable to a few ε·cond(F̂), far below the float32 term."""


def _ring(n: int) -> list[dict[str, Any]]:
    return [
        {
            "position": [4.5 * math.cos(p), 4.5 * math.sin(p), 2.0 + (k % 2)],
            "orientation": [p + math.pi, math.pi / 6, 0.0],
        }
        for k, p in enumerate(2 * math.pi * np.arange(n) / n + 0.1)
    ]


def _doc(n_sites: int = 7, **over: Any) -> dict[str, Any]:
    grid = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [1.0, 1.0, 1]}}
    doc: dict[str, Any] = {
        "candidates": _ring(n_sites),
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 300, "seed": 2},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [3],
    }
    return doc | over


@pytest.mark.parametrize("known", [(), ("clock",)])
def test_rows_on_demand_equal_the_full_evaluation(known: tuple[str, ...]) -> None:
    """The hall preset (blocked legs, LOS-referenced or not): a site's rows recomputed for a
    few pairs are those of the full-pair evaluation, bit for bit."""
    d = PlanDocument.model_validate(plan_preset("hall") | {"pairs": {"sample": 150, "seed": 5}})
    sites = expand_sites(d)[::5]
    pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
    vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, d.system.los)
    layout = CacheLayout("float64", rows=False)
    cache = build_site_cache(d.system, sites, pairs, visibility=vis, known=known, layout=layout)  # type: ignore[arg-type]
    stored = build_site_cache(d.system, sites, pairs, visibility=vis, known=known)  # type: ignore[arg-type]
    assert cache.factor is None and stored.factor is not None
    radio = fim.Radio.from_system(d.system)
    grad = los_gradient(los_path_information(pairs.tx, pairs.rx, radio, 1.0))
    rng = np.random.default_rng(0)
    for s, site in enumerate(sites):
        t, r = stand_ins(pairs.tx, pairs.rx, ue_on_ris(pairs.tx, pairs.rx, site.ris.position))
        g = np.ones(d.system.transmissions)
        info, _ = ris_path_information(site.ris, t, r, radio, None, 1, g)
        if not known:
            info = to_los_reference(info, grad)
        full = info.factor()
        full[~vis.present[s]] = 0.0
        pick = np.sort(rng.choice(pairs.size, 11, replace=False))
        got = cache.factor_rows(np.full(pick.size, s), pick)
        np.testing.assert_array_equal(got, full[pick])
        np.testing.assert_array_equal(stored.factor[s], full)  # type: ignore[index]


def _scaled_trace(cache_packed: np.ndarray, los: np.ndarray | None, lay: np.ndarray) -> Any:
    """trace(F̂⁻¹) [B, P] of each layout's summed FIM scaled to unit diagonal (numpy inverse)."""
    f = cache_packed[:, lay].sum(axis=2)  # [28, B, P]
    if los is not None:
        f = f + los[:, None, :]
    m = unpack(f, 7)  # [B, P, 7, 7]
    d = np.sqrt(np.einsum("...ii->...i", m))
    scaled = m / d[..., :, None] / d[..., None, :]
    return np.einsum("...ii->...", np.linalg.inv(scaled))


def test_float32_storage_within_its_rounding_bound_and_same_decisions() -> None:
    """Every layout of a 7-site ring: the float32 scores lie within the first-order bound of
    rounding each stored entry (relative PEB error ≤ ½·κ/(1 − κ), κ = 7·u·trace(F̂⁻¹): the
    scaled perturbation |δF̂_ij| ≤ u since the site matrices are PSD), and the ranking's best
    layouts are those of float64."""
    d = PlanDocument.model_validate(_doc())
    sites = expand_sites(d)
    pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
    known = tuple(d.known)
    c64 = build_site_cache(d.system, sites, pairs, known=known)
    c32 = build_site_cache(
        d.system, sites, pairs, known=known, layout=CacheLayout("float32", False)
    )
    assert c32.storage == "float32" and c32.blocks.nbytes * 2 == c64.blocks.nbytes
    s64 = Scorer(c64, pairs.weights, d.objective, known)
    s32 = Scorer(c32, pairs.weights, d.objective, known)
    lay = all_layouts(len(sites), 3)
    m64, m32 = s64.metric(lay), s32.metric(lay)
    np.testing.assert_array_equal(np.isinf(m64), np.isinf(m32))
    ok = np.isfinite(m64)
    kappa = 7 * UNIT_ROUNDOFF_F32 * _scaled_trace(c64.packed, c64.los, lay)
    assert np.all(kappa[ok] < 0.5)  # the bound applies
    bound = 0.5 * kappa / (1 - kappa) + F64_SLACK * kappa / UNIT_ROUNDOFF_F32
    err = np.abs(m32 - m64) / m64
    assert np.all(err[ok] <= bound[ok])
    assert err[ok].max() > 0  # float32 is not float64 in disguise
    l64, l32 = s64.loss(lay), s32.loss(lay)
    assert np.array_equal(np.argsort(l64, kind="stable")[:3], np.argsort(l32, kind="stable")[:3])


def test_exact_metric_of_a_float32_cache_is_compute_bounds() -> None:
    """Re-scored on float64 caches of a few sites (groups of ≤ EXACT_SITES), the layouts of a
    float32 cache get compute_bounds' bits."""
    d = PlanDocument.model_validate(_doc(known=["height"]))
    sites = expand_sites(d)
    pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
    c32 = build_site_cache(
        d.system, sites, pairs, known=("height",), layout=CacheLayout("float32", False)
    )
    s32 = Scorer(c32, pairs.weights, d.objective, ("height",))
    layouts = np.array([(0, 2, 5), (1, 3, 6), (2, 3, 4)])
    got = s32.exact_metric(layouts)
    for row, lay in enumerate(layouts):
        scen = Scenario(
            system=d.system,
            ris=[sites[s].ris for s in lay],
            tx=[0.1, 0.2, 9.0],
            rx=[0.3, -0.2, 9.0],
            codebook={"kind": "expected_random"},
            known=d.known,
        )
        res = compute_bounds(scen, tx=pairs.tx, rx=pairs.rx)
        np.testing.assert_array_equal(got[row], select_metric("rx", res.peb_tx, res.peb_rx))
    assert not np.array_equal(got, s32.metric(layouts))  # the float32 scores differ


def test_plan_above_the_float64_budget_reports_float32_with_exact_finalists(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """20 sites × 300 pairs: 2.2 MiB as float64 with rows, 1.3 MiB without, 0.7 MiB as
    float32. A 2 MiB budget recomputes the rows: the same plan bit for bit; a 1 MiB budget
    stores float32: the plan names it and reports the float64 plan's layouts and exact
    objectives."""
    doc = _doc(20, ris_count=[2, 3], search={"method": "exhaustive", "top_k": 4})
    ref = run_plan(doc, executor=SerialExecutor()).to_json()
    assert ref["site_cache"]["storage"] == "float64" and ref["site_cache"]["rows_stored"]
    monkeypatch.setenv("RIS_PLANNER_CACHE_MEMORY_MB", "2")
    rows = run_plan(doc, executor=SerialExecutor()).to_json()
    assert rows["site_cache"] == {
        "storage": "float64",
        "rows_stored": False,
        "bytes": 5 * 20 * 28 * 64 * 8,
    }
    assert {k: v for k, v in rows.items() if k not in ("timing_s", "site_cache")} == {
        k: v for k, v in ref.items() if k not in ("timing_s", "site_cache")
    }
    monkeypatch.setenv("RIS_PLANNER_CACHE_MEMORY_MB", "1")
    got = run_plan(doc, executor=SerialExecutor()).to_json()
    assert got["site_cache"] == {
        "storage": "float32",
        "rows_stored": False,
        "bytes": 5 * 20 * 28 * 64 * 4,
    }
    for a, b in zip(ref["by_count"], got["by_count"], strict=True):
        assert a["top_layouts"] == b["top_layouts"]  # same layouts, exact objectives
        assert a["objective"] == b["objective"] and a["quantiles_m"] == b["quantiles_m"]
        # exhaustive: the exact certificate is the re-scored best's value
        assert (
            b["certificate"]["objective_bound"]
            == b["objective"]
            == a["certificate"]["objective_bound"]
        )


def test_storage_blocks_are_the_kernels_chunks() -> None:
    """The cache's pair blocks are the compiled kernel's chunks (it reads them in place)."""
    from ris_planner.inversion import _crb_jit
    from ris_planner.planning.scoring import site_cache

    assert site_cache.CHUNK == _crb_jit.CHUNK
