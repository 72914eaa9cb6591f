"""The power-allocation SDP of the appendix (eqs. opt_formulation_3_r1_ – problem_all_sub2_).

    minimise   (1/P) Σ_p tr(U_p)
    subject to [[Σ_g γ_g S_g(p), E], [Eᵀ, U_p]] ⪰ 0   for every sampled position p,
               Σ_g γ_g = G̃,  γ ≥ 0,

with E selecting p_R (or p_T, or both) from the full state. By the Schur complement lemma
(Boyd & Vandenberghe §A.5.5) the LMI is U_p ⪰ Eᵀ I(s_p)⁻¹ E, so at the optimum tr(U_p) is the
PEB² of eq. PEBR — one LMI per position, equivalent to the appendix's three scalar LMIs plus
Σ_ℓ u_ℓ ≤ u. The powers are those of the first-block beams, repeated over the Γ blocks (so
Σ_g γ_g = G̃ is ‖δ‖² = G), which keeps the time-orthogonal path separation.

The CRB traces (the objective at given powers, the γ_P search's objective, the scale below)
take the one inversion route of the bounds (:meth:`BeamInformation.state_bounds`: each path's
block at the given powers, its gains eliminated, through
:func:`ris_planner.bounds.compute.bounds_from_paths`, docs/concepts/numerics.md): a position is
``inf`` only where the objective's states are not identifiable, so a null direction of the
information that involves only the clock or the TX does not make a position with a determined
PEB_R blind, and the values are ``compute_bounds``' to rounding.

Scaling: the FIM mixes metres with channel gains of ~1e-7, so each position's matrices are
whitened at uniform power, S̃ = W S Wᵀ with W F(1) Wᵀ = I on the range of F(1)
(:func:`whitening`, from the square-root factor), and E becomes W E / √c with c the uniform
objective; the solver then sees O(1) numbers and the objective is rescaled by c. Where F(1)
is singular, W keeps only its range (r < n rows): with uniform powers > 0,
null F(1) = ∩_g null S_g ⊆ null F(γ) for every γ ≥ 0, and the objective's E lies in range
F(1) (checked: else the SDP is ``infeasible`` at once), so the generalised Schur complement
(Boyd & Vandenberghe §A.5.5) turns the LMI on the range into U_p ⪰ Eᵀ F(γ)⁻ E, the CRB of
the estimable objective. All positions' FIMs come from ONE product of the [Σ_p r_p², G̃]
whitened stack with γ.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Any, Literal

import cvxpy as cp
import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.inversion import crb
from ris_planner.model.power import SOLVERS, Objective
from ris_planner.power.information import BeamInformation

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
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

    objective : the solver's mean PEB² [m²] (``None`` unless optimal/inaccurate; ``optimal``
    only where it is the bound re-evaluated at ``powers`` to :data:`OBJECTIVE_AGREEMENT`);
    powers : [G̃] first-block beam powers, clipped to ≥ 0 and rescaled to sum G̃ (``None``
    without a solution); solve_time_s : wall time of building the program (the whitening,
    and cvxpy's canonicalisation where it states it) and solving it; message : the solver's
    complaint, if any; solver_time_s : the solver's own time as it reports it (``None`` if it
    did not); bound : the mean PEB² [m²] re-evaluated at ``powers`` by the bounds' route
    (:func:`mean_trace_bound`; ``None`` without powers) – the number to report and to
    compare allocations by, whatever the status.
    """

    status: SolverStatus
    objective: float | None
    powers: FloatArray | None
    solve_time_s: float
    solver: str
    message: str | None = None
    solver_time_s: float | None = None
    bound: float | None = None


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


def position_traces(
    info: BeamInformation, powers: FloatArray, index: NDArray[np.int_]
) -> FloatArray:
    """[P] tr([I(s_p)⁻¹]_index) at the given powers for ``index`` = :func:`objective_index`
    (PEB_R², PEB_T² or their sum), by the route of the bounds
    (:meth:`BeamInformation.state_bounds`: the same numbers as ``compute_bounds``); ``inf``
    where a state of ``index`` is not identifiable."""
    peb_tx, peb_rx, _ = info.state_bounds(powers)
    total = np.zeros(info.stack.shape[0])
    if np.isin(info.tx_index, index).any():
        assert peb_tx is not None  # tx_index is empty when the TX is known
        total += np.square(peb_tx)
    if np.isin(info.rx_index, index).any():
        total += np.square(peb_rx)
    return total


