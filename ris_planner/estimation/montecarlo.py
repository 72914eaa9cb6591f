"""Monte-Carlo runner: RMSE of the two-stage estimator against the CRB over a power sweep.

Every run draws, from its own seed ``[seed, run]`` (the same across powers: common random
numbers make the curves smooth), the gain phases, the scattering points of the clusters and
the noise; the profiles are the scenario's codebook (the ones the bounds use).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import compute_bounds
from ris_planner.core.errors import LimitExceededError, RisPlannerError
from ris_planner.core.io_json import finite_or_none
from ris_planner.estimation.channel_estimation import ChannelEstimate, wrap
from ris_planner.estimation.document import SimulationDocument
from ris_planner.estimation.pipeline import Estimator
from ris_planner.estimation.position_estimation import EstimationError
from ris_planner.estimation.signal import (
    Paths,
    SignalSetup,
    realisation_paths,
    received_signal,
    separate_paths,
    signal_setup,
)
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]

MAX_RUNS = 100_000
"""Runs per power above this are refused (a run takes ~10 ms: this is already hours)."""
MAX_POWERS = 200


@dataclass(frozen=True)
class RunsAtPower:
    """Errors of every run at one power: state errors [runs, 7] (NaN = failed run), channel
    errors [runs, m] in the order of ``channel_names``, and the bounds."""

    power_dbm: float
    refined: FloatArray
    coarse: FloatArray
    channel_refined: FloatArray
    channel_coarse: FloatArray
    channel_names: tuple[str, ...]
    peb_tx: float
    peb_rx: float
    ceb: float
    channel_bounds: dict[str, float]
    seconds_per_run: float
    failures: int

    def rmse(self, which: str = "refined") -> tuple[float, float, float]:
        """(RMSE p_T, RMSE p_R, RMSE B) over the successful runs [m]."""
        e = self.refined if which == "refined" else self.coarse
        ok = np.all(np.isfinite(e), axis=1)
        if not np.any(ok):
            return float("nan"), float("nan"), float("nan")
        e = e[ok]
        return (
            float(np.sqrt(np.mean(np.sum(e[:, 0:3] ** 2, axis=1)))),
            float(np.sqrt(np.mean(np.sum(e[:, 3:6] ** 2, axis=1)))),
            float(np.sqrt(np.mean(e[:, 6] ** 2))),
        )

    def rx_errors(self, which: str = "refined") -> FloatArray:
        """‖p̂_R − p_R‖ per run [m] (inf for failed runs), for CDFs."""
        e = self.refined if which == "refined" else self.coarse
        err = np.linalg.norm(e[:, 3:6], axis=1)
        return np.asarray(np.where(np.isfinite(err), err, np.inf))


@dataclass(frozen=True)
class MonteCarloResult:
    powers: list[RunsAtPower]
    runs: int
    seed: int
    multipath: bool
    sigma: str
    meta: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary (``null`` where no run succeeded or a bound is infinite)."""
        ref = [p.rmse("refined") for p in self.powers]
        coa = [p.rmse("coarse") for p in self.powers]
        channel: list[dict[str, Any]] = []
        names = self.powers[0].channel_names if self.powers else ()
        for j, name in enumerate(names):
            path, param = name.split(":")
            entry = next((c for c in channel if c["path"] == path), None)
            if entry is None:
                entry = {"path": path}
                channel.append(entry)
            bound_key = BOUND_KEYS[param]
            unit = "_m" if param == "delay" else ""
            entry[f"rmse_{param}{unit}"] = [
                finite_or_none(rmse(p.channel_refined[:, j])) for p in self.powers
            ]
            entry[f"coarse_rmse_{param}{unit}"] = [
                finite_or_none(rmse(p.channel_coarse[:, j])) for p in self.powers
            ]
            entry[bound_key] = [finite_or_none(p.channel_bounds[name]) for p in self.powers]
        return {
            "powers_dbm": [p.power_dbm for p in self.powers],
            "runs": self.runs,
            "seed": self.seed,
            "multipath": self.multipath,
            "sigma": self.sigma,
            "rmse_tx_m": [finite_or_none(r[0]) for r in ref],
            "rmse_rx_m": [finite_or_none(r[1]) for r in ref],
            "rmse_clock_m": [finite_or_none(r[2]) for r in ref],
            "peb_tx_m": [finite_or_none(p.peb_tx) for p in self.powers],
            "peb_rx_m": [finite_or_none(p.peb_rx) for p in self.powers],
            "ceb_m": [finite_or_none(p.ceb) for p in self.powers],
            "coarse": {
                "rmse_tx_m": [finite_or_none(r[0]) for r in coa],
                "rmse_rx_m": [finite_or_none(r[1]) for r in coa],
                "rmse_clock_m": [finite_or_none(r[2]) for r in coa],
            },
            "channel": channel,
            "failures": [p.failures for p in self.powers],
            "seconds_per_run": [p.seconds_per_run for p in self.powers],
            **self.meta,
        }


BOUND_KEYS = {"delay": "deb_m", "xi": "seb_xi", "zeta": "seb_zeta"}
"""The core's channel-bound key (``BoundsResult.channel``) of each channel parameter."""


def rmse(e: FloatArray) -> float:
    """Root mean square over the finite entries (failed runs are NaN); NaN if none."""
    ok = np.isfinite(e)
    return float(np.sqrt(np.mean(e[ok] ** 2))) if np.any(ok) else float("nan")


