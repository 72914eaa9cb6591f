"""Benchmark: the Fig. 10 workload (4753 pairs) with ``system.wavefront = "spherical"`` and
100 × 100 RISs (N = 10⁴), ``expected_random``, per layout; and the planar ``random`` layout.

The engine computes the exact per-element terms once per distinct UE position and every
pair's Gram from one matrix product (:func:`ris_planner.physics.spherical.expected_gram`). The naive
reference evaluates each pair on its own (per-element distances and the 7 × 7 Gram summed over
the N elements for that pair, then the same inversion), measured in the same run on a few pairs
and extrapolated to 4753. Targets on the 2-core machine: ≤ 2 s per spherical layout, ≤ 0.1 s
for the planar ``random`` layout.

    python benchmarks/bounds/bench_spherical.py [--naive-pairs 20] [--repeats 3] [--quick]

``--quick``: one layout, one repeat, two naive pairs.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import FIG10_LAYOUTS, fig10_document, fig10_pairs, spherical_document
from harness import median_time

from ris_planner import compute_bounds, load_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--naive-pairs", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="one layout, one repeat, two pairs")
    args = ap.parse_args()
    if args.quick:
        args.naive_pairs, args.repeats = 2, 1
    tx, rx = fig10_pairs()
    print(f"{'layout':8s} {'time [s]':>9s} {'naive (extrap.) [s]':>20s} {'speed-up':>9s}  check")
    for layout in FIG10_LAYOUTS[:1] if args.quick else FIG10_LAYOUTS:
        sc = load_scenario(spherical_document(layout))
        t = median_time(lambda sc=sc: compute_bounds(sc, tx=tx, rx=rx), args.repeats)
        res = compute_bounds(sc, tx=tx, rx=rx)
        t0 = time.perf_counter()
        naive = [compute_bounds(sc, tx=tx[i], rx=rx[i]).peb_rx[0] for i in range(args.naive_pairs)]
        per_pair = (time.perf_counter() - t0) / args.naive_pairs
        diff = np.max(np.abs(np.array(naive) / res.peb_rx[: args.naive_pairs] - 1))
        print(
            f"{layout:8s} {t:9.3f} {per_pair * len(tx):20.1f} {per_pair * len(tx) / t:8.0f}x"
            f"  max rel. diff {diff:.1e}"
        )
    planar = load_scenario(fig10_document("2-ris-L", "random"))
    t = median_time(lambda: compute_bounds(planar, tx=tx, rx=rx), args.repeats if args.quick else 5)
    print(f"planar random 2-ris-L (N = 100), 4753 pairs: {t:.3f} s (target ≤ 0.1 s)")


if __name__ == "__main__":
    main()
