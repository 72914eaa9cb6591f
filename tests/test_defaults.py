"""One source for Table I: the document models' defaults are the paper's Table I, and every
shipped preset holds only what it overrides (docs/concepts/conventions.md, "Defaults")."""

from __future__ import annotations

import json
from importlib import resources
from typing import Any

import pytest

from ris_planner.model.plan import PlanDocument
from ris_planner.model.scenario import PRESET_NAMES, RIS, SystemParams, load_scenario

# the paper's Table I ("Default Simulation Parameters"), transcribed from the paper itself
TABLE_I = {
    "carrier_hz": 30e9,
    "bandwidth_hz": 400e6,
    "transmissions": 192,
    "subcarriers": 512,
    "clock_offset_m": 5.0,
    "tx_power_dbm": 30.0,
    "noise_psd_dbm_hz": -173.855,
    "noise_figure_db": 10.0,
}


def test_system_defaults_are_table_i() -> None:
    system = SystemParams()
    for name, value in TABLE_I.items():
        assert getattr(system, name) == value, name  # exact: parsed decimal literals
    assert (RIS.model_fields["rows"].default, RIS.model_fields["cols"].default) == (10, 10)


def shipped_presets() -> list[tuple[str, dict[str, Any]]]:
    root = resources.files("ris_planner.model.presets")
    found = [
        (f"{n}.json", json.loads(root.joinpath(f"{n}.json").read_text())) for n in PRESET_NAMES
    ]
    plans = root.joinpath("plans")
    found += [
        (f"plans/{f.name}", json.loads(f.read_text()))
        for f in plans.iterdir()
        if f.name.endswith(".json")
    ]
    return found


@pytest.mark.parametrize(
    ("name", "document"), shipped_presets(), ids=lambda v: v if isinstance(v, str) else ""
)
def test_presets_hold_overrides_only(name: str, document: dict[str, Any]) -> None:
    defaults = SystemParams().model_dump()
    repeated = {k: v for k, v in document.get("system", {}).items() if defaults.get(k) == v}
    assert repeated == {}, f"{name} repeats Table I defaults {repeated}: drop them"
    if not name.startswith("plans/"):
        for ris in document["ris"]:
            assert "rows" not in ris or ris["rows"] != 10, name
            assert "cols" not in ris or ris["cols"] != 10, name
    # and what is left is a valid document of its kind
    if name.startswith("plans/"):
        PlanDocument.model_validate(document)
    else:
        load_scenario(document)


def test_the_check_sees_a_repeated_default() -> None:
    """The rule can fail: a preset that copies Table I's carrier is caught."""
    defaults = SystemParams().model_dump()
    copied = {"system": {"carrier_hz": 30e9, "tx_power_dbm": 20}}
    assert {k for k, v in copied["system"].items() if defaults.get(k) == v} == {"carrier_hz"}
