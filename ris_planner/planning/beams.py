"""Beams and power for a recommended layout: DIR / DIR+DER codebooks designed from the UE map
and the power allocation of the appendix, re-evaluated on the plan's own pairs (section IV).

For a layout (one RIS per chosen site) and the plan's weighted pair set:

1. **Design samples from the map** (the map analogue of the Gaussian prior of eq.
   DIR_codebook): for each RIS, pairs are drawn with probability ∝ their plan weight among the
   pairs that RIS serves (both UEs in its field of view with clear legs,
   :func:`ris_planner.environment.ris_serves`), seeded by ``beams.seed``. A RIS's beams point
   only at UEs it can reach. The number of samples
   per block is the prior codebook's default: G̃ for DIR (one beam per sample) and ⌊G̃/3⌋ for
   DIR+DER (three beams per sample); the block cycles through them when they are fewer than G̃
   (as :func:`ris_planner.physics.beams.beam_layout`).
2. **Design positions of the power allocation** (eq. opt_formulation_2): a reproducible
   weighted subsample of at most ``beams.design_positions`` pairs (seeded; ∝ weight without
   replacement) among those the layout resolves under ``expected_random`` (finite bound), so
   every LMI of the SDP is feasible.
3. Uniform power, the best γ_P (:mod:`ris_planner.power.gamma`) and the SDP
   (:mod:`ris_planner.power.sdp`) on the design positions; then every allocation, the DIR beams,
   and ``random`` codebooks over several seeds are **re-evaluated by** ``compute_bounds`` **on
   the plan's full pair set with the plan's objective**, next to the ``expected_random`` value
   the search used. The SDP minimises the mean PEB² on the design positions; whether that helps
   the plan's objective on all pairs is reported as measured, not assumed.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import ComplexArray, compute_bounds
from ris_planner.bounds.paths import ris_serves
from ris_planner.core.errors import RisPlannerError
from ris_planner.core.io_json import finite_or_none
from ris_planner.environment import Scene
from ris_planner.model.objectives import objective_kind
from ris_planner.model.plan import LayoutBeamsDocument
from ris_planner.model.power import Objective as PowerObjective
from ris_planner.model.scenario import (
    RIS,
    ExpectedRandomCodebook,
    KnownPart,
    Scenario,
    SystemParams,
)
from ris_planner.physics import codebooks
from ris_planner.physics.beams import beam_layout, sample_beams
from ris_planner.planning.inputs.ue_maps import PairSet
from ris_planner.planning.scoring.scorer import objective_value, select_metric
from ris_planner.runtime.progress import ProgressCallback, no_progress

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

POWER_OBJECTIVE_OF_METRIC: dict[str, PowerObjective] = {"rx": "rx", "tx": "tx", "max": "sum"}
"""The SDP minimises a mean PEB² (a trace of the CRB): PEB_R² for metric ``rx``, PEB_T² for
``tx``, and their sum for ``max`` (a smooth stand-in for the larger of the two)."""


@dataclass(frozen=True)
class LayoutBeams:
    """The designed first blocks of one layout (per RIS [G̃, N]) and their samples."""

    directional: list[ComplexArray]
    derivative: list[ComplexArray]
    beam_types: NDArray[np.int_]
    samples: list[tuple[FloatArray, FloatArray]]
    """Per RIS the sampled (tx [S, 3], rx [S, 3]) its beams point at."""
    unserved: list[int]
    """RISs that serve none of the pairs (their beams are seeded random phases)."""


SDP_POOL_MIN_RIS = 12
"""From this many RISs with design positions on, a district layout's per-RIS SDPs run on the
plan's process pool (each task builds its RIS's information and solves its SDP:
:mod:`ris_planner.planning.district_beams`); fewer run in the plan's process (a pool's start
costs more than they take)."""


def served_pairs(scene: Scene, ris: list[RIS], pairs: PairSet) -> BoolArray:
    """[L, P] whether each RIS serves both UEs of each pair (field of view and clear legs)."""
    return np.stack([ris_serves(scene, r, pairs.tx) & ris_serves(scene, r, pairs.rx) for r in ris])


def _draw(
    weights: FloatArray, mask: BoolArray, count: int, rng: np.random.Generator
) -> NDArray[np.int_]:
    """``count`` pair indices ∝ weight within ``mask`` (without replacement when possible)."""
    idx = np.nonzero(mask & (weights > 0))[0]
    p = weights[idx] / weights[idx].sum()
    replace = idx.size < count
    return np.asarray(idx[rng.choice(idx.size, size=count, replace=replace, p=p)])


def design_beams(
    system: SystemParams,
    ris: list[RIS],
    pairs: PairSet,
    served: BoolArray,
    seed: int,
) -> LayoutBeams:
    """DIR and DIR+DER first blocks for a layout from map-drawn samples (module docstring)."""
    g_tilde = codebooks.block_length(system.transmissions, len(ris))
    if g_tilde < 3:
        raise RisPlannerError(
            f"DIR+DER beams need G/Γ ≥ 3 beams per block, the layout of {len(ris)} RISs has"
            f" G/Γ = {g_tilde}; raise system.transmissions"
        )
    rng = np.random.default_rng(seed)
    dir_index, _ = beam_layout(g_tilde, g_tilde, 1)
    der_index, der_types = beam_layout(g_tilde, g_tilde // 3, 3)
    directional, derivative, samples, unserved = [], [], [], []
    for i, r in enumerate(ris):
        if not np.any(served[i] & (pairs.weights > 0)):
            unserved.append(i)
            phases = codebooks.random_phases(1, g_tilde, [r.elements], rng)[0]
            directional.append(phases)
            derivative.append(phases)
            samples.append((np.empty((0, 3)), np.empty((0, 3))))
            continue
        pick = _draw(pairs.weights, served[i], g_tilde, rng)
        tx, rx = pairs.tx[pick], pairs.rx[pick]
        # DIR: one beam per sample (G̃ samples); DIR+DER: the first ⌊G̃/3⌋ samples' triples
        directional.append(sample_beams(r, tx, rx, system.wavelength, False)[dir_index, 0])
        triples = sample_beams(r, tx[: g_tilde // 3], rx[: g_tilde // 3], system.wavelength, True)
        derivative.append(triples[der_index, der_types])
        samples.append((tx, rx))
    return LayoutBeams(directional, derivative, der_types, samples, unserved)


def design_positions(
    weights: FloatArray, resolved: BoolArray, count: int, seed: int
) -> NDArray[np.int_]:
    """At most ``count`` pair indices ∝ weight without replacement among the resolved pairs
    (finite expected-random bound), sorted; reproducible from ``seed``."""
    idx = np.nonzero(resolved & (weights > 0))[0]
    if idx.size == 0:
        raise RisPlannerError(
            "the layout resolves none of the pairs (every bound is infinite): no design"
            " positions for the power allocation"
        )
    if idx.size <= count:
        return idx
    rng = np.random.default_rng(seed)
    pick = rng.choice(idx.size, size=count, replace=False, p=weights[idx] / weights[idx].sum())
    return np.asarray(np.sort(idx[pick]))


DESIGNS: dict[str, tuple[str, str]] = {
    "directional": ("dir", "uniform"),
    "dir_der_uniform": ("dir+der", "uniform"),
    "dir_der_gamma_p": ("dir+der", "gamma_p"),
    "dir_der_sdp": ("dir+der", "sdp"),
}
"""The designed codebooks of a :class:`BeamReport` (its ``objective`` keys): (beams, powers)."""


@dataclass(frozen=True)
class DesignedCodebook:
    """One designed codebook of a layout, as the RISs would apply it: first-block profiles
    (one [G̃, N_ℓ] per RIS, unit modulus) and the beam powers δ² [G̃] (sum G̃)."""

    name: str
    profiles: list[ComplexArray]
    powers: FloatArray

    def digest(self) -> str:
        """SHA-256 (first 16 hex digits) of the profiles and powers (little-endian complex128
        and float64 bytes, RIS by RIS): names the codebook in plan.json without its phases."""
        h = hashlib.sha256()
        for p in self.profiles:
            h.update(np.ascontiguousarray(p, dtype="<c16").tobytes())
        h.update(np.ascontiguousarray(self.powers, dtype="<f8").tobytes())
        return h.hexdigest()[:16]

    def describe(self) -> dict[str, Any]:
        """plan.json's summary of the codebook (``validation.codebook``): design, powers,
        beams per block, the power range and the digest."""
        beams, powers = DESIGNS[self.name]
        return {
            "kind": "designed",
            "name": self.name,
            "design": beams,
            "powers": powers,
            "beams_per_block": int(self.powers.size),
            "beam_power_min": float(np.min(self.powers)),
            "beam_power_max": float(np.max(self.powers)),
            "sha256_16": self.digest(),
        }


@dataclass
class BeamReport:
    """Objective of one layout on the plan's full pair set under each beam design, and the
    designed codebooks themselves (in memory only, never in plan.json: ``codebooks``)."""

    objective: dict[str, float | None] = field(default_factory=dict)
    detail: dict[str, Any] = field(default_factory=dict)
    codebooks: dict[str, DesignedCodebook] = field(default_factory=dict)
    """The designed codebooks by :data:`DESIGNS` name (``dir_der_sdp`` only when the SDP
    solved)."""

    def to_json(self) -> dict[str, Any]:
        return {"objective": self.objective, **self.detail}

    def best_design(self, better: str) -> str | None:
        """The designed codebook with the best plan objective on all pairs (``better``:
        ``"higher"`` or ``"lower"``); ties go to the first of :data:`DESIGNS` reversed (the SDP
        first); ``None`` when none has a finite objective."""
        best: tuple[float, str] | None = None
        for name in reversed(DESIGNS):
            value = self.objective.get(name)
            if name not in self.codebooks or value is None:
                continue
            key = -value if better == "higher" else value
            if best is None or key < best[0]:
                best = (key, name)
        return None if best is None else best[1]


def objective_on_pairs(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    weights: FloatArray,
    objective: Any,
    mirror: bool = False,
    profiles: list[ComplexArray] | str | None = "codebook",
    beam_powers: FloatArray | None = None,
    presence: dict[str, BoolArray] | None = None,
) -> float:
    """A plan objective of a layout by ``compute_bounds`` on pairs tx, rx [P, 3] with weights
    [P] (sum 1); with ``mirror`` each pair also counts reversed with half the weight (the
    reverse direction's PEB_R is the forward PEB_T, as the planning scorer counts it).
    ``presence``: the pairs' paths when the caller has them (the plan's visibility)."""
    metric, w = metric_on_pairs(
        scenario, tx, rx, weights, objective.metric, mirror, profiles, beam_powers, presence
    )
    return float(objective_value(objective, metric[None, :], w)[0])


def metric_on_pairs(
    scenario: Scenario,
    tx: FloatArray,
    rx: FloatArray,
    weights: FloatArray,
    metric_name: str,
    mirror: bool = False,
    profiles: list[ComplexArray] | str | None = "codebook",
    beam_powers: FloatArray | None = None,
    presence: dict[str, BoolArray] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """(metric [P] or [2P] with ``mirror``, its weights): the objective's bound per pair by
    ``compute_bounds``, laid out as the planning scorer's (:attr:`Scorer.metric_weights`)."""
    res = compute_bounds(
        scenario,
        tx,
        rx,
        profiles=profiles,
        beam_powers=beam_powers,
        presence=presence,
        channel=False,
    )
    metric = select_metric(metric_name, res.peb_tx, res.peb_rx)
    w = weights
    if mirror:  # j → i: its PEB_R is the PEB_T of i → j (and vice versa)
        assert res.peb_tx is not None  # mirror needs an unknown TX (maps.unordered_directions)
        metric = np.concatenate([metric, select_metric(metric_name, res.peb_rx, res.peb_tx)])
        w = np.concatenate([weights, weights]) / 2
    return metric, w


