"""``compute_bounds(presence=…, channel=False)``, the options the plan's per-point bounds and
codebook checks use (docs/concepts/planning.md, "Pipeline"): the paths handed in are the
ones ``compute_bounds`` finds itself (same process, same code: the same bits), a path taken
away is missing exactly as an obstacle would remove it, and leaving the channel bounds out
leaves the PEBs as they are."""

from __future__ import annotations

import numpy as np
import pytest

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.bounds.compute import scenario_path_presence


def pairs(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    tx = rng.uniform([-8, -8, 0], [8, 8, 2], (n, 3))
    rx = rng.uniform([-8, -8, 0], [8, 8, 2], (n, 3))
    return tx, rx


def test_given_presence_and_no_channel_bounds_keep_the_pebs() -> None:
    scenario = load_scenario(preset_document("paper-table1"))
    tx, rx = pairs()
    ref = compute_bounds(scenario, tx, rx, profiles=None)
    found = scenario_path_presence(scenario, tx, rx)
    got = compute_bounds(scenario, tx, rx, profiles=None, presence=found, channel=False)
    assert got.channel == {}
    for a, b in ((ref.peb_rx, got.peb_rx), (ref.peb_tx, got.peb_tx), (ref.ceb, got.ceb)):
        assert a is not None and b is not None
        np.testing.assert_array_equal(a, b)
    assert list(ref.reason) == list(got.reason)


def test_a_path_taken_away_is_missing() -> None:
    scenario = load_scenario(preset_document("paper-table1"))
    tx, rx = pairs()
    found = scenario_path_presence(scenario, tx, rx)
    off = dict(found)
    off["ris1"] = np.zeros_like(found["ris1"])  # the first RIS serves nobody
    got = compute_bounds(scenario, tx, rx, profiles=None, presence=off, channel=False)
    assert not np.any(got.paths_present["ris1"])
    # the same layout without that RIS, every other path as found
    rest = scenario.model_copy(update={"ris": list(scenario.ris)[1:]})
    fewer = {"los": found["los"]} | {
        f"ris{i}": found[f"ris{i + 1}"] for i in range(1, len(scenario.ris))
    }
    want = compute_bounds(rest, tx, rx, profiles=None, presence=fewer, channel=False)
    finite = np.isfinite(want.peb_rx)
    assert np.array_equal(finite, np.isfinite(got.peb_rx))
    # more unknown blocks with the RIS's path missing: the same information, other rounding
    np.testing.assert_allclose(got.peb_rx[finite], want.peb_rx[finite], rtol=1e-9)


def test_presence_must_name_every_path() -> None:
    scenario = load_scenario(preset_document("paper-table1"))
    tx, rx = pairs(5)
    found = scenario_path_presence(scenario, tx, rx)
    with pytest.raises(ValueError, match="presence must hold"):
        compute_bounds(scenario, tx, rx, presence={"los": found["los"]})