def mean_trace_bound(info: BeamInformation, powers: FloatArray, index: NDArray[np.int_]) -> float:
    """(1/P) Σ_p tr([I(s_p)⁻¹]_index) at the given powers (:func:`position_traces`; ``inf`` if
    the objective's states are not identifiable at some position)."""
    return float(np.mean(position_traces(info, powers, index)))


def whitening(info: BeamInformation, powers: FloatArray) -> tuple[FloatArray, BoolArray]:
    """(W [P, n, n], kept [P, n]): W F(powers) Wᵀ = I on the kept rows, zero rows on the
    numerical null space of F(powers) (:func:`ris_planner.inversion.crb.sqrt_range_whitening` of the
    square-root factor, so the null space is decided by the bounds' rule).

    The LMI is congruent under diag(W, I) on range(F): [[W F Wᵀ, W E], [(W E)ᵀ, U]] ⪰ 0 ⟺
    the original restricted to the range, and Eᵀ F⁻ E = (W E)ᵀ (W F Wᵀ)⁻¹ (W E) for E in
    range(F). Diagonal scaling alone leaves cond ≈ 1e7 (the clock offset and the path delays
    are strongly coupled), which interior-point solvers do not survive; whitening makes the
    uniform point the identity.
    """
    return crb.sqrt_range_whitening(info.factor(powers))


def _clean_powers(raw: FloatArray | None, total: float) -> FloatArray | None:
    if raw is None or not np.all(np.isfinite(raw)):
        return None
    g = np.clip(np.asarray(raw, dtype=float), 0.0, None)
    if g.sum() <= 0:
        return None
    return np.asarray(g * (total / g.sum()))


@dataclass(frozen=True)
class _Lmis:
    """The SDP's data after whitening: per position p its whitened path sum S_p [G, r_p, r_p]
    as one [Σ_p r_p², G] matrix (``mat``, rows of position p from ``offsets[p]``), its kept
    rows and E_p = W_p E / √c [r_p, m]; ``scale`` is c, the uniform objective."""

    mat: FloatArray
    offsets: NDArray[np.int_]
    rows: list[NDArray[np.int_]]
    e: list[FloatArray]
    scale: float
    m: int


def solve_power_sdp(
    info: BeamInformation,
    objective: Objective = "rx",
    solver: str = "CLARABEL",
    total_power: float | None = None,
    modeller: Literal["direct", "cvxpy"] = "direct",
) -> SdpResult:
    """Minimise the mean PEB² over the sampled positions by the beam powers (appendix SDP).

    total_power : Σ_g γ_g (default G̃, i.e. mean power 1 per beam as in ``compute_bounds``).
    modeller : ``direct`` hands Clarabel the cone program itself (:func:`_solve_direct`: the
    problem cvxpy would build, without its canonicalisation – a third of a small SDP's time);
    ``cvxpy`` states it in cvxpy (:func:`_solve_cvxpy`, always for SCS; the reference the
    suite checks the direct program against).
    """
    if solver not in SOLVERS:
        raise RisPlannerError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    n_pos, n_groups = info.stack.shape[:2]
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
    uniform = np.full(g_tilde, total / g_tilde)
    traces = position_traces(info, uniform, index)
    blind = np.flatnonzero(~np.isfinite(traces))
    if blind.size:
        # null F(uniform) ⊆ null F(γ) for every γ ≥ 0: blind at every allocation
        return SdpResult(
            "infeasible",
            None,
            None,
            0.0,
            solver,
            f"the objective's states are not identifiable at {blind.size} of {n_pos} design"
            " positions at any power allocation (singular Fisher information)",
        )
    start = time.perf_counter()
    lmis = _whitened_lmis(info, uniform, index, float(np.mean(traces)))
    if solver == "CLARABEL" and modeller == "direct":
        status, value, group, message, own = _solve_direct(lmis, n_groups, total)
    else:
        status, value, group, message, own = _solve_cvxpy(lmis, n_groups, total, solver)
    elapsed = time.perf_counter() - start
    powers = None
    if status in ("optimal", "inaccurate"):
        clean = _clean_powers(group, total)
        powers = None if clean is None else info.beam_powers(clean)
    if powers is None and status in ("optimal", "inaccurate"):
        status, message = "failed", message or "solver returned no usable powers"
    value = None if powers is None or value is None else value * lmis.scale
    bound = None if powers is None else mean_trace_bound(info, powers, index)
    agree = (
        bound is not None
        and value is not None
        and abs(bound - value) <= OBJECTIVE_AGREEMENT * bound
    )
    if status == "optimal" and value is not None and not agree:  # also a non-finite bound
        status = "inaccurate"
        message = (
            f"the solver's optimum {value:.6g} m² is not the bound at its powers"
            f" ({bound:.6g} m²): the allocation leaves a design position's information"
            " close to singular, where the solver's tolerance hides a large inverse"
        )
    return SdpResult(status, value, powers, elapsed, solver, message, own, bound)


