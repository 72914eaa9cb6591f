"""What a larger RIS brings within the level (docs/concepts/scoring.md, "One denominator"):
the shipped Helsinki example (``examples/plan_helsinki.py``'s document: OSM blocks of central
Helsinki, © OpenStreetMap contributors, ODbL 1.0; 1000 sampled street pairs, coverage of
PEB_R ≤ 2 m) planned by the district search with a sizing ladder of 10 × 10, 32 × 32 and
64 × 64 RISs; prints the servable pairs (the denominator, the same at every size) and, per
size, the share of them that every candidate together brings within the level.

    python benchmarks/district/coverable_by_size.py [--pairs 1000] [--quick]

``--quick``: 200 pairs (a check that the script runs).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SIZES = [[10, 10], [32, 32], [64, 64]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1000, help="sampled street pairs (1000)")
    ap.add_argument("--quick", action="store_true", help="200 pairs")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "examples"))
    from plan_helsinki import helsinki_document

    from ris_planner.io.geoplan import plan_document

    doc, _ = helsinki_document(200 if args.quick else args.pairs)
    doc["ris"] = {**doc["ris"], "rows": SIZES[0][0], "cols": SIZES[0][1]}
    doc["search"] = {"method": "district"}
    doc["sizing"] = {"ris_sizes": SIZES, "target": {"objective": 0.5}}
    t0 = time.perf_counter()
    plan = plan_document(doc, Path(tempfile.mkdtemp(prefix="coverable-"))).plan
    summary = plan["pairs_summary"]
    print(f"# Coverable share by RIS size ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())})")
    print(
        f"{summary['pairs']} pairs; servable weight {summary['servable_weight']:.3f}"
        f" ({summary['blind_everywhere']['pairs']} blind everywhere);"
        f" {time.perf_counter() - t0:.1f} s"
    )
    print("| RIS size | coverable share of the servable pairs |")
    print("|---|---|")
    for row in plan["sizing"]["sizes"]:
        rows, cols = row["ris_size"]
        print(f"| {rows} × {cols} | {100 * row['coverable_share']:.1f} % |")


if __name__ == "__main__":
    main()
