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


def _full_route(scenario, tx, rx, presence, profiles):  # type: ignore[no-untyped-def]
    """The bounds before the present-pairs routes: every pair's codebook products, every pair
    inverted, the settled pairs overwritten afterwards (what compute_bounds did)."""
    from ris_planner.bounds.compute import (
        bounds_from_paths,
        masked_state_information,
        n_observations,
        path_information,
        present_path_mask,
    )

    paths, _ = path_information(scenario, tx, rx, profiles)
    mask = present_path_mask(paths, presence)
    n_obs = n_observations(len(scenario.ris), scenario.system.los, scenario.system.wavefront)
    return bounds_from_paths(paths, (), n_obs, mask, lambda: masked_state_information(paths, mask))


@pytest.mark.parametrize(
    ("preset", "wavefront"),
    [("paper-table1", "planar"), ("4-ris", "planar"), ("paper-table1", "spherical")],
)
def test_codebook_products_of_present_pairs_only_keep_the_bounds(
    preset: str, wavefront: str
) -> None:
    """A random codebook's products are formed for the pairs a RIS serves only (the cost of a
    plan's codebook checks in a blind area); a missing pair carries a stand-in that nothing
    reads. Against the full route of every pair: the same PEBs and CEB to the bounds'
    accuracy, the same inf pattern (the settled pairs cost nothing and are inf)."""
    from tolerance import BOUND_ACCURACY, assert_close

    from ris_planner.bounds.compute import _codebook_profiles

    scenario = load_scenario(preset_document(preset))
    system = scenario.system.model_copy(update={"wavefront": wavefront})
    scenario = scenario.model_copy(update={"system": system})
    tx, rx = pairs(60)
    found = scenario_path_presence(scenario, tx, rx)
    rng = np.random.default_rng(11)
    # about a third of each RIS path missing, as blockage would remove it
    given = {k: v & (rng.random(v.size) > 0.35) if k != "los" else v for k, v in found.items()}
    profiles = _codebook_profiles(scenario)
    assert profiles is not None  # a random codebook: products per pair
    got = compute_bounds(scenario, tx, rx, presence=given, channel=False)
    want_tx, want_rx, want_ceb, _ = _full_route(scenario, tx, rx, given, profiles)
    settled = ~np.isfinite(got.peb_rx)
    assert settled.any() and (~settled).any()  # both kinds of pair occur
    for g, w in ((got.peb_rx, want_rx), (got.peb_tx, want_tx), (got.ceb, want_ceb)):
        assert g is not None and w is not None
        live = np.isfinite(w) & ~settled
        assert_close(g[live], w[live], accuracy=BOUND_ACCURACY)
    # a settled pair is underdetermined by its paths (a reason) or the full route's inf
    for i in np.flatnonzero(settled):
        assert got.reason[i] is not None or not np.isfinite(want_rx[i])


def test_settled_pairs_withhold_their_information_only() -> None:
    """Without the channel bounds, a pair the counting rule settles (too few paths present) or
    a degenerate pair gets no codebook products: its information is NaN (never a stand-in's
    finite number), its bounds inf with a reason; every other pair's information is the one
    the full call forms, to the bounds' accuracy."""
    from tolerance import BOUND_ACCURACY, assert_close

    scenario = load_scenario(preset_document("paper-table1"))
    tx, rx = pairs(60)
    rx[0] = tx[0]  # TX = RX: degenerate
    found = scenario_path_presence(scenario, tx, rx)
    rng = np.random.default_rng(2)
    given = {k: v & (rng.random(v.size) > 0.4) if k != "los" else v for k, v in found.items()}
    full = compute_bounds(scenario, tx, rx, presence=given)
    lean = compute_bounds(scenario, tx, rx, presence=given, channel=False)
    withheld = np.isnan(lean.fim).any(axis=(1, 2))
    assert withheld[0] and withheld.any() and (~withheld).any()
    assert np.all(np.isinf(lean.peb_rx[withheld])) and all(lean.reason[withheld] != None)  # noqa: E711
    assert np.all(np.isfinite(full.fim[withheld]))  # the full call forms them
    assert_close(lean.fim[~withheld], full.fim[~withheld], accuracy=BOUND_ACCURACY)
    np.testing.assert_array_equal(np.isinf(lean.peb_rx), np.isinf(full.peb_rx))


def test_unique_rows_is_numpys_unique_by_rows() -> None:
    from ris_planner.bounds.compute import unique_rows

    rng = np.random.default_rng(5)
    for k in (1, 2, 5, 9, 63, 64):
        flags = rng.random((500, k)) < 0.3
        want, inverse = np.unique(flags, axis=0, return_inverse=True)
        got, got_inverse = unique_rows(flags)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(got_inverse, inverse.ravel())


def test_per_pair_presence_is_path_presence_pair_by_pair() -> None:
    """:func:`path_presence_per_pair` (every pair its own RISs, one visibility query) answers
    as :func:`path_presence` called pair by pair with that pair's RISs, on the street site's
    buildings, with paths both blocked and clear among the answers; :func:`serves_each` as
    the rule itself point by point (in the RIS's field of view and the leg to its centre
    clear, one :meth:`Scene.blocked` query per point)."""
    from district_site import street_doc

    from ris_planner.bounds.paths import (
        in_field_of_view,
        path_presence,
        path_presence_per_pair,
        serves_each,
    )
    from ris_planner.environment.scene import Scene
    from ris_planner.planning.prepare import prepare_plan

    inputs = prepare_plan(street_doc())
    scene = Scene.from_environment(inputs.document.environment)
    rises = [s.ris for s in inputs.sites]
    rng = np.random.default_rng(5)
    pick = rng.choice(inputs.pairs.tx.shape[0], 60, replace=False)
    tx, rx = inputs.pairs.tx[pick], inputs.pairs.rx[pick]
    slots = rng.integers(0, len(rises), (pick.size, 4))
    got = path_presence_per_pair(scene, rises, slots, tx, rx, los=True)
    for p in range(pick.size):
        want = path_presence(scene, [rises[j] for j in slots[p]], tx[[p]], rx[[p]], los=True)
        assert {k: bool(v[p]) for k, v in got.items()} == {k: bool(v[0]) for k, v in want.items()}
    ris_paths = np.stack([got[f"ris{j + 1}"] for j in range(4)])
    assert ris_paths.any() and not ris_paths.all()
    which = rng.integers(0, len(rises), 200)
    points = np.concatenate([tx, rx, tx, rx])[rng.integers(0, 4 * pick.size, 200)]
    each = serves_each(scene, rises, which, points)
    assert each.any() and not each.all()
    for k in range(200):
        ris = rises[which[k]]
        clear = not scene.blocked(points[[k]], np.array([ris.position], dtype=float))[0]
        assert each[k] == (bool(in_field_of_view(ris, points[[k]])[0]) and clear), k
