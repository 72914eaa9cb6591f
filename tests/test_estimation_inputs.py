"""Estimation inputs and outputs: bad documents give clear errors; CLI and blind-area map."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from ris_planner import load_scenario, preset_document
from ris_planner.cli import main
from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.estimation.blind_area import cost_map
from ris_planner.estimation.document import load_simulation
from ris_planner.estimation.montecarlo import run_monte_carlo
from ris_planner.model.simulation import SearchArea


def sim_doc(**parts: Any) -> dict[str, Any]:
    doc = preset_document("paper-table1")
    doc["system"]["noise_figure_db"] = 0.0
    return {"scenario": doc, **parts}


@pytest.mark.parametrize(
    ("parts", "message"),
    [
        (
            {"estimator": {"search_area": {"min_m": [0, 0, 0], "max_m": [1, -1, 1]}}},
            "search area is empty: max_m[1]",
        ),
        ({"estimator": {"search_area": {"half_width_m": [1, -0.5, 1]}}}, "half_width_m"),
        ({"estimator": {"search_area": {"step_m": 0}}}, "step_m"),
        ({"estimator": {"search_area": {"step_m": -0.2}}}, "greater than 0"),
        ({"multipath": {"scatterers": [{"position": [2, 3, 0]}]}}, "lies on the rx"),
        ({"multipath": {"scatterers": [{"position": [-4, 0, 2]}]}}, "lies on the ris 0"),
        (
            {"multipath": {"clusters": [{"center": [-2, -4.5, 0], "radius_m": 1}]}},
            "contains the tx",
        ),
        ({"estimator": {"pair_weights": [0.5, 0.5]}}, "L(L−1)/2 = 1"),
        ({"estimator": {"delay_fft_size": 256}}, "must be ≥ K = 512"),
    ],
)
def test_bad_documents_name_the_problem(parts: dict[str, Any], message: str) -> None:
    with pytest.raises(ValidationError, match=None) as exc:
        load_simulation(sim_doc(**parts))
    assert message in str(exc.value)


def test_bad_scenarios_for_estimation() -> None:
    doc = sim_doc()
    doc["scenario"]["known"] = ["clock"]
    with pytest.raises(ValidationError, match="leave 'known' empty"):
        load_simulation(doc)
    doc = sim_doc()
    doc["scenario"]["system"]["los"] = False
    with pytest.raises(ValidationError, match="at least 3 RISs"):
        load_simulation(doc)
    doc = sim_doc()
    doc["scenario"]["codebook"] = {"kind": "expected_random"}
    with pytest.raises(ValueError, match="expected_random"):
        run_monte_carlo(load_simulation(doc), [30.0], 1)


def test_runner_limits() -> None:
    doc = load_simulation(sim_doc())
    with pytest.raises(LimitExceededError):
        run_monte_carlo(doc, [30.0], 10**7)
    with pytest.raises(RisPlannerError, match="finite dBm"):
        run_monte_carlo(doc, [float("nan")], 1)
    with pytest.raises(LimitExceededError, match="TX candidates"):
        SearchArea(half_width_m=[100, 100, 100], step_m=0.01).candidates(np.zeros(3))


def test_search_grid_includes_corners() -> None:
    grid = SearchArea(half_width_m=[1, 1, 0], step_m=0.2).candidates(np.array([1.0, 2.0, 3.0]))
    assert grid.shape == (121, 3)
    np.testing.assert_allclose(grid.min(axis=0), [0, 1, 3])
    np.testing.assert_allclose(grid.max(axis=0), [2, 3, 3], atol=1e-12)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_simulate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "sim.json"
    f.write_text(json.dumps(sim_doc()))
    code, out, err = run(
        capsys,
        "simulate",
        str(f),
        "--runs",
        "2",
        "--powers-dbm",
        "25,30",
        "--out",
        str(tmp_path / "o"),
        "--seed",
        "3",
    )
    assert code == 0, err
    got = json.loads(out)
    assert got["powers_dbm"] == [25.0, 30.0]
    for key in ("rmse_tx_m", "rmse_rx_m", "rmse_clock_m", "peb_tx_m", "peb_rx_m", "ceb_m"):
        assert len(got[key]) == 2 and all(v > 0 for v in got[key])
    assert set(got["coarse"]) == {"rmse_tx_m", "rmse_rx_m", "rmse_clock_m"}
    assert [c["path"] for c in got["channel"]] == ["los", "ris1", "ris2"]
    assert "simulate [" in err  # progress bar on stderr
    rows = (tmp_path / "o" / "errors.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 2 * 2  # header + powers × runs × (refined, coarse)
    for name in ("rmse_vs_power.png", "channel_rmse_vs_power.png", "rx_error_cdf.png"):
        assert (tmp_path / "o" / name).read_bytes()[:4] == b"\x89PNG"


def test_cli_errors_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "sim.json"
    f.write_text(json.dumps(sim_doc(estimator={"search_area": {"step_m": 0}})))
    code, out, err = run(capsys, "simulate", str(f), "--runs", "1")
    assert code == 2 and out == "" and "estimator.search_area.step_m" in err
    code, _, err = run(capsys, "simulate", "--preset", "paper-table1", "--powers-dbm", "a")
    assert code == 2 and "--powers-dbm" in err and "Traceback" not in err
    code, _, err = run(capsys, "blind-area", "--preset", "paper-table1", "--rx", "1,2")
    assert code == 2 and "--rx" in err
    for step in ("0", "inf", "nan", "-1"):  # checked by the argument parser, one message
        code, _, err = run(capsys, "blind-area", "--preset", "paper-table1", "--step", step)
        assert code == 2 and "--step" in err and "Traceback" not in err


def test_blind_area_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Noise-free: the true TX is a zero-cost global minimum of J; the swapped pair (TX at the
    RX, RX at the TX) gives the same spatial frequencies and delays with LOS, so it is a
    near-zero local minimum too – an inherent ambiguity of sidelink positioning."""
    doc = preset_document("paper-table1")
    doc["tx"] = [-1.0, -1.0, 0.0]
    cmap = cost_map(load_scenario(doc), rx=[-0.6, 2.4, 0.0], step_m=0.05)
    # both the true pair and the swapped pair lie on the grid here: two exact zeros
    zeros = [m for m in cmap.minima if m.cost < 1e-9]
    assert len(zeros) == 2
    for tx, rx in (([-1, -1, 0], [-0.6, 2.4, 0]), ([-0.6, 2.4, 0], [-1, -1, 0])):
        hit = [m for m in zeros if np.allclose(m.tx, tx, atol=1e-9)]
        assert hit and np.allclose(hit[0].rx, rx, atol=1e-9)
        assert abs(hit[0].clock_offset_m - 5.0) < 1e-9
    # every other local minimum costs more (the map separates them)
    assert all(m.cost > 1e-3 for m in cmap.minima[2:])
    f = tmp_path / "d.json"
    f.write_text(json.dumps(doc))
    code, out, err = run(
        capsys, "blind-area", str(f), "--rx", "1.01,1.01,0", "--out", str(tmp_path / "m.png")
    )
    assert code == 0, err
    got = json.loads(out)
    assert got["minima"][0]["cost_m"] < 1e-9
    assert (tmp_path / "m.png").read_bytes()[:4] == b"\x89PNG"


