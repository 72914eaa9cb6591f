"""A city as independent districts (docs/concepts/district.md, "A city"): the split keeps
every UE point in exactly one district with its candidates nearby, and the districts planned
on a Dask LocalCluster (2 worker processes on 127.0.0.1) equal the same plan in this process."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from dask_cluster import local_cluster
from district_site import street_doc
from waits import HANG_S

from ris_planner.model.plan import PlanDocument
from ris_planner.planning.city import plan_city, split_city
from ris_planner.planning.inputs.ue_maps import build_map
from ris_planner.runtime.executor import DaskExecutor, SerialExecutor

CELL_M = 40.0


def test_split_puts_each_point_in_one_district_with_its_candidates() -> None:
    doc = street_doc(counts=(2,), sample=400)
    parts = split_city(doc, CELL_M)
    assert len(parts) >= 2
    m = build_map(PlanDocument.model_validate(doc).tx_map, "tx")
    seen = np.concatenate([np.asarray(p["tx_map"]["points"]) for p in parts])
    # a point lies in at most one cell; the cells without candidates or RX points drop theirs
    assert len(seen) <= len(m.points)
    have = Counter(tuple(p) for p in m.points.tolist())
    for point, n in Counter(tuple(p) for p in seen.tolist()).items():
        assert n <= have[point]  # never the same map point in two districts
    assert abs(sum(p["weight"] for p in parts) - len(seen) / len(m.points)) < 1e-9
    for p in parts:
        assert p["search"] == {"method": "district"} and p["candidates"]
        assert p["pairs"]["sample"] >= 50


def test_city_on_a_dask_cluster_equals_the_serial_plan() -> None:
    distributed = pytest.importorskip("distributed")
    parts = split_city(street_doc(counts=(2,), sample=300), CELL_M)
    here = plan_city(parts, SerialExecutor())
    with local_cluster() as cluster, DaskExecutor(distributed.Client(cluster)) as ex:
        there = plan_city(parts, ex)
        ex.client.close()
    assert [d["district"] for d in here["districts"]] == [d["district"] for d in there["districts"]]
    for a, b in zip(here["districts"], there["districts"], strict=True):
        for ra, rb in zip(a["by_count"], b["by_count"], strict=True):
            # other processes: coverage within one pair's weight (a bound at the threshold)
            assert abs(ra["objective"] - rb["objective"]) <= 1 / a["pairs_summary"]["pairs"]
    assert here["by_count"] and here["by_count"][0]["ris_total"] == 2 * len(parts)
    row = here["by_count"][0]
    assert 0 <= row["coverage"] <= row["upper_bound"] + 1e-12


def test_city_command_writes_the_city_plan(tmp_path) -> None:
    """``ris-planner city FILE --cell-m M`` as a user runs it (one worker process)."""
    import json
    import subprocess
    import sys

    f = tmp_path / "city.json"
    f.write_text(json.dumps(street_doc(counts=(2,), sample=200)))
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "ris_planner.cli",
            "city",
            str(f),
            "--cell-m",
            "40",
            "--out",
            str(tmp_path / "out"),
            "--workers",
            "1",
        ],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    plan = json.loads((tmp_path / "out" / "plan.json").read_text())
    assert plan["method"] == "city" and len(plan["districts"]) >= 2
    assert "RIS per district" in run.stdout
