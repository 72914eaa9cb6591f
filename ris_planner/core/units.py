"""Unit conversions and physical constants (the only place where dB/dBm meet watts).

SI inside the package; anything else carries its unit in the name (``tx_power_dbm``,
``noise_figure_db``) and is converted here, at the boundary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

SPEED_OF_LIGHT = 299_792_458.0
"""c in m/s."""


def db_to_linear(value_db: ArrayLike) -> NDArray[np.float64]:
    """10^(x/10): a power ratio in dB to linear."""
    return np.power(10.0, np.asarray(value_db, dtype=float) / 10.0)


def dbm_to_watt(value_dbm: ArrayLike) -> NDArray[np.float64]:
    """A power (or a PSD, per Hz) in dBm to watts (W/Hz)."""
    return np.power(10.0, (np.asarray(value_dbm, dtype=float) - 30.0) / 10.0)


def watt_to_dbm(value_w: ArrayLike) -> NDArray[np.float64]:
    """Watts to dBm."""
    return 10.0 * np.log10(np.asarray(value_w, dtype=float)) + 30.0
