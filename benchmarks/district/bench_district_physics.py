"""District plans with the physics their range needs (docs/concepts/district-physics.md): on
the benchmark district of ``bench_district.py`` (400 m × 400 m of central Helsinki, 2122
facade candidates, 20 000 sidelink pairs ≤ 50 m along the streets, 64×64 RISs, PEB_R ≤ 1 m),
the sizing answer and the coverage at 60 and 120 RISs

* with random phases (the expected FIM) and with DIR+DER beams designed per site (γ_P), each
  count's layout then given the appendix SDP's slot powers (``--beams``);
* planar and spherical (exact per element inside the Fraunhofer distance, with the site's
  designed profiles for DIR+DER);

each with its certified interval and the time of each part; then ``--validate`` on the
designed plan: the two-stage estimator against the bound per pair, with and without the site's
reflections.

    python benchmarks/district/bench_district_physics.py [--out DIR] [--pairs 20000]
        [--validate 200] [--quick]

``--quick``: the suite's small street site (14 candidates, 300 pairs, 32×32 RISs, 2 and 3
RISs, 5 validated pairs): a check that the script runs, not a measurement.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures
from bench_district import district, district_doc, peak_mib, plan_district
from fixtures import street_document

COUNTS = [60, 120]
"""The counts of the table (``--quick``: 2 and 3 on the suite's small street site)."""
SIDE = 64
"""RIS rows = columns (``--quick``: 32)."""

RUNS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("random phases", "planar", {"kind": "expected_random"}),
    ("DIR+DER, γ_P", "planar", {"kind": "directional_derivative"}),
    ("random phases", "spherical", {"kind": "expected_random"}),
    ("DIR+DER, γ_P", "spherical", {"kind": "directional_derivative"}),
)


def stage_text(plan: dict[str, Any]) -> str:
    """The stages that took time, ``cache 12.1 s, search 20.3 s, …``."""
    t = plan.get("timing_s") or {}
    keep = [(k, v) for k, v in t.items() if v >= 0.5]
    return ", ".join(f"{k} {v:.1f} s" for k, v in keep)


def sizing_text(plan: dict[str, Any]) -> str:
    ans = (plan.get("sizing") or {}).get("answer")
    if not ans:
        return "not reached"
    return f"[{ans['lower_bound']}, {ans['count']}]"


