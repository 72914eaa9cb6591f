"""Shared fixtures: small random scenarios for checks against the naive reference."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tolerance import fim_cond, rtol

sys.path.insert(0, str(Path(__file__).parent))


INVERSION_ULPS = 45.0
"""The bounds agree to max(floor, 45 ulps · cond) (tests/tolerance.py's rule, 1e-14 · cond): a
backward-stable inversion of a matrix with (unit-diagonal) condition number cond loses about
cond·ε of relative accuracy, and random small scenarios include near-blind geometries."""


def bounds_rtol(f: np.ndarray, floor: float) -> float:
    """Relative tolerance for bounds computed from the FIM f by two rounding-different routes."""
    return max(floor, rtol(INVERSION_ULPS, fim_cond(f)))


def small_scenario_doc(
    rng: np.random.Generator, n_ris: int = 2, los: bool = True
) -> dict[str, Any]:
    """A small random scenario (K=16, G=12, 3×4 RISs) that the naive K×G sum handles fast."""
    ris = []
    for _ in range(n_ris):
        pos = rng.uniform(-5, 5, 3)
        pos[2] = rng.uniform(1.5, 3)
        ris.append(
            {
                "position": pos.tolist(),
                "orientation": rng.uniform(-np.pi, np.pi, 3).tolist(),
                "rows": 3,
                "cols": 4,
                # random orientations put UEs behind RISs: these scenarios test the measurement
                # model of every path, so the field of view admits the whole sphere
                "max_angle_deg": 180,
            }
        )
    return {
        "system": {
            "subcarriers": 16,
            "transmissions": 12,
            "noise_figure_db": float(rng.uniform(0, 10)),
            "tx_power_dbm": float(rng.uniform(10, 40)),
            "clock_offset_m": float(rng.uniform(-10, 10)),
            "los": los,
        },
        "ris": ris,
        "tx": rng.uniform(-3, 3, 3).tolist(),
        "rx": rng.uniform(-3, 3, 3).tolist(),
        "codebook": {"kind": "random", "seed": int(rng.integers(1000))},
    }


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)
