"""The power-allocation SDP of the appendix (eqs. opt_formulation_3_r1_ – problem_all_sub2_).

    minimise   (1/P) Σ_p tr(U_p)
    subject to [[Σ_g γ_g S_g(p), E], [Eᵀ, U_p]] ⪰ 0   for every sampled position p,
               Σ_g γ_g = G̃,  γ ≥ 0,

with E selecting p_R (or p_T, or both) from the full state. By the Schur complement lemma
(Boyd & Vandenberghe §A.5.5) the LMI is U_p ⪰ Eᵀ I(s_p)⁻¹ E, so at the optimum tr(U_p) is the
PEB² of eq. PEBR — one LMI per position, equivalent to the appendix's three scalar LMIs plus
Σ_ℓ u_ℓ ≤ u. The powers are those of the first-block beams, repeated over the Γ blocks (so
Σ_g γ_g = G̃ is ‖δ‖² = G), which keeps the time-orthogonal path separation.

Scaling: the FIM mixes metres with channel gains of ~1e-7, so each position's matrices are
whitened at uniform power, S̃ = W S Wᵀ with W F(1) Wᵀ = I (:func:`whitening`), and E becomes
W E / √c with c the uniform objective; the solver then sees O(1) numbers and the objective is
rescaled by c. All positions' FIMs come from ONE product of the [P·n², G̃] stack with γ.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Literal

import cvxpy as cp
import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import fim_inverse_diagonal
from ris_planner.errors import RisPlannerError
from ris_planner.power.information import BeamInformation
from ris_planner.power.options import SOLVERS, Objective

FloatArray = NDArray[np.float64]
SolverStatus = Literal["optimal", "inaccurate", "infeasible", "failed"]


_STATUS: dict[str, SolverStatus] = {
    cp.OPTIMAL: "optimal",
    cp.OPTIMAL_INACCURATE: "inaccurate",
    cp.INFEASIBLE: "infeasible",
    cp.INFEASIBLE_INACCURATE: "infeasible",
    cp.UNBOUNDED: "infeasible",
    cp.UNBOUNDED_INACCURATE: "infeasible",
}


@dataclass(frozen=True)
class SdpResult:
    """Solver outcome as data (never an exception for solver trouble).

    objective : the solver's mean PEB² [m²] (``None`` unless optimal/inaccurate);
    powers : [G̃] first-block beam powers, clipped to ≥ 0 and rescaled to sum G̃ (``None``
    without a solution); solve_time_s : wall time of the solve call incl. cvxpy
    canonicalisation; message : the solver's complaint, if any; solver_time_s : the solver's
    own time as it reports it (``None`` if it did not).
    """

    status: SolverStatus
    objective: float | None
    powers: FloatArray | None
    solve_time_s: float
    solver: str
    message: str | None = None
    solver_time_s: float | None = None


def objective_index(info: BeamInformation, objective: Objective) -> NDArray[np.int_]:
    """State indices whose CRB trace is minimised: p_R, p_T or both."""
    idx = {
        "rx": info.rx_index,
        "tx": info.tx_index,
        "sum": np.concatenate([info.tx_index, info.rx_index]),
    }[objective]
    if idx.size == 0:
        raise RisPlannerError(f"objective {objective!r} has no unknown position (TX is known)")
    return np.asarray(idx)


def mean_trace_bound(info: BeamInformation, powers: FloatArray, index: NDArray[np.int_]) -> float:
    """(1/P) Σ_p tr([I(s_p)⁻¹]_index) at the given powers (``inf`` if any position is blind)."""
    return _mean_trace(info.fim(powers), index)


def _mean_trace(f: FloatArray, index: NDArray[np.int_]) -> float:
    """(1/P) Σ_p tr([F_p⁻¹]_index) of FIMs [P, n, n] (``inf`` if any is singular)."""
    diag, singular = fim_inverse_diagonal(f)
    if np.any(singular):
        return float("inf")
    return float(np.mean(diag[:, index].sum(axis=1)))


def whitening(f_uniform: FloatArray) -> FloatArray:
    """W [P, n, n] with W F(uniform) Wᵀ = I (W = L⁻¹ of the Cholesky factor), or the unit-
    diagonal scaling where F(uniform) is not positive definite (a blind position).

    The LMI is congruent under diag(W, I): [[W F Wᵀ, W E], [(W E)ᵀ, U]] ⪰ 0 ⟺ the original,
    and Eᵀ F⁻¹ E = (W E)ᵀ (W F Wᵀ)⁻¹ (W E). Diagonal scaling alone leaves cond ≈ 1e7 (the
    clock offset and the path delays are strongly coupled), which interior-point solvers do
    not survive; whitening makes the uniform point the identity.
    """
    diag = np.diagonal(f_uniform, axis1=1, axis2=2)
    w = np.zeros_like(f_uniform)
    for p in range(f_uniform.shape[0]):  # P small Cholesky factorisations (P ≤ a few hundred)
        try:
            w[p] = np.linalg.inv(np.linalg.cholesky(f_uniform[p]))
        except np.linalg.LinAlgError:
            w[p] = np.diag(1.0 / np.sqrt(np.where(diag[p] > 0, diag[p], 1.0)))
    return w


def _clean_powers(raw: FloatArray | None, total: float) -> FloatArray | None:
    if raw is None or not np.all(np.isfinite(raw)):
        return None
    g = np.clip(np.asarray(raw, dtype=float), 0.0, None)
    if g.sum() <= 0:
        return None
    return np.asarray(g * (total / g.sum()))


def solve_power_sdp(
    info: BeamInformation,
    objective: Objective = "rx",
    solver: str = "CLARABEL",
    total_power: float | None = None,
) -> SdpResult:
    """Minimise the mean PEB² over the sampled positions by the beam powers (appendix SDP).

    total_power : Σ_g γ_g (default G̃, i.e. mean power 1 per beam as in ``compute_bounds``).
    """
    if solver not in SOLVERS:
        raise RisPlannerError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    n_pos, n_groups, n, _ = info.stack.shape
    g_tilde = info.beam_group.size
    total = float(g_tilde if total_power is None else total_power)
    if not np.isfinite(total) or total <= 0:
        raise RisPlannerError(f"total power must be a positive finite number, got {total}")
    index = objective_index(info, objective)
    if not np.all(np.isfinite(info.stack)):
        return SdpResult(
            "failed",
            None,
            None,
            0.0,
            solver,
            "non-finite Fisher information: a design position lies on a RIS or on the other UE",
        )
    f_uniform = info.fim(np.full(g_tilde, total / g_tilde))
    scale_obj = _mean_trace(f_uniform, index)
    if not np.isfinite(scale_obj):
        scale_obj = 1.0
    w = whitening(f_uniform)
    # [P, J, n, n] whitened stack W S Wᵀ, flattened to [P·n·n, J]
    scaled = w[:, None] @ info.stack @ w[:, None].transpose(0, 1, 3, 2)
    scaled = 0.5 * (scaled + scaled.transpose(0, 1, 3, 2))
    mat = scaled.transpose(0, 2, 3, 1).reshape(n_pos * n * n, n_groups)
    m = index.size
    # total power of each distinct beam (shared equally by its copies afterwards)
    gam = cp.Variable(n_groups, nonneg=True)
    flat = mat @ gam
    u_vars = [cp.Variable((m, m), symmetric=True) for _ in range(n_pos)]
    cons: list[cp.Constraint] = [cp.sum(gam) == total]
    for p in range(n_pos):
        fp = cp.reshape(flat[p * n * n : (p + 1) * n * n], (n, n), order="C")
        e = w[p][:, index] / np.sqrt(scale_obj)
        cons.append(cp.bmat([[fp, e], [e.T, u_vars[p]]]) >> 0)
    prob = cp.Problem(cp.Minimize(sum(cp.trace(u) for u in u_vars) / n_pos), cons)
    start = time.perf_counter()
    message = None
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            prob.solve(solver=solver)
        if caught:
            message = "; ".join(str(warn.message) for warn in caught)
    except (cp.SolverError, ArithmeticError, ValueError) as exc:
        return SdpResult("failed", None, None, time.perf_counter() - start, solver, str(exc))
    elapsed = time.perf_counter() - start
    status = _STATUS.get(str(prob.status), "failed")
    powers = None
    if status in ("optimal", "inaccurate"):
        group = _clean_powers(gam.value, total)
        powers = None if group is None else info.beam_powers(group)
    if powers is None and status in ("optimal", "inaccurate"):
        status, message = "failed", message or "solver returned no usable powers"
    value = None if powers is None or prob.value is None else float(prob.value) * scale_obj
    stats = prob.solver_stats
    own = None if stats is None or stats.solve_time is None else float(stats.solve_time)
    return SdpResult(status, value, powers, elapsed, solver, message, own)
