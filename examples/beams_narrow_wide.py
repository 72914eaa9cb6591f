"""Designed beams against random codebooks on a narrow and a wide UE map (the
paper's Fig. 5 trend over the prior's spread), the four Fig. 10 anchors as candidates.

    python examples/beams_narrow_wide.py [--positions 32] [--seeds 3]

Prints, per map, objective and RIS count, the plan objective of the best layout on all pairs
for every beam design (expected_random, random over seeds, DIR, DIR+DER uniform / γ_P / SDP)
and the SDP's design-position objectives.
"""

from __future__ import annotations

import argparse
from typing import Any

from ris_planner.planning import SerialExecutor, plan_preset, run_plan

NARROW_TX = {"grid": {"x": [-2.1, -1.9, 0.1], "y": [-2.1, -1.9, 0.1], "z": [0, 0, 1]}}
NARROW_RX = {"grid": {"x": [1.4, 1.6, 0.1], "y": [1.9, 2.1, 0.1], "z": [0, 0, 1]}}
WIDE = {"grid": {"x": [-3.5, 3.5, 1.0], "y": [-3.5, 3.5, 1.0], "z": [0, 0, 1]}}
OBJECTIVES = ({"kind": "mean_capped", "cap_m": 1.0}, {"kind": "quantile", "q": 0.5})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--positions", type=int, default=32)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument(
        "--smoke", action="store_true", help="one objective, the narrow maps, 4 positions"
    )
    args = ap.parse_args()
    objectives: tuple[dict[str, object], ...] = OBJECTIVES
    maps: tuple[tuple[str, dict[str, Any], dict[str, Any]], ...] = (
        ("narrow", NARROW_TX, NARROW_RX),
        ("wide", WIDE, WIDE),
    )
    if args.smoke:
        args.positions, args.seeds, objectives, maps = 4, 1, OBJECTIVES[:1], maps[:1]
    base = plan_preset("fig10-anchors")
    for obj in objectives:
        for name, tx_map, rx_map in maps:
            doc: dict[str, Any] = {k: base[k] for k in ("system", "ris", "candidates")}
            doc |= {
                "tx_map": tx_map,
                "rx_map": rx_map,
                "pairs": "all",
                "objective": obj,
                "ris_count": [2, 4],
                "beams": {"design_positions": args.positions, "random_seeds": args.seeds},
            }
            plan = run_plan(doc, executor=SerialExecutor()).to_json()
            for entry in plan["by_count"]:
                b = entry["beams"]
                vals = {k: round(v, 4) for k, v in b["objective"].items() if v is not None}
                print(f"{obj['kind']:11s} {name:6s} L={entry['ris_count']} {vals}")
                print(f"{'':21s} γ_P {b['gamma_p']:.2f}  design m²: {b['design_objective_m2']}")


if __name__ == "__main__":
    main()
