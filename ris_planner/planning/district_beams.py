"""Beams and power for a district plan's layouts (``beams`` / ``--beams`` with the district
search; docs/concepts/district-physics.md, "Beams and power").

For each count's layout (and ``beams.layouts``):

1. **Beams per RIS**: each RIS keeps its site's DIR+DER block designed from the pairs it serves
   (:mod:`ris_planner.planning.scoring.site_beams`: the plan's own when it scored with
   ``directional_derivative``, else designed here with ``beams.seed``), in the plan's Γ blocks
   (:func:`ris_planner.planning.district_plan.time_orthogonal`).
2. **Design positions**: at most ``beams.design_positions`` pairs the layout resolves (a finite
   bound), drawn ∝ weight (:func:`ris_planner.planning.beams.design_positions`). Each is
   described by the RISs that serve it, padded to Γ − 1 with RISs that serve nobody (so every
   position's state has the same size): its per-beam information
   (:func:`ris_planner.power.information.beam_information` with the plan's Γ).
3. **Power**: the slot powers δ² of the block are the transmitting UE's per transmission, the
   same for every RIS a pair hears. γ_P (eq. opt_formulation_3,
   :func:`ris_planner.power.gamma.search_gamma_p`) is searched once for the layout over the
   design positions; the appendix SDP (:func:`ris_planner.power.sdp.solve_power_sdp`) is
   solved once per RIS of the layout, over at most :data:`SDP_POSITIONS_PER_RIS` pairs it
   serves (a small SDP each: its status, time and objectives as data, per RIS and in total),
   and the layout's ``sdp`` allocation is the served-weight mean of the powers of the RISs
   whose SDP is ``optimal``.
4. **Coverage**: the layout re-scored on every pair with each allocation
   (:func:`ris_planner.planning.scoring.sparse.layout_information`), next to the plan's own.

plan.json ``beams.layouts[i]``: the objectives, the per-RIS SDPs (``sdp.per_ris``: status,
solver, message, seconds, objectives; ``sdp.status_counts``, total seconds), the powers, γ_P,
the design positions, and per RIS its site, colour and beams (each slot's type and
spatial frequencies, from which eqs. sum_diff_beam_1–3 give its phases) with the digest of its
phases.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import finite_or_none
from ris_planner.model.plan import PlanCodebook
from ris_planner.model.power import Objective
from ris_planner.physics.separable import SeparableBlock, beam_block, grid_axes
from ris_planner.planning.beams import (
    POWER_OBJECTIVE_OF_METRIC,
    SDP_POOL_MIN_RIS,
    design_positions,
)
from ris_planner.planning.inputs.plan_inputs import PlanInputs
from ris_planner.planning.outputs.estimator_check import padding_ris
from ris_planner.planning.outputs.result import PlanResult
from ris_planner.planning.scoring.site_beams import beams_per_block, design_site
from ris_planner.planning.scoring.sparse import (
    DistrictProblem,
    LayoutState,
    SparseScorer,
    layout_information,
    stand_ins,
    ue_on_ris,
)
from ris_planner.planning.scoring.time_blocks import profile_colours
from ris_planner.planning.search.layouts import Layout
from ris_planner.runtime.executor import Executor, SerialExecutor
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]


@dataclass
class DistrictBeams:
    """One layout's beams and power (in memory: the blocks; plan.json: :meth:`to_json`)."""

    blocks: dict[int, SeparableBlock]
    powers: dict[str, FloatArray] = field(default_factory=dict)
    """Slot powers per allocation: ``gamma_p`` and, when the SDP solved, ``sdp``."""
    detail: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return dict(self.detail)

    @property
    def objective(self) -> dict[str, float | None]:
        """The layout's coverage under each beam design (the beams figure's curves)."""
        return dict(self.detail.get("objective", {}))


