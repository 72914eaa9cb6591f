"""Plan validation inputs (issue 23): diffuse scatterers and clusters that reach a UE are
refused at the document boundary (simulation documents on the command line, plan documents
in Python, on the command line and over REST), and the search region in lon/lat."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from api_helpers import api_client
from pydantic import ValidationError
from test_estimator_check import table1_plan
from tolerance import assert_close

from ris_planner import preset_document
from ris_planner.core.errors import DocumentFieldError
from ris_planner.estimation.document import load_simulation
from ris_planner.model.simulation import (
    MIN_SCATTERER_DISTANCE_M,
    Multipath,
    scatterer_distances,
    scatterer_too_close,
)
from ris_planner.planning.plan import validate_document

ROOT = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-m", "ris_planner.cli"]
TX = [-2.0, -4.0, 0.0]
"""Table I's TX (its RX is [2, 3, 0])."""


def sim_doc(multipath: dict[str, Any]) -> dict[str, Any]:
    return {"scenario": preset_document("paper-table1"), "multipath": multipath}


def test_cluster_disk_distance_is_to_its_nearest_point() -> None:
    """The distance of a point to a cluster is to the nearest point of its disk."""
    mp = Multipath.model_validate(
        {
            "clusters": [{"center": [0, 0, 1], "radius_m": 2}],
            "scatterers": [{"position": [0, 0, 5]}],
        }
    )
    pts = np.array([[3.0, 4.0, 1.0], [1.0, 0.0, 1.0], [6.0, 8.0, 4.0]])
    (_, fixed), (_, disk) = scatterer_distances(mp, pts)
    assert_close(disk, [3.0, 0.0, np.hypot(8.0, 3.0)], atol=1e-15)  # 5 − 2; inside; 10 − 2, 3
    assert_close(fixed, [np.sqrt(41), np.sqrt(17), np.sqrt(101)])
    assert scatterer_too_close(mp, pts[:1]) is None
    assert scatterer_too_close(mp, pts) == ("clusters.0", 1, 0.0)


@pytest.mark.parametrize(
    ("multipath", "message"),
    [
        # the TX 0.2 m outside the disk's rim: an SP may land 0.2 m from it (accepted before)
        ({"clusters": [{"center": [-2, -5.2, 0], "radius_m": 1}]}, "clusters.0: the disk"),
        # a degenerate cluster (radius 0) on the RX: every SP at the RX
        (
            {"clusters": [{"center": [0, 0, 9]}, {"center": [2, 3, 0], "radius_m": 0}]},
            "clusters.1: the disk of SPs (centre [2.0, 3.0, 0.0], radius 0.0 m) contains the rx",
        ),
        ({"scatterers": [{"position": [-2, -4, 0.3]}]}, "scatterers.0: the SP at"),
    ],
)
def test_simulation_refuses_scatterers_that_reach_a_ue(
    multipath: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValidationError) as exc:
        load_simulation(sim_doc(multipath))
    assert message in str(exc.value)
    assert f"≥ {MIN_SCATTERER_DISTANCE_M:g} m" in str(exc.value)


def test_simulation_accepts_a_cluster_beyond_the_distance() -> None:
    doc = load_simulation(sim_doc({"clusters": [{"center": [-2, -5.6, 0], "radius_m": 1}]}))
    assert len(doc.multipath.clusters) == 1  # 0.6 m from the TX


def test_cli_simulate_refuses_a_cluster_on_the_tx_with_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "sim.json"
    path.write_text(json.dumps(sim_doc({"clusters": [{"center": TX, "radius_m": 0.5}]})))
    out = subprocess.run(
        [*CLI, "simulate", str(path), "--runs", "1"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert out.returncode == 2, out.stderr[-2000:]
    assert "multipath.clusters.0" in out.stderr and "contains the tx" in out.stderr
    assert "Traceback" not in out.stderr


def bad_cluster_plan() -> dict[str, Any]:
    """Table I as a plan whose validation cluster (radius 1 m at the TX's height) holds the
    TX map's point."""
    return table1_plan({"multipath": {"clusters": [{"center": [-2, -4.5, 0], "radius_m": 1}]}})


def test_plan_refuses_a_validation_cluster_over_a_map_point() -> None:
    with pytest.raises(DocumentFieldError) as exc:
        validate_document(bad_cluster_plan())
    assert exc.value.field == "validation.multipath.clusters.0"
    assert "tx_map point 0 [-2.0, -4.0, 0.0]" in str(exc.value)
    # 3 m up, as the paper's clusters: accepted
    ok = table1_plan({"multipath": {"clusters": [{"center": [-2, -4.5, 3], "radius_m": 1}]}})
    assert validate_document(ok).validation is not None


def test_plan_refuses_a_cluster_over_an_rx_map_point_on_the_cli(tmp_path: Path) -> None:
    doc = table1_plan({"multipath": {"scatterers": [{"position": [2, 3, 0.1]}]}})
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(doc))
    out = subprocess.run(
        [*CLI, "plan", str(path), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert out.returncode == 2, out.stderr[-2000:]
    assert "validation.multipath.scatterers.0" in out.stderr and "rx_map point 0" in out.stderr
    assert "Traceback" not in out.stderr


def test_rest_refuses_a_validation_cluster_over_a_map_point(tmp_path: Path) -> None:
    with api_client(tmp_path) as client:
        r = client.post("/v1/plans", json=bad_cluster_plan())
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["fields"][0]["field"] == "validation.multipath.clusters.0"
    assert "tx_map point 0" in r.text and "Traceback" not in r.text
