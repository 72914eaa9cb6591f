"""Expected-random optimism: PEB_R of the expected FIM (``expected_random``, the planning
default) against the mean PEB_R of seeded ``random`` codebooks, as a function of G/Γ.

By Jensen the CRB of the expected FIM is below the expected CRB; the gap shrinks as G/Γ (beams
per RIS and block) grows. For each G/Γ this prints, over a sample of Fig. 10 pairs with the
2-RIS L layout (P = 30 dBm, NF 10 dB), the median and 90th percentile over pairs of
mean_seeds(PEB_R random) / PEB_R expected, and the smallest G/Γ whose median stays ≤ 1.10
(``ris_planner.bounds.advice.EXPECTED_RANDOM_MIN_BLOCK`` is set from it).

    python examples/codebook_optimism.py [--seeds 20] [--pairs 200]
"""

from __future__ import annotations

import argparse

import numpy as np

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.model.paper import fig10_pairs

BLOCKS = (1, 2, 4, 8, 16, 32, 64)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument("--layout", default="2-ris-L")
    ap.add_argument("--smoke", action="store_true", help="2 seeds, 20 pairs, G/Γ ≤ 4")
    args = ap.parse_args()
    blocks: tuple[int, ...] = BLOCKS
    if args.smoke:
        args.seeds, args.pairs, blocks = 2, 20, BLOCKS[:3]
    tx, rx = fig10_pairs()
    pick = np.random.default_rng(0).choice(len(tx), args.pairs, replace=False)
    tx, rx = tx[pick], rx[pick]
    base = preset_document(args.layout)
    n_ris = len(base["ris"])
    gamma = n_ris + (1 if base["system"].get("los", True) else 0)
    print(f"{args.layout}: Γ = {gamma}, {args.pairs} pairs, {args.seeds} seeds")
    print("G/Γ   G    median ratio   p90 ratio")
    first_ok = None
    for g_tilde in blocks:
        system = base["system"] | {"transmissions": gamma * g_tilde}
        exp = compute_bounds(
            load_scenario(base | {"system": system, "codebook": {"kind": "expected_random"}}),
            tx=tx,
            rx=rx,
        ).peb_rx
        rand = np.array(
            [
                compute_bounds(
                    load_scenario(
                        base | {"system": system, "codebook": {"kind": "random", "seed": s}}
                    ),
                    tx=tx,
                    rx=rx,
                ).peb_rx
                for s in range(args.seeds)
            ]
        )
        # a seed whose codebook leaves a pair singular counts as an infinite ratio
        ok = np.isfinite(exp)
        ratio = rand[:, ok].mean(axis=0) / exp[ok]
        med, p90 = np.median(ratio), np.quantile(ratio, 0.9, method="higher")
        if first_ok is None and med <= 1.10:
            first_ok = g_tilde
        print(f"{g_tilde:3d} {gamma * g_tilde:4d}   {med:10.3f}   {p90:9.3f}")
    print(f"smallest G/Γ with median optimism ≤ 10 %: {first_ok}")


if __name__ == "__main__":
    main()
