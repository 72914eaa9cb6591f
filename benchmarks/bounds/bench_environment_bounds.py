"""Benchmark: what an environment adds to :func:`ris_planner.compute_bounds` on the Fig. 10
workload (4753 pairs, 4 RISs, N = 100, G = 192).

The same pairs and layout with and without an environment of ``--prisms`` random 0.6–1.2 m
pillars (UEs inside them have their legs blocked; the scenario document would reject them,
the array API scores them), median wall time of each, the share of the visibility
(:func:`ris_planner.bounds.compute.scenario_path_presence`) and the ratio to free space, for the
``random`` and ``expected_random`` codebooks. The masking itself is one ``np.where`` per path.

    python benchmarks/bounds/bench_environment_bounds.py [--prisms 10] [--repeats 5] [--quick]

``--quick``: one repeat.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import fig10_document, fig10_pairs
from harness import median_time

from ris_planner import compute_bounds, load_scenario
from ris_planner.bounds.compute import scenario_path_presence


def pillars(n: int, rng: np.random.Generator, keep_clear: np.ndarray) -> list[dict[str, Any]]:
    """n square pillars (half-width 0.3–0.6 m) at least 2 m from the points ``keep_clear``."""
    out: list[dict[str, Any]] = []
    while len(out) < n:
        c = rng.uniform(-5, 5, 2)
        if np.min(np.linalg.norm(keep_clear[:, :2] - c, axis=1)) < 2.0:
            continue
        i = len(out)
        h = rng.uniform(0.3, 0.6)
        square = [[c[0] - h, c[1] - h], [c[0] + h, c[1] - h], [c[0] + h, c[1] + h]]
        out.append(
            {
                "kind": "prism",
                "name": f"p{i}",
                "footprint": [*square, [c[0] - h, c[1] + h]],
                "height_m": float(rng.uniform(1, 4)),
            }
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prisms", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="one repeat")
    args = parser.parse_args()
    if args.quick:
        args.repeats = 1
    tx, rx = fig10_pairs()
    rng = np.random.default_rng(0)
    layout = fig10_document("4-ris")
    fixed = np.array([r["position"] for r in layout["ris"]] + [layout["tx"], layout["rx"]])
    env = {"obstacles": pillars(args.prisms, rng, fixed)}
    print(f"{len(tx)} pairs, 4-ris, {args.prisms} prisms")
    for kind in ("random", "expected_random"):
        doc = fig10_document("4-ris", kind)
        free = load_scenario(doc)
        site = load_scenario(doc | {"environment": env})
        t_free = median_time(lambda sc=free: compute_bounds(sc, tx=tx, rx=rx), args.repeats)
        t_env = median_time(lambda sc=site: compute_bounds(sc, tx=tx, rx=rx), args.repeats)
        t_vis = median_time(lambda sc=site: scenario_path_presence(sc, tx, rx), args.repeats)
        res = compute_bounds(site, tx=tx, rx=rx)
        present = np.mean([v.mean() for v in res.paths_present.values()])
        print(
            f"{kind:16s} free {t_free:.3f} s  environment {t_env:.3f} s"
            f" (visibility {t_vis:.3f} s)  ratio {t_env / t_free:.2f}"
            f"  paths present {100 * present:.0f} %"
        )


if __name__ == "__main__":
    main()
