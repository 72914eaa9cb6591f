"""One quick pass over every benchmark area (``make bench``): each script in its ``--quick``
(or ``--smoke``) mode, in its own process, one after another, each under a time limit; then the
asv suites' workloads once each, in this process. Prints one line per script (its area, its
wall time, ok or the tail of its error) and exits 1 when one failed.

The quick modes check that every benchmark still runs, in minutes; their figures are not
measurements (docs/validation/benchmarks.md names each script's full command).

    python benchmarks/quick.py [--area bounds] [--timeout 600] [--list]
"""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

QUICK: dict[str, list[list[str]]] = {
    "bounds": [
        ["bench_bounds.py", "--quick"],
        ["bench_environment_bounds.py", "--quick"],
        ["bench_spherical.py", "--quick"],
        ["bench_visibility.py", "--quick"],
        ["bench_single_pair_ab.py", "--quick"],
        ["bench_speed_ab.py", "--quick"],
    ],
    "power": [
        ["bench_power.py", "--quick"],
        ["bench_beams.py", "--quick"],
        ["bench_estimation.py", "--quick"],
    ],
    "planning": [
        ["bench_planning.py", "--quick"],
        ["bench_search.py", "--quick"],
        ["bench_search_quality.py", "--quick"],
        ["bench_scorer.py", "--quick"],
        ["bench_interactive.py", "--smoke"],
        ["bench_cold_start.py", "--quick"],
    ],
    "resources": [
        ["bench_estimates.py", "--quick"],
        ["bench_memory.py", "--smoke", "--stages", "--json", "{work}/runs.json"],
        ["fit_time_model.py", "{work}/runs.json", "--rounds", "1"],
    ],
    "service": [
        ["bench_api.py", "--quick"],
        ["bench_api_ab.py", "--quick"],
        ["bench_api_asgi.py", "--quick"],
        ["bench_cli.py", "--quick"],
        ["bench_rest_vs_cli.py", "--quick"],
        ["bench_service_liveness.py", "--smoke"],
        ["bench_refusals.py", "--quick"],
        ["fuzz_api.py", "--quick"],
    ],
    "district": [
        ["bench_district.py", "--quick", "--only", "quality"],
        ["bench_city.py", "--quick"],
        ["bench_district_physics.py", "--quick"],
        ["district_strong_sets.py", "--quick"],
        ["gap_probes.py", "--quick"],
        ["lp_solves.py", "--quick"],
        ["coverable_by_size.py", "--quick"],
    ],
}
"""Area → each script's quick command (``{work}``: a folder the pass shares)."""


def asv_suites() -> None:
    """Every asv suite's benchmarks once, this checkout (``setup``, each ``time_*``,
    ``teardown``)."""
    sys.path.insert(0, str(HERE / "asv"))
    for name in ("headline", "planning"):
        module = importlib.import_module(f"suites.{name}")
        for cls in [v for v in vars(module).values() if isinstance(v, type)]:
            if cls.__module__ != module.__name__:
                continue
            timed = [m for m in vars(cls) if m.startswith("time_")]
            if not timed:
                continue
            obj = cls()
            obj.setup()
            try:
                for method in timed:
                    t0 = time.perf_counter()
                    getattr(obj, method)()
                    print(f"  asv {cls.__name__}.{method}: {time.perf_counter() - t0:.2f} s")
            finally:
                if hasattr(obj, "teardown"):
                    obj.teardown()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--area", action="append", choices=[*QUICK, "asv"], help="only these")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per script")
    ap.add_argument("--list", action="store_true", help="print the commands and stop")
    args = ap.parse_args()
    areas = args.area or [*QUICK, "asv"]
    failed: list[str] = []
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bench-quick-") as work:
        for area in areas:
            for argv in QUICK.get(area, []):
                script = HERE / area / argv[0]
                cmd = [sys.executable, str(script), *(a.format(work=work) for a in argv[1:])]
                shown = f"benchmarks/{area}/{' '.join(argv)}"
                if args.list:
                    print(shown)
                    continue
                t0 = time.perf_counter()
                try:
                    done = subprocess.run(
                        cmd, capture_output=True, text=True, timeout=args.timeout, check=False
                    )
                    ok, tail = done.returncode == 0, (done.stderr or done.stdout)[-400:]
                except subprocess.TimeoutExpired:
                    ok, tail = False, f"over the {args.timeout:g} s limit"
                wall = time.perf_counter() - t0
                print(f"{'ok  ' if ok else 'FAIL'} {wall:7.1f} s  {shown}", flush=True)
                if not ok:
                    failed.append(shown)
                    print("      " + tail.replace("\n", "\n      "), flush=True)
            if area == "asv" and not args.list:
                t0 = time.perf_counter()
                try:
                    asv_suites()
                    print(f"ok   {time.perf_counter() - t0:7.1f} s  benchmarks/asv/suites")
                except Exception as exc:  # a suite that no longer runs
                    failed.append("benchmarks/asv/suites")
                    print(f"FAIL benchmarks/asv/suites: {type(exc).__name__}: {exc}")
    if not args.list:
        print(f"{len(failed)} failed; the pass took {time.perf_counter() - t_all:.0f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