def district_beams(
    result: PlanResult,
    inputs: PlanInputs,
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
) -> dict[Layout, DistrictBeams]:
    """Every count's layout (and ``beams.layouts``): beams, γ_P, the SDP and the coverage
    under each (module docstring)."""
    doc = result.document
    spec = doc.beams
    assert spec is not None
    scorer = result.scorer
    assert isinstance(scorer, SparseScorer)
    layouts: list[Layout] = [cr.ranked[0][0] for cr in result.counts]
    layouts += [tuple(sorted(lay)) for lay in spec.layouts]
    layouts = list(dict.fromkeys(layouts))
    out: dict[Layout, DistrictBeams] = {}
    for i, layout in enumerate(layouts):

        def sub(f: float, m: str, i: int = i) -> None:
            progress((i + f) / len(layouts), m)

        out[layout] = layout_beams(result, inputs, scorer.problem, layout, sub, executor)
    return out


def layout_beams(
    result: PlanResult,
    inputs: PlanInputs,
    problem: DistrictProblem,
    layout: Layout,
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
) -> DistrictBeams:
    """One layout's :class:`DistrictBeams` (module docstring; the per-RIS SDPs on
    ``executor``: :func:`_sdp_per_ris`)."""
    from ris_planner.power.gamma import search_gamma_p
    from ris_planner.power.sdp import mean_trace_bound, objective_index

    doc = result.document
    spec = doc.beams
    assert spec is not None
    t0 = time.perf_counter()
    timing = result.search_details.get("time_orthogonal") or {}
    gamma = int(timing.get("blocks") or problem.codebooks.blocks)
    g_tilde = beams_per_block(doc.system.transmissions, gamma, "directional_derivative")
    design = PlanCodebook(kind="directional_derivative", seed=spec.seed)
    blocks, types, aims = _layout_blocks(problem, inputs, layout, design, g_tilde)
    timing_s = {"design": time.perf_counter() - t0}
    progress(0.2, "beams: design positions")
    t1 = time.perf_counter()
    own = LayoutState(problem, list(layout))
    pick = design_positions(
        problem.weights, np.isfinite(own.metric), spec.design_positions, spec.seed
    )
    info = _position_information(result, inputs, layout, blocks, pick, gamma)
    objective = POWER_OBJECTIVE_OF_METRIC[doc.objective.metric]
    index = objective_index(info, objective)
    gp = search_gamma_p(lambda p: mean_trace_bound(info, p, index), types)
    timing_s["gamma_p"] = time.perf_counter() - t1
    progress(0.6, "beams: SDP per RIS")
    t2 = time.perf_counter()
    per_ris, sdp_powers = _sdp_per_ris(
        result,
        inputs,
        problem,
        layout,
        blocks,
        gamma,
        own,
        np.asarray(gp.powers, float),
        progress,
        executor,
    )
    timing_s["sdp"] = time.perf_counter() - t2
    progress(0.8, "beams: coverage")
    t3 = time.perf_counter()
    powers = {"uniform": np.ones(g_tilde), "gamma_p": np.asarray(gp.powers, dtype=float)}
    if sdp_powers is not None:
        powers["sdp"] = sdp_powers
    coverage = {
        name: LayoutState(layout_information(problem, inputs, blocks, gamma, p), list(layout))
        for name, p in powers.items()
    }
    objective_values = {
        problem.codebooks.kind: finite_or_none(own.coverage()),
        **{f"dir_der_{k}": finite_or_none(v.coverage()) for k, v in coverage.items()},
    }
    timing_s["evaluate"] = time.perf_counter() - t3
    colour = layout_colours(result, problem, layout)
    kinds = ("dir", "der_xi", "der_zeta")
    rises = []
    for j, s in enumerate(layout):
        block = blocks[s]
        xi, zeta = aims[s]
        rises.append(
            {
                "site": int(s),
                "name": result.sites[s].name,
                "colour": int(colour[j]),
                "beams": int(block.beam_types.size),
                "slots": [
                    {"type": kinds[int(t)], "xi": float(x), "zeta": float(z)}
                    for t, x, z in zip(block.beam_types, xi, zeta, strict=True)
                ],
                "sha256_16": _digest(block),
            }
        )
    detail = {
        "sites": [int(s) for s in layout],
        "objective": objective_values,
        "blocks": gamma,
        "beams_per_block": g_tilde,
        "design_positions": int(pick.size),
        "power_objective": objective,
        "gamma_p": float(gp.value),
        "design_objective_m2": {
            "uniform": finite_or_none(mean_trace_bound(info, np.ones(g_tilde), index)),
            "gamma_p": finite_or_none(float(gp.objective)),
            "sdp": None
            if sdp_powers is None
            else finite_or_none(mean_trace_bound(info, sdp_powers, index)),
        },
        "powers": {k: [float(x) for x in v] for k, v in powers.items()},
        "sdp": _sdp_summary(per_ris, spec.solver),
        "ris": rises,
        "timing_s": timing_s,
    }
    progress(1.0, "beams: done")
    return DistrictBeams(blocks, powers, detail)


