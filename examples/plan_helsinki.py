"""A real site end to end: OpenStreetMap buildings and streets of a few blocks of central
Helsinki (``examples/helsinki/``, © OpenStreetMap contributors, ODbL 1.0) → import → plan →
GeoJSON / GeoTIFF / CSV in WGS84.

1. ``helsinki.geojson`` → prisms (heights from ``building:levels`` × 3 m, else the 10 m
   default) and UE roads (residential streets, 6 m wide, sampled every 5 m at 1.5 m);
   ``sites.geojson`` (mounting points on the taller buildings' facades) → candidates.
2. The plan document carries ``"frame": {"origin": [lon, lat, 0]}``; ``to_local`` converts it
   to local metres once, the planner runs there (TX and RX on the streets, sampled pairs,
   UE heights known (street level), coverage Pr(PEB_R ≤ 2 m), 2–4 RISs of 64×64 elements –
   35 cm at 28 GHz: the streets are 100–200 m long, and smaller RISs leave most of them above
   10 m).
3. Results go back to WGS84: ``plan.geojson`` (sites, candidates, UE points with their bounds,
   buildings), ``heatmap.tif`` (georeferenced, nodata inside buildings), ``points.csv``, next
   to ``plan.json`` and the PNGs.

The plan document passes ``environment`` to the planner when the planner takes one (the
environment-aware planning, docs/concepts/planning.md); otherwise the buildings are exported only.

With ``--validate N`` each recommended layout is also checked by the two-stage estimator at N
pairs sampled from the streets (``--draws`` noise draws each; plan.json ``validation``,
``validation.png``, docs/validation/estimator.md).

    python examples/plan_helsinki.py --out out/helsinki [--pairs 1500] [--validate 10]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

from ris_planner.io.frames import to_local
from ris_planner.io.geojson_read import import_features
from ris_planner.io.gis_outputs import plan_outputs
from ris_planner.io.import_options import ImportOptions
from ris_planner.io.site_points import import_sites
from ris_planner.planning import PlanDocument, SerialExecutor, run_plan, write_figures
from ris_planner.planning.outputs.report import write_plan_json

DATA = Path(__file__).with_name("helsinki")
STREETS = ("residential",)


def helsinki_document(pairs: int = 1500) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the plan document of the example – WGS84 with a frame –, the imported environment),
    built from the committed data."""
    opts = ImportOptions(highways=STREETS)
    site = json.loads((DATA / "helsinki.geojson").read_text())
    fragment, _ = import_features(site, options=opts)
    origin = tuple(fragment["frame"]["origin"])
    sites, _ = import_sites(json.loads((DATA / "sites.geojson").read_text()), origin, opts)
    doc: dict[str, Any] = {
        "description": "Central Helsinki (OSM, © OpenStreetMap contributors, ODbL 1.0)",
        "frame": fragment["frame"],
        "system": {"tx_power_dbm": 30},
        "ris": {"rows": 64, "cols": 64},
        "candidates": sites["candidates"],
        "tx_map": fragment["ue_map"],
        "rx_map": fragment["ue_map"],
        "pairs": {"sample": pairs, "seed": 1},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 2.0},
        "known": ["height"],
        "ris_count": [2, 3, 4],
    }
    if "environment" in PlanDocument.model_fields:
        doc["environment"] = fragment["environment"]
    return doc, fragment["environment"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/helsinki"))
    ap.add_argument("--pairs", type=int, default=1500)
    ap.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, output in a temporary folder (seconds; tests/test_examples.py)",
    )
    ap.add_argument("--validate", type=int, default=0, help="estimator check at N pairs (0: off)")
    ap.add_argument("--draws", type=int, default=3, help="noise draws per validated pair")
    ap.add_argument(
        "--reflections", action="store_true", help="validate with the site's specular reflections"
    )
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.smoke:
        args.out, args.pairs = Path(tempfile.mkdtemp(prefix="ris-smoke-")), 100
    doc, environment = helsinki_document(args.pairs)
    if args.smoke:  # 2 RISs of 16×16 on 100 pairs
        doc |= {"ris": {"rows": 16, "cols": 16}, "ris_count": [2]}
    if args.validate:
        doc["validation"] = {
            "pairs": args.validate,
            "draws": args.draws,
            "reflections": args.reflections,
        }
    export_doc = {**doc, "environment": environment}  # buildings in the GIS files either way
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "helsinki_plan.json").write_text(json.dumps(doc, indent=1))
    local, frame = to_local(doc)
    with SerialExecutor() as ex:
        result = run_plan(local, executor=ex)
    plan = result.to_json()
    assert frame is not None
    plan["frame"] = {"origin": list(frame.origin), "local_crs": frame.proj4}
    write_plan_json(plan, args.out)
    files = {**write_figures(result, args.out), **plan_outputs(result, plan, export_doc, args.out)}
    elapsed = time.perf_counter() - t0
    n_env = len(environment["obstacles"])
    planned = "planned around" if "environment" in doc else "exported (planner is free-space)"
    print(
        f"{len(result.sites)} candidates, {len(result.rx_map.points)} street points,"
        f" {result.pairs.size} pairs, {n_env} buildings {planned}; {elapsed:.1f} s"
    )
    for entry in plan["by_count"]:
        median = entry["quantiles_m"]["0.5"]  # null: more than half of the pairs are blind
        print(
            f"{entry['ris_count']} RIS: sites {entry['sites']} coverage {entry['objective']:.3f}"
            f" median PEB_R {'inf (blind)' if median is None else f'{median:.3g} m'}"
        )
    if result.validation is not None:
        from ris_planner.planning.outputs.estimator_check import summary_lines

        print("\n".join(summary_lines(result.validation)))
    diagnosis = plan["diagnosis"]
    print(f"diagnosis: {diagnosis['verdict']}")
    for cause in diagnosis["causes"]:
        print(f"  - {cause['kind']}: {cause['message']}")
    for name, path in files.items():
        print(f"wrote {name}: {path}")


if __name__ == "__main__":
    main()
