"""The plan's memory estimate (:func:`ris_planner.planning.resources.estimate_plan`) against the
measured
peak resident memory of the same plan, case by case (docs/validation/resources.md).

Each case is a plan document (candidates on a ring facing grid UE maps, the shape of
``tests/test_api_plans.small_plan_doc``) run as a service job runs it
(:func:`ris_planner.io.geoplan.plan_document` on a :class:`SerialExecutor`: plan, figures, GIS
files) in a fresh Python process, whose peak resident set (``VmHWM``) is read at its end; the
estimate is computed in the same process, with the same site-cache budget, before the run. A
case passes when 1 ≤ estimate / peak ≤ 2 for the memory and 1 ≤ estimate / measured ≤ 2 for the
time (:func:`ris_planner.planning.work.time_estimate`; the time needs a quiet machine).

    python benchmarks/bench_memory.py            # the full table (a few minutes)
    python benchmarks/bench_memory.py --smoke    # three tiny cases (< 60 s)
    python benchmarks/bench_memory.py --case hall-ish --json out.json
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

ROOT = Path(__file__).resolve().parent.parent


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
    beside the fields and the figures, :func:`ris_planner.planning.work.checks_beside`)."""


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
import json, os, sys, tempfile, time
from pathlib import Path
case = json.loads(sys.argv[1])
from ris_planner.io.geoplan import plan_document
from ris_planner.model.limits import cache_layout
from ris_planner.planning.resources import estimate_plan
from ris_planner.planning import PlanDocument, SerialExecutor
sys.path.insert(0, sys.argv[2])
from bench_memory import Case, case_document
c = Case(**{**case, "ris_count": tuple(case["ris_count"])})
doc = case_document(c)
parsed = PlanDocument.model_validate(doc)
sizes = estimate_plan(parsed)
layout = cache_layout(sizes.cache_entries, c.wavefront)
from ris_planner.planning.inputs import prepare_plan
from ris_planner.planning.work import checks_beside, stage_seconds, stage_terms
inputs = prepare_plan(parsed)
est_stages = stage_seconds(inputs)
terms = stage_terms(inputs)
est_s = sum(est_stages.values())
trace = []
c0 = time.process_time()
t0 = time.perf_counter()
with tempfile.TemporaryDirectory() as tmp, SerialExecutor() as ex:
    done = plan_document(
        doc, Path(tmp), lambda f, m: trace.append((time.perf_counter() - t0, m)), ex
    )
seconds = time.perf_counter() - t0
cpu_s = time.process_time() - c0
stages = {k: round(v, 3) for k, v in done.plan["timing_s"].items()}
cpu_stages = {k: round(v, 3) for k, v in done.cpu_s.items()}
status = open("/proc/self/status").read()
hwm = int(status.split("VmHWM:")[1].split()[0]) * 1024
print(json.dumps({"estimate": sizes.memory_bytes, "peak": hwm, "seconds": seconds,
                  "cpu_s": cpu_s,
                  "estimate_s": est_s, "stages_s": stages, "cpu_stages_s": cpu_stages,
                  "estimate_stages_s": {k: round(v, 3) for k, v in est_stages.items()},
                  "terms": terms, "beside": checks_beside(inputs),
                  "layout": list(layout), "storage": done.plan["site_cache"]}))
"""


def run_case(case: Case, timeout: float = 900) -> dict[str, Any]:
    """Run one case in a fresh process: its estimate, measured peak [bytes] and wall time."""
    env = dict(os.environ)
    env["RIS_PLANNER_CACHE_MEMORY_MB"] = str(cache_budget_mb(case))
    env["RIS_PLANNER_JOB_MEMORY_MB"] = str(1 << 30)  # the bench measures; it does not refuse
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env.setdefault("OMP_NUM_THREADS", "1")
    env.setdefault("MPLBACKEND", "Agg")
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(asdict(case)), str(Path(__file__).parent)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        cwd=tempfile.gettempdir(),
    )
    if proc.returncode != 0:
        raise RuntimeError(f"{case.name} failed:\n{proc.stderr[-3000:]}")
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
    ap.add_argument("--json", type=Path, help="also write the rows as JSON here")
    ap.add_argument(
        "--stages", action="store_true", help="also print each stage's measured and estimated s"
    )
    args = ap.parse_args(argv)
    cases = SMOKE if args.smoke else FULL
    if args.case:
        cases = [c for c in SMOKE + FULL if any(s in c.name for s in args.case)]
    print(
        f"{'case':36} {'tier':13} {'wave':9} {'estimate MiB':>12} {'peak MiB':>9}"
        f" {'ratio':>6} {'memory':>6} {'time s':>7} {'est. s':>7} {'ratio':>6} {'time':>5}"
        f" {'cpu/wall':>8} {'est/CPU':>7}"
    )
    rows, t0 = [], time.perf_counter()
    for case in cases:
        r = run_case(case)
        rows.append({"case": asdict(case), **r})
        print(
            f"{case.name:36} {case.tier:13} {case.wavefront:9} {r['estimate'] / 2**20:12.0f}"
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
            for name in dict.fromkeys([*r["stages_s"], *est]):
                t, c, e = r["stages_s"].get(name, 0.0), cpu.get(name, 0.0), est.get(name, 0.0)
                print(f"    {name:16} measured {t:8.3f} s (CPU {c:8.3f} s)  estimated {e:8.3f} s")
    print(f"{sum(r['passed'] for r in rows)}/{len(rows)} passed, {time.perf_counter() - t0:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0 if all(r["passed"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
