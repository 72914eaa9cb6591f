"""Bounds semantics: known parts, LOS blockage, blind spots, bad input, batching."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydantic import ValidationError
from tolerance import BOUND_ACCURACY, assert_close

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.bounds.compute import (
    REASON_DEGENERATE,
    REASON_UNDERDETERMINED,
    first_block_profiles,
    path_information,
)
from ris_planner.inversion import crb, ldl
from ris_planner.model.scenario import Scenario


def table1(**changes: object) -> dict:  # type: ignore[type-arg]
    doc = preset_document("paper-table1")
    doc.update(changes)
    return doc


def test_known_parts_only_help_and_remove_their_bounds() -> None:
    base = compute_bounds(load_scenario(table1()))
    assert base.peb_tx is not None and base.ceb is not None
    clock = compute_bounds(load_scenario(table1(known=["clock"])))
    assert clock.ceb is None and clock.peb_rx[0] <= base.peb_rx[0]
    height = compute_bounds(load_scenario(table1(known=["height"])))
    assert height.peb_rx[0] <= base.peb_rx[0]
    tx = compute_bounds(load_scenario(table1(known=["tx"])))
    assert tx.peb_tx is None and tx.peb_rx[0] <= base.peb_rx[0]
    out = tx.to_json(batch=False)
    assert out["peb_tx_m"] is None and "known" in out["peb_tx_reason"]


def test_los_blocked_two_ris_is_underdetermined_with_reason() -> None:
    doc = table1()
    doc["system"] = doc["system"] | {"los": False}
    r = compute_bounds(load_scenario(doc))
    assert np.isinf(r.peb_rx[0]) and REASON_UNDERDETERMINED in r.reason[0]
    js = r.to_json(batch=False)
    assert js["peb_rx_m"] is None and REASON_UNDERDETERMINED in js["reason"]
    json.dumps(js, allow_nan=False)  # never NaN/inf in JSON
    # with a known clock, 6 observations for 6 unknowns: localisable
    ok = compute_bounds(load_scenario(doc | {"known": ["clock"]}))
    assert np.isfinite(ok.peb_rx[0])
    # three RISs without LOS: 9 observations for 7 unknowns
    doc3 = preset_document("3-ris")
    doc3["system"] = doc3["system"] | {"los": False}
    assert np.isfinite(compute_bounds(load_scenario(doc3)).peb_rx[0])


def test_single_ris_underdetermined() -> None:
    doc = table1()
    doc["ris"] = doc["ris"][:1]
    r = compute_bounds(load_scenario(doc))
    assert np.isinf(r.peb_rx[0]) and "4 geometric channel parameters for 7" in r.reason[0]


def test_singular_matrix_detected_never_nan() -> None:
    """The one inversion route (crb.crb_diagonal) on hand-made FIMs: a regular one gives its
    exact inverse diagonal; a rank-3 one whose null direction (1, −1, 0, 0) involves only
    states 0 and 1 leaves states 2 and 3 determined (their exact bound 1); zero information
    on one state makes only that state ``inf``. Never NaN."""
    f = np.zeros((3, 4, 4))
    f[0] = np.diag([1.0, 2.0, 3.0, 4.0])
    v = np.array([1.0, 1.0, 0.0, 0.0])
    f[1] = np.outer(v, v) + np.diag([0, 0, 1.0, 1.0])  # rank 3
    f[2] = np.diag([1.0, 0.0, 1.0, 1.0])  # zero information on one state

    def rows(idx: np.ndarray) -> np.ndarray:
        return crb.path_factor(f[idx], np.broadcast_to(np.eye(4), (idx.size, 4, 4)))

    diag, deficient = crb.crb_diagonal(ldl.pack(f), 4, rows)
    assert list(deficient) == [False, True, True]
    np.testing.assert_allclose(diag[:, 0], [1, 0.5, 1 / 3, 0.25], rtol=1e-15)
    assert np.all(np.isinf(diag[:2, 1])) and np.all(np.isinf(diag[1, 2]))
    np.testing.assert_allclose(diag[2:, 1], [1.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(diag[[0, 2, 3], 2], [1.0, 1.0, 1.0], rtol=1e-12)
    assert not np.any(np.isnan(diag))


def test_degenerate_pairs_in_a_batch_get_inf_with_reason() -> None:
    sc = load_scenario("paper-table1")
    tx = np.array([[-2.0, -4, 0], [-4, 0, 2], [1, 1, 0]])
    rx = np.array([[2.0, 3, 0], [2, 3, 0], [1, 1, 0]])
    r = compute_bounds(sc, tx=tx, rx=rx)
    assert np.isfinite(r.peb_rx[0])
    assert np.all(np.isinf(r.peb_rx[1:])) and list(r.reason[1:]) == [REASON_DEGENERATE] * 2
    assert not np.any(np.isnan(r.peb_rx))


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"tx": [float("nan"), 0, 0]}, "tx"),
        ({"rx": [0, float("inf"), 0]}, "rx"),
        ({"tx": [[0, 0, 0], [1, 1, 1]], "rx": [1, 2, 3]}, "tx and rx must hold the same number"),
        ({"tx": [-4, 0, 2]}, "lies on RIS 0"),
        ({"tx": [2, 3, 0]}, "tx equals rx"),
        ({"ris": []}, "ris"),
        ({"known": ["clock", "clock"]}, "twice"),
        ({"known": ["speed"]}, "known"),
        (
            {"codebook": {"kind": "explicit", "phases": [[[0.0] * 100] * 3]}},
            "one phase block per RIS",
        ),
        ({"codebook": {"kind": "explicit", "phases": [[[0.0] * 100] * 3] * 2}}, "64 × 100"),
        ({"codebook": {"kind": "magic"}}, "codebook"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_bad_documents_rejected_with_field(change: dict, field: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ValidationError) as exc:
        Scenario.model_validate(table1(**change))
    assert field in str(exc.value)


@pytest.mark.parametrize(
    ("system", "field"),
    [
        ({"subcarriers": 0}, "subcarriers"),
        ({"transmissions": -1}, "transmissions"),
        ({"bandwidth_hz": 0}, "bandwidth_hz"),
        ({"carrier_hz": -3e9}, "carrier_hz"),
        ({"tx_power_dbm": float("nan")}, "tx_power_dbm"),
        ({"noise_figure_db": -1}, "noise_figure_db"),
        ({"bandwidth_hz": 5e-324}, "bandwidth_hz"),  # Δf, σ² underflow to 0 (found by API fuzz)
        ({"carrier_hz": 1e-310}, "carrier_hz"),  # λ overflows to inf
        ({"bandwidth_hz": 1e300}, "bandwidth_hz"),  # Σω_k² overflows
        ({"carrier_hz": 1e300}, "carrier_hz"),  # k·aperture overflows
    ],
)
def test_bad_system_rejected(system: dict, field: str) -> None:  # type: ignore[type-arg]
    doc = table1()
    doc["system"] = doc["system"] | system
    with pytest.raises(ValidationError) as exc:
        Scenario.model_validate(doc)
    assert field in str(exc.value)


def test_bad_ris_rejected() -> None:
    doc = table1()
    doc["ris"][0] = doc["ris"][0] | {"rows": 0}
    with pytest.raises(ValidationError, match="rows"):
        Scenario.model_validate(doc)
    doc = table1()
    doc["ris"][0] = doc["ris"][0] | {"spacing_m": -0.01}
    with pytest.raises(ValidationError, match="spacing_m"):
        Scenario.model_validate(doc)
    doc["ris"][0] = doc["ris"][0] | {"spacing_m": 3e150}  # overflowed the FIM products (API fuzz)
    with pytest.raises(ValidationError, match="spacing_m"):
        Scenario.model_validate(doc)


def test_too_few_transmissions_for_the_blocks() -> None:
    doc = table1()
    doc["system"] = doc["system"] | {"transmissions": 2}
    with pytest.raises(ValueError, match="L\\+1 = 3"):
        compute_bounds(load_scenario(doc))


def test_array_api_rejects_bad_shapes() -> None:
    sc = load_scenario("paper-table1")
    with pytest.raises(ValueError, match="\\[P, 3\\]"):
        compute_bounds(sc, tx=np.zeros((2, 3)), rx=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="finite"):
        compute_bounds(sc, tx=[np.nan, 0, 0], rx=[1, 1, 1])


def test_far_field_flags() -> None:
    sc = load_scenario("paper-table1")
    r = compute_bounds(sc, tx=[[-3.5, 0, 1.8], [-2, -4, 0]], rx=[[2, 3, 0], [2, 3, 0]])
    assert list(r.far_field[:, 0]) == [False, True]  # 0.54 m from RIS 1: inside 2D²/λ = 1 m rule
    assert r.to_json()["far_field"] == [False, True]


def test_batch_json_lists_in_pair_order() -> None:
    doc = table1(tx=[[-2, -4, 0], [-1, -1, 0]], rx=[[2, 3, 0], [1, 2, 0.5]])
    sc = load_scenario(doc)
    assert sc.is_batch
    js = compute_bounds(sc).to_json(batch=True)
    assert len(js["peb_rx_m"]) == 2 and len(js["channel"][1]["seb_xi"]) == 2
    one = compute_bounds(load_scenario(table1(tx=[-1, -1, 0], rx=[1, 2, 0.5]))).to_json(batch=False)
    assert one["peb_rx_m"] == pytest.approx(js["peb_rx_m"][1], rel=1e-12)


def test_random_codebook_is_reproducible_and_seeded() -> None:
    a = compute_bounds(load_scenario(table1(codebook={"kind": "random", "seed": 3})))
    b = compute_bounds(load_scenario(table1(codebook={"kind": "random", "seed": 3})))
    c = compute_bounds(load_scenario(table1(codebook={"kind": "random", "seed": 4})))
    assert a.peb_rx[0] == b.peb_rx[0] != c.peb_rx[0]


def test_explicit_codebook_equals_random_with_same_phases() -> None:
    rng = np.random.default_rng(0)
    phases = [rng.uniform(0, 2 * np.pi, (64, 100)).tolist() for _ in range(2)]
    e = compute_bounds(load_scenario(table1(codebook={"kind": "explicit", "phases": phases})))
    r = compute_bounds(load_scenario(table1(codebook={"kind": "random", "seed": 0})))
    assert e.peb_rx[0] == pytest.approx(r.peb_rx[0], rel=1e-12)


def test_batch_points_checked_at_once_naming_the_bad_point() -> None:
    """The vectorised point check keeps the single-point messages (the first bad point)."""
    doc = table1()
    doc["tx"], doc["rx"] = [[-2.0, -4.0, 0.0]] * 50, [[2.0, 3.0, 0.0]] * 50
    doc["tx"][37] = [1.0, 2e6, 0.0]
    doc["tx"][40] = [float("nan"), 0.0, 0.0]
    with pytest.raises(ValidationError, match=r"within ±1e\+06 m, got \[1.0, 2000000.0, 0.0\]"):
        Scenario.model_validate(doc)
    doc["tx"][37] = [1.0, 2.0, 0.0]
    with pytest.raises(ValidationError, match=r"finite numbers, got \[nan, 0.0, 0.0\]"):
        Scenario.model_validate(doc)


@pytest.mark.parametrize("codebook", [{"kind": "expected_random"}, {"kind": "random", "seed": 2}])
def test_linear_ris_channel_bounds_keep_delay_and_xi(codebook: dict) -> None:  # type: ignore[type-arg]
    """A one-row RIS cannot observe ζ (its array has no extent along that axis), but its delay
    and ξ are determined: DEB and SEB_ξ are finite and equal the analytic route (the 2 × 2
    (ξ, cτ) block of the EFIM inverted, ζ dropping out: its row and column are zero), SEB_ζ is
    ``inf`` (``null`` in JSON). The square 10 × 10 RIS beside it keeps its three bounds."""
    doc = table1(codebook=codebook)
    doc["ris"][1] = doc["ris"][1] | {"rows": 1, "cols": 64}
    sc = load_scenario(doc)
    res = compute_bounds(sc)
    chan = res.channel["ris2"]
    assert np.isfinite(chan["deb_m"][0]) and np.isfinite(chan["seb_xi"][0])
    assert np.isinf(chan["seb_zeta"][0])
    prof = first_block_profiles(sc)
    paths, _ = path_information(sc, sc.tx_array, sc.rx_array, prof)
    efim = paths[2].efim[0]
    assert np.max(np.abs(efim[1])) <= 1e-12 * np.max(np.abs(efim))
    sub = np.linalg.inv(efim[np.ix_([0, 2], [0, 2])])
    assert_close(chan["seb_xi"][0], np.sqrt(sub[0, 0]), accuracy=BOUND_ACCURACY)
    assert_close(chan["deb_m"][0], np.sqrt(sub[1, 1]), accuracy=BOUND_ACCURACY)
    for name in ("ris1", "los"):
        assert all(np.all(np.isfinite(v)) for v in res.channel[name].values())
    js = res.to_json(batch=False)["channel"][2]
    assert js["path"] == "ris2" and js["seb_zeta"] is None and js["deb_m"] is not None


def test_channel_bounds_unchanged_for_ordinary_ris(rng: np.random.Generator) -> None:
    """Ordinary (two-dimensional) RISs: the DEB/SEBs equal the plain inverse of each path's
    EFIM (numpy's LU, the former whole-matrix route) to the bounds' accuracy, on random
    pairs of the Table I layout with a random and an expected-random codebook."""
    tx, rx = rng.uniform(-4, 4, (20, 3)), rng.uniform(-4, 4, (20, 3))
    tx[:, 2] = rx[:, 2] = 0.0
    for codebook in ({"kind": "expected_random"}, {"kind": "random", "seed": 5}):
        sc = load_scenario(table1(codebook=codebook))
        res = compute_bounds(sc, tx, rx)
        prof = first_block_profiles(sc)
        paths, _ = path_information(sc, tx, rx, prof)
        for p in paths:
            want = np.sqrt(np.diagonal(np.linalg.inv(p.efim), axis1=1, axis2=2))
            got = res.channel[p.name]
            keys = ["deb_m"] if p.name == "los" else ["seb_xi", "seb_zeta", "deb_m"]
            for k, key in enumerate(keys):
                assert_close(got[key], want[:, k], accuracy=BOUND_ACCURACY)
