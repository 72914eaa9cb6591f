"""The plan's resource estimate (time and peak memory, printed before a plan starts and kept in
plan.json ``resources``) against what real-site runs measure, as a user runs them
(docs/validation/resources.md, "Real sites").

Each site goes through the command line: ``ris-planner sites`` (candidate mounting points, when
the site has no committed candidate file), ``ris-planner import geojson FILE --plan --candidates
SITES`` (a starting plan document) and ``ris-planner plan plan.json --out DIR`` plain, with
``--sizing``, ``--nested`` and ``--validate 5``. Every plan run prints its estimate on stderr
before it starts (``estimate: ≈ … s, ≈ … MiB peak``) and writes ``resources.estimate`` and
``resources.measured`` (wall seconds from the estimate to plan.json, peak resident memory of the
plan's process) into plan.json; the table gives estimate / measured for both. Pass: both ratios
within [0.5, 2]. ``cpu/wall`` is the command's CPU seconds (its processes) over its wall time:
well below 1 on a busy machine, where the measured time is the load's as much as the plan's.

The **held-out** set is the committed OpenStreetMap sites (``examples/helsinki`` with its 26
committed candidates and with the candidates ``ris-planner sites`` finds, and
``tests/data/osm/bulevardi.geojson``); no run of it was used to fit the model. The
**calibration** set (``--calibration``) is seeded synthetic city grids (rectangular blocks of
buildings between streets, in a WGS84 frame elsewhere) through the same steps; ``--documents
DIR`` writes its plan documents (with each variant) for ``bench_memory.py --document``, whose
per-stage CPU seconds ``fit_time_model.py`` fits.

    python benchmarks/resources/bench_estimates.py             # the held-out table (~3 min)
    python benchmarks/resources/bench_estimates.py --site helsinki --variant plain
    python benchmarks/resources/bench_estimates.py --quick     # that one row
    python benchmarks/resources/bench_estimates.py --calibration --documents /tmp/cal
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import random
import re
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import ROOT

VARIANTS: dict[str, list[str]] = {
    "plain": [],
    "sizing": ["--sizing"],
    "nested": ["--nested"],
    "validate": ["--validate", "5"],
}
"""The ``ris-planner plan`` options of each run of a site."""

ESTIMATE_LINE = re.compile(r"^estimate: ≈ ([\d.]+) s, ≈ ([\d ]+) MiB peak")
"""The estimate line ``ris-planner plan`` prints on stderr before it plans."""


@dataclass(frozen=True)
class Site:
    """A site: its GeoJSON and its candidates (a committed file, or ``ris-planner sites``)."""

    name: str
    geojson: Path | None
    """The site's GeoJSON; None: the synthetic city ``city`` (written when it runs)."""
    candidates: Path | None = None
    """A committed candidate file; None: what ``ris-planner sites`` writes."""
    city: tuple[int, int, float, float, int] | None = None
    """Synthetic city (blocks east, blocks north, block side m, street width m, seed)."""
    sites_args: tuple[str, ...] = ()
    """Extra options of ``ris-planner sites``."""


HELD_OUT = [
    Site(
        "helsinki",
        ROOT / "examples/helsinki/helsinki.geojson",
        ROOT / "examples/helsinki/sites.geojson",
    ),
    Site("helsinki-sites", ROOT / "examples/helsinki/helsinki.geojson"),
    Site("bulevardi-sites", ROOT / "tests/data/osm/bulevardi.geojson"),
]
"""The committed real sites: never part of the calibration."""

CALIBRATION = [
    Site("city-3x3", None, city=(3, 3, 60.0, 16.0, 1)),
    Site("city-4x3-sparse", None, city=(4, 3, 50.0, 20.0, 2), sites_args=("--spacing-m", "30")),
    Site("city-5x4", None, city=(5, 4, 45.0, 14.0, 3)),
    Site("city-2x2-sparse", None, city=(2, 2, 70.0, 18.0, 4), sites_args=("--spacing-m", "25")),
    Site("city-3x2-few", None, city=(3, 2, 55.0, 15.0, 5), sites_args=("--spacing-m", "45")),
]
"""Synthetic city grids (seeded): the time model's and the memory terms' real-site-like
calibration cases."""


def _lonlat(x: float, y: float, origin: tuple[float, float]) -> list[float]:
    lon0, lat0 = origin
    return [
        round(lon0 + x / (111_320.0 * math.cos(math.radians(lat0))), 7),
        round(lat0 + y / 110_540.0, 7),
    ]


