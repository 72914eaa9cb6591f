"""The plan's figures, checked on the data they are drawn from: the served fraction per RX point
against a loop over its pairs (and plan.json's heatmap and points carrying it), the chosen
sites' labels not overlapping in the rendered top view and heatmap, the site table's headers
unbroken and its names complete, the validation figure's axes naming their quantities."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from test_planning_points import candidates

from ris_planner.bounds.compute import compute_bounds
from ris_planner.model.scenario import Scenario
from ris_planner.planning import PlanResult, SerialExecutor, run_plan
from ris_planner.planning.outputs.report import (
    SITE_LABEL_GID,
    SITE_TABLE_HEADERS,
    heatmap_figure,
    pack_entries,
    raster,
    text_table,
    topview_figure,
    validation_figure,
)
from ris_planner.planning.outputs.rx_fields import served_fractions, served_level

THRESHOLD_M = 0.1
TX_POINTS = [[-1.5, 0.5, 0.0], [0.5, -1.5, 0.0], [1.0, 1.0, 0.0]]
"""The last TX point lies on the RX grid: that RX point has one partner less."""
TX_WEIGHTS = [1.0, 2.0, 3.0]


def small_plan(**over: Any) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "candidates": candidates(),
        "tx_map": {"points": TX_POINTS, "weights": TX_WEIGHTS},
        "rx_map": {"grid": {"x": [-2, 2, 1], "y": [-2, 2, 1], "z": [0, 0, 1]}},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": THRESHOLD_M},
        "ris_count": [2, 4],
        "search": {"top_k": 2},
    }
    doc.update(over)
    return doc


@pytest.fixture(scope="module")
def result() -> PlanResult:
    return run_plan(small_plan(), executor=SerialExecutor())


def brute_served(result: PlanResult, layout: tuple[int, ...], level: float) -> list[float]:
    """Per RX point: a loop over its TX partners of single-pair compute_bounds calls, summing
    the weight of those with a finite bound ≤ level (NaN without a partner)."""
    ris = [result.sites[s].ris for s in layout]
    out = []
    for rx in result.rx_map.points:
        served = total = 0.0
        for tx, w in zip(TX_POINTS, TX_WEIGHTS, strict=True):
            if np.allclose(tx, rx):
                continue
            scen = Scenario.model_validate(
                {"ris": ris, "tx": tx, "rx": rx.tolist(), "codebook": {"kind": "expected_random"}}
            )
            v = float(compute_bounds(scen).peb_rx[0])
            assert not math.isclose(v, level, rel_tol=1e-6)  # rounding cannot flip it
            total += w
            served += w if math.isfinite(v) and v <= level else 0.0
        out.append(served / total if total else math.nan)
    return out


def test_served_fraction_is_the_weight_of_served_pairs(result: PlanResult) -> None:
    assert served_level(result.document) == THRESHOLD_M
    seen = set()
    for cr in result.counts:
        lay = cr.ranked[0][0]
        got = result.rx_field(lay).served
        want = brute_served(result, lay, THRESHOLD_M)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
        seen |= {"none" if v == 0 else "all" if v == 1 else "part" for v in got}
    assert seen == {"none", "part", "all"}  # the test can fail either way


def test_without_a_threshold_a_finite_bound_is_served() -> None:
    """A quantile objective without a target: the served fraction is the weight of the
    finite bounds (the outward site alone with one other is blind for some pairs)."""
    objective = {"kind": "quantile", "metric": "rx", "q": 0.5}
    res = run_plan(small_plan(objective=objective, ris_count=[2]), executor=SerialExecutor())
    assert served_level(res.document) == math.inf
    lay = res.counts[0].ranked[0][0]
    np.testing.assert_allclose(
        res.rx_field(lay).served, brute_served(res, lay, math.inf), rtol=1e-12, atol=1e-15
    )
    assert res.to_json()["heatmap"]["served_level_m"] is None


def test_served_fractions_of_weightless_rows_are_nan() -> None:
    metric = np.array([[0.1, np.inf, 0.3], [1.0, 2.0, 3.0]])
    weights = np.array([[1.0, 1.0, 2.0], [0.0, 0.0, 0.0]])
    got = served_fractions(metric, weights, 0.5)
    assert got[0] == pytest.approx(0.75) and math.isnan(got[1])  # 0.1 and 0.3 of 4


def test_plan_json_carries_the_served_fraction(result: PlanResult) -> None:
    """points: each point's fraction per count; heatmap: the grid holds one point per cell, so
    each cell is its point's fraction."""
    plan = result.to_json()
    hm = plan["heatmap"]
    assert hm["served_level_m"] == THRESHOLD_M
    assert set(hm["served_fraction"]) == set(hm["bound_m"]) == {"2", "4"}
    for cr in result.counts:
        key = str(cr.ris_count)
        served = result.rx_field(cr.ranked[0][0]).served
        for entry, v in zip(plan["points"], served, strict=True):
            assert entry["served_fraction"][key] == v
            x, y, _ = entry["position"]
            assert hm["served_fraction"][key][round(y + 2)][round(x + 2)] == v