def layout_scenario(
    system: SystemParams, ris: list[RIS], known: list[KnownPart], environment: Any = None
) -> Scenario:
    """A scenario of the layout's RISs (parts validated by the plan document; the pairs are
    passed to ``compute_bounds`` as arrays)."""
    return Scenario.model_construct(
        system=system,
        ris=ris,
        tx=[0.0, 0.0, 0.0],
        rx=[1.0, 0.0, 0.0],
        codebook=ExpectedRandomCodebook(),
        known=list(known),
        environment=environment,
    )


def evaluate_layout_beams(
    scenario: Scenario,
    pairs: PairSet,
    plan_objective: Any,
    expected_metric: FloatArray,
    served: BoolArray,
    *,
    seed: int = 0,
    positions: int = 64,
    random_seeds: int = 3,
    solver: str = "CLARABEL",
    mirror: bool = False,
    progress: ProgressCallback = no_progress,
) -> BeamReport:
    """Every beam design of a layout, each re-evaluated on all pairs with the plan objective.

    scenario : the layout (:func:`layout_scenario`); pairs : the plan's pair set;
    plan_objective : the plan's :class:`~ris_planner.model.plan.Objective`;
    expected_metric : [P] the layout's expected-random metric (the search's own score), [2P]
    with ``mirror`` (unordered pairs counted in both directions: the reverse direction's PEB_R
    is the forward PEB_T, :class:`~ris_planner.planning.scoring.scorer.Scorer`);
    served : [L, P] :func:`served_pairs`.
    """
    from ris_planner.power.gamma import search_gamma_p
    from ris_planner.power.information import beam_information
    from ris_planner.power.report import design_objective
    from ris_planner.power.sdp import mean_trace_bound, objective_index, solve_power_sdp

    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    power_objective = POWER_OBJECTIVE_OF_METRIC[plan_objective.metric]
    n_ris = len(scenario.ris)
    g_tilde = codebooks.block_length(scenario.system.transmissions, n_ris)

    weights = np.concatenate([pairs.weights, pairs.weights]) / 2 if mirror else pairs.weights

    def on_pairs(profiles: list[ComplexArray], powers: FloatArray | None = None) -> float:
        return objective_on_pairs(
            scenario, pairs.tx, pairs.rx, pairs.weights, plan_objective, mirror, profiles, powers
        )

    report = BeamReport()
    obj = report.objective
    obj["expected_random"] = finite_or_none(
        float(objective_value(plan_objective, expected_metric[None, :], weights)[0])
    )
    randoms = []
    for s in range(random_seeds):
        rng = np.random.default_rng(s)  # the random codebook of seed s (RandomCodebook)
        prof = codebooks.random_phases(n_ris, g_tilde, [r.elements for r in scenario.ris], rng)
        randoms.append(on_pairs(prof))
    obj["random_mean"] = finite_or_none(float(np.mean(randoms)))
    obj["random_min"] = finite_or_none(float(np.min(randoms)))
    obj["random_max"] = finite_or_none(float(np.max(randoms)))
    progress(0.2, "beams: random codebooks")
    beams = design_beams(scenario.system, list(scenario.ris), pairs, served, seed)
    obj["directional"] = finite_or_none(on_pairs(beams.directional))
    obj["dir_der_uniform"] = finite_or_none(on_pairs(beams.derivative))
    timing["design_and_codebooks"] = time.perf_counter() - t0
    progress(0.4, "beams: design positions")

    t1 = time.perf_counter()
    resolved = np.isfinite(expected_metric[: pairs.size])
    pick = design_positions(pairs.weights, resolved, positions, seed)
    tx_d, rx_d = pairs.tx[pick], pairs.rx[pick]
    on_design = design_objective(scenario, tx_d, rx_d, beams.derivative, power_objective)
    info = beam_information(scenario, tx_d, rx_d, beams.derivative)
    index = objective_index(info, power_objective)
    gamma = search_gamma_p(lambda p: mean_trace_bound(info, p, index), beams.beam_types)
    uniform_design = on_design(np.ones(g_tilde))
    if not on_design(gamma.powers) <= uniform_design:
        # the search ran on the stacked information (≈ compute_bounds to rounding); γ_P = 1 is
        # one of its grid points, so keep the answer never worse than uniform by the bounds code
        gamma = replace(gamma, value=1.0, objective=uniform_design, powers=np.ones(g_tilde))
    timing["gamma_p"] = time.perf_counter() - t1
    progress(0.6, "beams: SDP")
    t2 = time.perf_counter()
    sdp = solve_power_sdp(info, power_objective, solver=solver)
    timing["sdp"] = time.perf_counter() - t2
    t3 = time.perf_counter()
    obj["dir_der_gamma_p"] = finite_or_none(on_pairs(beams.derivative, gamma.powers))
    obj["dir_der_sdp"] = (
        None if sdp.powers is None else finite_or_none(on_pairs(beams.derivative, sdp.powers))
    )
    ones = np.ones(g_tilde)
    report.codebooks = {
        "directional": DesignedCodebook("directional", beams.directional, ones),
        "dir_der_uniform": DesignedCodebook("dir_der_uniform", beams.derivative, ones),
        "dir_der_gamma_p": DesignedCodebook(
            "dir_der_gamma_p", beams.derivative, np.asarray(gamma.powers, dtype=float)
        ),
        **(
            {}
            if sdp.powers is None
            else {
                "dir_der_sdp": DesignedCodebook(
                    "dir_der_sdp", beams.derivative, np.asarray(sdp.powers, dtype=float)
                )
            }
        ),
    }
    report.detail = {
        "random_seeds": random_seeds,
        "seed": seed,
        "samples_per_block": {"directional": g_tilde, "directional_derivative": g_tilde // 3},
        "unserved_ris": beams.unserved,
        "design_positions": int(pick.size),
        "power_objective": power_objective,
        "design_objective_m2": {
            "uniform": finite_or_none(uniform_design),
            "gamma_p": finite_or_none(on_design(gamma.powers)),
            "sdp": None if sdp.powers is None else finite_or_none(on_design(sdp.powers)),
            "sdp_solver": finite_or_none(sdp.objective),
        },
        "gamma_p": float(gamma.value),
        "sdp": {
            "status": sdp.status,
            "solver": sdp.solver,
            "solve_time_s": sdp.solve_time_s,
            "message": sdp.message,
            "powers": None if sdp.powers is None else [float(x) for x in sdp.powers],
        },
    }
    timing["evaluate"] = time.perf_counter() - t3
    report.detail["timing_s"] = timing
    progress(1.0, "beams: done")
    return report


def run_layout_beams(
    document: LayoutBeamsDocument | dict[str, Any], progress: ProgressCallback = no_progress
) -> dict[str, Any]:
    """A layout and UE maps → the beam report (``POST /v1/power-allocations`` with maps):
    pairs as a plan builds them, the layout's expected-random metric by ``compute_bounds``,
    then :func:`evaluate_layout_beams`."""
    from ris_planner.planning.inputs.ue_maps import build_map, build_pairs, unordered_directions

    doc = (
        document
        if isinstance(document, LayoutBeamsDocument)
        else LayoutBeamsDocument.model_validate(document)
    )
    tx_map = build_map(doc.tx_map, "tx_map")
    rx_map = build_map(doc.rx_map, "rx_map")
    directions = unordered_directions(doc.pairs, doc.objective.metric, tuple(doc.known))
    pairs = build_pairs(tx_map, rx_map, doc.pairs, doc.max_pairs, directions == "explicit")
    scenario = layout_scenario(doc.system, list(doc.ris), list(doc.known), doc.environment)
    expected = compute_bounds(scenario, pairs.tx, pairs.rx, profiles=None)
    metric = select_metric(doc.objective.metric, expected.peb_tx, expected.peb_rx)
    mirror = directions == "mirror"
    if mirror:
        assert expected.peb_tx is not None  # mirror needs an unknown TX (unordered_directions)
        reverse = select_metric(doc.objective.metric, expected.peb_rx, expected.peb_tx)
        metric = np.concatenate([metric, reverse])
    served = served_pairs(Scene.from_environment(doc.environment), list(doc.ris), pairs)
    spec = doc.beams
    report = evaluate_layout_beams(
        scenario,
        pairs,
        doc.objective,
        metric,
        served,
        seed=spec.seed,
        positions=spec.design_positions,
        random_seeds=spec.random_seeds,
        solver=spec.solver,
        mirror=mirror,
        progress=progress,
    )
    return {
        "objective_spec": doc.objective.model_dump(),
        "objective_better": objective_kind(doc.objective.kind).better,
        "pairs": pairs.size,
        **report.to_json(),
    }
