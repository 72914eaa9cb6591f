"""Per-point plan results (plan.json "points" and "heatmap"): bounds against compute_bounds and
a brute-force weighted median, serving sites against the field-of-view angle computed by hand,
blind reasons, the heatmap grid against the points, strict JSON."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from ris_planner.bounds.compute import REASON_DEGENERATE, REASON_UNDERDETERMINED, compute_bounds
from ris_planner.model.scenario import Scenario
from ris_planner.physics.geometry import rotation_matrix
from ris_planner.planning import PlanResult, SerialExecutor, plan_preset, run_plan
from ris_planner.planning.outputs.points import raster_cells
from ris_planner.planning.outputs.rx_fields import REASON_NO_TX, cell_medians

RTOL = 1e-9
"""A point's bound is compute_bounds' value for the same pairs (the same code path, batched
differently), so only the rounding of a differently batched inversion can move it."""

SMALL_GRID = {"grid": {"x": [-2, 2, 1], "y": [-2, 2, 1], "z": [0, 0, 1]}}


def candidates() -> list[dict[str, Any]]:
    """Three sites facing the centre and one facing away from the map (+x, at x = 3)."""
    out = []
    for k, phi in enumerate((0.3, 2.4, 4.3)):
        out.append(
            {
                "position": [3.5 * math.cos(phi), 3.5 * math.sin(phi), 2.0],
                "orientation": [phi + math.pi, 0.5, 0.0],
                "name": f"ring {k}",
            }
        )
    out.append({"position": [1.0, 0.0, 2.0], "orientation": [0.0, 0.0, 0.0], "name": "outward"})
    return out


def small_plan(**over: Any) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "candidates": candidates(),
        "tx_map": {"points": [[-1.5, 0.5, 0.0], [0.5, -1.5, 0.0], [1.5, 1.5, 0.0]]},
        "rx_map": SMALL_GRID,
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 0.1},
        "ris_count": [2, 4],
        "search": {"top_k": 2},
    }
    doc.update(over)
    return doc


@pytest.fixture(scope="module")
def result() -> PlanResult:
    return run_plan(small_plan(), executor=SerialExecutor())


def brute_median(values: list[float], weights: list[float]) -> float:
    """Smallest v whose cumulative weight (sorted, inf last) reaches half the total."""
    pairs = sorted((v, w) for v, w in zip(values, weights, strict=True) if w > 0)
    total = sum(w for _, w in pairs)
    acc = 0.0
    for v, w in pairs:
        acc += w
        if acc >= 0.5 * total - 1e-12:
            return v
    raise AssertionError("no weight")


def test_point_bounds_are_weighted_medians_of_compute_bounds(result: PlanResult) -> None:
    """Each point's bound, per count, from a loop over TX points of single-pair compute_bounds
    calls and a sorted-list median."""
    plan = result.to_json()
    tx = result.tx_map.points
    for cr in result.counts:
        lay = cr.ranked[0][0]
        ris = [result.sites[s].ris for s in lay]
        for entry in plan["points"][::3]:
            rx = entry["position"]
            vals = []
            for t in tx:
                scen = Scenario(ris=ris, tx=t.tolist(), rx=rx, codebook={"kind": "expected_random"})
                vals.append(float(compute_bounds(scen).peb_rx[0]))
            want = brute_median(vals, [1.0] * len(vals))
            got = entry["bound_m"][str(cr.ris_count)]
            assert got == pytest.approx(want, rel=RTOL)


def test_largest_count_is_the_heatmap(result: PlanResult) -> None:
    pts, vals, lay = result.heatmap()
    plan = result.to_json()
    key = str(len(lay))
    np.testing.assert_array_equal(pts, [p["position"] for p in plan["points"]])
    got = np.array(
        [np.nan if p["bound_m"][key] is None else p["bound_m"][key] for p in plan["points"]]
    )
    np.testing.assert_array_equal(got, vals)
    assert plan["heatmap"]["ris_count"] == len(lay) == 4
    assert plan["heatmap"]["sites"][key] == list(lay)


def test_serving_sites_follow_the_field_of_view(result: PlanResult) -> None:
    """Free space: a site serves an RX point iff the point and at least one TX point lie in its
    open front half-space (normal · direction > 0), computed here from the rotation matrix."""
    plan = result.to_json()
    tx = result.tx_map.points
    seen_partial = False
    for cr in result.counts:
        lay = cr.ranked[0][0]
        for entry in plan["points"]:
            rx = np.array(entry["position"])
            want = []
            for s in lay:
                ris = result.sites[s].ris
                n = rotation_matrix(ris.orientation)[:, 0]
                p = np.array(ris.position)
                front_rx = float(n @ (rx - p)) > 0
                front_tx = any(float(n @ (t - p)) > 0 for t in tx if np.linalg.norm(t - rx) > 0)
                if front_rx and front_tx:
                    want.append(s)
            got = entry["serving"][str(cr.ris_count)]
            assert got == want
            seen_partial |= 0 < len(got) < len(lay)
    assert seen_partial  # the outward site serves only part of the map: the test can fail


def test_blind_and_empty_points_carry_reasons() -> None:
    """One RIS with LOS: 4 observations for 7 unknowns, every pair underdetermined; the fixed
    heatmap TX on an RX point leaves that point without TX."""
    rx = {"points": [[0.0, 0.0, 0.0], [-1.0, 1.0, 0.0]]}
    one = run_plan(
        small_plan(rx_map=rx, ris_count=[1, 3], heatmap_tx=[0.0, 0.0, 0.0]),
        executor=SerialExecutor(),
    )
    plan = one.to_json()
    json.dumps(plan, allow_nan=False)  # strict JSON: no NaN/inf anywhere
    first, second = plan["points"]
    assert first["bound_m"] == {"1": None, "3": None}
    assert first["reason"] == {"1": REASON_NO_TX, "3": REASON_NO_TX}
    assert second["bound_m"]["1"] is None
    assert second["reason"]["1"].startswith(REASON_UNDERDETERMINED)
    assert second["bound_m"]["3"] > 0 and second["reason"]["3"] is None


def test_degenerate_point_reason() -> None:
    """An RX point on the only candidate pair's RIS: every pair degenerate."""
    cand = candidates()[:2]
    res = run_plan(
        small_plan(candidates=cand, rx_map={"points": [cand[1]["position"]]}, ris_count=[2]),
        executor=SerialExecutor(),
    )
    (entry,) = res.to_json()["points"]
    assert entry["bound_m"] == {"2": None}
    assert entry["reason"] == {"2": REASON_DEGENERATE}