def synthetic_city(nx: int, ny: int, block_m: float, street_m: float, seed: int) -> dict[str, Any]:
    """A GeoJSON FeatureCollection (WGS84) of a grid city: ``nx`` × ``ny`` blocks of
    ``block_m`` with ``street_m`` streets between them, each block one to three buildings
    (heights 9–30 m, some as ``building:levels``), residential streets on the block edges'
    centre lines and a footway through some blocks."""
    rng = random.Random(seed)
    origin = (8.55 + 0.01 * seed, 47.37)
    pitch = block_m + street_m
    feats: list[dict[str, Any]] = []

    def ring(x0: float, y0: float, x1: float, y1: float) -> list[list[list[float]]]:
        pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
        return [[_lonlat(x, y, origin) for x, y in pts]]

    for i in range(nx):
        for j in range(ny):
            x0, y0 = i * pitch + street_m / 2, j * pitch + street_m / 2
            cuts = sorted(rng.uniform(0.3, 0.7) for _ in range(rng.randint(0, 2)))
            edges = [0.0, *cuts, 1.0]
            for a, b in itertools.pairwise(edges):
                props: dict[str, Any] = {"building": "yes", "@id": f"way/{len(feats) + 1}"}
                if rng.random() < 0.5:
                    props["building:levels"] = str(rng.randint(3, 9))
                else:
                    props["height"] = str(round(rng.uniform(9, 30), 1))
                xa, xb = x0 + a * block_m, x0 + b * block_m
                geom = {"type": "Polygon", "coordinates": ring(xa, y0, xb - 1.0, y0 + block_m)}
                feats.append({"type": "Feature", "properties": props, "geometry": geom})
    width, height = nx * pitch, ny * pitch
    for i in range(nx + 1):
        line = [_lonlat(i * pitch, 0.0, origin), _lonlat(i * pitch, height, origin)]
        feats.append(_road(line, "residential" if i % 2 else "tertiary", len(feats)))
    for j in range(ny + 1):
        line = [_lonlat(0.0, j * pitch, origin), _lonlat(width, j * pitch, origin)]
        feats.append(_road(line, "residential", len(feats)))
    return {"type": "FeatureCollection", "license": "synthetic (benchmarks)", "features": feats}


def _road(line: list[list[float]], kind: str, k: int) -> dict[str, Any]:
    return {
        "type": "Feature",
        "properties": {"highway": kind, "@id": f"way/{10_000 + k}"},
        "geometry": {"type": "LineString", "coordinates": line},
    }


def _cli(args: list[str], cwd: Path, timeout: float = 900) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env.setdefault("MPLBACKEND", "Agg")
    exe = Path(sys.executable).with_name("ris-planner")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "ris_planner.cli"]
    return subprocess.run(
        [*cmd, *args], capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd
    )


def site_plan(site: Site, work: Path) -> tuple[Path, dict[str, float]]:
    """The site's starting plan document (``ris-planner sites`` when it has no committed
    candidates, then ``ris-planner import geojson --plan --candidates``) and each step's wall
    seconds."""
    work.mkdir(parents=True, exist_ok=True)
    steps: dict[str, float] = {}
    geo = site.geojson
    if geo is None:
        assert site.city is not None
        geo = work / f"{site.name}.geojson"
        geo.write_text(json.dumps(synthetic_city(*site.city)))
    cands = site.candidates
    if cands is None:
        cands = work / "sites.geojson"
        t0 = time.perf_counter()
        proc = _cli(["sites", str(geo), "--out", str(cands), *site.sites_args], work)
        steps["sites"] = time.perf_counter() - t0
        if proc.returncode != 0:
            raise RuntimeError(f"{site.name}: ris-planner sites failed:\n{proc.stderr[-2000:]}")
    plan = work / "plan.json"
    t0 = time.perf_counter()
    args = ["import", "geojson", str(geo), "--plan", "--candidates", str(cands), "--out", str(plan)]
    proc = _cli(args, work)
    steps["import"] = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{site.name}: ris-planner import failed:\n{proc.stderr[-2000:]}")
    return plan, steps


