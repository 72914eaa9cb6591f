"""A small street site for the sidelink-pair and district tests: two crossing streets, two
buildings and facade candidates facing the streets (positions in local metres)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.planning.scoring.sparse import DistrictProblem, LayoutState


def street_doc(
    threshold_m: float = 1.0,
    sample: int = 300,
    side: int = 32,
    counts: tuple[int, ...] = (2, 3),
    method: str = "district",
    separation_m: float = 30.0,
    seed: int = 3,
) -> dict[str, Any]:
    """A plan document: 14 facade candidates, UEs on two crossing streets, sidelink pairs at
    most ``separation_m`` apart along the streets, coverage of PEB_R ≤ ``threshold_m``."""
    cands = []
    for x in (-8, -4, 0, 4, 8):
        north = {"position": [x, 4.95, 4], "orientation": [-math.pi / 2, 0, 0], "name": f"N{x}"}
        south = {"position": [x, -4.95, 4], "orientation": [math.pi / 2, 0, 0], "name": f"S{x}"}
        cands += [north, south]
    for y in (8, 12, -8, -12):
        cands.append({"position": [10.05, y, 4], "orientation": [0, 0, 0], "name": f"E{y}"})
    road = {
        "roads": [
            {"points": [[-40, 0], [20, 0], [40, 0]], "width_m": 6, "step_m": 3, "height_m": 1.5},
            {"points": [[20, -40], [20, 0], [20, 40]], "width_m": 6, "step_m": 3, "height_m": 1.5},
        ]
    }
    prism = {"kind": "prism", "base_m": 0, "height_m": 10}
    return {
        "system": {"tx_power_dbm": 30},
        "ris": {"rows": side, "cols": side},
        "environment": {
            "obstacles": [
                {**prism, "name": "north", "footprint": [[-10, 5], [10, 5], [10, 15], [-10, 15]]},
                {
                    **prism,
                    "name": "south",
                    "footprint": [[-10, -15], [10, -15], [10, -5], [-10, -5]],
                },
            ]
        },
        "candidates": cands,
        "tx_map": road,
        "rx_map": road,
        "pairs": {
            "sample": sample,
            "seed": seed,
            "max_separation_m": separation_m,
            "separation": "street",
        },
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": threshold_m},
        "ris_count": list(counts),
        "known": ["height"],
        "search": {"method": method},
    }


def every_layout(problem: DistrictProblem) -> tuple[list[tuple[int, ...]], NDArray[np.bool_]]:
    """The brute-force truth: every layout of the problem's sites (all 2^S, in Gray-code
    order) and, per layout, which pairs it covers ([2^S, P]). One :class:`LayoutState` walks
    the Gray code, putting in or taking out one site per step: each step refreshes the pairs
    that site serves from the layout's members (no running sums), half the time of building
    each layout afresh."""
    n = problem.n_sites
    state = LayoutState(problem)
    covered = np.zeros((2**n, problem.n_pairs), dtype=bool)
    layouts: list[tuple[int, ...]] = [()]
    covered[0] = state.metric <= problem.threshold
    code = 0
    for i in range(1, 2**n):
        site = (i & -i).bit_length() - 1  # the bit that changes from Gray code i − 1 to i
        code ^= 1 << site
        state.set(site, bool(code >> site & 1))
        covered[i] = state.metric <= problem.threshold
        layouts.append(tuple(s for s in range(n) if code >> s & 1))
    return layouts, covered
