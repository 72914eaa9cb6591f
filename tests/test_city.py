"""A city as one map (docs/concepts/district.md, "A city"): the city's pairs are the document's
own draw over the whole city, each owned by one cell and planned whole there, border pairs
included; the city's counts, coverage and certified bound are the cells' summed and weighted;
the city planned on a Dask LocalCluster (2 worker processes on 127.0.0.1) equals the city
planned on the process pool; ``ris-planner city`` on the committed Helsinki example writes one
plan.json, plan.geojson, heatmap.tif and points.csv for the whole city; ``POST /v1/cities``
answers the command line's plan.json."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from api_helpers import api_client, wait_for
from dask_cluster import local_cluster
from district_site import street_doc
from tolerance import BOUND_ACCURACY, assert_close
from waits import HANG_S

from ris_planner.core.errors import DocumentFieldError, RisPlannerError
from ris_planner.planning.city import allocate, plan_city, split_city
from ris_planner.planning.prepare import prepare_plan
from ris_planner.runtime.executor import DaskExecutor, LocalExecutor, SerialExecutor

ROOT = Path(__file__).resolve().parents[1]
CELL_M = 40.0


def city_doc(**over: Any) -> dict[str, Any]:
    """The street site of the district tests as a small city: four cells of 40 m, 400 pairs
    at most 30 m apart along the streets, city budgets of 4 and 6 RISs."""
    return street_doc(counts=(4, 6), sample=400) | over


def helsinki_city() -> dict[str, Any]:
    """The committed Helsinki example (examples/helsinki, OSM, © OpenStreetMap contributors,
    ODbL 1.0) with sidelink pairs along its streets, 32 × 32 RISs, the district search."""
    sys.path.insert(0, str(ROOT / "examples"))
    from plan_helsinki import helsinki_document

    doc, _ = helsinki_document(400)
    doc["pairs"] |= {"max_separation_m": 50, "separation": "street"}
    return doc | {"ris": {"rows": 32, "cols": 32}, "ris_count": [6, 8]}


def stable(plan: dict[str, Any]) -> dict[str, Any]:
    """A city's plan.json without what each run measures (times, memory)."""
    out = {k: v for k, v in plan.items() if k != "timing_s"}
    out["cells"] = [{k: v for k, v in c.items() if k != "resources"} for c in plan["cells"]]
    return out


def test_the_city_pairs_are_the_documents_own_draw_each_owned_by_one_cell() -> None:
    doc = city_doc()
    city = split_city(doc, CELL_M)
    drawn = prepare_plan(doc | {"search": {"method": "district"}}).pairs
    assert np.array_equal(city.pairs.tx_index, drawn.tx_index)  # one draw, the whole city's
    assert np.array_equal(city.pairs.rx_index, drawn.rx_index)
    assert sorted(np.concatenate([c.pairs for c in city.cells]).tolist()) == list(range(400))
    assert city.border.sum() > 0 and sum(c.border_pairs for c in city.cells) == city.border.sum()
    assert abs(sum(c.weight for c in city.cells) - 1) < 1e-12
    for n, cell in enumerate(city.cells):
        assert np.all(city.owner[cell.pairs] == n)
        mid = (city.pairs.tx[cell.pairs, :2] + city.pairs.rx[cell.pairs, :2]) / 2
        x0, y0, x1, y1 = cell.bounds
        assert np.all((mid >= [x0, y0]) & (mid < [x1, y1]))
        listed = cell.document["pairs"]
        tx = np.asarray(cell.document["tx_map"]["points"])[listed["tx_index"]]
        rx = np.asarray(cell.document["rx_map"]["points"])[listed["rx_index"]]
        # each owned pair whole in its cell's document, border pairs included
        assert np.array_equal(tx, city.pairs.tx[cell.pairs])
        assert np.array_equal(rx, city.pairs.rx[cell.pairs])
        pos = np.asarray([c["position"] for c in cell.document["candidates"]])
        h = city.halo_m
        assert np.all((pos[:, :2] >= [x0 - h, y0 - h]) & (pos[:, :2] <= [x1 + h, y1 + h]))


