"""Sidelink pairs (docs/concepts/planning.md, "Pairs"): the separation along the streets
against hand-computed ways, the draw's support and frequencies against a brute-force
enumeration, and line-of-sight pairs against the visibility engine."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from district_site import street_doc
from pydantic import ValidationError
from tolerance import assert_close

from ris_planner.bounds.paths import los_clear
from ris_planner.core.errors import RisPlannerError
from ris_planner.environment import Scene
from ris_planner.model.plan import PairSample, PlanDocument
from ris_planner.planning.inputs.separation import near_combinations, street_distance
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.prepare import prepare_plan


def _map(roads: list[dict]) -> object:
    return build_map(
        PlanDocument.model_validate(street_doc()).tx_map.model_copy(
            update={
                "roads": [
                    PlanDocument.model_validate(street_doc()).tx_map.roads[0].model_copy(update=r)
                    for r in roads
                ]
            }
        ),
        "map",
    )


def test_street_distance_follows_the_roads_round_a_corner() -> None:
    """An L of two roads meeting at (20, 0) and a road that does not touch them: the way
    between two UEs on different legs is |o_a| + (along to the corner) + (along from it) +
    |o_b|, on one leg the straight distance, to the detached road none."""
    pm = _map(
        [
            {"points": [[0, 0], [20, 0]], "width_m": 4, "step_m": 2},
            {"points": [[20, 0], [20, 30]], "width_m": 4, "step_m": 2},
            {"points": [[60, 0], [60, 30]], "width_m": 4, "step_m": 2},
        ]
    )
    pts, st = pm.points, pm.street
    assert st is not None
    n = len(pts)
    it, ir = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    got = street_distance(st, st, it, ir, 1e9).reshape(n, n)
    x, y = pts[:, 0], pts[:, 1]
    # which road piece each point was sampled on (its segment's start)
    leg = np.where(st[:, 0] == 60, 2, np.where(st[:, 0] == 20, 1, 0))
    want = np.full((n, n), np.inf)
    for i, j in itertools.product(range(n), range(n)):
        a, b = leg[i], leg[j]
        if a == 2 or b == 2:
            if a == b:
                want[i, j] = np.hypot(x[i] - x[j], y[i] - y[j])
            continue
        if a == b:
            want[i, j] = np.hypot(x[i] - x[j], y[i] - y[j])
            continue
        # to the corner along each leg's centre line, plus the lateral offsets
        along = {0: 20 - (x[i] if a == 0 else x[j]), 1: (y[i] if a == 1 else y[j])}
        lat = {0: abs(y[i] if a == 0 else y[j]), 1: abs(20 - (x[i] if a == 1 else x[j]))}
        want[i, j] = along[0] + along[1] + lat[0] + lat[1]
    assert np.array_equal(np.isinf(got), np.isinf(want))
    fin = np.isfinite(want)
    assert_close(got[fin], want[fin])
    # never below the straight distance: every street separation is a real way
    straight = np.hypot(x[:, None] - x[None], y[:, None] - y[None])
    assert np.all(got[fin] >= straight[fin] - 1e-9)


def test_near_pairs_are_the_combinations_within_the_separation() -> None:
    """Support: exactly the combinations of distinct positions within 12 m (brute force);
    frequencies ∝ w_i · w_j within five standard deviations."""
    doc = street_doc()
    doc["tx_map"] = {
        "points": [[0, 0, 1.5], [5, 0, 1.5], [11, 0, 1.5], [30, 0, 1.5]],
        "weights": [1, 2, 3, 4],
    }
    doc["rx_map"] = doc["tx_map"]
    d = PlanDocument.model_validate(doc)
    m = build_map(d.tx_map, "m")
    spec = PairSample(sample=60_000, seed=5, max_separation_m=12.0)
    pairs = build_pairs(m, m, spec, 10**6)
    dist = np.linalg.norm(m.points[:, None] - m.points[None], axis=-1)
    allowed = (dist <= 12) & (dist > 0)
    w = m.weights[:, None] * m.weights[None] * allowed
    p = w / w.sum()
    counts = np.zeros_like(p)
    np.add.at(counts, (pairs.tx_index, pairs.rx_index), 1)
    assert np.array_equal(counts > 0, allowed)
    sigma = np.sqrt(spec.sample * p * (1 - p))
    assert np.all(np.abs(counts - spec.sample * p) <= 5 * sigma + 1e-9)


def test_line_of_sight_pairs_have_a_clear_leg_and_cover_every_clear_combination() -> None:
    d = street_doc(sample=4000)
    d["pairs"] = {"sample": 4000, "seed": 2, "max_separation_m": 45, "line_of_sight": True}
    inp = prepare_plan(d)
    assert np.all(los_clear(inp.scene, inp.pairs.tx, inp.pairs.rx))
    # the same combinations without the condition: some are blocked (the buildings' corner)
    it, ir = near_combinations(
        inp.tx_map.points, inp.rx_map.points, None, None, PairSample(sample=1, max_separation_m=45)
    )
    clear = los_clear(inp.scene, inp.tx_map.points[it], inp.rx_map.points[ir])
    assert not np.all(clear)
    drawn = set(zip(inp.pairs.tx_index.tolist(), inp.pairs.rx_index.tolist(), strict=True))
    assert drawn <= set(zip(it[clear].tolist(), ir[clear].tolist(), strict=True))


def test_street_pairs_stay_within_the_separation_along_the_streets() -> None:
    inp = prepare_plan(street_doc(sample=2000, separation_m=25))
    st = inp.tx_map.street
    assert st is not None
    d = street_distance(st, st, inp.pairs.tx_index, inp.pairs.rx_index, 25.0)
    assert np.all(d <= 25.0)
    assert np.all(np.linalg.norm(inp.pairs.tx - inp.pairs.rx, axis=1) > 0)


def test_separation_errors_say_what_to_change() -> None:
    doc = street_doc()
    doc["pairs"] = {"sample": 10, "separation": "street"}
    with pytest.raises(ValidationError, match="needs max_separation_m"):
        PlanDocument.model_validate(doc)
    doc["pairs"] = {"sample": 10, "max_separation_m": 0.001}
    with pytest.raises(RisPlannerError, match="raise max_separation_m"):
        prepare_plan(doc)
    # a leg that no pair has clear
    doc = street_doc()
    doc["tx_map"] = {"points": [[30, 10, 1.5]]}
    doc["rx_map"] = {"points": [[30, -10, 1.5]]}
    doc["environment"]["obstacles"].append(
        {"kind": "wall", "start": [25, 2], "end": [35, 2], "base_m": 0, "height_m": 50}
    )
    doc["pairs"] = {"sample": 10, "max_separation_m": 50, "line_of_sight": True}
    with pytest.raises(RisPlannerError, match="line of sight"):
        prepare_plan(doc)


def test_plain_sample_is_unchanged_without_a_separation() -> None:
    """No separation, no line of sight: the independent draw of before (the same pairs)."""
    d = PlanDocument.model_validate(street_doc())
    m = build_map(d.tx_map, "m")
    a = build_pairs(m, m, PairSample(sample=50, seed=1), 10**6)
    b = build_pairs(
        m,
        m,
        PairSample(sample=50, seed=1, line_of_sight=False),
        10**6,
        scene=Scene.from_environment(None),
    )
    assert np.array_equal(a.tx_index, b.tx_index) and np.array_equal(a.rx_index, b.rx_index)
