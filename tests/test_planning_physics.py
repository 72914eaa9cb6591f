"""The plan's physical RIS element (ris_planner.model.plan_physics): the default pattern and field
of view when the document sets none, the document's values when it does, the paper presets
unchanged (isotropic, explicit), and plan.json's ``physics``."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from tolerance import assert_close

from ris_planner.bounds.compute import compute_bounds
from ris_planner.io.site_import import PLAN_DEFAULTS
from ris_planner.model.plan import PlanDocument, physics_json
from ris_planner.model.plan_physics import (
    ISOTROPIC_SOURCE,
    PLAN_MAX_ANGLE_DEG,
    PLAN_PATTERN_EXPONENT,
    PLAN_PHYSICS_SOURCE,
)
from ris_planner.model.scenario import RIS
from ris_planner.planning import SerialExecutor, plan_preset, run_plan
from ris_planner.planning.beams import layout_scenario, objective_on_pairs
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.scoring.scorer import objective_value, select_metric

BOUND_COND = 1e8
"""Scaled condition number of the Fisher informations of these layouts (the heatmap symmetry
test of test_planning meets ≤ ~1e8): two routes inverting them agree to 64 ulps × that."""

SITES = [
    {"position": [-4.0, 0.5, 2.0], "orientation": [0.0, 0.3, 0.0]},
    {"position": [0.5, 4.0, 2.5], "orientation": [-math.pi / 2, 0.3, 0.0]},
    {"position": [4.0, -0.5, 2.0], "orientation": [math.pi, 0.3, 0.0]},
]
GRID = {"grid": {"x": [-3, 3, 1.5], "y": [-3, 3, 1.5], "z": [0, 0, 1]}}


def doc(**over: Any) -> dict[str, Any]:
    base: dict[str, Any] = {
        "candidates": SITES,
        "tx_map": GRID,
        "rx_map": GRID,
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 2.0},
        "ris_count": [2],
    }
    return base | over


def test_default_constants_are_the_cited_pattern() -> None:
    # amplitude exponent of the cos^3 power pattern: (cos θ)^(2q) = cos^3 θ
    theta = np.linspace(0.0, 1.4, 8)
    np.testing.assert_allclose(np.cos(theta) ** (2 * PLAN_PATTERN_EXPONENT), np.cos(theta) ** 3)
    # field of view: one leg's power pattern 30 dB below boresight
    assert 10 * math.log10(math.cos(math.radians(PLAN_MAX_ANGLE_DEG)) ** 3) == pytest.approx(-30)
    assert pytest.approx(84.2608, abs=1e-4) == PLAN_MAX_ANGLE_DEG


def test_default_applies_when_unset_and_scores_with_it() -> None:
    d = PlanDocument.model_validate(doc())
    assert d.ris.model_fields_set == set()
    sites = expand_sites(d)
    assert {(s.ris.pattern_exponent, s.ris.max_angle_deg) for s in sites} == {
        (PLAN_PATTERN_EXPONENT, PLAN_MAX_ANGLE_DEG)
    }
    phys = physics_json(d)
    assert phys["from"] == "default" and phys["set_in_document"] == []
    assert phys["source"] == PLAN_PHYSICS_SOURCE and phys["wavefront"] == "planar"
    res = run_plan(doc(), executor=SerialExecutor())
    assert res.to_json()["physics"] == phys
    # independent route: a scenario whose RISs are built here with the cited values
    lay = res.counts[0].ranked[0][0]
    ris = [
        RIS(
            **SITES[s],
            pattern_exponent=1.5,
            max_angle_deg=math.degrees(math.acos(0.1)),
        )
        for s in lay
    ]
    scen = layout_scenario(d.system, ris, [], None)
    b = compute_bounds(scen, tx=res.pairs.tx, rx=res.pairs.rx)
    metric = select_metric("rx", b.peb_tx, b.peb_rx)
    want = float(objective_value(d.objective, metric[None], res.pairs.weights)[0])
    got = res.to_json()["by_count"][0]["objective"]
    assert_close(got, want, cond=BOUND_COND)
    # ... and the paper's isotropic element scores differently on these grazing-angle pairs
    iso = [RIS(**SITES[s]) for s in lay]
    b0 = compute_bounds(layout_scenario(d.system, iso, [], None), tx=res.pairs.tx, rx=res.pairs.rx)
    m0 = select_metric("rx", b0.peb_tx, b0.peb_rx)
    assert float(objective_value(d.objective, m0[None], res.pairs.weights)[0]) < want


@pytest.mark.parametrize(
    ("ris", "q", "angle", "source"),
    [
        ({"pattern_exponent": 0, "max_angle_deg": 90}, 0.0, 90.0, ISOTROPIC_SOURCE),
        ({"pattern_exponent": 1.5}, 1.5, PLAN_MAX_ANGLE_DEG, None),  # = default, still "set"
        ({"pattern_exponent": 2.0, "max_angle_deg": 60}, 2.0, 60.0, "document"),
    ],
)
def test_document_wins_when_set(
    ris: dict[str, Any], q: float, angle: float, source: str | None
) -> None:
    d = PlanDocument.model_validate(doc(ris=ris))
    assert {(s.ris.pattern_exponent, s.ris.max_angle_deg) for s in expand_sites(d)} == {(q, angle)}
    phys = physics_json(d)
    assert phys["from"] == "document" and phys["set_in_document"] == [
        f for f in ("pattern_exponent", "max_angle_deg") if f in ris
    ]
    assert (phys["pattern_exponent"], phys["max_angle_deg"]) == (q, angle)
    if source is not None:
        assert phys["source"] == source
    else:
        assert phys["source"].startswith("document (pattern_exponent)")


def test_import_starting_plan_writes_the_default() -> None:
    d = PlanDocument.model_validate(doc() | {k: PLAN_DEFAULTS[k] for k in ("ris",)})
    assert (d.ris.pattern_exponent, d.ris.max_angle_deg) == (
        PLAN_PATTERN_EXPONENT,
        PLAN_MAX_ANGLE_DEG,
    )


@pytest.mark.parametrize("name", ["fig10-anchors", "hall", "junction"])
def test_paper_presets_keep_the_isotropic_model(name: str) -> None:
    raw = plan_preset(name)
    d = PlanDocument.model_validate(raw)
    assert (d.ris.pattern_exponent, d.ris.max_angle_deg) == (0.0, 90.0)
    assert {"pattern_exponent", "max_angle_deg"} <= d.ris.model_fields_set
    assert "isotropic" in (d.description or "")
    assert physics_json(d)["source"] == ISOTROPIC_SOURCE


@pytest.mark.parametrize("name", ["hall", "junction"])
def test_preset_result_unchanged(name: str) -> None:
    """Before this default, a plan's RIS was the scenario's (q = 0, 90°): the preset's best
    layout scores the same as that layout built from scenario-default RISs, on an
    independent route (compute_bounds through the codebook evaluation)."""
    raw = plan_preset(name) | {"pairs": {"sample": 150, "seed": 3}, "ris_count": [2]}
    res = run_plan(raw, executor=SerialExecutor())
    d = res.document
    lay, _ = res.counts[0].ranked[0]
    old = [RIS(position=res.sites[s].ris.position, orientation=res.sites[s].ris.orientation,
               rows=d.ris.rows, cols=d.ris.cols) for s in lay]  # fmt: skip
    scen = layout_scenario(d.system, old, list(d.known), d.environment)
    mirror = d.pairs == "unordered" or len(res.metric_weights) == 2 * res.pairs.size
    want = objective_on_pairs(
        scen, res.pairs.tx, res.pairs.rx, res.pairs.weights, d.objective, mirror
    )
    assert_close(res.to_json()["by_count"][0]["objective"], want, cond=BOUND_COND)
    assert res.to_json()["physics"]["from"] == "document"
