"""Plan validation: the paper's two-stage estimator (Algorithms 1 and 2) on each recommended
layout, at pairs sampled from the plan's own maps (plan.json ``validation``).

One stage of :func:`~ris_planner.planning.run_plan` (:func:`run_estimator_check`, its own
``timing_s`` entry and progress). For each count's best layout:

* ``pairs`` TX–RX pairs are drawn with replacement ∝ the plan's pair weights (seed
  ``[seed, 0]``; with mirrored unordered pairs each draw also picks its direction), the same
  pairs for every layout;
* the layout's codebook (:func:`layout_codebook`) is, when the plan designed its beams
  (``beams``) and ``codebook`` is ``"plan"``, the designed profiles and beam powers of
  ``design`` (default the one with the best plan objective on all pairs), else a ``random``
  codebook of seed ``seed`` (the plan scores with the expected-random FIM, which is an
  expectation, not profiles a RIS can apply); the signal and the bounds use the same one;
* the received signal (eq. signal_model) is simulated with the environment's blockage (a
  blocked or out-of-view leg carries no path), the document's diffuse ``multipath`` and, with
  ``reflections``, the site's first-order specular reflections; gain phases and noise come
  from seed ``[seed, 1, pair, draw]``;
* Algorithm 1 then Algorithm 2 run with the TX candidates of a region a deployment knows: the
  TX map's extent (or ``search_region``), never centred on the true TX, on a ``step_m`` grid
  coarsened until it holds ≤ ``max_candidates`` points (:func:`search_candidates`);
* each pair's error (RMSE over the draws of the objective's metric: ‖p̂_R − p_R‖,
  ‖p̂_T − p_T‖ or their max) is set next to PEB_T, PEB_R, CEB of the same configuration
  (``compute_bounds`` with that codebook and its powers, nothing known: the estimator
  estimates all of p_T, p_R, B).

Outliers (a draw whose error exceeds :data:`OUTLIER_FACTOR` × the pair's bound) get a cause
(:func:`classify_draw`): ``ghost`` (another solution of the position equations fits the
channel estimates as well as the truth: the TX↔RX swap, or an exact second solution of an
exactly-determined geometry), ``threshold_snr`` (the channel estimates themselves are off:
below the SNR threshold the MLE leaves the main lobe), ``multipath_bias`` (they are off with
strong paths and multipath or reflections in the signal), ``coarse_failed`` (the coarse
stage found no consistent candidate, or started the refinement in a wrong basin) and
``not_enough_paths``
(fewer paths than Algorithm 2 needs: LOS + 2 RISs, or 3 RISs without LOS). A covered pair
(bound ≤ threshold) whose error exceeds :data:`SHORTFALL_RATIO` × its bound is a shortfall;
its cause is the most frequent outlier cause of its draws, else ``multipath_bias`` when the
channel estimates are biased by multipath, else ``threshold_snr`` when its weakest path's
integrated SNR is below :data:`SNR_THRESHOLD_DB`, else ``few_draws`` (no outlier, strong
paths: the RMSE of a few draws scatters). A misfit channel estimate is ``threshold_snr`` when
the weakest path is below that SNR, else ``multipath_bias`` with multipath in the signal, else
``coarse_failed`` (the coarse FFT picked a wrong peak). With the LOS the swap
always gives the same η, so ``estimator_coverage_swap_resolved`` also counts each draw's error
up to it (what a deployment that knows which UE is the TX reaches).
docs/validation/estimator.md.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import compute_bounds
from ris_planner.core.errors import RisPlannerError
from ris_planner.core.io_json import finite_or_none
from ris_planner.estimation.channel_estimation import ChannelEstimate, wrap
from ris_planner.estimation.pipeline import Estimator
from ris_planner.estimation.position_estimation import (
    EstimationError,
    channel_model,
    observation,
    whitening,
)
from ris_planner.estimation.signal import (
    Paths,
    RisArray,
    SignalSetup,
    direct_paths,
    noise_free_signal,
    realisation_paths,
    received_signal,
    separate_paths,
    signal_setup,
)
from ris_planner.model.scenario import RIS, ExplicitCodebook, RandomCodebook, Scenario
from ris_planner.model.simulation import EstimatorSettings, Multipath
from ris_planner.physics.separable import beam_block, grid_axes
from ris_planner.planning.beams import BeamReport
from ris_planner.planning.scoring.sparse import SparseScorer
from ris_planner.runtime.progress import ProgressCallback, no_progress

if TYPE_CHECKING:
    from ris_planner.model.plan import PlanDocument, ValidationSpec
    from ris_planner.planning.beams import DesignedCodebook
    from ris_planner.planning.outputs.result import PlanResult
    from ris_planner.planning.search.layouts import Layout

FloatArray = NDArray[np.float64]

OUTLIER_FACTOR = 4.0
"""A draw is an outlier when its error exceeds this many times the pair's bound: for an
efficient Gaussian estimator P(‖e‖ > 4·PEB) < 7·10⁻⁵ (all variance on one axis, the worst
case), so outliers are failures of the estimator, not noise."""
SHORTFALL_RATIO = 1.5
"""A covered pair whose RMSE exceeds this many times its bound is a shortfall."""
CHI2_PROBABILITY = 0.999
"""Quantile of the χ² tests of :func:`classify_draw` (a fit or channel estimate is called
bad only when noise explains it with probability < 0.1 %)."""
SECONDS_PER_ESTIMATE = 0.08
"""Work estimate of one estimate (simulation + Algorithms 1 and 2) for the progress bar."""
SNR_THRESHOLD_DB = 18.0
"""Weakest-path integrated SNR (:func:`path_snr_db`) below which a misfit channel estimate is
put down to the SNR threshold: Table I's estimator leaves its bound below ≈ 15 dBm
(docs/guides/estimation.md), where its weakest path has 17.8 dB (32.8 dB at 30 dBm)."""
CAUSES = (
    "ghost",
    "threshold_snr",
    "multipath_bias",
    "coarse_failed",
    "not_enough_paths",
    "few_draws",
)


def chi2_quantile(probability: float, dof: int) -> float:
    """The χ² distribution's ``probability`` quantile with ``dof`` degrees of freedom
    (scipy.stats.chi2.ppf; imported here, on first use: scipy.stats costs a plan that does
    not validate ~1 s of start-up)."""
    from scipy.stats import chi2

    return float(chi2.ppf(probability, dof))


def validation_work(spec: ValidationSpec, n_layouts: int) -> float:
    """Estimated seconds of the validation (for the progress bar's shares)."""
    return SECONDS_PER_ESTIMATE * spec.pairs * spec.draws * max(n_layouts, 1)


def search_candidates(
    spec: ValidationSpec, tx_points: FloatArray
) -> tuple[FloatArray, dict[str, Any]]:
    """TX candidates [Q, 3] of the coarse position search and their description.

    The box is ``spec.search_region`` or the TX map's extent (what a deployment knows: where
    TXs may be, not where this one is); the grid step is ``spec.step_m``, grown by factors of
    1.25 until the grid holds ≤ ``spec.max_candidates`` points."""
    if spec.search_region is not None:
        assert spec.search_region.min_m is not None  # the lon/lat form is converted before
        lo = np.asarray(spec.search_region.min_m, float)
        hi = np.asarray(spec.search_region.max_m, float)
        source = "search_region"
    else:
        lo, hi = tx_points.min(axis=0), tx_points.max(axis=0)
        source = "tx_map_extent"
    step = float(spec.step_m)
    while True:
        counts = np.floor((hi - lo) / step + 1e-9).astype(int) + 1
        if int(np.prod(counts.astype(float))) <= spec.max_candidates:
            break
        step *= 1.25
    axes = [lo[i] + step * np.arange(counts[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    info = {
        "source": source,
        "min_m": [float(v) for v in lo],
        "max_m": [float(v) for v in hi],
        "step_m": step,
        "candidates": int(grid.shape[0]),
    }
    return grid, info


def sample_pairs(
    result: PlanResult, n: int, seed: int
) -> tuple[FloatArray, FloatArray, NDArray[np.int_]]:
    """(tx [n, 3], rx [n, 3], pair index [n]) drawn with replacement ∝ the plan's weights; with
    mirrored unordered pairs each draw is reversed with probability ½ (the plan counts both
    directions with half the weight each)."""
    pairs = result.pairs
    rng = np.random.default_rng([seed, 0])
    w = pairs.weights / pairs.weights.sum()
    pick = rng.choice(pairs.size, n, replace=True, p=w)
    tx, rx = pairs.tx[pick].copy(), pairs.rx[pick].copy()
    if result.scorer.mirror:
        flip = rng.uniform(size=n) < 0.5
        tx[flip], rx[flip] = pairs.rx[pick][flip], pairs.tx[pick][flip]
    return tx, rx, pick


def pair_scenario(base: Scenario, tx: FloatArray, rx: FloatArray) -> Scenario:
    """The layout's scenario for one pair (built anew: the scenario caches its arrays)."""
    return Scenario.model_construct(
        system=base.system,
        ris=base.ris,
        tx=[float(v) for v in tx],
        rx=[float(v) for v in rx],
        codebook=base.codebook,
        known=[],
        environment=base.environment,
    )


def layout_base(
    doc: PlanDocument, ris: list[RIS], seed: int, design: DesignedCodebook | None = None
) -> Scenario:
    """The layout's scenario with nothing known and a seeded random codebook, or the designed
    codebook's profiles as an ``explicit`` one (their phases: the profiles are unit modulus)."""
    codebook: RandomCodebook | ExplicitCodebook = (
        RandomCodebook(seed=seed)
        if design is None
        else ExplicitCodebook.model_construct(
            kind="explicit", phases=[np.angle(p).tolist() for p in design.profiles]
        )
    )
    return Scenario.model_construct(
        system=doc.system,
        ris=ris,
        tx=[0.0, 0.0, 0.0],
        rx=[1.0, 0.0, 0.0],
        codebook=codebook,
        known=[],
        environment=doc.environment,
    )


def layout_codebook(
    result: PlanResult, layout: Layout
) -> tuple[DesignedCodebook | None, dict[str, Any]]:
    """(the designed codebook the layout is validated with or ``None`` for the seeded random
    one, plan.json's description of it). With ``validation.codebook = "plan"`` and the
    layout's beams designed (``document.beams``): ``validation.design``, ``best`` = the design
    with the best plan objective on all pairs (:meth:`BeamReport.best_design`); a design that
    is missing (the SDP did not solve) falls back to the best one, said in ``note``."""
    from ris_planner.model.objectives import objective_kind

    doc = result.document
    spec = doc.validation
    assert spec is not None
    random = {"kind": "random", "seed": spec.seed}
    report = result.beams.get(layout)
    if spec.codebook == "random" or not isinstance(report, BeamReport):
        return None, random
    best = report.best_design(objective_kind(doc.objective.kind).better)
    name: str | None = spec.design
    note = None
    if name == "best" or name not in report.codebooks:
        if name != "best":
            note = f"design {name!r} is not available for this layout; the best design used"
        name = best
    if name is None:
        return None, {**random, "note": "no designed codebook with a finite objective"}
    design = report.codebooks[name]
    return design, {
        **design.describe(),
        "seed": doc.beams.seed if doc.beams is not None else None,
        "objective_on_pairs": report.objective.get(name),
        **({"note": note} if note else {}),
    }


def path_snr_db(setup: SignalSetup) -> dict[str, float]:
    """Integrated SNR of each direct path present, ‖μ_m‖²/σ² in dB (μ_m: the path's noise-free
    signal over all K subcarriers and G transmissions, eq. signal_model): the threshold effect
    sets in when a path's is near or below ~10–15 dB (the coarse FFT peaks drown in noise)."""
    sc = setup.scenario
    paths = direct_paths(setup, sc.tx_array[0], sc.rx_array[0], 0.0, np.zeros(setup.n_ris + 1))
    out = {}
    for k in range(paths.ris.size):
        sl = slice(k, k + 1)
        one = Paths(
            ris=paths.ris[sl],
            length=paths.length[sl],
            gain=paths.gain[sl],
            xi=paths.xi[sl],
            zeta=paths.zeta[sl],
            direct=paths.direct[sl],
        )
        energy = float(np.sum(np.abs(noise_free_signal(setup, one)) ** 2))
        name = "los" if paths.ris[k] == 0 else f"ris{int(paths.ris[k])}"
        out[name] = 10 * math.log10(max(energy / setup.noise_variance_w, 1e-300))
    return out


def enough_paths(setup: SignalSetup) -> bool:
    """Whether Algorithm 2 can run: LOS and ≥ 2 RIS paths, or ≥ 3 RIS paths (Remark)."""
    n = len(setup.ris_present)
    return n >= 2 if setup.los else n >= 3


def fit_chi2(
    ris: tuple[RisArray, ...],
    wavelength: float,
    los: bool,
    channel: ChannelEstimate,
    state: FloatArray,
) -> float:
    """‖W (η̂ − η(s))‖² with W^T W = EFIM of the refined channel estimate (Σ = CRB): the
    misfit of state ``s`` to the channel estimates in units of their own noise (ξ, ζ
    residuals modulo their period λ/d, as the position MLE takes them)."""
    eta_hat = observation(channel, los)
    eta, _ = channel_model(ris, los, state)
    e = eta_hat - eta
    at = 1 if los else 0
    for w, arr in enumerate(ris):
        i = at + 3 * w
        e[i : i + 2] = wrap(e[i : i + 2], arr.period(wavelength))
    try:
        wmat = whitening(channel, los, "crb")
    except np.linalg.LinAlgError:
        # a singular EFIM (a designed codebook whose beams all point one way carries no angle
        # information off its beam): the same misfit as the quadratic form eᵀ F e, which
        # counts only the directions the channel estimate informs
        return _quadratic_misfit(channel, los, e)
    return float(np.sum((wmat @ e) ** 2))


def _quadratic_misfit(channel: ChannelEstimate, los: bool, e: FloatArray) -> float:
    """eᵀ F e with F the block-diagonal EFIM of the channel estimate (as :func:`whitening`
    lays it out), for a positive semidefinite F."""
    assert channel.efim is not None
    blocks = [b for b in (channel.efim if los else channel.efim[1:]) if b is not None]
    total, at = 0.0, 0
    for b in blocks:
        m = b.shape[0]
        total += float(e[at : at + m] @ b @ e[at : at + m])
        at += m
    return max(total, 0.0)


def classify_draw(
    error: float,
    bound: float,
    swap: bool,
    chi_est: float,
    chi_true: float,
    n_obs: int,
    biased_signal: bool,
    weakest_snr_db: float,
) -> str | None:
    """The cause of an outlier draw (``None``: not an outlier; the module docstring)."""
    if not error > OUTLIER_FACTOR * bound:
        return None
    if swap:
        return "ghost"
    if chi_true > chi2_quantile(CHI2_PROBABILITY, n_obs):  # the channel estimates are off
        if weakest_snr_db < SNR_THRESHOLD_DB:
            return "threshold_snr"
        return "multipath_bias" if biased_signal else "coarse_failed"
    if chi_est <= max(chi_true, chi2_quantile(CHI2_PROBABILITY, max(n_obs - 7, 1))):
        return "ghost"
    return "coarse_failed"


def _metric(doc_metric: str, e_tx: float, e_rx: float) -> float:
    if doc_metric == "rx":
        return e_rx
    if doc_metric == "tx":
        return e_tx
    return max(e_tx, e_rx)


def validation_threshold(doc: PlanDocument) -> float:
    """The coverage threshold: ``validation.threshold_m``, else the objective kind's
    :meth:`~ris_planner.model.objectives.protocol.ObjectiveKind.check_level` (its threshold or
    cap)."""
    from ris_planner.model.objectives import objective_kind

    spec = doc.validation
    assert spec is not None
    obj = doc.objective
    value = spec.threshold_m or objective_kind(obj.kind).check_level(obj)
    if value is None:
        raise RisPlannerError(
            f"validation.threshold_m: a {obj.kind} objective has no threshold; give one (metres)"
        )
    return float(value)


def check_pair(
    setup: SignalSetup,
    candidates: FloatArray,
    spec: ValidationSpec,
    multipath: Multipath,
    pair: int,
    bounds: tuple[float, float, float],
    metric_name: str,
    weakest_snr_db: float,
) -> dict[str, Any]:
    """Every draw of one pair: errors, outliers with their causes, times."""
    sc = setup.scenario
    truth = np.concatenate([sc.tx_array[0], sc.rx_array[0], [sc.system.clock_offset_m]])
    peb_tx, peb_rx, _ceb = bounds
    bound = _metric(metric_name, peb_tx, peb_rx)
    biased = spec.reflections or not multipath.empty
    est = Estimator(setup, EstimatorSettings(), candidates)
    used = setup.ris_present
    ris_used = tuple(setup.ris[i] for i in used)
    n_obs = (1 if setup.los else 0) + 3 * len(used)
    errors = np.full((spec.draws, 3), np.inf)  # ‖Δp_T‖, ‖Δp_R‖, |ΔB| per draw
    coarse = np.full((spec.draws, 2), np.inf)
    chi_true = np.full(spec.draws, np.nan)
    resolved = np.full(spec.draws, np.inf)  # the metric's error up to the TX↔RX swap
    outliers: list[dict[str, Any]] = []
    seconds = 0.0
    for d in range(spec.draws):
        rng = np.random.default_rng([spec.seed, 1, pair, d])
        paths = realisation_paths(setup, multipath, rng)
        ytilde = separate_paths(setup, received_signal(setup, paths, rng))
        t0 = time.perf_counter()
        try:
            fe = est.estimate(ytilde)
        except EstimationError as exc:
            seconds += time.perf_counter() - t0
            outliers.append({"draw": d, "cause": "coarse_failed", "detail": str(exc)})
            continue
        seconds += time.perf_counter() - t0
        s = fe.position_refined.state
        err = s - truth
        err[6] = wrap(err[6], setup.delay_period_m)
        errors[d] = [np.linalg.norm(err[0:3]), np.linalg.norm(err[3:6]), abs(err[6])]
        c = fe.position_coarse.state - truth
        coarse[d] = [np.linalg.norm(c[0:3]), np.linalg.norm(c[3:6])]
        e_metric = _metric(metric_name, errors[d, 0], errors[d, 1])
        e_swapped = _metric(
            metric_name,
            float(np.linalg.norm(s[3:6] - truth[0:3])),
            float(np.linalg.norm(s[0:3] - truth[3:6])),
        )
        resolved[d] = min(e_metric, e_swapped)
        swap_tol = OUTLIER_FACTOR * max(peb_tx, peb_rx)
        swap = bool(
            np.linalg.norm(s[0:3] - truth[3:6]) <= swap_tol
            and np.linalg.norm(s[3:6] - truth[0:3]) <= swap_tol
        )
        ch = fe.channel_refined.restricted(used)
        chi_est = fit_chi2(ris_used, setup.wavelength, setup.los, ch, s)
        chi_true[d] = fit_chi2(ris_used, setup.wavelength, setup.los, ch, truth)
        cause = classify_draw(
            e_metric, bound, swap, chi_est, chi_true[d], n_obs, biased, weakest_snr_db
        )
        if cause is not None:
            outliers.append(
                {
                    "draw": d,
                    "cause": cause,
                    **(
                        {"ghost": "tx_rx_swap" if swap else "other_solution"}
                        if cause == "ghost"
                        else {}
                    ),
                    "detail": "TX↔RX swap"
                    if swap
                    else f"fit χ² {chi_est:.3g} vs truth {chi_true[d]:.3g} ({n_obs} observations)",
                    "error_m": finite_or_none(e_metric),
                    "tx_m": [float(v) for v in s[0:3]],
                    "rx_m": [float(v) for v in s[3:6]],
                }
            )
    rmse = np.sqrt(np.mean(errors**2, axis=0))
    error = _metric(metric_name, float(rmse[0]), float(rmse[1]))
    biased_channel = bool(
        biased and np.nanmean(chi_true) > chi2_quantile(CHI2_PROBABILITY, n_obs)
        if np.any(np.isfinite(chi_true))
        else False
    )
    return {
        "errors": errors,
        "rmse": rmse,
        "error": error,
        "error_swap_resolved": float(np.sqrt(np.mean(resolved**2))),
        "bound": bound,
        "coarse_rmse": np.sqrt(np.mean(coarse**2, axis=0)),
        "outliers": outliers,
        "seconds": seconds,
        "biased_channel": biased_channel,
    }


def shortfall_cause(
    outliers: list[dict[str, Any]], biased_channel: bool, weakest_snr_db: float
) -> str:
    """Why a covered pair misses its bound by > :data:`SHORTFALL_RATIO` (module docstring)."""
    if outliers:
        return Counter(o["cause"] for o in outliers).most_common(1)[0][0]
    if biased_channel:
        return "multipath_bias"
    return "threshold_snr" if weakest_snr_db < SNR_THRESHOLD_DB else "few_draws"


PairSetup = tuple[Scenario, list[int], FloatArray | None]
"""(the scenario a pair is simulated and bounded with, the candidate site of each of its RISs
(padding aside), the beam powers or None)."""


def pair_bounds(
    per_pair: list[PairSetup], tx: FloatArray, rx: FloatArray
) -> list[tuple[float, float, float]]:
    """(PEB_T, PEB_R, CEB) of each pair under its own scenario (``compute_bounds`` with the
    scenario's codebook and powers, nothing known), batched over the pairs that share one."""
    out: list[tuple[float, float, float]] = [(math.inf, math.inf, math.inf)] * len(tx)
    groups: dict[int, list[int]] = {}
    for j, (base, _, _) in enumerate(per_pair):
        groups.setdefault(id(base), []).append(j)
    for idx in groups.values():
        base, _, powers = per_pair[idx[0]]
        res = compute_bounds(base, tx=tx[idx], rx=rx[idx], beam_powers=powers)
        n = len(idx)
        peb_tx = res.peb_tx if res.peb_tx is not None else np.full(n, np.inf)
        ceb = res.ceb if res.ceb is not None else np.full(n, np.inf)
        for i, j in enumerate(idx):
            out[j] = (float(peb_tx[i]), float(res.peb_rx[i]), float(ceb[i]))
    return out


PAD_HEIGHT_M = 1000.0
"""Height of the padding RISs of a district pair's scenario (:func:`district_pair`): facing
up from there they serve no UE, so they carry no path and only fix Γ."""


def padding_ris(template: RIS) -> RIS:
    """A RIS that serves no UE (:data:`PAD_HEIGHT_M` above ``template``, facing up): it pads a
    scenario to the Γ − 1 RIS columns of a district's blocks and carries no path."""
    x, y = float(template.position[0]), float(template.position[1])
    return template.model_copy(
        update={"position": [x, y, PAD_HEIGHT_M], "orientation": [0.0, -math.pi / 2, 0.0]}
    )


def district_pair(result: PlanResult, layout: tuple[int, ...], pair: int, seed: int) -> PairSetup:
    """A district pair's scenario: the layout's RISs it hears audibly (their paths separated by
    the plan's profile colours; the others reach it by no path or below the noise over the
    whole pilot, :data:`~ris_planner.planning.scoring.sparse.AUDIBLE_SNR_DB`), each with its
    site's designed block – or a seeded random one under the expected-random codebook – in the
    plan's Γ blocks: RISs that serve no UE pad the scenario to Γ − 1 RIS columns (the columns
    the pair's RISs take among the district's colours do not change its information: B's
    columns are orthogonal and unit-modulus)."""
    scorer = result.scorer
    assert isinstance(scorer, SparseScorer)
    problem = scorer.problem
    doc = result.document
    timing = result.search_details.get("time_orthogonal") or {}
    blocks = int(timing.get("blocks") or problem.codebooks.blocks)
    lo, hi = problem.pair_start[pair], problem.pair_start[pair + 1]
    loud = set(problem.entry_site[lo:hi][problem.audible[lo:hi]].tolist())
    mine = [s for s in layout if s in loud]
    ris = [result.sites[s].ris for s in mine]
    pad_count = max(0, blocks - 1 - len(ris))
    pad = padding_ris(result.sites[layout[0]].ris)
    cb = problem.codebooks
    wavelength = doc.system.wavelength
    if cb.designed:
        profiles = [site_profiles(problem, s, result.sites[s].ris, wavelength) for s in mine]
        profiles += profiles[:1] * pad_count
        if not mine:
            codebook: RandomCodebook | ExplicitCodebook = RandomCodebook(seed=seed)
            powers = None
        else:
            codebook = ExplicitCodebook.model_construct(
                kind="explicit", phases=[np.angle(p).tolist() for p in profiles]
            )
            powers = cb.powers
    else:
        codebook, powers = RandomCodebook(seed=seed), None
    base = Scenario.model_construct(
        system=doc.system,
        ris=ris + [pad] * pad_count,
        tx=[0.0, 0.0, 0.0],
        rx=[1.0, 0.0, 0.0],
        codebook=codebook,
        known=[],
        environment=doc.environment,
    )
    return base, mine, powers


def site_profiles(problem: Any, site: int, ris: RIS, wavelength: float) -> Any:
    """[G̃, N] the designed first block of a district site (its beams' spatial frequencies as
    the plan stored them, :class:`~ris_planner.planning.scoring.sparse.Codebooks`)."""
    cb = problem.codebooks
    yc, zr = grid_axes(ris.rows, ris.cols, ris.element_spacing(wavelength))
    return beam_block(yc, zr, cb.xi[site], cb.zeta[site], cb.beam_types, wavelength).profiles()


def district_codebook(result: PlanResult, seed: int) -> dict[str, Any]:
    """plan.json's description of a district layout's codebook in the validation: each site's
    designed block (its kind, Γ, the slots' powers) or a seeded random one."""
    scorer = result.scorer
    assert isinstance(scorer, SparseScorer)
    cb = scorer.problem.codebooks
    if not cb.designed:
        return {"kind": "random", "seed": seed, "note": "each pair with the RISs that serve it"}
    return {
        "kind": "designed",
        "name": cb.kind,
        "design": "per site",
        "seed": result.document.codebook.seed or 0,
        "blocks": cb.blocks,
        "beams_per_block": int(cb.powers.size),
        "powers": "gamma_p" if cb.kind == "directional_derivative" else "uniform",
        "note": "each pair with the RISs that serve it, each RIS with its site's designed block",
    }


def check_layout(
    result: PlanResult,
    layout: tuple[int, ...],
    tx: FloatArray,
    rx: FloatArray,
    candidates: FloatArray,
    threshold: float,
    multipath: Multipath,
    progress: ProgressCallback,
    picks: NDArray[np.int_] | None = None,
) -> dict[str, Any]:
    """The validation of one layout (plan.json ``validation.layouts[i]``); ``picks``: the
    plan's pair index of each checked pair."""
    doc = result.document
    spec = doc.validation
    assert spec is not None
    metric_name = doc.objective.metric
    local = isinstance(result.scorer, SparseScorer)
    if local:  # a district layout: each pair with the RISs that serve it, in Γ blocks
        design, codebook = None, district_codebook(result, spec.seed)
        assert picks is not None, "a district layout is checked at the plan's own pairs"
        per_pair = [district_pair(result, layout, int(p), spec.seed) for p in picks]
    else:
        design, codebook = layout_codebook(result, layout)
        powers = None if design is None else design.powers
        base = layout_base(doc, [result.sites[s].ris for s in layout], spec.seed, design)
        per_pair = [(base, list(layout), powers)] * len(tx)
    rows: list[dict[str, Any]] = []
    causes: Counter[str] = Counter()
    shortfalls: Counter[str] = Counter()
    seconds, n_est = 0.0, 0
    bounds_all = pair_bounds(per_pair, tx, rx)
    for j in range(len(tx)):
        progress(j / len(tx), f"{len(layout)} RISs: pair {j + 1}/{len(tx)}")
        base_j, sites_j, powers_j = per_pair[j]
        setup = signal_setup(pair_scenario(base_j, tx[j], rx[j]), beam_powers=powers_j)
        bounds = bounds_all[j]
        bound = _metric(metric_name, bounds[0], bounds[1])
        row: dict[str, Any] = {
            "tx": [float(v) for v in tx[j]],
            "rx": [float(v) for v in rx[j]],
            "paths": {"los": setup.los, "ris": [int(sites_j[i]) for i in setup.ris_present]},
            "path_snr_db": path_snr_db(setup),
            "peb_tx_m": finite_or_none(bounds[0]),
            "peb_rx_m": finite_or_none(bounds[1]),
            "ceb_m": finite_or_none(bounds[2]),
            "bound_m": finite_or_none(bound),
        }
        if not enough_paths(setup):
            outl = [
                {
                    "draw": d,
                    "cause": "not_enough_paths",
                    "detail": f"LOS {'present' if setup.los else 'blocked'},"
                    f" {len(setup.ris_present)} RIS paths (Algorithm 2 needs LOS + 2 or 3)",
                }
                for d in range(spec.draws)
            ]
            res: dict[str, Any] = {
                "rmse": np.full(3, np.inf),
                "error": math.inf,
                "error_swap_resolved": math.inf,
                "coarse_rmse": np.full(2, np.inf),
                "outliers": outl,
                "biased_channel": False,
            }
        else:
            weakest = min(row["path_snr_db"].values())
            res = check_pair(setup, candidates, spec, multipath, j, bounds, metric_name, weakest)
            seconds += res["seconds"]
            n_est += spec.draws
        error = float(res["error"])
        covered_b = bool(bound <= threshold)
        ratio = error / bound if math.isfinite(bound) and bound > 0 else math.inf
        shortfall = None
        if covered_b and not ratio <= SHORTFALL_RATIO:
            snrs = row["path_snr_db"].values()
            shortfall = shortfall_cause(
                res["outliers"], res["biased_channel"], min(snrs) if snrs else -math.inf
            )
            shortfalls[shortfall] += 1
        for o in res["outliers"]:
            causes[o["cause"]] += 1
        row.update(
            {
                "rmse_tx_m": finite_or_none(float(res["rmse"][0])),
                "rmse_rx_m": finite_or_none(float(res["rmse"][1])),
                "rmse_clock_m": finite_or_none(float(res["rmse"][2])),
                "coarse_rmse_tx_m": finite_or_none(float(res["coarse_rmse"][0])),
                "coarse_rmse_rx_m": finite_or_none(float(res["coarse_rmse"][1])),
                "error_m": finite_or_none(error),
                "ratio": finite_or_none(ratio),
                "bound_covered": covered_b,
                "estimator_covered": bool(error <= threshold),
                "error_swap_resolved_m": finite_or_none(float(res["error_swap_resolved"])),
                "outliers": res["outliers"],
                "shortfall": shortfall,
            }
        )
        rows.append(row)
    progress(1.0, f"{len(layout)} RISs done")
    n = len(rows)
    n_covered = sum(r["bound_covered"] for r in rows)
    ratios = [r["ratio"] for r in rows if r["bound_covered"] and r["ratio"] is not None]
    weakest = [min(r["path_snr_db"].values()) for r in rows if r["shortfall"] and r["path_snr_db"]]
    by_count = next(cr for cr in result.counts if cr.ranked[0][0] == layout)
    return {
        "ris_count": len(layout),
        "sites": [int(s) for s in layout],
        "codebook": codebook,
        "estimator_coverage": sum(r["estimator_covered"] for r in rows) / n,
        "bound_coverage": n_covered / n,
        "estimator_coverage_swap_resolved": sum(
            (r["error_swap_resolved_m"] or math.inf) <= threshold for r in rows
        )
        / n,
        "plan_loss": finite_or_none(float(by_count.ranked[0][1])),
        "outliers": {c: causes.get(c, 0) for c in CAUSES},
        "outlier_fraction": sum(causes.values()) / (n * spec.draws),
        "shortfall": {
            "ratio": SHORTFALL_RATIO,
            "covered_pairs": n_covered,
            "count": sum(shortfalls.values()),
            "by_cause": {c: shortfalls.get(c, 0) for c in CAUSES},
            "median_weakest_path_snr_db": finite_or_none(float(np.median(weakest)))
            if weakest
            else None,
        },
        "median_ratio_covered": finite_or_none(float(np.median(ratios))) if ratios else None,
        "seconds_per_estimate": seconds / n_est if n_est else None,
        "pairs": rows,
    }


def summary_lines(validation: dict[str, Any]) -> list[str]:
    """The CLI's honest summary of plan.json ``validation``: per layout the estimator's
    coverage next to the bound's, and why and how often it falls short."""
    lines = []
    thr = validation["threshold_m"]
    for lay in validation["layouts"]:
        head = (
            f"validation {lay['ris_count']} RIS {lay['sites']}: estimator coverage"
            f" {lay['estimator_coverage']:.2f} vs bound {lay['bound_coverage']:.2f}"
            f" (error ≤ {thr:g} m, {validation['pairs']} pairs × {validation['draws']} draws)"
        )
        if lay["outliers"]["ghost"]:
            head += f" ({lay['estimator_coverage_swap_resolved']:.2f} with the TX↔RX roles known)"
        sf = lay["shortfall"]
        if sf["count"]:
            why = ", ".join(f"{c} {k}" for c, k in sf["by_cause"].items() if k)
            head += (
                f"; short of the bound (> {sf['ratio']:g}×) at {sf['count']} of"
                f" {sf['covered_pairs']} covered pairs: {why}"
            )
            if sf["median_weakest_path_snr_db"] is not None:
                head += f" (median weakest-path SNR {sf['median_weakest_path_snr_db']:.1f} dB)"
        out = {c: k for c, k in lay["outliers"].items() if k}
        if out:
            head += "; outlier draws: " + ", ".join(f"{c} {k}" for c, k in out.items())
        lines.append(head)
    return lines


def overall_codebook(spec: ValidationSpec, layouts: list[dict[str, Any]]) -> dict[str, Any]:
    """plan.json ``validation.codebook``: ``{"kind": "random", "seed"}`` when every layout ran
    the seeded random codebook, ``{"kind": "designed", "design", "powers", …}`` when every
    one ran a design (each layout's own in ``layouts[i].codebook``), else ``"mixed"``."""
    kinds = {lay["codebook"]["kind"] for lay in layouts}
    if kinds == {"designed"}:
        names = sorted({lay["codebook"]["name"] for lay in layouts})
        first = layouts[0]["codebook"]
        return {
            "kind": "designed",
            "setting": spec.design,
            "names": names,
            "design": first["design"] if len(names) == 1 else "per layout",
            "powers": first["powers"] if len(names) == 1 else "per layout",
            "seed": first["seed"],
        }
    if kinds <= {"random"}:
        return {"kind": "random", "seed": spec.seed}
    return {"kind": "mixed", "setting": spec.design, "seed": spec.seed}


def run_estimator_check(
    result: PlanResult, progress: ProgressCallback = no_progress
) -> dict[str, Any]:
    """plan.json ``validation``: every count's best layout checked by the estimator (module
    docstring). Reproducible: the same document and seed give the same numbers."""
    doc = result.document
    spec = doc.validation
    assert spec is not None
    threshold = validation_threshold(doc)
    multipath = Multipath.model_validate(
        {**(spec.multipath or {}), **({"site_reflections": True} if spec.reflections else {})}
    )
    candidates, region = search_candidates(spec, result.tx_map.points)
    tx, rx, picks = sample_pairs(result, spec.pairs, spec.seed)
    layouts = list(dict.fromkeys(cr.ranked[0][0] for cr in result.counts))
    out = []
    for i, lay in enumerate(layouts):

        def sub(f: float, m: str, i: int = i) -> None:
            progress((i + f) / len(layouts), m)

        out.append(check_layout(result, lay, tx, rx, candidates, threshold, multipath, sub, picks))
    body: dict[str, Any] = {
        "settings": spec.model_dump(mode="json"),
        "pairs": spec.pairs,
        "draws": spec.draws,
        "seed": spec.seed,
        "metric": doc.objective.metric,
        "threshold_m": threshold,
        "codebook": overall_codebook(spec, out),
        "multipath": not multipath.empty,
        "reflections": spec.reflections,
        "search_region": region,
        "known_ignored": list(doc.known),
        "wavefront_note": None
        if doc.system.wavefront == "planar"
        else "the estimator assumes planar wavefronts; the bounds use the plan's wavefront",
        "layouts": out,
    }
    body["summary"] = summary_lines(body)
    return body