def run_table(work: Path, base: dict[str, Any], pairs: int, beams: bool) -> dict[str, Any]:
    rows = {}
    print(
        "\n| codebook | wavefront | RISs | coverage (of servable) | certified ≤ |"
        " sizing [certified, found] | time [s] | peak [MiB] |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, wavefront, codebook in RUNS:
        doc = district_doc(base, pairs, COUNTS, None, SIDE)
        doc["sizing"] = {"ris_sizes": [[SIDE, SIDE]], "target": {"objective": 0.9}}
        doc["codebook"] = codebook
        doc["system"] = {**doc.get("system", {}), "wavefront": wavefront}
        if beams and codebook["kind"] != "expected_random":
            doc["beams"] = {"design_positions": 64}
        tag = f"{codebook['kind']}-{wavefront}"
        plan = plan_district(work, doc, tag)
        rows[tag] = plan
        for e in plan["by_count"]:
            cert = e["certificate"]["objective_bound"]
            print(
                f"| {name} | {wavefront} | {e['ris_count']} | {e['objective']:.3f}"
                f" ({100 * (e['share_of_servable'] or 0):.1f} %) | {cert:.3f} |"
                f" {sizing_text(plan)} | {plan['wall_s']:.1f} | {peak_mib(plan)} |"
            )
        print(f"|  |  |  | stages: {stage_text(plan)} |  |  |  |  |")
        if "beams" in plan:
            for lay in plan["beams"]["layouts"]:
                sdp = lay["sdp"]
                per = [r.get("seconds", 0.0) for r in sdp["per_ris"]]
                parts = ", ".join(f"{k} {v:.1f} s" for k, v in lay["timing_s"].items())
                obj = lay["objective"]
                print(
                    f"|  | beams of {len(lay['sites'])} RISs | | γ_P {lay['gamma_p']:.2f}:"
                    f" {obj.get('dir_der_gamma_p')}, SDP per RIS"
                    f" {sdp['status_counts']}, {sdp['seconds']:.1f} s in all,"
                    f" ≤ {max(per, default=0.0):.2f} s per RIS: {obj.get('dir_der_sdp')}"
                    f" | | | | ({parts}) |"
                )
    return rows


def validation(work: Path, base: dict[str, Any], pairs: int, n: int) -> None:
    """``--validate`` of the designed plan at the first count, then the same check with the
    site's first-order reflections in the simulated signal: one plan (in this process), the
    plan's own estimator check (:func:`~ris_planner.planning.outputs.estimator_check.
    run_estimator_check`) run twice."""
    from dataclasses import replace

    from ris_planner.io.frames import to_local
    from ris_planner.planning.outputs.estimator_check import run_estimator_check
    from ris_planner.planning.pipeline import run_plan

    print(f"\n## The estimator on the designed plan: {n} pairs × 5 draws, {COUNTS[0]} RISs")
    print(
        "| reflections | estimator coverage | bound coverage | median RMSE/bound (covered) |"
        " outliers | time [s] |"
    )
    print("|---|---|---|---|---|---|")
    doc = district_doc(base, pairs, COUNTS[:1], None, SIDE)
    doc["codebook"] = {"kind": "directional_derivative"}
    doc["validation"] = {"pairs": n, "draws": 5, "reflections": False}
    t0 = time.perf_counter()
    result = run_plan(to_local(doc)[0])
    plan_s = time.perf_counter() - t0
    for reflections in (False, True):
        spec = result.document.validation
        assert spec is not None
        t0 = time.perf_counter()
        if reflections:
            spec = spec.model_copy(update={"reflections": True})
            body = run_estimator_check(
                replace(result, document=result.document.model_copy(update={"validation": spec}))
            )
            seconds = time.perf_counter() - t0
        else:
            body = result.validation
            seconds = result.timing.get("validation", float("nan"))
        assert body is not None
        (work / f"validation-reflections-{reflections}.json").write_text(json.dumps(body))
        lay = body["layouts"][0]
        ratios = [p["ratio"] for p in lay["pairs"] if p["bound_covered"] and p["ratio"]]
        med = statistics.median(ratios) if ratios else float("nan")
        outl = sum(lay["outliers"].values())
        causes = ", ".join(f"{k} {v}" for k, v in lay["outliers"].items() if v)
        print(
            f"| {reflections} | {lay['estimator_coverage']:.3f} | {lay['bound_coverage']:.3f} |"
            f" {med:.2f} | {outl} ({causes}) | {seconds:.1f} |"
        )
    print(f"(the plan with the first check: {plan_s:.1f} s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="work folder (default: a temporary one)")
    ap.add_argument("--pairs", type=int, default=20000, help="sidelink pairs (20 000)")
    ap.add_argument("--validate", type=int, default=200, help="pairs the estimator checks")
    ap.add_argument("--no-beams", action="store_true", help="skip the SDP on the layouts")
    ap.add_argument("--quick", action="store_true", help="the small street site (a smoke run)")
    args = ap.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="district-physics-"))
    work.mkdir(parents=True, exist_ok=True)
    if args.quick:
        global COUNTS, SIDE
        COUNTS, SIDE = [2, 3], 32
        args.pairs, args.validate = 300, 5
        base = street_document(counts=(2, 3), sample=300)
    else:
        base = district(work, 3.2)
    print(f"# District physics ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())})")
    print(f"work folder {work}; {len(base['candidates'])} candidates, {args.pairs} pairs")
    run_table(work, base, args.pairs, not args.no_beams)
    if args.validate:
        validation(work, base, args.pairs, args.validate)


if __name__ == "__main__":
    main()