def layout_colours(result: PlanResult, problem: DistrictProblem, layout: Layout) -> IntArray:
    """[L] each layout RIS's profile colour: the one the plan reported for a count's layout
    (plan.json ``time_orthogonal.counts``: a designed plan's held colouring), DSatur's for
    another layout."""
    timing = result.search_details.get("time_orthogonal") or {}
    for row in timing.get("counts", []):
        by_site = row["colour_of_site"]
        if {int(s) for s in by_site} == set(layout):
            return np.array([int(by_site[str(s)]) for s in layout])
    return profile_colours(problem, layout)


SDP_POSITIONS_PER_RIS = 8
"""Design positions of each RIS's SDP (at most ``beams.design_positions``): pairs the RIS
serves and the layout resolves, drawn ∝ weight, seeded per site – one small SDP per RIS."""


@dataclass(frozen=True)
class RisSdpShared:
    """What every per-RIS SDP of a layout shares (a pool's shared object): the plan's system,
    environment and Γ, the padding RIS and its block, the objective, solver and γ_P powers."""

    system: Any
    environment: Any
    pad: tuple[Any, SeparableBlock]
    gamma: int
    objective: Objective
    solver: str
    gamma_p: FloatArray


@dataclass(frozen=True)
class RisSdpTask:
    """One RIS's SDP (a pool task): its design positions' transmitters and receivers, and
    each position's RISs (this one first) with their DIR+DER blocks."""

    tx: FloatArray
    rx: FloatArray
    ris: list[list[Any]]
    blocks: list[list[SeparableBlock]]


def _solve_ris(common: RisSdpShared, task: RisSdpTask) -> dict[str, Any]:
    """A :class:`RisSdpTask`'s row of plan.json ``sdp.per_ris`` (with ``powers``: the SDP's slot
    powers, ``None`` unless solved): its information, the positions singular there, the
    appendix SDP (:func:`ris_planner.power.sdp.solve_power_sdp`) and the mean PEB² at
    uniform, γ_P and SDP powers."""
    from ris_planner.power.sdp import (
        mean_trace_bound,
        objective_index,
        position_traces,
        solve_power_sdp,
    )

    t0 = time.perf_counter()
    info = _stacked_information(
        common.system,
        common.environment,
        task.tx,
        task.rx,
        task.ris,
        task.blocks,
        common.pad,
        common.gamma,
    )
    g_tilde = common.gamma_p.size
    index = objective_index(info, common.objective)
    uniform = position_traces(info, np.ones(g_tilde), index)
    finite = np.isfinite(uniform)
    row: dict[str, Any] = {"positions_singular": int((~finite).sum()), "powers": None}
    if not finite.any():
        row |= {"status": "no design positions", "design_positions": 0}
        row["message"] = (
            f"each of the {finite.size} design positions is singular with its"
            f" {SDP_RISES_PER_POSITION} strongest RISs"
        )
        return row
    info = _take_positions(info, np.flatnonzero(finite))
    t_info = time.perf_counter() - t0
    sdp = solve_power_sdp(info, common.objective, solver=common.solver)
    return row | {
        "design_positions": int(finite.sum()),
        "information_s": t_info,
        "status": sdp.status,
        "solver": sdp.solver,
        "message": sdp.message,
        "solve_time_s": sdp.solve_time_s,
        "seconds": time.perf_counter() - t0,
        "rises_per_position": max(len(r) for r in task.ris),
        "solver_objective_m2": finite_or_none(sdp.objective),
        "design_objective_m2": {
            "uniform": finite_or_none(float(np.mean(uniform[finite]))),
            "gamma_p": finite_or_none(mean_trace_bound(info, common.gamma_p, index)),
            "sdp": finite_or_none(sdp.bound),
        },
        "powers": None if sdp.powers is None else np.asarray(sdp.powers, dtype=float),
    }


