"""Algorithm 2: position and clock-offset estimation from the channel parameters η̂_N.

Coarse stage (eqs. candidate_direction_vec_RX to coarse_position_hatpv), vectorised over all
TX candidates p̌_T of the search box:
  * t̂_T,ℓ from eq. tv_T; t̂_R,ℓ,2 = ξ̂_ℓ − t̂_T,ℓ,2, t̂_R,ℓ,3 = ζ̂_ℓ − t̂_T,ℓ,3 taken modulo the
    period λ/d of ξ, ζ (the spatial-frequency ambiguity the paper notes) and
    t̂_R,ℓ,1 = +sqrt(1 − t̂_R,ℓ,2² − t̂_R,ℓ,3²) (erratum: concepts/model.md); a candidate for which the
    root is imaginary is inconsistent with η̂ and gets an infinite cost.
  * p̌_R = Σ_{i<j} w_ij p̌_ij with p̌_ij the point closest to both bearing lines
    p_i + r t̂_G,i and p_j + r t̂_G,j (the midpoint of the common perpendicular, eqs. a1,
    closest_points; both ranges must be positive: the RX is in front of both RISs).
  * B̌ = cτ̂_0 − ‖p̌_R − p̌_T‖ (eq. coarse_position_checkB), or from the shortest RIS path when
    the LOS is blocked (Remark), and the cost J = Σ_ℓ w_ℓ |B̌ + d_T,ℓ + d_R,ℓ − cτ̂_ℓ|
    (eq. coarse_position_costFun), the reference RIS left out of the sum without LOS.

Refinement (eq. mle_position_estimation): weighted least squares of η̂_N − η_N(s_N) by
scipy's trust-region reflective solver with the core's closed-form Jacobians; Σ = I, or the
CRB Σ = EFIM⁻¹ of the channel estimate.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.estimation.channel_estimation import ChannelEstimate, wrap
from ris_planner.estimation.signal import RisArray
from ris_planner.model.scenario import MIN_UE_RIS_DISTANCE_M
from ris_planner.physics import geometry

FloatArray = NDArray[np.float64]

PARALLEL_TOL = 1e-9
"""Bearing lines with 1 − (t_i·t_j)² below this are parallel: no intersection."""


class EstimationError(RisPlannerError):
    """The estimator cannot produce an estimate from this observation."""


@dataclass(frozen=True)
class PositionEstimate:
    """Estimated state s_N = [p_T, p_R, B] and the coarse cost at p_T (coarse stage)."""

    tx: FloatArray
    rx: FloatArray
    clock_offset_m: float
    cost: float = float("nan")

    @property
    def state(self) -> FloatArray:
        return np.concatenate([self.tx, self.rx, [self.clock_offset_m]])


@dataclass(frozen=True)
class CandidateCosts:
    """Eq. coarse_position_costFun over candidates: cost [Q] (inf = inconsistent),
    RX candidates [Q, 3], clock offsets [Q]."""

    cost: FloatArray
    rx: FloatArray
    clock_offset_m: FloatArray


def _weights(given: list[float] | None, n: int) -> FloatArray:
    w = np.ones(n) if given is None else np.asarray(given, dtype=float)
    return np.asarray(w / w.sum())


def candidate_costs(
    ris: tuple[RisArray, ...],
    wavelength: float,
    channel: ChannelEstimate,
    candidates: FloatArray,
    pair_weights: list[float] | None = None,
    path_weights: list[float] | None = None,
) -> CandidateCosts:
    """Eqs. candidate_direction_vec_RX … coarse_position_costFun for TX candidates [Q, 3]."""
    n_ris = len(ris)
    q = candidates.shape[0]
    valid = np.ones(q, dtype=bool)
    dirs = []
    for i, arr in enumerate(ris):
        v = candidates - arr.position
        dist = np.linalg.norm(v, axis=-1, keepdims=True)
        on_ris = dist[:, 0] < MIN_UE_RIS_DISTANCE_M  # no direction: inconsistent candidate
        valid &= ~on_ris
        t_tx = (v / np.where(on_ris[:, None], 1.0, dist)) @ arr.rotation
        period = arr.period(wavelength)
        t2 = wrap(channel.xi[i] - t_tx[:, 1], period)
        t3 = wrap(channel.zeta[i] - t_tx[:, 2], period)
        rest = 1.0 - t2**2 - t3**2
        valid &= rest >= 0
        t_rx = np.stack([np.sqrt(np.clip(rest, 0.0, None)), t2, t3], axis=-1)
        dirs.append(t_rx @ arr.rotation.T)  # t_G = R t_R, [Q, 3]
    pairs = list(combinations(range(n_ris), 2))
    w_ij = _weights(pair_weights, len(pairs))
    rx = np.zeros((q, 3))
    for w, (i, j) in zip(w_ij, pairs, strict=True):
        ti, tj = dirs[i], dirs[j]
        diff = ris[i].position - ris[j].position
        c = np.sum(ti * tj, axis=-1)
        di, dj = ti @ diff, tj @ diff
        denom = 1.0 - c**2
        ok = denom > PARALLEL_TOL
        denom = np.where(ok, denom, 1.0)
        # ranges of the closest points on line i and line j
        ri = (c * dj - di) / denom
        rj = (dj - c * di) / denom
        valid &= ok & (ri > 0) & (rj > 0)
        mid = 0.5 * (ris[i].position + ri[:, None] * ti + ris[j].position + rj[:, None] * tj)
        rx += w * mid
    d_t = np.stack([np.linalg.norm(candidates - a.position, axis=-1) for a in ris], axis=-1)
    d_r = np.stack([np.linalg.norm(rx - a.position, axis=-1) for a in ris], axis=-1)
    ris_len = channel.length[1:]
    w_l = np.ones(n_ris) if path_weights is None else np.asarray(path_weights, dtype=float)
    if np.isfinite(channel.length[0]):
        clock = channel.length[0] - np.linalg.norm(rx - candidates, axis=-1)
        keep = np.ones(n_ris, dtype=bool)
    else:  # Remark: B from the shortest RIS path, which leaves the sum
        ref = int(np.argmin(ris_len))
        clock = ris_len[ref] - d_t[:, ref] - d_r[:, ref]
        keep = np.arange(n_ris) != ref
    resid = np.abs(clock[:, None] + d_t + d_r - ris_len[None, :])
    cost = resid[:, keep] @ w_l[keep]
    cost = np.where(valid & np.isfinite(cost), cost, np.inf)
    return CandidateCosts(cost=cost, rx=rx, clock_offset_m=clock)


def coarse_position(
    ris: tuple[RisArray, ...],
    wavelength: float,
    channel: ChannelEstimate,
    candidates: FloatArray,
    pair_weights: list[float] | None = None,
    path_weights: list[float] | None = None,
) -> PositionEstimate:
    """The coarse stage of Algorithm 2: the TX candidate of least cost (eq.
    coarse_position_hatpv) with its RX and clock offset."""
    if candidates.shape[0] == 0:
        raise EstimationError("the search area holds no TX candidate")
    cc = candidate_costs(ris, wavelength, channel, candidates, pair_weights, path_weights)
    best = int(np.argmin(cc.cost))
    if not np.isfinite(cc.cost[best]):
        raise EstimationError(
            "no TX candidate in the search area is consistent with the estimated spatial"
            " frequencies (no bearing-line intersection in front of the RISs)"
        )
    return PositionEstimate(
        tx=candidates[best].copy(),
        rx=cc.rx[best].copy(),
        clock_offset_m=float(cc.clock_offset_m[best]),
        cost=float(cc.cost[best]),
    )


def channel_model(
    ris: tuple[RisArray, ...], los: bool, state: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """η_N(s_N) = [cτ0, (ξ_ℓ, ζ_ℓ, cτ_ℓ)_ℓ] and its Jacobian ∂η_N/∂s_N [m, 7] (the core's
    closed forms, eq. crb_sidelink)."""
    tx, rx, b = state[None, 0:3], state[None, 3:6], float(state[6])
    eta, jac = [], []
    if los:
        eta.append(geometry.los_distance(tx, rx) + b)
        jac.append(geometry.los_jacobian(tx, rx)[0])
    for arr in ris:
        geo = geometry.ris_path_geometry(tx, rx, arr.position, arr.orientation)
        eta.append(np.concatenate([geo.xi, geo.zeta, geo.path_length(b)]))
        jac.append(geo.jacobian()[0])
    return np.concatenate(eta), np.concatenate(jac, axis=0)


def observation(channel: ChannelEstimate, los: bool) -> FloatArray:
    """η̂_N in the order of :func:`channel_model`."""
    parts = [channel.length[:1]] if los else []
    for i in range(len(channel.xi)):
        parts.append(np.array([channel.xi[i], channel.zeta[i], channel.length[i + 1]]))
    return np.concatenate(parts)


def whitening(channel: ChannelEstimate, los: bool, sigma: str) -> FloatArray:
    """W with W^T W = Σ⁻¹: I, or the Cholesky factor of the block-diagonal EFIM (Σ = EFIM⁻¹)."""
    n = (1 if los else 0) + 3 * len(channel.xi)
    if sigma == "identity":
        return np.eye(n)
    if channel.efim is None:
        raise EstimationError("Σ = CRB needs the refined channel estimate (with its EFIM)")
    blocks = [b for b in (channel.efim if los else channel.efim[1:]) if b is not None]
    out = np.zeros((n, n))
    at = 0
    for b in blocks:
        m = b.shape[0]
        out[at : at + m, at : at + m] = np.linalg.cholesky(b).T
        at += m
    return out


def refine_position(
    ris: tuple[RisArray, ...],
    wavelength: float,
    los: bool,
    channel: ChannelEstimate,
    start: PositionEstimate,
    sigma: str = "identity",
) -> PositionEstimate:
    """The MLE refinement of Algorithm 2 (eq. mle_position_estimation) by trust-region
    least squares (scipy 'trf') from the coarse estimate."""
    eta_hat = observation(channel, los)
    wmat = whitening(channel, los, sigma)
    # which entries are ξ/ζ (wrapped residuals) and their periods
    periods = np.full(eta_hat.shape, np.inf)
    at = 1 if los else 0
    for arr in ris:
        periods[at : at + 2] = arr.period(wavelength)
        at += 3
    angular = np.isfinite(periods)

    def residual(s: FloatArray) -> FloatArray:
        eta, _ = channel_model(ris, los, s)
        e = eta_hat - eta
        e[angular] = wrap(e[angular], periods[angular])
        return np.asarray(wmat @ e)

    def jacobian(s: FloatArray) -> FloatArray:
        _, jac = channel_model(ris, los, s)
        return np.asarray(-wmat @ jac)

    if not np.all(np.isfinite(residual(start.state))):
        raise EstimationError("the coarse estimate puts a UE on a RIS; cannot refine from it")
    from scipy.optimize import least_squares  # on first use: ≈ 0.6 s that a plan never needs

    sol = least_squares(
        residual,
        start.state,
        jac=jacobian,
        method="trf",
        x_scale="jac",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=200,
    )
    s = sol.x
    if not np.all(np.isfinite(s)):  # pragma: no cover - trf keeps iterates finite
        raise EstimationError("the position MLE did not return a finite estimate")
    return PositionEstimate(tx=s[0:3], rx=s[3:6], clock_offset_m=float(s[6]), cost=float(sol.cost))