def test_heatmap_draws_the_served_fraction(result: PlanResult) -> None:
    """The left panel's cells are the raster (worst point per cell) of the served fractions."""
    pts, _, lay = result.heatmap()
    fig = heatmap_figure(result)
    left = fig.axes[0]
    mesh = left.collections[0]
    _, _, frac, empty = raster(pts, result.rx_field(lay).served, result.scene, worst="min")
    np.testing.assert_array_equal(np.ma.getdata(mesh.get_array()), frac)
    np.testing.assert_array_equal(np.ma.getmaskarray(mesh.get_array()), empty)
    assert "TX partners served" in left.get_title() and "≤ 0.1 m" in left.get_title()


def test_raster_worst_min_keeps_the_smallest_value() -> None:
    pts = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    vals = np.array([0.75, 0.25, np.nan, 1.0])
    _, _, lo, empty = raster(pts, vals, None, worst="min")
    _, _, hi, _ = raster(pts, vals, None)
    assert list(lo[0][~empty[0]]) == [0.25, 1.0]  # the first two points share a cell
    assert list(hi[0][~empty[0]]) == [0.75, 1.0]


# --- labels and tables -------------------------------------------------------------------------


def crowded_plan() -> dict[str, Any]:
    """Six chosen sites within 2 m of each other on a 60 m map, with long names."""
    cands = []
    for k in range(6):
        phi = 2 * math.pi * k / 6
        cands.append(
            {
                "position": [0.8 * math.cos(phi), 0.8 * math.sin(phi), 4.0 + k],
                "orientation": [phi, 0.3, 0.0],
                "name": f"facade {k} of the long building name number {k} (north wing)",
            }
        )
    grid = {"grid": {"x": [-30, 30, 6], "y": [-30, 30, 6], "z": [1.5, 1.5, 1]}}
    return {
        "candidates": cands,
        "tx_map": grid,
        "rx_map": grid,
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "ris_count": [5, 6],
    }


@pytest.fixture(scope="module")
def crowded() -> PlanResult:
    return run_plan(crowded_plan(), executor=SerialExecutor())


def _boxes(fig: Any, ax: Any) -> list[Any]:
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return [t.get_window_extent(renderer) for t in ax.texts if t.get_gid() == SITE_LABEL_GID]


def _overlapping(boxes: list[Any]) -> list[tuple[int, int]]:
    return [
        (i, j)
        for i in range(len(boxes))
        for j in range(i + 1, len(boxes))
        if boxes[i].overlaps(boxes[j])
    ]


def test_topview_labels_do_not_overlap(crowded: PlanResult) -> None:
    fig = topview_figure(crowded)
    boxes = _boxes(fig, fig.axes[0])
    assert len(boxes) == 6  # every chosen site, each at its own position
    assert _overlapping(boxes) == []
    frame = fig.axes[0].get_window_extent()
    for b in boxes:  # inside the map
        assert frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1


def test_heatmap_labels_do_not_overlap(crowded: PlanResult) -> None:
    fig = heatmap_figure(crowded)
    for ax in fig.axes[:2]:  # the two map panels (the colour bars follow)
        boxes = _boxes(fig, ax)
        assert len(boxes) == 6 and _overlapping(boxes) == []
    renderer = fig.canvas.get_renderer()
    (legend,) = fig.legends
    key = next(t for t in fig.texts if t.get_gid() == "site-key")
    below = [legend.get_window_extent(renderer), key.get_window_extent(renderer)]
    for ax in fig.axes[:2]:
        labels = ax.xaxis.get_label().get_window_extent(renderer)
        assert not any(labels.overlaps(b) for b in below)
    assert not below[0].overlaps(below[1])
    for s in crowded.counts[-1].ranked[0][0]:
        assert f"{s}: {crowded.sites[s].name}" in key.get_text()  # names, not only indices


