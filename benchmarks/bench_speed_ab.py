"""Old vs new in the same run: ``compute_bounds`` on the Fig. 10 workload (4753 pairs; planar
``random`` and ``expected_random`` with N = 100, spherical ``expected_random`` with 100 × 100
RISs) and the planning site cache of the 156-site × 6400-pair hall of ``bench_search.py``.

Each measurement runs in a fresh subprocess, alternating between this checkout's interpreter
and ``--old-python`` (another checkout's environment, e.g. main's ``.venv/bin/python``: it
imports its own ``ris_planner``), ``--rounds`` times; the table gives the minimum wall time per
call over all rounds and repeats (the least disturbed one on a shared machine) and the ratio.
Both run with the machine's default BLAS threads.

    python benchmarks/bench_speed_ab.py --old-python ../main/.venv/bin/python [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
LAYOUTS = ("2-ris-L", "2-ris-P", "3-ris", "4-ris")
CASES = [f"planar random {lay}" for lay in LAYOUTS]
CASES += [f"planar expected_random {lay}" for lay in LAYOUTS]
CASES += [f"spherical expected_random {lay}" for lay in ("2-ris-L", "4-ris")]
CASES += ["site cache hall"]


def measure(case: str, repeats: int) -> dict[str, float]:
    """Min wall and CPU seconds of one call of ``case`` (run in the worker process)."""
    sys.path.insert(0, str(HERE))
    from bench_spherical import spherical_doc

    from ris_planner import compute_bounds, load_scenario, preset_document
    from ris_planner.model.paper import fig10_pairs

    words = case.split()
    if words[0] == "site":
        from bench_search import hall_doc

        from ris_planner.environment import Scene
        from ris_planner.planning import PlanDocument
        from ris_planner.planning.inputs.sites import expand_sites
        from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
        from ris_planner.planning.scoring.site_cache import build_site_cache
        from ris_planner.planning.scoring.visibility import pair_visibility

        d = PlanDocument.model_validate(hall_doc([3]))
        sites = expand_sites(d)
        pairs = build_pairs(build_map(d.tx_map, "tx"), build_map(d.rx_map, "rx"), d.pairs, 10**6)
        vis = pair_visibility(Scene.from_environment(d.environment), sites, pairs, d.system.los)

        def call() -> Any:
            return build_site_cache(d.system, sites, pairs, visibility=vis, known=())

    else:
        wavefront, kind, layout = words
        tx, rx = fig10_pairs()
        if wavefront == "spherical":
            doc = spherical_doc(layout)
        else:
            cb = {"kind": kind, "seed": 0} if kind == "random" else {"kind": kind}
            doc = preset_document(layout) | {"codebook": cb}
        sc = load_scenario(doc)

        def call() -> Any:
            return compute_bounds(sc, tx=tx, rx=rx)

    call()  # warm-up
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        call()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {"wall": min(wall), "cpu": min(cpu)}


def run_worker(python: str, case: str, repeats: int) -> dict[str, float]:
    env = os.environ | {"PYTHONDONTWRITEBYTECODE": "1"}
    out = subprocess.run(
        [python, __file__, "--worker", case, "--repeats", str(repeats)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
        cwd=str(Path(python).resolve().parents[2]) if "/.venv/" in python else None,
        timeout=600,
    )
    result: dict[str, float] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old-python", required="--worker" not in sys.argv)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cases", nargs="*", default=CASES)
    ap.add_argument("--worker")
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(measure(args.worker, args.repeats)))
        return
    new_python = sys.executable
    print(f"old: {args.old_python}\nnew: {new_python}\nload before: {os.getloadavg()}")
    header = f"{'case':32s} {'old [s]':>9s} {'new [s]':>9s} {'old/new':>8s}   (CPU old, new)"
    print(header)
    for case in args.cases:
        best: dict[str, dict[str, float]] = {}
        for r in range(args.rounds):
            order = [("old", args.old_python), ("new", new_python)]
            for name, py in order if r % 2 == 0 else order[::-1]:
                got = run_worker(py, case, args.repeats)
                prev = best.get(name)
                best[name] = got if prev is None else {k: min(prev[k], got[k]) for k in got}
        o, n = best["old"], best["new"]
        print(
            f"{case:32s} {o['wall']:9.4f} {n['wall']:9.4f} {o['wall'] / n['wall']:7.2f}x"
            f"   ({o['cpu']:.4f}, {n['cpu']:.4f})",
            flush=True,
        )
    print(f"load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