def run_plan(plan: Path, variant: str, work: Path) -> dict[str, Any]:
    """``ris-planner plan`` of one variant: the estimate line (and that it came before the
    plan's progress), plan.json ``resources``, the process's wall seconds."""
    out = work / f"out-{variant}"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = _cli(["plan", str(plan), "--out", str(out), *VARIANTS[variant]], work)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    row: dict[str, Any] = {
        "variant": variant,
        "process_s": wall,
        "process_cpu_s": cpu,
        "returncode": proc.returncode,
    }
    lines = proc.stderr.splitlines()
    first = next((i for i, ln in enumerate(lines) if ESTIMATE_LINE.match(ln)), None)
    row["estimate_line"] = None if first is None else lines[first]
    if proc.returncode != 0:
        row["error"] = lines[-1] if lines else "?"
        return row
    plan_json = json.loads((out / "plan.json").read_text())
    res = plan_json["resources"]
    row["timing_s"] = plan_json["timing_s"]
    row.update(
        estimate_s=res["estimate"]["time_s"],
        estimate_mib=res["estimate"]["memory_mib"],
        measured_s=res["measured"]["time_s"],
        peak_mib=res["measured"]["peak_memory_mib"],
    )
    row["time_ratio"] = row["estimate_s"] / row["measured_s"]
    row["memory_ratio"] = row["estimate_mib"] / row["peak_mib"]
    row["passed"] = 0.5 <= row["time_ratio"] <= 2 and 0.5 <= row["memory_ratio"] <= 2
    return row


def write_documents(sites: list[Site], variants: list[str], folder: Path) -> list[Path]:
    """The sites' plan documents, one per variant (``bench_memory.py --document``: the
    calibration's per-stage CPU seconds)."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for site in sites:
        plan, _ = site_plan(site, folder / site.name)
        doc = json.loads(plan.read_text())
        for v in variants:
            d = dict(doc)
            if v == "sizing":
                d["sizing"] = {}
            elif v == "nested":
                d["rollout"] = "nested"
            elif v == "validate":
                d["validation"] = {"pairs": 5}
            path = folder / f"{site.name}-{v}.json"
            path.write_text(json.dumps(d))
            out.append(path)
    return out


def _load() -> str:
    try:
        return " ".join(f"{v:.1f}" for v in os.getloadavg())
    except OSError:
        return "?"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calibration", action="store_true", help="the synthetic cities instead")
    ap.add_argument("--site", action="append", help="only sites whose name contains this")
    ap.add_argument("--variant", action="append", choices=list(VARIANTS), help="only these")
    ap.add_argument("--documents", type=Path, help="write the plan documents here and stop")
    ap.add_argument("--json", type=Path, help="also write the rows as JSON here")
    ap.add_argument("--quick", action="store_true", help="the helsinki site, plain run only")
    args = ap.parse_args(argv)
    if args.quick:
        args.site, args.variant = ["helsinki"], ["plain"]
    sites = CALIBRATION if args.calibration else HELD_OUT
    if args.site:
        sites = [s for s in sites if any(k == s.name for k in args.site)] or [
            s for s in sites if any(k in s.name for k in args.site)
        ]
    variants = args.variant or list(VARIANTS)
    if args.documents is not None:
        for p in write_documents(sites, variants, args.documents):
            print(p)
        return 0
    print(f"load average {_load()}, {os.cpu_count()} cores")
    print(
        f"{'site':18} {'run':9} {'est. s':>7} {'time s':>7} {'ratio':>6} {'est. MiB':>9}"
        f" {'peak MiB':>9} {'ratio':>6} {'pass':>5} {'cpu/wall':>8}"
    )
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for site in sites:
            work = Path(tmp) / site.name
            plan, steps = site_plan(site, work)
            for step, s in steps.items():
                print(f"{site.name:18} {step:9} {'':>7} {s:7.2f}", flush=True)
            for v in variants:
                r = run_plan(plan, v, work)
                rows.append({"site": site.name, "steps_s": steps, **r})
                if "error" in r:
                    print(f"{site.name:18} {v:9} refused or failed: {r['error']}", flush=True)
                    continue
                print(
                    f"{site.name:18} {v:9} {r['estimate_s']:7.2f} {r['measured_s']:7.2f}"
                    f" {r['time_ratio']:6.2f} {r['estimate_mib']:9.0f} {r['peak_mib']:9.0f}"
                    f" {r['memory_ratio']:6.2f} {'pass' if r['passed'] else 'FAIL':>5}"
                    f" {r['process_cpu_s'] / r['process_s']:8.2f}",
                    flush=True,
                )
    done = [r for r in rows if "error" not in r]
    print(f"{sum(r['passed'] for r in done)}/{len(done)} within [0.5, 2]; load average {_load()}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0 if all(r["passed"] for r in done) else 1


if __name__ == "__main__":
    sys.exit(main())