def test_topview_site_table_names_every_chosen_site(crowded: PlanResult) -> None:
    fig = topview_figure(crowded)
    table = next(t for t in fig.texts if t.get_gid() == "site-table")
    lines = table.get_text().split("\n")
    assert lines[0] == "chosen sites"
    assert lines[1].split() == ["#", "site", "height", "tilt", "chosen", "for"]
    text = " ".join(" ".join(line.split()) for line in lines[2:])
    for site in crowded.sites:
        for word in site.name.split():
            assert word in text
    renderer = fig.canvas.get_renderer()
    box = table.get_window_extent(renderer)
    assert not box.overlaps(fig.axes[0].get_legend().get_window_extent(renderer))
    assert box.x1 <= fig.bbox.x1 and box.y0 >= 0  # inside the figure


def test_text_table_never_breaks_headers_or_words() -> None:
    rows = [
        ["3", "wall 0 at (-8.0, -12.4, 6) tilt 0.30 rad", "6 m", "17°", "6 RIS"],
        ["28", "Puolustusministeriö facade 4", "4 m", "17°", "3, 4, 6 RIS"],
        ["5", "x", "6 m", "9°", "3 RIS"],
    ]
    for width in (10, 30, 45, 200):
        lines = text_table(SITE_TABLE_HEADERS, rows, width, wrap=1)
        header = lines[0]
        starts = [header.index(h) for h in SITE_TABLE_HEADERS]
        assert starts == sorted(starts)  # each header whole, in order
        assert "RIS" not in header and all(h in header for h in SITE_TABLE_HEADERS)
        # the wrapped column rebuilds each name, word for word
        col = slice(starts[1], starts[2])
        names: list[list[str]] = []
        for line in lines[1:]:
            if line[: starts[1]].strip():
                names.append([])
            names[-1] += line[col].split()
        assert [" ".join(n) for n in names] == [r[1] for r in rows]
        for line in lines[1:]:  # other cells whole, under their headers
            for c in (0, 2, 3, 4):
                cell = line[starts[c] : starts[c + 1] if c < 4 else None].strip()
                assert cell in {"", *(r[c] for r in rows)}
        # as wide as asked, unless the fixed columns and the longest word need more (50)
        assert max(len(line) for line in lines) <= max(width, 50)


def test_pack_entries_keeps_entries_whole() -> None:
    entries = ["sites –", "3: wall 0 at (-8.0, -12.4, 6)", "5: wall 0", "12: wall 1 at (19.9, 0)"]
    lines = pack_entries(entries, 40, 4)
    assert " ".join(" ".join(line.split("   ")) for line in lines) == " ".join(entries)
    assert all(len(line) <= 40 for line in lines)
    assert pack_entries(entries, 10, 2)[-1].endswith("… 2 more")


# --- the validation figure ---------------------------------------------------------------------


def validation(metric: str) -> dict[str, Any]:
    pairs = [{"bound_m": 0.05 * (k + 1), "error_m": 0.07 * (k + 1)} for k in range(5)]
    return {"metric": metric, "threshold_m": 0.2, "layouts": [{"ris_count": 2, "pairs": pairs}]}


@pytest.mark.parametrize(
    ("metric", "error", "bound"),
    [
        ("rx", "RX position error", "PEB_R"),
        ("tx", "TX position error", "PEB_T"),
        ("max", "max(TX, RX) position error", "max(PEB_T, PEB_R)"),
    ],
)
def test_validation_axes_name_their_quantity(metric: str, error: str, bound: str) -> None:
    fig = validation_figure(validation(metric))
    scatter, cdf = fig.axes
    assert cdf.get_xlabel() == f"{error} (solid) / {bound} (dashed) [m]"
    assert scatter.get_xlabel() == f"bound: {bound} [m]"
    assert scatter.get_ylabel() == f"estimator RMSE: {error} [m]"
    assert cdf.get_ylabel() == "fraction of sampled pairs"


def test_validation_without_finite_values_says_so() -> None:
    v = validation("rx")
    v["layouts"][0]["pairs"] = [{"bound_m": None, "error_m": None}]
    fig = validation_figure(v)
    assert any("no sampled pair" in t.get_text() for t in fig.axes[1].texts)
