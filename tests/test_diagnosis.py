"""Honest plans: the diagnosis (verdicts, the link_budget / geometry / blocked causes on cases
built to trigger them, the size and power suggestions re-run), the RIS-size scaling law of the
expected-random information, the sizing question against brute force, the CLI's warning and
exit status, rounded human output, the heatmap and sizing figures."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ris_planner.bounds.compute import compute_bounds
from ris_planner.bounds.paths import ris_serves
from ris_planner.cli import main
from ris_planner.model.scenario import RIS, SystemParams
from ris_planner.physics.fim import steering_gram
from ris_planner.physics.geometry import element_positions
from ris_planner.planning import PlanDocument, SerialExecutor, run_plan
from ris_planner.planning.beams import layout_scenario
from ris_planner.planning.enumerating import run_enumerating
from ris_planner.planning.outputs.diagnosis import (
    BLOCKED_EXAMPLES,
    COVERAGE_FLOOR,
    MAX_SIDE,
    SPREAD_MIN,
    per_pair_side,
    relative_spread,
    rescore,
    served_fraction,
    smallest_power_step,
    smallest_side,
    verdict,
)
from ris_planner.planning.outputs.report import BLIND_COLOUR, write_figures
from ris_planner.planning.prepare import prepare_plan
from ris_planner.planning.resources.admission import estimate_plan
from ris_planner.planning.search.sizing import SizeRow, answer_row
from ris_planner.runtime.progress import no_progress

GRID = {"grid": {"x": [-3, 3, 1.5], "y": [-3, 3, 1.5], "z": [1.5, 1.5, 1]}}
RTOL = 1e-9
"""Same-process comparisons of two routes to one bound (compute_bounds vs the site cache):
both invert through ris_planner.inversion.ldl, only the summation order of the 7×7 blocks
differs."""


def ring(n: int, radius: float, h: float = 3.0) -> list[dict[str, Any]]:
    """n candidates on a circle around the origin, facing its centre."""
    out = []
    for k in range(n):
        phi = 2 * math.pi * k / n + 0.1
        out.append(
            {
                "position": [radius * math.cos(phi), radius * math.sin(phi), h],
                "orientation": [phi + math.pi, 0.0, 0.0],
            }
        )
    return out


def doc_of(**over: Any) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "tx_map": GRID,
        "rx_map": GRID,
        "pairs": {"sample": 200, "seed": 1},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "candidates": ring(4, 6.0),
        "ris_count": [2],
    }
    return doc | over


GOOD = doc_of()
"""Four 10×10 RISs 6 m from a 6 m × 6 m street square: most pairs below 1 m."""
LINK = doc_of(candidates=ring(5, 25.0), ris={"rows": 4, "cols": 4}, ris_count=[3])
"""Tiny (4×4) RISs 25 m away: every pair finite, none below 1 m – a link budget problem."""
GEOMETRY = doc_of(ris_count=[1])
"""One RIS and the LOS: 4 geometric channel parameters for 7 unknowns – every pair blind."""
BEHIND_WALL = [
    {"position": [0.0, 10.0, 3.0], "orientation": [-math.pi / 2, 0.0, 0.0]},
    {"position": [2.0, 10.0, 3.0], "orientation": [-math.pi / 2, 0.0, 0.0]},
]
WALL = {"kind": "wall", "start": [-8, 8], "end": [8, 8], "height_m": 10}
BLOCKED = doc_of(candidates=[*ring(4, 6.0)[:1], *BEHIND_WALL], environment={"obstacles": [WALL]})
"""Two of three candidates face the square from behind a 10 m wall."""


def plan(doc: dict[str, Any]) -> Any:
    return run_plan(doc, executor=SerialExecutor())


def kinds(result: Any) -> list[str]:
    return [c["kind"] for c in result.diagnosis["causes"]]


# --- the scaling law --------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3, 5, 10, 16])
def test_expected_gram_grows_as_n_and_n_squared(n: int) -> None:
    """E[Q] = W·VᴴV (fim.transmission_gram_expected): the response entry is N and the angle
    entries k²Σy², k²Σz² of a centred n×n grid of spacing d are k²d²(N² − N)/12 – the
    closed form of Σ_c y_c² = d² n(n² − 1)/12, repeated over n rows – and the cross terms
    vanish: the information of a RIS path is N·D + (N² − N)·E with D, E independent of N."""
    wavelength = 0.01
    d = wavelength / 2
    g = steering_gram(element_positions(n, n, d), wavelength)
    big_n = n * n
    k = 2 * np.pi / wavelength
    angle = k**2 * d**2 * (big_n**2 - big_n) / 12
    assert g[2, 2].real == big_n
    np.testing.assert_allclose([g[0, 0].real, g[1, 1].real], [angle, angle], rtol=1e-12, atol=0)
    scale = max(angle, 1.0)
    for i, j in [(0, 1), (0, 2), (1, 2)]:
        assert abs(g[i, j]) <= 1e-12 * scale


def _three_ris_peb(n: int, tx_power_dbm: float = 30.0) -> np.ndarray:
    rng = np.random.default_rng(3)
    tx = np.column_stack([rng.uniform(-3, 3, 40), rng.uniform(-3, 3, 40), np.full(40, 1.5)])
    rx = np.column_stack([rng.uniform(-3, 3, 40), rng.uniform(-3, 3, 40), np.full(40, 1.5)])
    ris = [RIS(rows=n, cols=n, **c) for c in ring(3, 20.0)]
    system = SystemParams(los=False, tx_power_dbm=tx_power_dbm)
    res = compute_bounds(layout_scenario(system, ris, [], None), tx=tx, rx=rx)
    return np.asarray(res.peb_rx)


def test_bound_falls_between_sqrt_n_and_n_laws() -> None:
    """Without LOS every path is a RIS path with per-path information diag(a(N² − N), a(N² −
    N), bN) on (ξ, ζ, r) (the nuisance gain couples only with r, the angles decouple on a
    centred grid), so 4N elements give 4J(N) ⪯ J(4N) ⪯ (16N − 4)/(N − 1)·J(N): the PEB
    falls by a factor in [2, √((16N − 4)/(N − 1))]: ≈ 4 while the angle-resolved directions
    dominate the error, towards 2 as the delay-resolved ones (information ∝ N) take over."""
    prev = _three_ris_peb(8)
    assert np.all(np.isfinite(prev))
    ratios = []
    for n in (16, 32, 64, 128):
        cur = _three_ris_peb(n)
        ratio = prev / cur  # N grows 4×
        big_n = (n // 2) ** 2
        assert np.all(ratio >= 2 * (1 - 1e-9))
        assert np.all(ratio <= math.sqrt((16 * big_n - 4) / (big_n - 1)) * (1 + 1e-9))
        ratios.append(ratio)
        prev = cur
    # the angle-limited 1/N law at small N, drifting towards the delay-limited 1/√N
    assert np.all(ratios[0] > 3.5) and np.all(ratios[-1] < 3.5)


def test_bound_falls_exactly_as_power_to_the_minus_half() -> None:
    """Every FIM block carries 2P/σ²: +20 dB of power divides every PEB by 10."""
    np.testing.assert_allclose(
        _three_ris_peb(8, 30.0) / _three_ris_peb(8, 50.0), 10.0, rtol=1e-9, atol=0
    )


# --- the rules ----------------------------------------------------------------------------


def test_verdict_rules() -> None:
    assert verdict(0.05, 0.9) == "useless"  # below a tenth served
    assert verdict(0.3, 0.01) == "useless"  # below the floor and flat
    assert verdict(0.3, 0.5) == "weak"  # below the floor
    assert verdict(0.8, 0.01) == "weak"  # the choice of sites barely matters
    assert verdict(0.97, 0.0) == "ok"  # every layout good: saturated
    assert verdict(0.8, None) == "ok"  # one layout: no spread
    assert verdict(COVERAGE_FLOOR, SPREAD_MIN) == "ok"
    assert relative_spread(0.2, 0.1) == 0.5
    assert relative_spread(2.0, math.inf) == 1.0
    assert relative_spread(math.inf, math.inf) == 0.0
    assert relative_spread(0.0, 0.0) == 0.0


def test_smallest_side_and_power_step_are_the_first_reaching_by_scan() -> None:
    rng = np.random.default_rng(0)
    metric = rng.uniform(0.5, 400.0, 50)
    metric[:5] = np.inf
    w = np.full(50, 1 / 50)

    def reaches(m: np.ndarray) -> bool:
        return served_fraction(m, w, 1.0) >= 0.5

    side = smallest_side(metric, 16, reaches)
    scan = next(n for n in range(1, MAX_SIDE + 1) if reaches(metric * 16 / n**2))
    assert side == scan
    step = smallest_power_step(metric, 700, reaches)
    scan = next(k for k in range(701) if reaches(metric * 10 ** (-k * 0.1 / 20)))
    assert step == scan
    assert smallest_side(np.full(50, np.inf), 16, reaches) is None
    # per pair: the smallest n with metric·16/n² ≤ 1, by scan; its weighted median
    sides = [
        next((n for n in range(1, 4000) if m * 16 / n**2 <= 1.0), None) if np.isfinite(m) else None
        for m in metric
    ]
    finite = sorted(x for x in sides if x is not None)
    assert per_pair_side(metric, w, 16, 1.0)["0.5"] == finite[24]  # 25 of 50 pairs, 5 blind last


# --- the constructed cases ---------------------------------------------------------------------


def test_good_plan_is_ok_and_the_contract_holds() -> None:
    result = plan(GOOD)
    d = result.to_json()["diagnosis"]
    assert d["verdict"] == "ok" and d["causes"] == []
    assert d["floor"] == COVERAGE_FLOOR
    best = result.counts[-1].ranked[0]
    assert d["best"] == -best[1] and d["sites"] == list(best[0])
    assert d["worst"] == -float(np.max(result.counts[-1].outcome.losses))
    assert d["served_fraction"] >= COVERAGE_FLOOR
    json.dumps(d, allow_nan=False)


def test_rescore_at_the_plans_size_is_the_cached_metric() -> None:
    result = plan(GOOD)
    layout = result.counts[-1].ranked[0][0]
    metric, w = rescore(result, layout, side=10)
    np.testing.assert_allclose(metric, result.layout_metric(layout), rtol=RTOL)
    np.testing.assert_array_equal(w, result.metric_weights)


def test_link_budget_suggests_a_size_and_a_power_that_reach_the_floor_when_rerun() -> None:
    result = plan(LINK)
    d = result.diagnosis
    assert d["verdict"] == "useless" and kinds(result) == ["link_budget"]
    cause = d["causes"][0]
    n, m = cause["suggested_ris_size"]
    assert n == m and 4 < n <= MAX_SIDE
    assert cause["verified_objective"] >= COVERAGE_FLOOR
    # the whole plan again at the suggested size: its (exhaustive) best reaches the floor
    again = plan(LINK | {"ris": {"rows": n, "cols": n}})
    assert again.diagnosis["served_fraction"] >= COVERAGE_FLOOR
    assert again.diagnosis["verdict"] != "useless"
    # the power alternative, also re-run
    power = cause["suggested_tx_power_dbm"]
    assert cause["verified"] and power > 30
    louder = plan(LINK | {"system": {"tx_power_dbm": power}})
    assert louder.diagnosis["served_fraction"] >= COVERAGE_FLOOR
    # P^(−1/2) is exact: 0.1 dB less misses the floor with the same layout
    quieter, w = rescore(result, tuple(d["sites"]), tx_power_dbm=power - 0.1)
    assert served_fraction(quieter, w, 1.0) < COVERAGE_FLOOR


def test_geometry_names_the_blind_pairs_and_suggests_no_size() -> None:
    result = plan(GEOMETRY)
    d = result.diagnosis
    assert d["verdict"] == "useless" and kinds(result) == ["geometry"]
    cause = d["causes"][0]
    assert cause["pairs"] == result.pairs.size and "more RISs" in cause["message"]
    # two RISs resolve the same pairs: it was the geometry, not the link budget
    assert plan(GEOMETRY | {"ris_count": [2]}).diagnosis["verdict"] == "ok"


def test_blocked_names_the_candidates_behind_the_wall() -> None:
    result = plan(BLOCKED)
    d = result.diagnosis
    assert d["verdict"] == "useless"
    blocked = next(c for c in d["causes"] if c["kind"] == "blocked")
    assert [c["index"] for c in blocked["candidates"]] == [1, 2]
    assert blocked["candidates"][0]["name"] == result.sites[1].name
    assert not result.cache.present[[1, 2]].any() and result.cache.present[0].any()
    assert blocked["no_visible_point"] == 2 and blocked["no_pair_with_both_ues"] == 0
    assert all(c["reason"] == "no_visible_point" for c in blocked["candidates"])
    assert all(c["visible_points"] == 0 for c in blocked["candidates"])
    assert blocked["message"].startswith("2 of 3 candidates serve no pair")
    assert "2 see no UE point" in blocked["message"]


SQUARE_POINTS = [
    [x, y, 1.5] for x in (-3.0, -1.5, 0.0, 1.5, 3.0) for y in (-3.0, -1.5, 0.0, 1.5, 3.0)
]
SOUTH_TX = [[-1.0, -9.0, 1.5], [0.0, -9.0, 1.5], [1.0, -9.0, 1.5]]
"""Three TX points south of a second wall, where only the lone candidate sees them."""
LONE = {"position": [0.0, -12.0, 3.0], "orientation": [math.pi / 2, 0.0, 0.0], "name": "lone"}
SOUTH_WALL = {"kind": "wall", "start": [-8, -8], "end": [8, -8], "height_m": 10}


def test_blocked_tells_seeing_no_point_from_serving_no_pair() -> None:
    """A candidate that sees UE points (three TX points) but no pair – a RIS path needs both
    UEs in view – is not reported as seeing none; the counts per reason are in the message,
    the names of a few only, every candidate with its visible points in the details."""
    behind = [
        {"position": [x, 10.0, 3.0], "orientation": [-math.pi / 2, 0.0, 0.0]}
        for x in (-6.0, -4.0, -2.0, 0.0, 2.0, 4.0)
    ]
    doc = doc_of(
        tx_map={"points": SQUARE_POINTS + SOUTH_TX},
        rx_map={"points": SQUARE_POINTS},
        candidates=[ring(4, 6.0)[0], *behind, LONE],
        environment={"obstacles": [WALL, SOUTH_WALL]},
    )
    result = plan(doc)
    blocked = next(c for c in result.diagnosis["causes"] if c["kind"] == "blocked")
    entries = blocked["candidates"]
    assert [c["index"] for c in entries] == [1, 2, 3, 4, 5, 6, 7]
    assert [c["reason"] for c in entries] == ["no_visible_point"] * 6 + ["no_pair_with_both_ues"]
    lone = entries[-1]
    assert lone["name"] == "lone" and lone["visible_points"] == 3
    assert (lone["visible_tx_points"], lone["visible_rx_points"]) == (3, 0)
    assert lone["map_pair_fraction"] == 0.0  # it sees no RX point: no pair can have it
    assert (blocked["no_visible_point"], blocked["no_pair_with_both_ues"]) == (6, 1)
    # the visible points are the plan's own per-site rule (ris_serves) on the maps' points
    points = np.unique(np.concatenate([result.tx_map.points, result.rx_map.points]), axis=0)
    for c in entries:
        want = ris_serves(result.scene, result.sites[c["index"]].ris, points)
        assert c["visible_points"] == int(np.count_nonzero(want)), c
    message = blocked["message"]
    assert message.startswith("7 of 8 candidates serve no pair")
    assert "6 see no UE point (none of the 28 map points" in message
    assert "1 see UE points (3 of 28 each) but serve no pair" in message
    assert "a RIS path needs both UEs of a pair in view" in message
    # a few names, not all of them
    named = [f"{i} (candidate {i})" for i in range(1, 7)]
    assert all(n in message for n in named[:BLOCKED_EXAMPLES])
    assert not any(n in message for n in named[BLOCKED_EXAMPLES:]) and "7 (lone)" in message


# --- sizing ---------------------------------------------------------------------------------


SIZES = [[8, 8], [16, 16], [32, 32], [64, 64]]


def test_sizing_answer_is_the_smallest_reaching_size_times_count() -> None:
    doc = LINK | {
        "candidates": ring(5, 25.0),
        "ris_count": [2, 3],
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "sizing": {"ris_sizes": SIZES, "counts": [2, 3], "target": {"objective": 0.6}},
    }
    result = plan(doc)
    sizing = result.to_json()["sizing"]
    goal = sizing["goal"]["min"]
    assert goal == pytest.approx(0.6 * sizing["servable_weight"], rel=1e-12)
    # brute force: every size and count, each a plan of its own in this process
    brute: dict[tuple[int, int, int], float] = {}
    with SerialExecutor() as ex:
        for r, c in [row["ris_size"] for row in sizing["sizes"]]:  # the ladder and the own size
            sub = {k: v for k, v in doc.items() if k != "sizing"} | {"ris": {"rows": r, "cols": c}}
            for cr in run_enumerating(prepare_plan(sub), no_progress, ex).counts:
                brute[(r, c, cr.ris_count)] = -cr.ranked[0][1]
    rows = [
        SizeRow((r, c), n, None, v)
        for (r, c, n), v in brute.items()
        if v >= goal - 1e-12 and all(brute[(r, c, m)] < goal for m in (2, 3) if m < n)
    ]
    want = answer_row(rows)
    assert want is not None
    ans = sizing["answer"]
    assert (tuple(ans["ris_size"]), ans["count"]) == (want.ris_size, want.count)
    assert ans["objective"] == want.objective
    for row in sizing["sizes"]:  # every evaluated count is the brute-force one
        r, c = row["ris_size"]
        for tried in row["counts"]:
            assert tried["objective"] == brute[(r, c, tried["count"])]
            assert tried["reaches"] == (tried["objective"] >= goal - 1e-12)
        if row["note"] is not None and row["note"].startswith("skipped"):
            assert r * c * 2 >= ans["elements"]  # skipped sizes could not have won
    assert "RISs of" in sizing["message"] and "of the servable pairs" in sizing["message"]


def test_sizing_ties_go_to_fewer_rises() -> None:
    rows = [
        SizeRow((16, 16), 4, None, 0.9),
        SizeRow((32, 32), 1, None, 0.9),
        SizeRow((8, 8), None, None, note="not reached"),
    ]
    assert answer_row(rows) == rows[1]
    assert answer_row(rows[2:]) is None


def test_sizing_defaults_and_errors() -> None:
    doc = PlanDocument.model_validate(GOOD | {"sizing": {}})
    assert doc.sizing is not None
    assert doc.sizing.ris_sizes[0] == [10, 10] and doc.sizing.ris_sizes[-1] == [100, 100]
    assert doc.sizing_target().min == 0.9
    capped = GOOD | {"objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0}}
    with pytest.raises(ValueError, match=r"sizing\.target"):
        PlanDocument.model_validate(capped | {"sizing": {}})
    with pytest.raises(ValueError, match=r"sizing\.ris_sizes"):
        PlanDocument.model_validate(GOOD | {"sizing": {"ris_sizes": [[0, 4]]}})
    # the limits count every sizing run's search
    plain = estimate_plan(PlanDocument.model_validate(GOOD))
    sized = estimate_plan(doc)
    assert sized.search_layouts == plain.search_layouts * (1 + len(doc.sizing.ris_sizes))


# --- CLI and figures --------------------------------------------------------------------------


def _cli(tmp_path: Path, doc: dict[str, Any], *extra: str) -> tuple[int, str, str]:
    path = tmp_path / "doc.json"
    path.write_text(json.dumps(doc))
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["plan", str(path), "--out", str(tmp_path / "out"), "--workers", "1", *extra])
    return rc, out.getvalue(), err.getvalue()


def test_cli_warns_exits_zero_and_three_with_fail_on_useless(tmp_path: Path) -> None:
    rc, _, err = _cli(tmp_path, GEOMETRY)
    assert rc == 0
    assert "WARNING: this plan is USELESS" in err and "  - geometry:" in err
    plan_json = json.loads((tmp_path / "out" / "plan.json").read_text())
    assert plan_json["diagnosis"]["verdict"] == "useless"
    rc, _, _ = _cli(tmp_path, GEOMETRY, "--fail-on-useless")
    assert rc == 3
    assert (tmp_path / "out" / "plan.json").exists()
    rc, _, err = _cli(tmp_path, GOOD, "--fail-on-useless")
    assert rc == 0 and "WARNING" not in err


def test_cli_prints_rounded_objectives_and_answers_sizing(tmp_path: Path) -> None:
    doc = LINK | {"sizing": {"ris_sizes": SIZES, "counts": [3]}}
    rc, out, _ = _cli(tmp_path, doc, "--sizing")
    assert rc == 0
    plan_json = json.loads((tmp_path / "out" / "plan.json").read_text())
    full = plan_json["by_count"][0]["objective"]
    line = next(x for x in out.splitlines() if x.startswith("3 RIS:"))
    assert f"3 RIS: {full:.3g} = " in line  # rounded, with its share of the servable pairs
    assert "sizing: " in out and plan_json["sizing"]["message"] in out
    assert (tmp_path / "out" / "sizing.png").read_bytes()[:4] == b"\x89PNG"
    # --sizing without the option in the document: the default ladder
    rc, _, _ = _cli(tmp_path, GOOD, "--sizing")
    assert rc == 0
    sizes = json.loads((tmp_path / "out" / "plan.json").read_text())["sizing"]["sizes"]
    assert sizes[0]["ris_size"] == [10, 10]


def _colour_share(path: Path, rgb: tuple[float, float, float]) -> float:
    import matplotlib.image

    img = matplotlib.image.imread(path)[..., :3]
    return float(np.mean(np.all(np.abs(img - np.array(rgb)) < 0.02, axis=-1)))


def test_heatmap_shows_useless_plans_as_such(tmp_path: Path) -> None:
    from matplotlib.colors import to_rgb

    blind = to_rgb(BLIND_COLOUR)
    files = write_figures(plan(GEOMETRY), tmp_path / "geo")
    assert _colour_share(files["heatmap"], blind) > 0.05  # the square is blind
    files = write_figures(plan(GOOD), tmp_path / "good")
    assert _colour_share(files["heatmap"], blind) < 0.001


# --- REST -------------------------------------------------------------------------------------


def test_rest_plan_carries_sizing_and_diagnosis(tmp_path: Path) -> None:
    """The plan document passes ``sizing`` through POST /v1/plans unchanged: the job's result
    has the same ``sizing`` and ``diagnosis`` as run_plan here (another process: floats under
    the tolerance rule), ``sizing`` among the figures, the schema documents it, a bad sizing
    is a 422 naming its field."""
    from api_helpers import api_client, wait_for
    from tolerance import assert_close

    doc = LINK | {"sizing": {"ris_sizes": SIZES[:3], "counts": [3]}}
    with api_client(tmp_path, workers=1) as client:
        schema = client.get("/openapi.json").json()["components"]["schemas"]
        assert "sizing" in schema["PlanDocument"]["properties"]
        assert "ris_sizes" in schema["Sizing"]["properties"]
        bad = client.post("/v1/plans", json=GOOD | {"sizing": {"ris_sizes": [[600, 4]]}})
        assert bad.status_code == 422 and "sizing" in bad.json()["fields"][0]["field"]
        r = client.post("/v1/plans", json=doc)
        assert r.status_code == 202
        view = wait_for(client, r.json()["id"], ("succeeded", "failed"))
        assert view["status"] == "succeeded", view["error"]
        assert "sizing" in view["figures"]
    want = plan(doc).to_json()
    # bounds inverted from a Fisher information: a few hundred roundings, conditioning 1e6
    assert_close(view["result"]["sizing"], want["sizing"], ulps=256, cond=1e6)
    assert_close(view["result"]["diagnosis"], want["diagnosis"], ulps=256, cond=1e6)


@pytest.mark.parametrize(
    "objective",
    [
        {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        {"kind": "quantile", "metric": "rx", "q": 0.5, "target": {"max": 1.0}},
    ],
)
def test_link_budget_for_the_other_objectives(objective: dict[str, Any]) -> None:
    """mean_capped serves below its cap, quantile below its target: the same link budget cause,
    its suggested size re-scored against the same goal."""
    result = plan(LINK | {"objective": objective})
    d = result.diagnosis
    assert d["level_m"] == 1.0 and d["verdict"] == "useless"
    cause = d["causes"][0]
    assert cause["kind"] == "link_budget"
    n = cause["suggested_ris_size"][0]
    metric, w = rescore(result, tuple(d["sites"]), side=n)
    assert served_fraction(metric, w, 1.0) >= COVERAGE_FLOOR
    if "target" in objective:  # the target is part of the goal: the median ≤ 1 m
        assert cause["verified_objective"] <= 1.0


def test_spherical_suggestions_are_capped_by_pairs_times_elements() -> None:
    from types import SimpleNamespace

    from ris_planner.planning.outputs.diagnosis import SPHERICAL_PAIR_ELEMENTS, largest_side

    def fake(wavefront: str, pairs: int) -> Any:
        system = SimpleNamespace(wavefront=wavefront)
        return SimpleNamespace(
            document=SimpleNamespace(system=system), pairs=SimpleNamespace(size=pairs)
        )

    assert largest_side(fake("planar", 500_000)) == MAX_SIDE
    assert largest_side(fake("spherical", 100)) == MAX_SIDE
    side = largest_side(fake("spherical", 20_000))
    assert side**2 * 20_000 <= SPHERICAL_PAIR_ELEMENTS < (side + 1) ** 2 * 20_000