OBJECTIVE_AGREEMENT = 1e-3
"""An ``optimal`` solve whose objective differs from the mean PEB² re-evaluated at its powers
by the bounds' route (:func:`mean_trace_bound`) by more than this relative amount is reported
``inaccurate``, saying both. On the suite's district per-RIS SDPs the two agree to 1.1e-6
where the solve is sound and differ by 0.97–0.9997 where the powers leave a position's
information near singular (docs/guides/power.md)."""


_Solved = tuple[SolverStatus, float | None, FloatArray | None, str | None, float | None]
"""(status, the solver's objective before the scale c, γ per distinct beam, message, the
solver's own time)."""


def _whitened_lmis(
    info: BeamInformation, uniform: FloatArray, index: NDArray[np.int_], scale: float
) -> _Lmis:
    """The LMIs' data at the whitening of uniform power (module docstring, "Scaling")."""
    n_groups = info.stack.shape[1]
    w, kept = whitening(info, uniform)
    # [P, J, n, n] whitened stack W S Wᵀ = Σ_ℓ (T_ℓ Wᵀ)ᵀ F_ℓ (T_ℓ Wᵀ) from the path blocks
    # (never W (Σ_ℓ T_ℓᵀ F_ℓ T_ℓ) Wᵀ: forming S first loses ε·cond(S) where F(1) is ill
    # conditioned); each position's kept rows flattened to [r_p², J] and all positions
    # concatenated: one product with γ gives every whitened FIM
    scaled = np.zeros_like(info.stack)
    for path in info.paths:
        tw = path.maps @ w.transpose(0, 2, 1)
        scaled += np.einsum("pai,pgab,pbj->pgij", tw, path.blocks, tw, optimize=True)
    scaled = 0.5 * (scaled + scaled.transpose(0, 1, 3, 2))
    rows = [np.flatnonzero(k) for k in kept]
    mat = np.concatenate(
        [scaled[p][:, r][:, :, r].reshape(n_groups, -1).T for p, r in enumerate(rows)]
    )
    offsets = np.concatenate([[0], np.cumsum([r.size**2 for r in rows])]).astype(np.int_)
    e = [w[p][r][:, index] / np.sqrt(scale) for p, r in enumerate(rows)]
    return _Lmis(mat, offsets, rows, e, scale, int(index.size))


_CLARABEL_STATUS: dict[str, SolverStatus] = {
    "Solved": "optimal",
    "AlmostSolved": "inaccurate",
    "PrimalInfeasible": "infeasible",
    "DualInfeasible": "infeasible",
    "AlmostPrimalInfeasible": "infeasible",
    "AlmostDualInfeasible": "infeasible",
}


def _triangle(k: int) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """(i, j) of a k × k symmetric matrix's upper triangle column by column – Clarabel's
    order of a PSD cone's entries, the off-diagonal ones scaled by √2."""
    lower_r, lower_c = np.tril_indices(k)
    return lower_c, lower_r


