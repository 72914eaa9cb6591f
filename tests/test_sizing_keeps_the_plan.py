"""``--sizing`` keeps the plan (docs/concepts/planning.md, "Search methods"): a plan the
enumerating search answers keeps its search, layouts, diagnosis, verdict, exit status and
files when the sizing question is asked beside it; where the sizing needs the district search,
the plan says so in one line and still writes the same files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from district_site import street_doc
from waits import HANG_S

ROOT = Path(__file__).resolve().parents[1]
FILES = ("plan.json", "topview.png", "heatmap.png", "cdf.png", "sizing.png", "plan.geojson")


def _plan(tmp_path: Path, doc: dict, *flags: str) -> tuple[subprocess.CompletedProcess[str], dict]:
    tmp_path.mkdir(parents=True, exist_ok=True)
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc))
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, "-m", "ris_planner.cli", "plan", str(f), "--out", str(out), *flags],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    plan = json.loads((out / "plan.json").read_text()) if (out / "plan.json").exists() else {}
    return run, plan


def test_a_useless_real_site_stays_useless_with_sizing(tmp_path: Path) -> None:
    """The Helsinki example with 10 × 10 RISs: the same layouts, the USELESS verdict and exit
    status 3 under ``--fail-on-useless`` with and without ``--sizing``; every file written."""
    sys.path.insert(0, str(ROOT / "examples"))
    from plan_helsinki import helsinki_document

    doc = helsinki_document(300)[0] | {"ris": {"rows": 10, "cols": 10}, "ris_count": [2, 3]}
    plain, plain_plan = _plan(tmp_path / "plain", doc, "--fail-on-useless")
    sized, sized_plan = _plan(
        tmp_path / "sized", doc | {"sizing": {"ris_sizes": [[16, 16]]}}, "--fail-on-useless"
    )
    for run in (plain, sized):
        assert run.returncode == 3, run.stderr[-2000:]
        assert "WARNING: this plan is USELESS" in run.stderr
    assert sized_plan["search_method"] == plain_plan["search_method"]
    assert sized_plan["search_method"]["used"] == "auto"
    assert [e["sites"] for e in sized_plan["by_count"]] == [
        e["sites"] for e in plain_plan["by_count"]
    ]
    assert sized_plan["diagnosis"]["verdict"] == plain_plan["diagnosis"]["verdict"] == "useless"
    assert sized_plan["sizing"]["search_method"]["used"] == "auto"
    for name in (*FILES, "heatmap.tif", "points.csv"):
        assert (tmp_path / "sized" / "out" / name).exists(), name
    assert not any(
        line.startswith(("search:", "sizing search:")) for line in sized.stderr.splitlines()
    )


def test_a_sizing_the_enumerating_runs_cannot_take_says_so_and_keeps_the_plan(
    tmp_path: Path,
) -> None:
    """The enumerating sizing runs would exceed the search limit: the plan keeps its own
    exhaustive search and layouts, the sizing takes the district search, one line says why."""
    doc = street_doc(method="auto", counts=(2,))
    doc["search"] = {"method": "auto", "restarts": 1000, "max_rounds": 10000, "max_exhaustive": 100}
    doc["sizing"] = {"ris_sizes": [[16, 16], [48, 48]], "counts": [3, 4, 5, 6]}
    run, plan = _plan(tmp_path, doc)
    assert run.returncode == 0, run.stderr[-2000:]
    assert plan["search_method"]["used"] == "auto"
    assert plan["sizing"]["search_method"]["used"] == "district"
    assert "the plan keeps its own search" in plan["sizing"]["search_method"]["why"]
    line = next(x for x in run.stderr.splitlines() if x.startswith("sizing search:"))
    assert "district" in line and "search limit" in line
    for name in FILES:
        assert (tmp_path / "out" / name).exists(), name