def test_search_box_through_a_ris_is_harmless() -> None:
    """A user box whose grid contains a RIS position: that candidate is inconsistent (inf
    cost, never NaN or a warning) and the estimate still explains the noise-free η exactly.
    (In this larger box the coarse stage lands near a ghost: TX ≈ [−2.32, −1.25, 0.76],
    RX ≈ [2.42, 0.83, 0.78] gives the same η as the truth – 7 equations, 7 unknowns – which is
    why the paper limits the search area with prior information.)"""
    from ris_planner.estimation.blind_area import noise_free_channel
    from ris_planner.estimation.pipeline import Estimator
    from ris_planner.estimation.position_estimation import candidate_costs
    from ris_planner.estimation.signal import (
        noise_free_signal,
        realisation_paths,
        separate_paths,
        signal_setup,
    )

    sim = load_simulation(
        sim_doc(estimator={"search_area": {"min_m": [-4, -5, 0], "max_m": [-1, 0, 2]}})
    )
    setup = signal_setup(sim.scenario)
    cand = sim.estimator.search_area.candidates(sim.scenario.tx_array[0])
    assert np.any(np.all(np.isclose(cand, [-4, 0, 2]), axis=1))  # RIS 1 is on the grid
    on_ris = np.all(np.isclose(cand, [-4, 0, 2]), axis=1)
    channel = noise_free_channel(sim.scenario, sim.scenario.tx_array[0], sim.scenario.rx_array[0])
    costs = candidate_costs(setup.ris, setup.wavelength, channel, cand).cost
    assert np.all(np.isinf(costs[on_ris])) and not np.any(np.isnan(costs))
    paths = realisation_paths(setup, sim.multipath, np.random.default_rng(0))
    fe = Estimator(setup, sim.estimator, cand).estimate(
        separate_paths(setup, noise_free_signal(setup, paths))
    )
    assert np.all(np.isfinite(fe.position_refined.state))
    assert fe.position_refined.cost < 1e-20  # ½‖η̂ − η(ŝ)‖²: an exact fit