def test_heatmap_grid_holds_the_point_values(result: PlanResult) -> None:
    """A single-level grid map: one point per cell, each cell equals its point."""
    plan = result.to_json()
    hm = plan["heatmap"]
    assert hm["grid"] == {"x0": -2.0, "y0": -2.0, "cell_m": 1.0, "nx": 5, "ny": 5}
    for entry in plan["points"]:
        x, y, _ = entry["position"]
        ix, iy = round(x + 2), round(y + 2)
        for key in ("2", "4"):
            assert hm["bound_m"][key][iy][ix] == entry["bound_m"][key]
    assert hm["threshold_m"] == {"2": 0.1, "4": 0.1}
    assert hm["threshold_label"] == "coverage threshold 0.1 m"


def test_cell_medians_against_a_loop() -> None:
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 10, size=(400, 2))
    vals = rng.lognormal(size=400)
    vals[rng.choice(400, 40, replace=False)] = np.inf
    vals[rng.choice(400, 20, replace=False)] = np.nan
    w = rng.uniform(0.1, 2, size=400)
    grid, cells = raster_cells(xy)
    n = grid["nx"] * grid["ny"]
    got = cell_medians(cells, vals, w, int(n))
    for c in range(int(n)):
        mask = (cells == c) & ~np.isnan(vals)
        if not np.any(mask):
            assert np.isnan(got[c])
        else:
            assert got[c] == brute_median(list(vals[mask]), list(w[mask]))
    # cells are centred on the points' lattice: every point within half a cell of its centre
    ix, iy = cells % grid["nx"], cells // grid["nx"]
    cx = grid["x0"] + ix * grid["cell_m"]
    cy = grid["y0"] + iy * grid["cell_m"]
    assert np.all(np.abs(xy[:, 0] - cx) <= 0.5 * grid["cell_m"] * (1 + 1e-9))
    assert np.all(np.abs(xy[:, 1] - cy) <= 0.5 * grid["cell_m"] * (1 + 1e-9))


def test_fig10_points_are_strict_json_and_quantile_threshold() -> None:
    res = run_plan(plan_preset("fig10-anchors"), executor=SerialExecutor())
    plan = json.loads(json.dumps(res.to_json(), allow_nan=False))
    assert len(plan["points"]) == plan["rx_points"] == 98
    assert plan["heatmap"]["grid"]["nx"] == plan["heatmap"]["grid"]["ny"] == 7
    for b in plan["by_count"]:
        key = str(b["ris_count"])
        assert plan["heatmap"]["threshold_m"][key] == pytest.approx(b["objective"], rel=1e-12)
        assert all(p["serving"][key] for p in plan["points"])  # the anchors face the centre