def test_a_budget_is_shared_by_pair_weight_at_least_one_each() -> None:
    assert allocate(10, [0.5, 0.3, 0.2], [9, 9, 9]) == [5, 3, 2]
    assert allocate(3, [0.9, 0.05, 0.05], [9, 9, 9]) == [1, 1, 1]
    assert allocate(10, [0.8, 0.1, 0.1], [2, 9, 9]) == [2, 4, 4]  # the cap moves the rest on
    with pytest.raises(DocumentFieldError, match="below its 3 cells"):
        allocate(2, [0.5, 0.3, 0.2], [9, 9, 9])
    with pytest.raises(DocumentFieldError, match="exceeds its 6 candidates"):
        allocate(7, [0.5, 0.3, 0.2], [2, 2, 2])


@pytest.mark.parametrize(
    ("over", "field"),
    [
        ({"pairs": {"sample": 100, "seed": 1}}, "pairs.max_separation_m"),
        ({"search": {"method": "exhaustive"}}, "search.method"),
        ({"constraints": {"require": [1]}}, "constraints.require"),
        ({"ris_count": [3]}, "ris_count"),  # below one RIS per cell
    ],
)
def test_what_a_city_cannot_plan_is_refused_before_work(over: dict[str, Any], field: str) -> None:
    with pytest.raises(DocumentFieldError) as err:
        split_city(city_doc(**over), CELL_M)
    assert err.value.field == field


def test_a_cell_size_must_be_positive() -> None:
    with pytest.raises(RisPlannerError, match="cell size"):
        split_city(city_doc(), 0.0)


def test_the_city_totals_are_the_cells_summed_and_weighted() -> None:
    city = split_city(city_doc(), CELL_M)
    plan = plan_city(city, SerialExecutor())
    weight = {c["id"]: c["weight"] for c in plan["cells"]}
    assert [r["ris_count"] for r in plan["by_count"]] == [4, 6]
    for row in plan["by_count"]:
        assert sum(row["ris_per_cell"].values()) == row["ris_count"]
        found = bound = 0.0
        for cell in plan["cells"]:
            entry = next(
                e for e in cell["by_count"] if e["ris_count"] == row["ris_per_cell"][cell["id"]]
            )
            found += weight[cell["id"]] * entry["objective"]
            bound += weight[cell["id"]] * entry["objective_bound"]
        assert_close(row["objective"], found)
        assert_close(row["certificate"]["objective_bound"], bound)
        assert row["objective"] <= row["certificate"]["objective_bound"]
        assert len(row["sites"]) + row["shared_sites"] == row["ris_count"]
    assert plan["city"]["border_pairs"] == int(city.border.sum()) > 0
    assert plan["pairs_summary"]["pairs"] == 400 == sum(c["pairs"] for c in plan["cells"])
    indices = [p["index"] for p in plan["points"]]
    assert indices == sorted(set(indices))  # every RX point once, at city-level indices
    for point in plan["points"]:
        assert set(point["bound_m"]) == {"4", "6"}


def test_sizing_sums_the_cells_certified_interval() -> None:
    doc = city_doc(sizing={"ris_sizes": [[32, 32]], "target": {"objective": 0.3}})
    plan = plan_city(split_city(doc, CELL_M), SerialExecutor())
    answer = plan["sizing"]["answer"]
    cells = [c["sizing"] for c in plan["cells"]]
    assert answer["count"] == sum(c["count"] for c in cells)
    assert answer["lower_bound"] == sum(c["lower_bound"] for c in cells) <= answer["count"]