def _sdp_per_ris(
    result: PlanResult,
    inputs: PlanInputs,
    problem: DistrictProblem,
    layout: Layout,
    blocks: dict[int, SeparableBlock],
    gamma: int,
    own: LayoutState,
    gamma_p: FloatArray,
    progress: ProgressCallback = no_progress,
    executor: Executor | None = None,
) -> tuple[list[dict[str, Any]], FloatArray | None]:
    """The appendix SDP (:func:`ris_planner.power.sdp.solve_power_sdp`) once per RIS of the
    layout, over its own design positions (:data:`SDP_POSITIONS_PER_RIS`: pairs it serves
    that the layout resolves, each with every layout RIS that serves it): per RIS its
    status, solver, message, seconds, and the mean PEB² there at uniform, γ_P and its own SDP
    powers. The slot powers δ² are the transmitting UE's, shared by every RIS a pair hears,
    so the layout's ``sdp`` allocation is the served-weight mean of the powers of the RISs
    whose SDP is ``optimal`` (a convex combination: Σ δ² = G̃ kept); an ``inaccurate`` solve's
    powers are left out of it (its optimum is not the bound at its powers); ``None`` when no
    RIS's SDP is optimal – never a silent fallback: each RIS's status is in the rows. From
    :data:`SDP_POOL_MIN_RIS` RISs on the SDPs run on ``executor`` (the plan's process pool),
    in the layout's order."""
    doc = result.document
    spec = doc.beams
    assert spec is not None
    objective = POWER_OBJECTIVE_OF_METRIC[doc.objective.metric]
    serves = result.scorer.serves(layout)
    resolved = np.isfinite(own.metric)
    member = np.zeros(problem.n_sites, dtype=bool)
    member[list(layout)] = True
    strength = problem.strength()
    per = min(spec.design_positions, SDP_POSITIONS_PER_RIS)
    g_tilde = gamma_p.size
    pad = (padding_ris(inputs.sites[layout[0]].ris), blocks[layout[0]])
    common = RisSdpShared(doc.system, doc.environment, pad, gamma, objective, spec.solver, gamma_p)
    rows: list[dict[str, Any]] = []
    tasks: list[RisSdpTask] = []
    asked: list[int] = []
    for j, s in enumerate(layout):
        mine = serves[j] & resolved
        row: dict[str, Any] = {"site": int(s), "weight": float(problem.weights[mine].sum())}
        rows.append(row)
        if not np.any(mine & (problem.weights > 0)):
            row |= {"status": "no design positions", "design_positions": 0}
            row["message"] = "the layout resolves none of the pairs this RIS serves"
            continue
        pick = design_positions(problem.weights, mine, per, spec.seed + int(s))
        rises = [_strongest_rises(problem, strength, member, int(s), p) for p in pick.tolist()]
        tasks.append(
            RisSdpTask(
                inputs.pairs.tx[pick],
                inputs.pairs.rx[pick],
                [[inputs.sites[r].ris for r in rs] for rs in rises],
                [[blocks[r] for r in rs] for rs in rises],
            )
        )
        asked.append(j)

    def done(n: int) -> None:
        progress(0.6 + 0.2 * n / max(len(tasks), 1), f"beams: SDP of RIS {n}/{len(tasks)}")

    runner = executor if executor is not None and len(tasks) >= SDP_POOL_MIN_RIS else None
    answers = (runner or SerialExecutor()).map(_solve_ris, common, tasks, done)
    solved: list[tuple[float, FloatArray]] = []
    for j, answer in zip(asked, answers, strict=True):
        powers = answer.pop("powers")
        rows[j] |= answer
        if powers is not None and answer["status"] == "optimal":
            solved.append((rows[j]["weight"], powers))
    if not solved:
        return rows, None
    w = np.array([x for x, _ in solved])
    mean = (w[:, None] * np.array([p for _, p in solved])).sum(axis=0) / w.sum()
    return rows, mean * (g_tilde / mean.sum())