def _channel_names(setup: SignalSetup) -> tuple[str, ...]:
    names = ["los:delay"] if setup.los else []
    for i in setup.ris_present:
        names += [f"ris{i + 1}:xi", f"ris{i + 1}:zeta", f"ris{i + 1}:delay"]
    return tuple(names)


def channel_errors(setup: SignalSetup, est: ChannelEstimate, truth: Paths) -> FloatArray:
    """Errors of (cτ0, (ξ, ζ, cτ)_ℓ) against the direct paths present, ξ/ζ modulo their
    period."""
    direct_len = truth.length[truth.direct]
    direct_ris = truth.ris[truth.direct]
    out = []
    period_r = setup.delay_period_m
    if setup.los:
        out.append(wrap(est.length[0] - direct_len[direct_ris == 0][0], period_r))
    for i in setup.ris_present:
        arr = setup.ris[i]
        k = int(np.flatnonzero(truth.direct & (truth.ris == i + 1))[0])
        per = arr.period(setup.wavelength)
        out += [
            wrap(est.xi[i] - truth.xi[k], per),
            wrap(est.zeta[i] - truth.zeta[k], per),
            wrap(est.length[i + 1] - truth.length[k], period_r),
        ]
    return np.asarray(out, dtype=float)


def _state_error(setup: SignalSetup, state: FloatArray) -> FloatArray:
    sc = setup.scenario
    truth = np.concatenate([sc.tx_array[0], sc.rx_array[0], [sc.system.clock_offset_m]])
    err = state - truth
    err[6] = wrap(err[6], setup.delay_period_m)  # B is identifiable modulo c/Δf
    return err


def run_at_power(
    doc: SimulationDocument,
    power_dbm: float,
    runs: int,
    seed: int,
    progress: ProgressCallback = no_progress,
) -> RunsAtPower:
    """``runs`` realisations at one transmit power."""
    system = doc.scenario.system.model_copy(update={"tx_power_dbm": float(power_dbm)})
    scenario = doc.scenario.model_copy(update={"system": system})
    setup = signal_setup(scenario)
    est = Estimator(
        setup, doc.estimator, doc.estimator.search_area.candidates(scenario.tx_array[0])
    )
    bounds = compute_bounds(scenario)
    names = _channel_names(setup)
    chan_bounds: dict[str, float] = {}
    for name in names:
        path, param = name.split(":")
        key = BOUND_KEYS[param]
        chan_bounds[name] = float(bounds.channel[path][key][0])
    refined = np.full((runs, 7), np.nan)
    coarse = np.full((runs, 7), np.nan)
    ch_ref = np.full((runs, len(names)), np.nan)
    ch_coa = np.full((runs, len(names)), np.nan)
    failures = 0
    seconds = 0.0
    for run in range(runs):
        rng = np.random.default_rng([seed, run])
        paths = realisation_paths(setup, doc.multipath, rng)
        ytilde = separate_paths(setup, received_signal(setup, paths, rng))
        try:
            fe = est.estimate(ytilde)
        except EstimationError:
            failures += 1
        else:
            seconds += sum(fe.seconds.values())
            refined[run] = _state_error(setup, fe.position_refined.state)
            coarse[run] = _state_error(setup, fe.position_coarse.state)
            ch_ref[run] = channel_errors(setup, fe.channel_refined, paths)
            ch_coa[run] = channel_errors(setup, fe.channel_coarse, paths)
        progress((run + 1) / runs, f"{power_dbm:g} dBm run {run + 1}/{runs}")
    done = max(runs - failures, 1)
    return RunsAtPower(
        power_dbm=float(power_dbm),
        refined=refined,
        coarse=coarse,
        channel_refined=ch_ref,
        channel_coarse=ch_coa,
        channel_names=names,
        peb_tx=float(bounds.peb_tx[0]) if bounds.peb_tx is not None else float("inf"),
        peb_rx=float(bounds.peb_rx[0]),
        ceb=float(bounds.ceb[0]) if bounds.ceb is not None else float("inf"),
        channel_bounds=chan_bounds,
        seconds_per_run=seconds / done,
        failures=failures,
    )


def run_monte_carlo(
    doc: SimulationDocument,
    powers_dbm: list[float],
    runs: int,
    seed: int = 0,
    progress: ProgressCallback = no_progress,
) -> MonteCarloResult:
    """RMSE of the coarse and refined estimates and the bounds at each power."""
    if runs < 1:
        raise RisPlannerError(f"runs must be ≥ 1, got {runs}")
    if runs > MAX_RUNS:
        raise LimitExceededError(f"runs = {runs} exceeds the limit {MAX_RUNS}", MAX_RUNS)
    if not powers_dbm:
        raise RisPlannerError("give at least one transmit power")
    if len(powers_dbm) > MAX_POWERS:
        raise LimitExceededError(
            f"{len(powers_dbm)} powers exceed the limit {MAX_POWERS}", MAX_POWERS
        )
    for p in powers_dbm:
        if not np.isfinite(p) or abs(p) > 100:
            raise RisPlannerError(f"transmit powers must be finite dBm within ±100, got {p}")
    out = []
    n = len(powers_dbm)
    for i, p in enumerate(powers_dbm):

        def sub(frac: float, msg: str, i: int = i) -> None:
            progress((i + frac) / n, msg)

        out.append(run_at_power(doc, p, runs, seed, sub))
    return MonteCarloResult(
        powers=out,
        runs=runs,
        seed=seed,
        multipath=not doc.multipath.empty,
        sigma=doc.estimator.sigma,
    )
