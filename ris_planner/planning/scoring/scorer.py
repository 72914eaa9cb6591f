"""Objectives over weighted pairs and the batched layout score.

Scoring a batch of layouts: LOS + Σ cached site matrices on the packed entries of the unknown
states, then the core's hybrid inversion (:func:`ris_planner.inversion.crb.crb_diagonal`: the
batched
LDLᵀ, and the square-root route over the cached per-site factors for the ill-conditioned
combinations) giving the CRB diagonal. :meth:`Scorer.metric` does the sum, the LDLᵀ, the trace
test and the metric in one compiled pass per (layout, pair)
(:func:`ris_planner.inversion._crb_jit.score_layouts`, the same operations as the numpy route of
:meth:`Scorer.metric_reference`, so the same bits) and sends only the flagged pairs that are
not ``inf`` anyway on to the square-root route. Known parts (``clock``, ``height``, ``tx``)
remove their rows before inversion, as :func:`ris_planner.bounds.compute.bounds_from_state_fim`
does.

With an environment the cache's per-pair presence masks make a pair ``inf`` in a layout where
its present paths give fewer geometric channel parameters than unknown states
(:func:`underdetermined`, the rule of ``compute_bounds``).

``mirror`` (unordered pairs, metric ``rx`` or ``tx``): each pair also counts in the reverse
direction with half the weight. Swapping TX and RX permutes the state FIM (the channel
parameters ξ, ζ, τ, τ0 are symmetric in the two UEs and the clock offset is shared), so the
reverse direction's PEB_R is this direction's PEB_T: one inversion gives both, and the metric
holds 2P values – this direction's, then the reverse's – weighted by :attr:`Scorer.metric_weights`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds.compute import kept_states, n_observations, uses_los_reference
from ris_planner.inversion.crb import FAST_TRACE_LIMIT, crb_diagonal, sqrt_crb_diagonal
from ris_planner.inversion.ldl import packed_index
from ris_planner.model.objectives.protocol import objective_kind
from ris_planner.model.plan import Objective
from ris_planner.model.scenario import KnownPart
from ris_planner.planning.scoring.site_cache import N_PACKED, N_STATES, KeptInformation, SiteCache
from ris_planner.planning.scoring.visibility import BoolArray
from ris_planner.runtime.kernels import parallel_kernel

if TYPE_CHECKING:
    from ris_planner.model.plan import Objective

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

BATCH_MATRICES = 24_576
"""Matrices per inner vector operation of :meth:`Scorer.metric_reference`: large enough to
amortise numpy's per-call overhead, small enough that the ~60 working vectors stay in cache
(measured on the 2-core dev machine: 7–10 M matrices/s at 16–32 k, 5.7 M/s at 131 k)."""

KERNEL_MATRICES = 1 << 21
"""(layout, pair) combinations per call of the compiled kernel: bounds the square-root
route's gathered factor rows (≤ a few % of them, ~40 MB at 7 × 7) and the route flags
(1 byte each); the kernel itself streams over pair blocks whatever the size."""

EXACT_SITES = 32
"""Sites per float64 rebuild of :meth:`Scorer.exact_metric` (a float32 cache's finalists):
bounds the rebuilt cache to 32 × P × 224 B (360 MB at 50 000 pairs) whatever their number."""

SCREEN_MARGIN = 1e-4
"""Relative margin on PEB² of the screen: a pair is settled (uncovered, or at the cap) only
when its sub-problem bound exceeds threshold² (or cap²) × (1 + 1e-4), far above the bound's own
rounding (≲ 1e-7, ``_crb_jit.SCREEN_PIVOT_RTOL``) and the full bound's accuracy (1e-6), so no
pair the full computation would put below it is screened out (tested against
:meth:`Scorer.metric`)."""

TX_STATES = (0, 1, 2)
RX_STATES = (3, 4, 5)


@dataclass(frozen=True)
class Scorer:
    """Everything a worker needs to score layouts (sent once per worker)."""

    cache: SiteCache
    weights: FloatArray
    objective: Objective
    known: tuple[KnownPart, ...]
    mirror: bool = False

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the per-process caches (the compiled score's inputs and the numpy
        readers' float64 copy of the selected entries): a worker builds its own."""
        state = dict(self.__dict__)
        state.pop("_kernel_inputs", None)
        state.pop("_selected", None)
        return state

    def __share_state__(self) -> dict[str, Any]:
        """The state pickled when the arrays are shared, not copied
        (:func:`ris_planner.runtime.executor.share_pickle`): the compiled score's inputs (the
        cache's block storage, referenced, and their small LOS blocks and masks) are built here
        once and go too, so the workers map them instead of each building its own."""
        self._kernel_inputs  # noqa: B018 - the cached property is built, then shared
        state = dict(self.__dict__)
        state.pop("_selected", None)
        return state

    def __post_init__(self) -> None:
        if self.cache.los_referenced != uses_los_reference(self.cache.los is not None, self.known):
            raise ValueError(
                "the site cache was built for other known parts than the scorer's"
                f" {list(self.known)}: pass known= to build_site_cache"
            )

    @property
    def states(self) -> tuple[list[int], list[int], list[int]]:
        """(kept states in natural order, positions in it of the metric's TX / RX states;
        both with ``mirror``)."""
        keep = [int(k) for k in kept_states(self.known)]
        metric = self.objective.metric
        both = self.mirror
        tx = [i for i, k in enumerate(keep) if k in TX_STATES] if metric != "rx" or both else []
        rx = [i for i, k in enumerate(keep) if k in RX_STATES] if metric != "tx" or both else []
        return keep, tx, rx

    @property
    def metric_weights(self) -> FloatArray:
        """Weights of the metric's columns: the pair weights, or [2P] halves with ``mirror``."""
        if not self.mirror:
            return self.weights
        return np.concatenate([self.weights, self.weights]) * 0.5

    @property
    def _src(self) -> IntArray:
        """[E] the cache's packed entries of the kept states, in the packing order of
        ldl.packed_index(n): (0,0), (1,0), (1,1), (2,0), … (0, 1, …, 27 when nothing is known)."""
        keep, _, _ = self.states
        src_idx = packed_index(N_STATES)
        n = len(keep)
        return np.array(
            [src_idx[keep[i], keep[j]] for i in range(n) for j in range(i + 1)], dtype=np.int64
        )

    @cached_property
    def _selected(self) -> tuple[FloatArray, FloatArray | None]:
        """The cache's packed entries of the kept states as float64 [E, S, P] (a copy of the
        block storage, made once per scorer and process by the numpy readers only)."""
        src = self._src
        _, los = self.selected_packed
        return self.cache.information(src if src.size < N_PACKED else None), los

    @property
    def selected_packed(self) -> tuple[KeptInformation, FloatArray | None]:
        """(site information on the kept states, read as float64 [E, F, P] slices, LOS [E, P]
        or ``None``), packed in :func:`ris_planner.inversion.ldl.packed_index` order (the
        certificates'
        relaxation and branch-and-bound read it)."""
        src = self._src
        los = self.cache.los
        if los is not None and src.size < los.shape[0]:
            los = los[src]
        return KeptInformation(self.cache, src), los

    @cached_property
    def _kernel_inputs(self) -> dict[str, Any]:
        """The compiled score's fixed arguments
        (:func:`ris_planner.inversion._crb_jit.score_layouts`):
        the cache's block storage itself (no copy) with the kept entries' index, the LOS
        information as blocks, masks as uint8, the metric's rows."""
        from ris_planner.inversion._crb_jit import to_blocks

        keep, tx, rx = self.states
        n = len(keep)
        src = self._src
        cache = self.cache
        none = np.zeros((0, 0), dtype=np.uint8)
        deg = cache.degenerate.view(np.uint8) if np.any(cache.degenerate) else none
        present, need = none, np.zeros(0, dtype=np.int64)
        if cache.counts_paths:
            assert cache.present is not None
            present = np.ascontiguousarray(cache.present).view(np.uint8)
            los_n = 0 if cache.los_present is None else cache.los_present.astype(np.int64)
            # RIS paths a pair needs: ceil((n − LOS present) / 3) (see underdetermined)
            need = np.broadcast_to(-((los_n - n) // 3), (cache.n_pairs,)).astype(np.int64)
        if self.mirror:
            rows = (rx, tx) if self.objective.metric == "rx" else (tx, rx)
            mode = 2
        elif tx and rx:
            rows, mode = (tx, rx), 1
        else:
            rows, mode = (tx or rx, tx or rx), 0
        los = np.zeros((0, 0, 0))
        if cache.los is not None:
            los = to_blocks(np.ascontiguousarray(cache.los[:, None, :]), src)[:, 0]
        return {
            "blocks": cache.blocks,
            "src": src,
            "los": np.ascontiguousarray(los),
            "n_pairs": cache.n_pairs,
            "n": n,
            "trace_limit": FAST_TRACE_LIMIT,
            "first": np.array(rows[0], dtype=np.int64),
            "second": np.array(rows[1], dtype=np.int64),
            "mode": mode,
            "degenerate": deg,
            "present": present,
            "need": need,
            "screen": self._screen_states(keep, rows[0], mode),
            "screen_m": len(rows[0]),
        }

    def _screen_states(self, keep: list[int], metric_rows: list[int], mode: int) -> IntArray:
        """The coverage screen's sub-problem (:func:`ris_planner.inversion._crb_jit.screen_chunk`):
        positions among the kept states of the other UE's height and the clock, then the
        metric's states; empty (no screen) unless a coverage or capped-mean objective scores
        one UE's PEB (their losses see only whether a PEB exceeds the threshold or the cap:
        the kind's :meth:`~ris_planner.model.objectives.protocol.ObjectiveKind.screen_level`)."""
        if objective_kind(self.objective.kind).screen_level(self.objective) is None or mode != 0:
            return np.zeros(0, dtype=np.int64)
        other_height = 5 if self.objective.metric == "tx" else 2
        nuisance = [i for i, k in enumerate(keep) if k in (other_height, 6)]
        return np.array([*nuisance, *metric_rows], dtype=np.int64)

    def _observations(self, n_ris: int) -> int | None:
        """Channel parameters of a layout of ``n_ris`` RISs and the LOS
        (:func:`ris_planner.bounds.compute.n_observations`; ``None`` for the spherical model)."""
        return n_observations(n_ris, self.cache.los is not None, self.cache.wavefront)

    def _screen_limit(self, n_ris: int) -> float:
        """The screen's limit on PEB² for layouts of ``n_ris`` RISs: (threshold or cap)² ×
        (1 + :data:`SCREEN_MARGIN`), else 0 (off). Where the cache has per-pair presence
        masks the kernel screens each pair at its own smallest identifiable count; without
        them the whole layout must be at it (as many channel parameters as unknown states)."""
        args = self._kernel_inputs
        n_obs = self._observations(n_ris)
        if not args["screen"].size or n_obs is None:
            return 0.0
        if not args["present"].size and n_obs > len(self.states[0]):
            return 0.0
        limit = objective_kind(self.objective.kind).screen_level(self.objective)
        assert limit is not None
        return float(limit**2 * (1 + SCREEN_MARGIN))

    def _blind(self, n_ris: int) -> bool:
        """Whether the layout-wide count of :func:`ris_planner.bounds.compute.n_observations` leaves
        every pair of an ``n_ris``-RIS layout underdetermined (its metric is then all ``inf``,
        as ``compute_bounds`` reports)."""
        n_obs = self._observations(n_ris)
        return n_obs is not None and n_obs < len(self.states[0])

    def metric(self, layouts: IntArray, screen: bool = False) -> FloatArray:
        """[B, P] metric bound (m) of each layout [B, L] and pair ([B, 2P] with ``mirror``);
        ``inf`` for blind spots. With ``screen`` (:meth:`loss` of a coverage or capped-mean
        objective), a pair at its smallest identifiable count (as many channel parameters as
        unknown states, where most pairs are ill-conditioned) that the kernel's sub-problem
        bound proves above the threshold or cap × (1 + :data:`SCREEN_MARGIN`) gets that bound
        instead of its PEB: the same loss, without the full factorisation or the square-root
        route (hall, 2 RISs: 86 % of the pairs, 3.4× faster). Pairs that see more RISs than
        they need are screened only while nearly all of those are settled (a city where
        nearly every pair stays above the cap): otherwise the vectorised LDLᵀ is as cheap as
        the screen (``_crb_jit.SCREEN_KEEP``).

        Bit for bit what ``compute_bounds`` gives for the layout (same FIM sum, LOS first, same
        square-root factors, and the core's inversion,
        :func:`ris_planner.inversion.crb.crb_diagonal`):
        the compiled kernel (:func:`ris_planner.inversion._crb_jit.score_layouts`) sums, factors
        and scores
        each (layout, pair) in one pass; the pairs it flags go to the square-root route
        (:func:`ris_planner.inversion.crb.sqrt_crb_diagonal`). :meth:`metric_reference` is the same
        score
        in numpy (identical bits; tested)."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=np.int64))
        out = np.empty((layouts.shape[0], self.metric_weights.size))
        for _ in self._metric_blocks(layouts, screen, out):
            pass
        return out

    def _metric_blocks(
        self, layouts: IntArray, screen: bool, out: FloatArray | None = None
    ) -> Iterator[tuple[int, FloatArray]]:
        """(first row, [nb, P] metric) of :meth:`metric` for layouts [B, L] (int64), one kernel
        call of ≤ :data:`KERNEL_MATRICES` combinations at a time, written into ``out`` [B, P]
        or, without it, into one reused block (:meth:`loss` never holds the whole [B, P])."""
        from ris_planner.inversion._crb_jit import n_tasks, score_layouts

        (b_all, n_ris), p = layouts.shape, self.cache.n_pairs
        _, tx, rx = self.states
        step = max(1, KERNEL_MATRICES // p)
        reuse = out is None
        target = np.empty((min(step, b_all), self.metric_weights.size)) if out is None else out
        blind = self._blind(n_ris)
        limit = self._screen_limit(n_ris) if screen and not blind else 0.0
        route = np.empty((0 if blind else min(step, b_all), p), dtype=np.uint8)
        for b0 in range(0, b_all, step):
            nb = min(step, b_all - b0)
            block = target[:nb] if reuse else target[b0 : b0 + nb]
            if blind:
                block[:] = np.inf
                yield b0, block
                continue
            lay = np.ascontiguousarray(layouts[b0 : b0 + nb])
            with parallel_kernel():
                score_layouts(
                    layouts=lay,
                    out=block,
                    route=route[:nb],
                    n_tasks=n_tasks(),
                    screen_limit=limit,
                    **self._kernel_inputs,
                )
            slow = np.flatnonzero(route[:nb])
            if slow.size:
                diag, _ = sqrt_crb_diagonal(self._gathered_rows(lay, slow))
                b, pair = np.divmod(slow, p)
                if self.mirror:
                    both = self._mirrored(diag.T, tx, rx, 1)[0]
                    block[b, pair], block[b, p + pair] = both[: slow.size], both[slow.size :]
                else:
                    block[b, pair] = self._bound(diag.T, tx, rx)
            yield b0, block

    def metric_reference(self, layouts: IntArray) -> FloatArray:
        """:meth:`metric` in numpy: the gather-and-add of [E, nb, P] blocks, the batched LDLᵀ of
        :mod:`ris_planner.inversion.ldl` through :func:`ris_planner.inversion.crb.crb_diagonal`,
        and the masks
        applied afterwards (the route before the compiled kernel; the same bits)."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=np.int_))
        out = np.empty((layouts.shape[0], self.metric_weights.size))
        if self._blind(layouts.shape[1]):
            out[:] = np.inf
            return out
        (b_all, n_ris), p = layouts.shape, self.cache.n_pairs
        keep, tx, rx = self.states
        n = len(keep)
        packed, los = self._selected
        step = max(1, BATCH_MATRICES // p)
        deg = self.cache.degenerate
        any_deg = bool(np.any(deg))
        for b0 in range(0, b_all, step):
            lay = layouts[b0 : b0 + step]
            nb = lay.shape[0]
            # [E, nb, P], in the core's order: ((LOS + RIS 1) + RIS 2) + …
            a = packed[:, lay[:, 0]]
            if los is not None:
                np.add(los[:, None, :], a, out=a)
            for col in range(1, n_ris):
                a += packed[:, lay[:, col]]
            diag, _ = crb_diagonal(
                a.reshape(len(packed), nb * p), n, self._factor_rows(lay), engine="numpy"
            )
            if self.mirror:
                block = self._mirrored(diag, tx, rx, nb)
            else:
                block = self._bound(diag, tx, rx).reshape(nb, p)
            if any_deg:
                block[np.tile(np.any(deg[lay], axis=1), block.shape[1] // p)] = np.inf
            under = underdetermined(self.cache, lay, n)
            if under is not None:
                block[np.tile(under, block.shape[1] // p)] = np.inf
            out[b0 : b0 + nb] = block
        return out

    def _gathered_rows(self, lay: IntArray, idx: IntArray) -> FloatArray:
        """``self._factor_rows(lay)(idx)``: the square-root rows of the flagged combinations."""
        return self._factor_rows(lay)(idx)

    def _factor_rows(self, lay: IntArray) -> Callable[[IntArray], FloatArray]:
        """``factors(idx)`` over the flattened (layout, pair) index of a block: the stacked
        square-root rows [len(idx), n_obs, kept] in the core's path order (LOS, RIS 1, …),
        the sites' rows from :meth:`SiteCache.factor_rows` (recomputed for just these pairs
        where the cache does not store them)."""
        keep, _, _ = self.states
        cache = self.cache

        def rows(idx: IntArray) -> FloatArray:
            b, pair = np.divmod(idx, cache.n_pairs)
            n_l = lay.shape[1]
            sites = cache.factor_rows(lay[b].reshape(-1), np.repeat(pair, n_l))
            parts = [] if cache.los_factor is None else [cache.los_factor[pair]]
            parts.append(sites.reshape(idx.size, -1, N_STATES))  # [N, L·m, 7], column order
            return np.concatenate(parts, axis=1)[:, :, keep]

        return rows

    @staticmethod
    def _peb(diag: FloatArray, rows: list[int]) -> FloatArray:
        """sqrt of the summed CRB diagonal in the core's order (``diag[:, cols].sum(axis=1)``)."""
        acc = diag[rows[0]].copy()
        for r in rows[1:]:
            acc += diag[r]
        return np.sqrt(acc)

    @classmethod
    def _bound(cls, diag: FloatArray, tx: list[int], rx: list[int]) -> FloatArray:
        """The metric from the CRB diagonal: PEB_T, PEB_R or their maximum."""
        if tx and rx:
            return np.maximum(cls._peb(diag, tx), cls._peb(diag, rx))
        return cls._peb(diag, tx or rx)

    def _mirrored(self, diag: FloatArray, tx: list[int], rx: list[int], nb: int) -> FloatArray:
        """[nb, 2P]: the metric of this direction, then of the reverse one (PEB_R of the
        reverse is PEB_T of this direction, and vice versa)."""
        peb_t, peb_r = self._peb(diag, tx).reshape(nb, -1), self._peb(diag, rx).reshape(nb, -1)
        first, second = (peb_r, peb_t) if self.objective.metric == "rx" else (peb_t, peb_r)
        return np.concatenate([first, second], axis=1)

    def far_field_of(self, layout: Sequence[int]) -> BoolArray:
        """[P] whether every site of ``layout`` has the pair in its far field
        (:class:`~ris_planner.planning.scoring.layout_scorer.LayoutScorer`)."""
        return np.asarray(np.all(self.cache.far_field[list(layout)], axis=0))

    def near_field_by_site(self, weights: FloatArray) -> FloatArray:
        """[S] per site the weight of the pairs it has in its near field."""
        return np.asarray((~self.cache.far_field) @ weights, dtype=np.float64)

    def serves(self, layout: Sequence[int]) -> BoolArray:
        """[L, P] whether each site of ``layout`` has a RIS path to each pair (every one
        without presence masks)."""
        present = self.cache.present
        if present is None:
            return np.ones((len(layout), self.cache.n_pairs), dtype=bool)
        return np.asarray(present[list(layout)])

    def idle_sites(self) -> IntArray:
        """The sites that serve no pair (none without presence masks: every path exists)."""
        present = self.cache.present
        if present is None:
            return np.zeros(0, dtype=np.int64)
        return np.flatnonzero(~present.any(axis=1))

    def servable(self) -> BoolArray:
        """[P] the pairs a layout of every candidate gives a finite bound: the planar
        counting rule on the present paths (3 channel parameters per RIS path, 1 for LOS, at
        least the unknown states), the spherical model's bound with every site."""
        cache = self.cache
        if cache.wavefront == "spherical":
            every = np.arange(cache.n_sites)[None]
            metric = self.metric(every)[0]
            n = cache.n_pairs
            return np.isfinite(metric[:n]) & (np.isfinite(metric[n:]) if self.mirror else True)
        paths = cache.n_sites if cache.present is None else cache.present.sum(axis=0)
        los: IntArray | int = 0 if cache.los is None else 1
        if cache.los_present is not None:
            los = cache.los_present.astype(int)
        return np.asarray(los + 3 * paths >= len(kept_states(self.known)))

    def storage_json(self) -> dict[str, Any]:
        """plan.json ``site_cache``: its storage precision, whether the square-root rows are
        stored, and its bytes."""
        return {
            "storage": self.cache.storage,
            "rows_stored": self.cache.factor is not None,
            "bytes": self.cache.nbytes,
        }

    def exact_metric(self, layouts: IntArray) -> FloatArray:
        """:meth:`metric`, float64-exact whatever the cache's storage: with float32 storage
        each group of layouts using ≤ :data:`EXACT_SITES` sites is scored on a float64 cache
        of just those sites (:meth:`SiteSource.rebuild`, the same bits as a float64 cache of
        every site); with float64 storage this is :meth:`metric`."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=np.int64))
        if self.cache.storage == "float64" or layouts.shape[0] == 0:
            return self.metric(layouts)
        out = np.empty((layouts.shape[0], self.metric_weights.size))
        for rows, used in site_groups(layouts, max(EXACT_SITES, layouts.shape[1])):
            exact = Scorer(
                self.cache.source.rebuild(used),
                self.weights,
                self.objective,
                self.known,
                self.mirror,
            )
            out[rows] = exact.metric(np.searchsorted(used, layouts[rows]))
        return out

    def exact_loss(self, layouts: IntArray) -> FloatArray:
        """[B] :meth:`loss` from :meth:`exact_metric`."""
        return loss_from_metric(self.objective, self.exact_metric(layouts), self.metric_weights)

    def ranked_loss(self, layouts: IntArray) -> FloatArray:
        """[B, 2] (:meth:`loss`, tie-break) of each layout: the tie-break orders layouts whose
        losses are infinite (the kind's
        :meth:`~ris_planner.model.objectives.protocol.ObjectiveKind.search_tiebreak`:
        by default minus the weight of the pairs with a finite bound); 0 where the loss is
        finite."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=np.int64))
        out = np.zeros((layouts.shape[0], 2))
        weights = self.metric_weights
        obj = self.objective
        kind = objective_kind(obj.kind)
        for b0, block in self._metric_blocks(layouts, screen=True):
            loss = kind.loss(obj, block, weights)
            rows = slice(b0, b0 + block.shape[0])
            out[rows, 0] = loss
            blind = ~np.isfinite(loss)
            if np.any(blind):
                tb = out[rows, 1]
                tb[blind] = kind.search_tiebreak(obj, block[blind], weights)
        return out

    def loss(self, layouts: IntArray) -> FloatArray:
        """[B] loss (lower is better) of each layout: the objective, negated where higher is
        better."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=np.int64))
        losses = np.empty(layouts.shape[0])
        weights = self.metric_weights
        for b0, block in self._metric_blocks(layouts, screen=True):
            losses[b0 : b0 + block.shape[0]] = loss_from_metric(self.objective, block, weights)
        return losses


def site_groups(layouts: IntArray, max_sites: int) -> list[tuple[IntArray, IntArray]]:
    """(rows, their sites ascending) of consecutive layouts [B, L] whose sites together number
    ≤ max_sites (≥ L): the groups :meth:`Scorer.exact_metric` rebuilds one at a time."""
    groups: list[tuple[IntArray, IntArray]] = []
    start, used = 0, np.zeros(0, dtype=np.int64)
    for b in range(layouts.shape[0]):
        more = np.union1d(used, layouts[b])
        if more.size > max_sites:
            groups.append((np.arange(start, b), used))
            start, more = b, np.unique(layouts[b])
        used = more
    groups.append((np.arange(start, layouts.shape[0]), used))
    return groups


def underdetermined(cache: SiteCache, layouts: IntArray, n_states: int) -> BoolArray | None:
    """[nb, P] pairs whose present paths in each layout [nb, L] give fewer geometric channel
    parameters (3 per RIS path, 1 for LOS) than ``n_states`` unknowns; ``None`` in free
    space (the layout-wide count of :func:`ris_planner.bounds.compute.n_observations` applies).

    Counted as present RIS paths (uint8 sums, one gather per layout column) against the
    RIS paths each pair needs, ⌈(n_states − LOS present) / 3⌉."""
    if cache.present is None or cache.wavefront == "spherical":  # no counting rule there
        return None
    wide = layouts.shape[1] > np.iinfo(np.uint8).max
    p8 = cache.present.astype(np.int32) if wide else cache.present.view(np.uint8)
    count = p8[layouts[:, 0]]  # [nb, P] (a gather: a new array)
    for col in range(1, layouts.shape[1]):
        count += p8[layouts[:, col]]
    los = 0 if cache.los_present is None else cache.los_present.astype(np.int64)
    need = -((los - n_states) // 3)  # ceil((n_states - los) / 3)
    return np.asarray(count < need)


def select_metric(metric: str, peb_tx: FloatArray | None, peb_rx: FloatArray) -> FloatArray:
    """The objective's metric from PEB_T and PEB_R arrays: ``rx``, ``tx`` or ``max``."""
    if metric == "rx":
        return peb_rx
    if peb_tx is None:
        raise ValueError(f"metric {metric!r} needs PEB_T, but the TX position is known")
    return peb_tx if metric == "tx" else np.maximum(peb_tx, peb_rx)


def objective_value(obj: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
    """[B] objective of metric values [B, P] with weights [P] summing to 1 (the registered
    kind's :meth:`~ris_planner.model.objectives.protocol.ObjectiveKind.value`)."""
    return objective_kind(obj.kind).value(obj, metric, weights)


def loss_from_metric(obj: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
    """Lower-is-better form of :func:`objective_value` (negated where higher is better)."""
    return objective_kind(obj.kind).loss(obj, metric, weights)


def objective_from_loss(obj: Objective, loss: float) -> float:
    """The objective's value from a loss of :func:`loss_from_metric` (the inverse map)."""
    return objective_kind(obj.kind).from_loss(loss)


def score_chunk(scorer: Scorer, layouts: IntArray) -> FloatArray:
    """Executor task: losses of a chunk of layouts."""
    return scorer.loss(layouts)


def score_chunk_ranked(scorer: Scorer, layouts: IntArray) -> FloatArray:
    """Executor task: [B, 2] (loss, tie-break) of a chunk of layouts
    (:meth:`Scorer.ranked_loss`)."""
    return scorer.ranked_loss(layouts)