SDP_RISES_PER_POSITION = 6
"""RISs that describe a design position of a per-RIS SDP: the RIS itself and the layout's
strongest others serving the position (by their information on the metric's position,
:meth:`~ris_planner.planning.scoring.sparse.DistrictProblem.strength`) – the LMI's size stays
small however many RISs the layout has."""


def _strongest_rises(
    problem: DistrictProblem, strength: FloatArray, member: NDArray[np.bool_], site: int, pair: int
) -> list[int]:
    """``site`` and up to :data:`SDP_RISES_PER_POSITION` − 1 other layout sites serving
    ``pair``, strongest first (``strength`` [E]: :meth:`DistrictProblem.strength`)."""
    lo, hi = problem.pair_start[pair], problem.pair_start[pair + 1]
    sites = problem.entry_site[lo:hi]
    keep = member[sites] & (sites != site)
    strength = strength[lo:hi][keep]
    others = sites[keep][np.argsort(-strength, kind="stable")]
    return [site, *[int(x) for x in others[: SDP_RISES_PER_POSITION - 1]]]


def _take_positions(info: Any, idx: NDArray[np.int_]) -> Any:
    """The :class:`~ris_planner.power.information.BeamInformation` of positions ``idx``."""
    from ris_planner.power.information import PathBlocks

    paths = tuple(
        PathBlocks(p.blocks[idx], p.maps[idx], p.name, p.jacobian[idx], p.present[idx])
        for p in info.paths
    )
    return replace(info, stack=info.stack[idx], paths=paths)


def _sdp_summary(rows: list[dict[str, Any]], solver: str) -> dict[str, Any]:
    """plan.json ``beams.layouts[i].sdp``: the per-RIS SDPs' rows, how many ended in each
    status, their total time, and how the layout's allocation combines them."""
    status: dict[str, int] = {}
    for r in rows:
        status[r["status"]] = status.get(r["status"], 0) + 1
    return {
        "per_ris": rows,
        "status_counts": status,
        "solver": solver,
        "solve_time_s": float(sum(r.get("solve_time_s", 0.0) for r in rows)),
        "seconds": float(sum(r.get("seconds", 0.0) for r in rows)),
        "combined": "served-weight mean of the slot powers of the RISs whose SDP is optimal"
        " (inaccurate, infeasible and failed solves left out)",
    }


def _layout_blocks(
    problem: DistrictProblem,
    inputs: PlanInputs,
    layout: Layout,
    design: PlanCodebook,
    g_tilde: int,
) -> tuple[dict[int, SeparableBlock], NDArray[np.int_], dict[int, tuple[FloatArray, FloatArray]]]:
    """Each layout site's DIR+DER block (the plan's own when it designed them with this G̃),
    the slots' beam types, and each site's slots' spatial frequencies (ξ₀, ζ₀)."""
    cb = problem.codebooks
    pairs = inputs.pairs
    wavelength = inputs.document.system.wavelength
    own = cb.kind == "directional_derivative" and cb.xi.shape[1] == g_tilde
    out: dict[int, SeparableBlock] = {}
    aims: dict[int, tuple[FloatArray, FloatArray]] = {}
    types = np.zeros(0, dtype=int)
    for s in layout:
        ris = inputs.sites[s].ris
        yc, zr = grid_axes(ris.rows, ris.cols, ris.element_spacing(wavelength))
        if own:
            xi, zeta = cb.xi[s], cb.zeta[s]
            block = beam_block(yc, zr, xi, zeta, cb.beam_types, wavelength)
        else:
            p = problem.pairs_of(int(s))
            bad = ue_on_ris(pairs.tx[p], pairs.rx[p], ris.position)
            t, r = stand_ins(pairs.tx[p], pairs.rx[p], bad)
            w = np.where(bad, 0.0, pairs.weights[p])
            rng = np.random.default_rng([design.seed or 0, int(s)])
            beams = design_site(ris, t, r, w, design, g_tilde, wavelength, rng)
            block, xi, zeta = beams.block, beams.xi, beams.zeta
        out[int(s)] = block
        aims[int(s)] = (xi, zeta)
        types = block.beam_types
    return out, types, aims


