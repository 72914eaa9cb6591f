"""ris_planner: planning RIS deployments for base-station-free 3D sidelink positioning.

Public surface (batch scripts)::

    import ris_planner as rp
    sc = rp.load_scenario("paper-table1")          # preset name, JSON path, dict or Scenario
    res = rp.compute_bounds(sc, tx=tx_array, rx=rx_array)   # [P, 3] arrays, no JSON
    res.peb_rx, res.peb_tx, res.ceb                 # numpy arrays in pair order
"""

from ris_planner.bounds.compute import BoundsResult, compute_bounds
from ris_planner.model.scenario import (
    PRESET_NAMES,
    RIS,
    Scenario,
    SystemParams,
    load_scenario,
    preset_document,
)

__all__ = [
    "PRESET_NAMES",
    "RIS",
    "BoundsResult",
    "Scenario",
    "SystemParams",
    "compute_bounds",
    "load_scenario",
    "preset_document",
]
