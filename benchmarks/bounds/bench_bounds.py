"""Benchmark: the Fig. 10 workload (4753 pairs, N = 100, G = 192) per layout.

For each layout and for the ``random`` and ``expected_random`` codebooks, the median wall time of
:func:`ris_planner.compute_bounds` over all 4753 pairs, next to the naive evaluation of eq.
FIM_measurement (tests/naive.py: the full K×G sum for one pair, then the inversion) measured in
the same run on a few pairs and extrapolated to 4753. Targets on the 2-core machine: ≤ 0.1 s per
layout for ``random``, ≤ 0.02 s for ``expected_random``. Old vs new code in the same
run: ``benchmarks/bounds/bench_speed_ab.py``. ``--quick``: one layout, one repeat, one naive
pair.

    python benchmarks/bounds/bench_bounds.py [--naive-pairs 3] [--repeats 7] [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from fixtures import FIG10_LAYOUTS, fig10_document, fig10_pairs
from harness import median_time
from naive import naive_bounds, naive_state_fim

from ris_planner import compute_bounds, load_scenario
from ris_planner.bounds.compute import first_block_profiles
from ris_planner.physics import codebooks


def naive_seconds_per_pair(layout: str, n_pairs: int) -> float:
    sc = load_scenario(fig10_document(layout, None))
    tx, rx = fig10_pairs()
    prof = first_block_profiles(sc)
    assert prof is not None
    b = codebooks.orthogonal_code_matrix(sc.system.transmissions, len(sc.ris))
    full = [codebooks.expand_profiles(prof[i], b[:, i + 1]) for i in range(len(sc.ris))]
    t0 = time.perf_counter()
    for i in range(n_pairs):
        f = naive_state_fim(sc, tx[i], rx[i], full, np.ones(sc.system.transmissions))
        naive_bounds(f, list(range(7)))
    return (time.perf_counter() - t0) / n_pairs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--naive-pairs", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--quick", action="store_true", help="one layout, one repeat, one pair")
    args = parser.parse_args()
    layouts = FIG10_LAYOUTS[:1] if args.quick else FIG10_LAYOUTS
    if args.quick:
        args.repeats, args.naive_pairs = 1, 1
    tx, rx = fig10_pairs()
    header = ("layout", "codebook", "time [s]", "naive (extrap.) [s]", "speed-up")
    print(f"{header[0]:8s} {header[1]:16s} {header[2]:>9s} {header[3]:>20s} {header[4]:>9s}")
    for layout in layouts:
        naive_total = naive_seconds_per_pair(layout, args.naive_pairs) * len(tx)
        for kind in ("random", "expected_random"):
            sc = load_scenario(fig10_document(layout, kind))
            t = median_time(lambda sc=sc: compute_bounds(sc, tx=tx, rx=rx), args.repeats)
            print(f"{layout:8s} {kind:16s} {t:9.4f} {naive_total:20.1f} {naive_total / t:9.0f}x")


if __name__ == "__main__":
    main()