def test_a_cell_out_of_reach_leaves_the_city_without_an_answer_but_names_it() -> None:
    """At 45 % two cells cannot reach the target with every candidate (their coverable shares
    are about 0.4): no city answer, the two named, the interval of the other two."""
    doc = city_doc(sizing={"ris_sizes": [[32, 32]], "target": {"objective": 0.45}})
    plan = plan_city(split_city(doc, CELL_M), SerialExecutor())
    sizing = plan["sizing"]
    cells = {c["id"]: c for c in plan["cells"]}
    assert sizing["answer"] is None and sizing["unreached_cells"]
    assert all(cells[c]["sizing"] is None for c in sizing["unreached_cells"])
    reaching = [c for c in cells.values() if c["sizing"] is not None]
    part = sizing["reaching"]
    assert part["count"] == sum(c["sizing"]["count"] for c in reaching)
    assert part["lower_bound"] == sum(c["sizing"]["lower_bound"] for c in reaching)
    assert_close(part["weight"], sum(c["weight"] for c in reaching))
    assert ", ".join(sizing["unreached_cells"]) in sizing["message"]


def test_the_city_on_a_dask_cluster_equals_the_process_pool() -> None:
    distributed = pytest.importorskip("distributed")
    city = split_city(city_doc(), CELL_M)
    with LocalExecutor(2) as pool:
        here = plan_city(city, pool)
    with local_cluster() as cluster, DaskExecutor(distributed.Client(cluster)) as ex:
        there = plan_city(city, ex)
        ex.client.close()
    # other processes: the plan figures to the bounds' accuracy, decisions exactly
    assert_close(stable(there), stable(here), accuracy=BOUND_ACCURACY)


def test_city_command_writes_one_plan_for_a_real_city(tmp_path: Path) -> None:
    """``ris-planner city FILE --cell-m 110`` as a user runs it (one worker process) on the
    committed Helsinki example: four cells, one plan.json and one set of GIS files."""
    f = tmp_path / "city.json"
    f.write_text(json.dumps(helsinki_city()))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ris_planner.cli", "city", str(f), "--cell-m", "110"]
    run = subprocess.run(
        [*cmd, "--out", str(out), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    plan = json.loads((out / "plan.json").read_text())
    assert plan["city"]["cells"] == 4 and plan["city"]["border_pairs"] > 0
    assert plan["frame"]["origin"]  # a geographic document: its GIS files in WGS84
    assert "RISs over 4 cells" in run.stdout
    geo = json.loads((out / "plan.geojson").read_text())
    sites = [f["properties"] for f in geo["features"] if f["properties"]["role"] == "site"]
    chosen = {(r["ris_count"], s) for r in plan["by_count"] for s in r["sites"]}
    assert {(s["ris_count"], s["candidate"]) for s in sites} == chosen
    n_cand = sum(f["properties"]["role"] == "candidate" for f in geo["features"])
    assert n_cand == len(plan["candidates"])
    assert (out / "heatmap.tif").read_bytes()[:4] == b"II*\x00"
    rows = (out / "points.csv").read_text().splitlines()
    assert len([r for r in rows if not r.startswith("#")]) == 1 + len(plan["points"])


def test_city_job_answers_the_command_lines_plan(tmp_path: Path) -> None:
    doc = city_doc()
    with api_client(tmp_path, workers=1, plan_workers=1) as client:
        r = client.post("/v1/cities", json={"document": doc, "cell_m": CELL_M})
        assert r.status_code == 202 and r.json()["kind"] == "city", r.text
        view = wait_for(client, r.json()["id"], ("succeeded", "failed"), timeout_s=300)
        assert view["status"] == "succeeded", view["error"]
        assert {"geojson", "geotiff", "points_csv"} <= set(view["figures"])
        bad = client.post("/v1/cities", json={"document": doc | {"ris_count": [3]}, "cell_m": 40})
        assert bad.status_code == 422 and bad.json()["fields"][0]["field"] == "ris_count"
        bad = client.post("/v1/cities", json={"document": doc, "cell_m": -1})
        assert bad.status_code == 422
        assert client.get("/v1/jobs").json()["total"] == 1
    expected = plan_city(split_city(doc, CELL_M), SerialExecutor())
    assert_close(stable(view["result"]), stable(expected), accuracy=BOUND_ACCURACY)