def _solve_direct(lmis: _Lmis, n_groups: int, total: float) -> _Solved:
    """The SDP as Clarabel's cone program min qᵀx s.t. Ax + s = b, s ∈ K, with
    x = (γ [G], the upper triangle of each U_p): Σγ = total (zero cone), γ ≥ 0, and per
    position s = svec([[F_p(γ), E_p], [E_pᵀ, U_p]]) in the PSD cone – cvxpy's program for
    Clarabel, entry for entry (the suite compares the two)."""
    import clarabel
    import scipy.sparse as sp

    m, n_pos = lmis.m, len(lmis.rows)
    nu = m * (m + 1) // 2
    n_x = n_groups + n_pos * nu
    ui, uj = _triangle(m)
    q = np.zeros(n_x)
    for p in range(n_pos):
        q[n_groups + p * nu + np.flatnonzero(ui == uj)] = 1.0 / n_pos
    data: list[FloatArray] = [np.ones(n_groups), -np.ones(n_groups)]
    row_ix: list[NDArray[np.int_]] = [np.zeros(n_groups, np.int_), 1 + np.arange(n_groups)]
    col_ix: list[NDArray[np.int_]] = [np.arange(n_groups), np.arange(n_groups)]
    b_parts: list[FloatArray] = [np.array([total]), np.zeros(n_groups)]
    cones: list[Any] = [clarabel.ZeroConeT(1), clarabel.NonnegativeConeT(n_groups)]
    row0 = 1 + n_groups
    for p, r in enumerate(lmis.rows):
        nr = r.size
        k = nr + m
        i, j = _triangle(k)
        f = np.where(i == j, 1.0, np.sqrt(2.0))
        t = np.arange(i.size)
        s_p = lmis.mat[lmis.offsets[p] : lmis.offsets[p + 1]].reshape(nr, nr, n_groups)
        fb = j < nr  # the F block: −svec(Σ_g γ_g S_g)
        tt, gg = np.repeat(t[fb], n_groups), np.tile(np.arange(n_groups), int(fb.sum()))
        data.append(-(f[fb, None] * s_p[i[fb], j[fb]]).ravel())
        row_ix.append(row0 + tt)
        col_ix.append(gg)
        ub = i >= nr  # the U block: −svec(U_p)
        ii, jj = i[ub] - nr, j[ub] - nr
        data.append(-f[ub])
        row_ix.append(row0 + t[ub])
        col_ix.append(n_groups + p * nu + jj * (jj + 1) // 2 + ii)
        b = np.zeros(i.size)  # the E block, constant: b = svec([[0, E], [Eᵀ, 0]])
        eb = (i < nr) & (j >= nr)
        b[eb] = f[eb] * lmis.e[p][i[eb], j[eb] - nr]
        b_parts.append(b)
        cones.append(clarabel.PSDTriangleConeT(k))
        row0 += i.size
    a = sp.csc_matrix(
        (np.concatenate(data), (np.concatenate(row_ix), np.concatenate(col_ix))),
        shape=(row0, n_x),
    )
    a.eliminate_zeros()  # as cvxpy's: stored zeros would change the solver's KKT pattern
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    try:
        sol = clarabel.DefaultSolver(
            sp.csc_matrix((n_x, n_x)), q, a, np.concatenate(b_parts), cones, settings
        ).solve()
    except (ValueError, RuntimeError, ArithmeticError) as exc:
        return "failed", None, None, str(exc), None
    name = str(sol.status).rsplit(".", 1)[-1]
    status = _CLARABEL_STATUS.get(name, "failed")
    message = None if status in ("optimal", "infeasible") else f"Clarabel: {name}"
    group = np.asarray(sol.x[:n_groups], dtype=float)
    return status, float(sol.obj_val), group, message, float(sol.solve_time)


def _solve_cvxpy(lmis: _Lmis, n_groups: int, total: float, solver: str) -> _Solved:
    """The SDP stated in cvxpy and solved by ``solver`` (its canonicalisation included)."""
    m, n_pos = lmis.m, len(lmis.rows)
    # total power of each distinct beam (shared equally by its copies afterwards)
    gam = cp.Variable(n_groups, nonneg=True)
    flat = lmis.mat @ gam
    u_vars = [cp.Variable((m, m), symmetric=True) for _ in range(n_pos)]
    cons: list[cp.Constraint] = [cp.sum(gam) == total]
    for p, r in enumerate(lmis.rows):
        fp = cp.reshape(flat[lmis.offsets[p] : lmis.offsets[p + 1]], (r.size, r.size), order="C")
        cons.append(cp.bmat([[fp, lmis.e[p]], [lmis.e[p].T, u_vars[p]]]) >> 0)
    prob = cp.Problem(cp.Minimize(sum(cp.trace(u) for u in u_vars) / n_pos), cons)
    message = None
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            prob.solve(solver=solver)
        if caught:
            message = "; ".join(str(warn.message) for warn in caught)
    except (cp.SolverError, ArithmeticError, ValueError) as exc:
        return "failed", None, None, str(exc), None
    status = _STATUS.get(str(prob.status), "failed")
    stats = prob.solver_stats
    own = None if stats is None or stats.solve_time is None else float(stats.solve_time)
    value = None if prob.value is None else float(prob.value)
    return status, value, gam.value, message, own
