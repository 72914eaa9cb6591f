"""The plan's memory estimate (:func:`ris_planner.planning.resources.admission.estimate_plan`)
against the
measured
peak resident memory of the same plan, case by case (docs/validation/resources.md).

Each case is a plan document (candidates on a ring facing grid UE maps, the shape of
``tests/test_api_plans.small_plan_doc``) run as a service job runs it
(:func:`ris_planner.io.geoplan.plan_document` on a :class:`SerialExecutor`: plan, figures, GIS
files) in a fresh Python process, whose peak resident set (``VmHWM``) is read at its end; the
estimate is computed in the same process, with the same site-cache budget, before the run. A
case passes when 1 ≤ estimate / peak ≤ 2 for the memory and 1 ≤ estimate / measured ≤ 2 for the
time (:func:`ris_planner.planning.resources.time_estimate.time_estimate`; the time needs a quiet
machine).

    python benchmarks/resources/bench_memory.py            # the full table (a few minutes)
    python benchmarks/resources/bench_memory.py --smoke    # three tiny cases (< 60 s)
    python benchmarks/resources/bench_memory.py --case hall-ish --json out.json
    python benchmarks/resources/bench_memory.py --document plan.json:sizing --stages --json out.json

``--document FILE[:VARIANT]`` runs a plan document instead of a case (a real site's import,
``bench_estimates.py --documents``' calibration cities), plain or as ``ris-planner plan
--sizing`` / ``--nested`` / ``--validate 5`` would (:data:`VARIANT_FIELDS`); every row also
holds the peak resident memory per progress stage (``stage_peaks_mib``), the memory terms
(``terms_mib``) and the layouts the search scored (``evaluated``), for the memory terms'
calibration.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import ROOT


@dataclass(frozen=True)
class Case:
    """One plan: RIS size, candidates, sampled pairs, site-cache tier, wavefront."""

    name: str
    ris: int
    """RIS rows = cols."""
    sites: int
    pairs: int
    tier: str = "float64+rows"
    """The site-cache tier forced through the cache budget: float64+rows, float64, float32."""
    wavefront: str = "planar"
    grid: int = 15
    """UE grid points per axis (TX and RX maps: grid² points each)."""
    ris_count: tuple[int, ...] = (1, 2)
    rx_grid: int = 0
    """RX grid points per axis when they differ from ``grid`` (a large heatmap)."""
    search: str = "greedy"
    """``greedy`` (few rounds) or ``auto`` (exhaustive here: the checks run on their thread
    beside the fields and the figures,
    :func:`ris_planner.planning.resources.time_estimate.checks_beside`)."""


SMOKE = [
    Case("smoke-planar", 10, 10, 1000, grid=8),
    Case("smoke-float32", 16, 12, 1000, tier="float32", grid=8),
    Case("smoke-spherical", 10, 10, 1000, wavefront="spherical", grid=8),
]
FULL = [
    Case("10x10 10 sites 1e3 pairs", 10, 10, 1000, grid=12),
    Case("32x32 50 sites 1e4 pairs", 32, 50, 10_000, grid=30),
    Case("64x64 52 sites 1e3 pairs", 64, 52, 1000, grid=20, ris_count=(2, 3)),
    Case("100x100 20 sites 5e4 pairs", 100, 20, 50_000, grid=40),
    Case("20x20 500 sites 2e3 pairs", 20, 500, 2000, grid=20, ris_count=(1,)),
    Case("20x20 10 sites 1e3, 9e4 RX points", 20, 10, 1000, grid=10, rx_grid=300),
    Case("32x32 100 sites 2e4 pairs f64", 32, 100, 20_000, tier="float64", grid=30),
    Case("32x32 200 sites 2e4 pairs f32", 32, 200, 20_000, tier="float32", grid=30),
    Case("16x16 10 sites 5e4 pairs f32", 16, 10, 50_000, tier="float32", grid=40),
    Case("40x40 20 sites 5e3 spherical", 40, 20, 5000, wavefront="spherical", grid=20),
    Case("64x64 10 sites 1e3 spherical", 64, 10, 1000, wavefront="spherical", grid=12),
    Case(
        "64x64 26 sites 1e3 pairs auto", 64, 26, 1000, grid=20, ris_count=(2, 3, 4), search="auto"
    ),
    Case("32x32 40 sites 1e4 pairs auto", 32, 40, 10_000, grid=30, search="auto"),
]


def ring(n: int, radius: float = 6.0) -> list[dict[str, Any]]:
    """n candidates on a circle of ``radius`` facing its centre, heights 2–3 m."""
    out = []
    for k in range(n):
        phi = 2 * math.pi * k / n + 0.1
        out.append(
            {
                "position": [radius * math.cos(phi), radius * math.sin(phi), 2.0 + (k % 2)],
                "orientation": [phi + math.pi, math.pi / 6, 0.0],
            }
        )
    return out


def case_document(case: Case) -> dict[str, Any]:
    """The plan document of a case: grid maps of ``grid``² points inside the ring, sampled
    pairs, a greedy search of few rounds (the search's memory does not grow with its rounds)
    or the case's ``search`` method."""

    def grid(g: int) -> dict[str, Any]:
        step = 8.0 / (g - 1)
        return {"grid": {"x": [-4, 4 + 1e-9, step], "y": [-4, 4 + 1e-9, step], "z": [0, 0, 1]}}

    return {
        "system": {"wavefront": case.wavefront},
        "ris": {"rows": case.ris, "cols": case.ris},
        "candidates": ring(case.sites),
        "tx_map": grid(case.grid),
        "rx_map": grid(case.rx_grid or case.grid),
        "pairs": {"sample": case.pairs, "seed": 1},
        "max_pairs": max(case.pairs, 20_000),
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": list(case.ris_count),
        "search": (
            {"method": "greedy", "restarts": 0, "max_rounds": 2}
            if case.search == "greedy"
            else {"method": case.search}
        ),
    }


def cache_budget_mb(case: Case) -> int:
    """A site-cache budget [MiB] that selects the case's tier (:func:`limits.cache_layout`)."""
    from ris_planner.model.limits import CacheLayout, cache_layout

    entries = case.sites * case.pairs
    storage = "float32" if case.tier == "float32" else "float64"
    rows = case.tier == "float64+rows" or case.wavefront == "spherical"
    want = CacheLayout(storage, rows)  # type: ignore[arg-type]
    mb = max(1, math.ceil(want.bytes(entries, case.wavefront) / 2**20))
    got = cache_layout(entries, case.wavefront, mb)
    assert got == want, f"{case.name}: budget {mb} MiB selects {got}, not {want}"
    return mb


CHILD = r"""
import json, os, sys, tempfile, threading, time
from pathlib import Path
spec = json.loads(sys.argv[1])
from ris_planner.io.candidates import in_document_coordinates
from ris_planner.io.frames import to_local
from ris_planner.io.geoplan import plan_document
from ris_planner.model.limits import cache_layout
from ris_planner.planning.resources.admission import estimate_plan, largest_plan_shape, plan_memory
from ris_planner.planning import PlanDocument, SerialExecutor
import ris_planner.planning.search.layouts as search_module
sys.path.insert(0, sys.argv[2])
from bench_memory import Case, case_document, variant_document
if "case" in spec:
    case = spec["case"]
    c = Case(**{**case, "ris_count": tuple(case["ris_count"])})
    doc = case_document(c)
else:
    doc = variant_document(json.loads(Path(spec["document"]).read_text()), spec["variant"])
local, frame = to_local(doc)
parsed = PlanDocument.model_validate(local)
sizes = estimate_plan(parsed)
terms_mib = {k: v / 2**20 for k, v in plan_memory(largest_plan_shape(parsed)).items()}
layout = cache_layout(sizes.cache_entries, parsed.system.wavefront)
from ris_planner.planning.resources.time_estimate import checks_beside, stage_seconds, stage_terms
# the estimate from the document alone, as the command line and the service make it
est_stages = stage_seconds(parsed)
terms = stage_terms(parsed)
est_s = sum(est_stages.values())
evaluated = [0]
scored = search_module.evaluate
def counting(scorer, layouts, *args, **kw):
    evaluated[0] += int(layouts.shape[0])
    return scored(scorer, layouts, *args, **kw)
search_module.evaluate = counting
def rss_kib():
    status = open("/proc/self/status").read()
    return int(status.split("VmRSS:")[1].split()[0])
stage = ["start"]
stage_peaks = {}
done_flag = []
def sample():
    while not done_flag:
        k = stage[0]
        stage_peaks[k] = max(stage_peaks.get(k, 0), rss_kib())
        time.sleep(0.005)
threading.Thread(target=sample, daemon=True).start()
def on_progress(f, m):
    name = m.split(":")[0].split(" ")[0]
    if name == "plan" and ": sizing" in m:
        name = "sizing"
    stage[0] = name
c0 = time.process_time()
t0 = time.perf_counter()
with tempfile.TemporaryDirectory() as tmp, SerialExecutor() as ex:
    done = plan_document(doc, Path(tmp), on_progress, ex)
seconds = time.perf_counter() - t0
cpu_s = time.process_time() - c0
done_flag.append(1)
stages = {k: round(v, 3) for k, v in done.plan["timing_s"].items()}
cpu_stages = {k: round(v, 3) for k, v in done.cpu_s.items()}
status = open("/proc/self/status").read()
hwm = int(status.split("VmHWM:")[1].split()[0]) * 1024
print(json.dumps({"estimate": sizes.memory_bytes, "peak": hwm, "seconds": seconds,
                  "cpu_s": cpu_s, "terms_mib": terms_mib,
                  "stage_peaks_mib": {k: v / 1024 for k, v in stage_peaks.items()},
                  "evaluated": evaluated[0],
                  "estimate_s": est_s, "stages_s": stages, "cpu_stages_s": cpu_stages,
                  "estimate_stages_s": {k: round(v, 3) for k, v in est_stages.items()},
                  "terms": terms, "beside": checks_beside(parsed),
                  "layout": list(layout), "storage": done.plan.get("site_cache")}))
"""

VARIANT_FIELDS: dict[str, dict[str, Any]] = {
    "plain": {},
    "sizing": {"sizing": {}},
    "nested": {"rollout": "nested"},
    "validate": {"validation": {"pairs": 5}},
}
"""A document's runs (``--document FILE[:VARIANT]``): as ``ris-planner plan`` with no option,
``--sizing``, ``--nested`` and ``--validate 5`` makes them."""


def variant_document(doc: dict[str, Any], variant: str) -> dict[str, Any]:
    """The plan document of one variant of ``doc`` (:data:`VARIANT_FIELDS`)."""
    extra = VARIANT_FIELDS[variant]
    if "validation" in extra:
        extra = {"validation": {**(doc.get("validation") or {}), **extra["validation"]}}
    return {**doc, **extra}


def run_case(case: Case, timeout: float = 900) -> dict[str, Any]:
    """Run one case in a fresh process: its estimate, measured peak [bytes] and wall time."""
    env = {"RIS_PLANNER_CACHE_MEMORY_MB": str(cache_budget_mb(case))}
    return _run_child({"case": asdict(case)}, env, timeout)


def run_document(path: Path, variant: str = "plain", timeout: float = 900) -> dict[str, Any]:
    """Run a plan document file (local metres or with a frame) as :func:`run_case` runs a case,
    as the ``variant`` of :data:`VARIANT_FIELDS` (the default site-cache budget)."""
    return _run_child({"document": str(path.resolve()), "variant": variant}, {}, timeout)


def _run_child(spec: dict[str, Any], extra_env: dict[str, str], timeout: float) -> dict[str, Any]:
    env = dict(os.environ)
    env.update(extra_env)
    env["RIS_PLANNER_JOB_MEMORY_MB"] = str(1 << 30)  # the bench measures; it does not refuse
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("MPLBACKEND", "Agg")
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(spec), str(Path(__file__).parent)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        cwd=tempfile.gettempdir(),
    )
    if proc.returncode != 0:
        raise RuntimeError(f"{spec} failed:\n{proc.stderr[-3000:]}")
    out: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    out["ratio"] = out["estimate"] / out["peak"]
    out["time_ratio"] = out["estimate_s"] / out["seconds"]
    # the process's CPU over its wall time: 1 on a quiet core, below it on a busy machine
    out["cpu_share"] = out["cpu_s"] / out["seconds"]
    out["memory_passed"] = 1.0 <= out["ratio"] <= 2.0
    out["time_passed"] = 1.0 <= out["time_ratio"] <= 2.0
    out["passed"] = out["memory_passed"] and out["time_passed"]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="three tiny cases (< 60 s)")
    ap.add_argument("--case", action="append", help="run only cases whose name contains this")
    ap.add_argument(
        "--document",
        action="append",
        metavar="FILE[:VARIANT]",
        help="run this plan document instead of the cases (repeatable); VARIANT: "
        + ", ".join(VARIANT_FIELDS),
    )
    ap.add_argument("--json", type=Path, help="also write the rows as JSON here")
    ap.add_argument(
        "--stages", action="store_true", help="also print each stage's measured and estimated s"
    )
    args = ap.parse_args(argv)
    cases = SMOKE if args.smoke else FULL
    if args.case:
        cases = [c for c in SMOKE + FULL if any(s in c.name for s in args.case)]
    runs: list[tuple[str, str, str, Any]] = [(c.name, c.tier, c.wavefront, c) for c in cases]
    if args.document:
        runs = []
        for spec in args.document:
            path, _, variant = spec.partition(":")
            runs.append((f"{Path(path).stem}:{variant or 'plain'}", "", "", spec))
    print(
        f"{'case':36} {'tier':13} {'wave':9} {'estimate MiB':>12} {'peak MiB':>9}"
        f" {'ratio':>6} {'memory':>6} {'time s':>7} {'est. s':>7} {'ratio':>6} {'time':>5}"
        f" {'cpu/wall':>8} {'est/CPU':>7}"
    )
    rows, t0 = [], time.perf_counter()
    for name, tier, wave, what in runs:
        if isinstance(what, Case):
            r = run_case(what)
            rows.append({"case": asdict(what), **r})
        else:
            path, _, variant = what.partition(":")
            r = run_document(Path(path), variant or "plain")
            tier, wave = "/".join(map(str, r["layout"])), ""
            doc_case = {"name": name, "document": str(Path(path).resolve())}
            rows.append({"case": doc_case, "variant": variant or "plain", **r})
        print(
            f"{name:36} {tier:13} {wave:9} {r['estimate'] / 2**20:12.0f}"
            f" {r['peak'] / 2**20:9.0f} {r['ratio']:6.2f}"
            f" {'pass' if r['memory_passed'] else 'FAIL':>6} {r['seconds']:7.1f}"
            f" {r['estimate_s']:7.1f} {r['time_ratio']:6.2f}"
            f" {'pass' if r['time_passed'] else 'FAIL':>5} {r['cpu_share']:8.2f}"
            f" {r['estimate_s'] / r['cpu_s']:7.2f}",
            flush=True,
        )
        if args.stages:
            est = r["estimate_stages_s"]
            cpu = r["cpu_stages_s"]
            for stage in dict.fromkeys([*r["stages_s"], *est]):
                t, c, e = r["stages_s"].get(stage, 0.0), cpu.get(stage, 0.0), est.get(stage, 0.0)
                print(f"    {stage:16} measured {t:8.3f} s (CPU {c:8.3f} s)  estimated {e:8.3f} s")
    print(f"{sum(r['passed'] for r in rows)}/{len(rows)} passed, {time.perf_counter() - t0:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0 if all(r["passed"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