def _position_information(
    result: PlanResult,
    inputs: PlanInputs,
    layout: Layout,
    blocks: dict[int, SeparableBlock],
    pick: NDArray[np.int_],
    gamma: int,
    mine: list[list[int]] | None = None,
) -> Any:
    """The stacked per-beam information of the design positions in the plan's Γ blocks: each
    with the layout's RISs that serve it (``mine``: the RISs of each position, when the caller
    chose them), padded with RISs that serve nobody to the most any position has (one state
    size for all: a padding RIS's gains are decoupled from every other state,
    :data:`~ris_planner.power.information.ABSENT_GAIN_INFORMATION`)."""
    pairs = inputs.pairs
    if mine is None:
        serves = result.scorer.serves(layout)  # [L, P]
        mine = [[s for j, s in enumerate(layout) if serves[j, p]] for p in pick.tolist()]
    doc = result.document
    return _stacked_information(
        doc.system,
        doc.environment,
        pairs.tx[pick],
        pairs.rx[pick],
        [[inputs.sites[s].ris for s in sites] for sites in mine],
        [[blocks[s] for s in sites] for sites in mine],
        (padding_ris(inputs.sites[layout[0]].ris), blocks[layout[0]]),
        gamma,
    )


def _stacked_information(
    system: Any,
    environment: Any,
    tx: FloatArray,
    rx: FloatArray,
    ris: list[list[Any]],
    blocks: list[list[SeparableBlock]],
    pad: tuple[Any, SeparableBlock],
    gamma: int,
) -> Any:
    """:func:`_position_information` from its parts: per position (``tx[i]``, ``rx[i]``) its
    RISs and their blocks, padded with the padding RIS and block ``pad`` to the most any
    position has."""
    from ris_planner.planning.beams import layout_scenario
    from ris_planner.power.information import BeamInformation, PathBlocks, beam_information

    width = max(len(r) for r in ris)  # every position's state padded to the same size
    padded = [list(rises) + [pad[0]] * (width - len(rises)) for rises in ris]
    present = _presence(system, environment, padded, tx, rx)
    parts = []
    for i, (rises, own) in enumerate(zip(padded, blocks, strict=True)):
        scenario = layout_scenario(system, rises, [], environment)
        prof = [b.profiles() for b in own] + [pad[1].profiles()] * (width - len(own))
        mine = {k: v[[i]] for k, v in present.items()}
        parts.append(
            beam_information(scenario, tx[[i]], rx[[i]], prof, [], n_blocks=gamma, presence=mine)
        )
    first = parts[0]
    paths = tuple(
        PathBlocks(
            np.concatenate([q.paths[k].blocks for q in parts]),
            np.concatenate([q.paths[k].maps for q in parts]),
            first.paths[k].name,
            np.concatenate([q.paths[k].jacobian for q in parts]),
            np.concatenate([q.paths[k].present for q in parts]),
        )
        for k in range(len(first.paths))
    )
    return BeamInformation(
        np.concatenate([q.stack for q in parts]),
        first.beam_group,
        first.tx_index,
        first.rx_index,
        paths,
        first.known,
        first.n_observations,
    )


def _presence(
    system: Any, environment: Any, padded: list[list[Any]], tx: FloatArray, rx: FloatArray
) -> dict[str, NDArray[np.bool_]]:
    """The paths present at each design position (``padded[i]``: position i's RISs, all
    positions as many) as :func:`~ris_planner.bounds.compute.scenario_path_presence` finds them
    position by position – in one visibility query over every position's legs
    (:func:`~ris_planner.bounds.compute.presence_per_pair`)."""
    from ris_planner.bounds.compute import presence_per_pair

    rises: list[Any] = []  # each distinct RIS object once, in first-seen order
    index: dict[int, int] = {}
    for r in (r for row in padded for r in row):
        if id(r) not in index:
            index[id(r)] = len(rises)
            rises.append(r)
    slots = np.array([[index[id(r)] for r in row] for row in padded], dtype=np.int64)
    return presence_per_pair(environment, rises, slots, tx, rx, bool(system.los))


def _digest(block: SeparableBlock) -> str:
    """SHA-256 (first 16 hex digits) of the block's profiles (little-endian complex128)."""
    return hashlib.sha256(
        np.ascontiguousarray(block.profiles(), dtype="<c16").tobytes()
    ).hexdigest()[:16]
