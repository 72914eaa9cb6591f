"""Benchmark: the first plan after an install, with and without ``ris-planner warmup``
(the cold start; docs/getting-started.md "Compiled kernels").

Two empty numba cache folders (``NUMBA_CACHE_DIR``), so the package's own ``__pycache__`` is
never touched and nothing is compiled before the run:

* cold – ``ris-planner plan --preset NAME`` straight away (it compiles what it needs);
* warmed – ``ris-planner warmup`` (timed: the install's extra step), then the same plan.

Each plan runs in a fresh process that counts numba's compilations (the ``numba:compile``
events: a kernel loaded from the cache fires none). Printed: the wall times, the warm-up's own
time, the compilations, the ratio cold / warmed. The machine may be shared: the ratio of two
runs in the same minute is the figure to read; absolute seconds need a quiet machine.

    python benchmarks/planning/bench_cold_start.py                 # the demo's first plan
    python benchmarks/planning/bench_cold_start.py --preset hall
    python benchmarks/planning/bench_cold_start.py --json out.json
    python benchmarks/planning/bench_cold_start.py --quick

``--quick``: the plan once on this checkout's own cache (what ``make setup`` compiled), no empty
caches: its time and its compilations, which must be none.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import ROOT

COUNTING_PLAN = """
import json, sys, time
from numba.core import event
compiled = []
class Count(event.Listener):
    def on_start(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__qualname__)
    def on_end(self, ev):
        pass
event.register("numba:compile", Count())
from ris_planner.cli import main
t0 = time.perf_counter()
status = main(sys.argv[1:])
print(json.dumps({"status": status, "seconds": time.perf_counter() - t0,
                  "compiled": sorted(set(compiled)), "compilations": len(compiled)}))
"""
"""A plan in a fresh process, numba's compilations counted (the ``numba:compile`` event
fires only on a cache miss)."""


def _env(cache: Path | None) -> dict[str, str]:
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    numba = {} if cache is None else {"NUMBA_CACHE_DIR": str(cache)}
    return dict(os.environ, PYTHONPATH=path, **numba)


def first_plan(preset: str, cache: Path | None, out: Path) -> dict[str, Any]:
    """``ris-planner plan --preset`` in a fresh process on numba cache ``cache``: its wall
    time (the process included) and its compilations."""
    cmd = [sys.executable, "-c", COUNTING_PLAN, "plan", "--preset", preset, "--out", str(out)]
    t0 = time.perf_counter()
    run = subprocess.run(cmd, capture_output=True, text=True, env=_env(cache), check=False)
    wall = time.perf_counter() - t0
    if run.returncode != 0:
        raise RuntimeError(f"plan failed: {run.stderr[-2000:]}")
    figures = json.loads(run.stdout.strip().splitlines()[-1])
    return {"wall_s": round(wall, 2), "compilations": figures["compilations"]} | {
        "compiled": figures["compiled"]
    }


def warm_up(cache: Path) -> dict[str, Any]:
    """``ris-planner warmup --json`` on numba cache ``cache``: its wall time and report."""
    cmd = [sys.executable, "-m", "ris_planner.cli", "warmup", "--json", "--quiet"]
    t0 = time.perf_counter()
    run = subprocess.run(cmd, capture_output=True, text=True, env=_env(cache), check=False)
    wall = time.perf_counter() - t0
    if run.returncode != 0:
        raise RuntimeError(f"warm-up failed: {run.stderr[-2000:]}")
    report = json.loads(run.stdout)
    return {"wall_s": round(wall, 2), "kernels": len(report["kernels"])}


def measure(preset: str) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        cold = first_plan(preset, root / "cache-cold", root / "out-cold")
        warm = warm_up(root / "cache-warm")
        warmed = first_plan(preset, root / "cache-warm", root / "out-warm")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {
        "preset": preset,
        "cold_first_plan": cold,
        "warmup": warm,
        "first_plan_after_warmup": warmed,
        "ratio_cold_over_warmed": round(cold["wall_s"] / warmed["wall_s"], 2),
        "load_average_1min": round(load, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="fig10-anchors", help="the plan preset to time")
    parser.add_argument("--json", type=Path, help="write the figures here")
    parser.add_argument("--quick", action="store_true", help="the plan on this checkout's cache")
    args = parser.parse_args()
    if args.quick:
        with tempfile.TemporaryDirectory() as tmp:
            run = first_plan(args.preset, None, Path(tmp) / "out")
        print(
            f"plan ({args.preset}) on this checkout's cache: {run['wall_s']:.1f} s,"
            f" {run['compilations']} compilations {run['compiled']}"
        )
        if run["compilations"]:
            sys.exit("the checkout's cache misses kernels: run `ris-planner warmup`")
        return
    res = measure(args.preset)
    cold, warm, warmed = res["cold_first_plan"], res["warmup"], res["first_plan_after_warmup"]
    print(
        f"first plan ({args.preset}), cold cache:   {cold['wall_s']:7.1f} s,"
        f" {cold['compilations']} compilations"
    )
    print(f"ris-planner warmup:                {warm['wall_s']:7.1f} s, {warm['kernels']} kernels")
    print(
        f"first plan after the warm-up:      {warmed['wall_s']:7.1f} s,"
        f" {warmed['compilations']} compilations {warmed['compiled']}"
    )
    print(
        f"cold / warmed: {res['ratio_cold_over_warmed']}×"
        f"  (load average {res['load_average_1min']})"
    )
    if args.json:
        args.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
