"""Benchmark: the Fig. 10 workload (4753 pairs) with ``system.wavefront = "spherical"`` and
100 × 100 RISs (N = 10⁴), ``expected_random``, per layout; and the planar ``random`` layout.

The engine computes the exact per-element terms once per distinct UE position and every
pair's Gram from one matrix product (:func:`ris_planner.physics.spherical.expected_gram`). The naive
reference evaluates each pair on its own (per-element distances and the 7 × 7 Gram summed over
the N elements for that pair, then the same inversion), measured in the same run on a few pairs
and extrapolated to 4753. Targets on the 2-core machine: ≤ 2 s per spherical layout, ≤ 0.1 s
for the planar ``random`` layout.

    python benchmarks/bench_spherical.py [--naive-pairs 20] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from timing import median_time  # the script's folder is on sys.path

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.model.paper import fig10_pairs

LAYOUTS = ("2-ris-L", "2-ris-P", "3-ris", "4-ris")


def spherical_doc(layout: str) -> dict[str, Any]:
    doc = preset_document(layout)
    doc["ris"] = [r | {"rows": 100, "cols": 100} for r in doc["ris"]]
    doc["system"] = doc["system"] | {"wavefront": "spherical"}
    return doc | {"codebook": {"kind": "expected_random"}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--naive-pairs", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    tx, rx = fig10_pairs()
    print(f"{'layout':8s} {'time [s]':>9s} {'naive (extrap.) [s]':>20s} {'speed-up':>9s}  check")
    for layout in LAYOUTS:
        sc = load_scenario(spherical_doc(layout))
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
    planar = load_scenario(preset_document("2-ris-L") | {"codebook": {"kind": "random"}})
    t = median_time(lambda: compute_bounds(planar, tx=tx, rx=rx), 5)
    print(f"planar random 2-ris-L (N = 100), 4753 pairs: {t:.3f} s (target ≤ 0.1 s)")


if __name__ == "__main__":
    main()
