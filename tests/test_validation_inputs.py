"""Plan validation inputs: diffuse scatterers and clusters that reach a UE are
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
from waits import HANG_S

from ris_planner import preset_document
from ris_planner.core.errors import DocumentFieldError
from ris_planner.estimation.document import load_simulation
from ris_planner.model.simulation import (
    MIN_SCATTERER_DISTANCE_M,
    Multipath,
    scatterer_distances,
    scatterer_too_close,
)
from ris_planner.planning.prepare import validate_document

ROOT = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-m", "ris_planner.cli"]


def cli_plan(path: Path, out: Path) -> subprocess.CompletedProcess[str]:
    """``ris-planner plan PATH --out OUT`` as a process (its status and streams)."""
    cmd = [*CLI, "plan", str(path), "--out", str(out)]
    return subprocess.run(
        cmd, capture_output=True, text=True, timeout=HANG_S, cwd=ROOT, check=False
    )


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
        timeout=HANG_S,
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
    out = cli_plan(path, tmp_path / "out")
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


# --- search_region in lon/lat ------------------------------------------------------------------

ORIGIN = [24.94, 60.17, 10.0]
"""A frame origin (Helsinki, 10 m above the ellipsoid)."""
REGION = {"min_m": [-3.5, -5.0, -0.4], "max_m": [-1.2, -2.8, 0.6]}
"""test_estimator_check's prior box around Table I's TX."""


def framed_plan(region: dict[str, Any] | None) -> dict[str, Any]:
    """Table I as a plan with a frame: every point in [lon, lat, h], the search region as
    given (``None``: none)."""
    from ris_planner.io.frames import Frame

    frame = Frame(tuple(ORIGIN))  # type: ignore[arg-type]
    doc = table1_plan({"draws": 1})

    def geo(p: list[float]) -> list[float]:
        return [float(v) for v in frame.to_geographic(np.array([p], dtype=float))[0]]

    for c in doc["candidates"]:
        c["position"] = geo(c["position"])
    for m in ("tx_map", "rx_map"):
        doc[m] = {"points": [geo(p) for p in doc[m]["points"]]}
    doc["validation"].pop("search_region")
    if region is not None:
        doc["validation"]["search_region"] = region
    return {"frame": {"origin": ORIGIN}, **doc}


def lonlat_region() -> dict[str, Any]:
    """REGION's corners in [lon, lat, h] (h = z + the origin's height)."""
    from ris_planner.io.frames import Frame

    frame = Frame(tuple(ORIGIN))  # type: ignore[arg-type]
    lo = frame.to_geographic(np.array([REGION["min_m"]], dtype=float))[0]
    hi = frame.to_geographic(np.array([REGION["max_m"]], dtype=float))[0]
    return {"min_lonlat": [float(v) for v in lo], "max_lonlat": [float(v) for v in hi]}


def test_lonlat_search_region_is_converted_through_the_frame() -> None:
    """The lon/lat box's local box: REGION again up to the parallels' curvature in the local
    frame (a parallel through a corner x from the meridian of the origin bends by
    ≈ x²·tan φ/(2R) ≈ 1.6 µm at x = 3.5 m), z = h − h_origin."""
    from ris_planner.io.frames import to_local

    local, frame = to_local(framed_plan(lonlat_region()))
    assert frame is not None
    region = local["validation"]["search_region"]
    assert set(region) == {"min_m", "max_m"}
    assert_close(region["min_m"], REGION["min_m"], ulps=0, atol=1e-5)
    assert_close(region["max_m"], REGION["max_m"], ulps=0, atol=1e-5)
    doc = validate_document(local)
    assert doc.validation is not None and doc.validation.search_region is not None


@pytest.mark.parametrize(
    ("change", "field", "message"),
    [
        (lambda r: r | {"min_m": [0, 0, 0]}, SEARCH := "validation.search_region", "not both"),
        (lambda r: {"min_lonlat": r["min_lonlat"]}, SEARCH, "give both"),
        (  # the corners swapped: south-west ↔ north-east
            lambda r: {"min_lonlat": r["max_lonlat"], "max_lonlat": r["min_lonlat"]},
            SEARCH,
            "the box is empty: max_lonlat lon",
        ),
        (  # written [lat, lon, h]
            lambda r: r | {"min_lonlat": [r["min_lonlat"][1], r["min_lonlat"][0], 10.0]},
            f"{SEARCH}.min_lonlat",
            "lat/lon swapped?",
        ),
        (lambda r: r | {"max_lonlat": [24.9, 60.1]}, f"{SEARCH}.max_lonlat", "expected 3 numbers"),
    ],
)
def test_bad_lonlat_search_regions_name_the_field(change: Any, field: str, message: str) -> None:
    from ris_planner.io.frames import to_local

    with pytest.raises(DocumentFieldError) as exc:
        to_local(framed_plan(change(lonlat_region())))
    assert exc.value.field == field and message in str(exc.value)


def test_lonlat_search_region_without_a_frame_is_refused() -> None:
    doc = table1_plan({"search_region": lonlat_region()})
    with pytest.raises(ValidationError, match="this document has none: add"):
        validate_document(doc)


def test_rest_refuses_bad_lonlat_search_regions_with_422(tmp_path: Path) -> None:
    region = lonlat_region()
    swapped = {"min_lonlat": region["max_lonlat"], "max_lonlat": region["min_lonlat"]}
    with api_client(tmp_path) as client:
        no_frame = client.post("/v1/plans", json=table1_plan({"search_region": region}))
        empty = client.post("/v1/plans", json=framed_plan(swapped))
    assert no_frame.status_code == 422, no_frame.text
    assert "search_region" in no_frame.json()["fields"][0]["field"]
    assert "frame" in no_frame.text and "Traceback" not in no_frame.text
    assert empty.status_code == 422, empty.text
    assert empty.json()["fields"][0]["field"] == "validation.search_region"
    assert "corners swapped?" in empty.text


def test_cli_refuses_a_swapped_lonlat_corner_with_exit_2(tmp_path: Path) -> None:
    region = lonlat_region()
    region["max_lonlat"] = [region["max_lonlat"][1], region["max_lonlat"][0], 10.0]
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(framed_plan(region)))
    out = cli_plan(path, tmp_path / "out")
    assert out.returncode == 2, out.stderr[-2000:]
    assert "validation.search_region.max_lonlat" in out.stderr and "swapped?" in out.stderr


def test_plan_json_echoes_the_region_in_metres_and_lonlat(tmp_path: Path) -> None:
    """A framed plan validated with a lon/lat region: plan.json's validation.search_region
    gives the box in local metres and in [lon, lat, h], and the corners as given."""
    from ris_planner.io.geoplan import plan_document
    from ris_planner.planning import SerialExecutor

    region = lonlat_region()
    done = plan_document(framed_plan(region), tmp_path, executor=SerialExecutor())
    got = done.plan["validation"]["search_region"]
    assert got["source"] == "search_region" and got["given"] == region
    assert_close(got["min_m"], REGION["min_m"], ulps=0, atol=1e-5)
    # the local min corner is the given south-west bottom corner (to the projection's round trip)
    assert_close(got["min_lonlat"], region["min_lonlat"], ulps=0, atol=1e-9)
    assert_close(got["max_lonlat"], region["max_lonlat"], ulps=0, atol=1e-9)
    assert done.plan["frame"]["origin"] == ORIGIN
