"""Objectives over weighted pairs and the batched layout score.

Scoring a batch of layouts: LOS + Σ cached site matrices on the packed entries of the unknown
states (one gather-and-add per RIS over all entries × layouts × pairs), then one batched LDLᵀ
(:func:`ris_planner.ldl.inverse_diagonal_from`) giving the CRB diagonal of the
metric's states. Known parts (``clock``, ``height``, ``tx``) remove their rows
before inversion, as :func:`ris_planner.bounds.bounds_from_state_fim` does.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from ris_planner.bounds import kept_states, n_observations
from ris_planner.ldl import inverse_diagonal_from, packed_index
from ris_planner.planning.document import Objective
from ris_planner.planning.site_cache import N_STATES, SiteCache
from ris_planner.scenario import KnownPart

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]

BATCH_MATRICES = 24_576
"""Matrices per inner vector operation: large enough to amortise numpy's per-call overhead,
small enough that the ~60 working vectors stay in cache (measured on the 2-core dev machine:
7–10 M matrices/s at 16–32 k, 5.7 M/s at 131 k)."""

TX_STATES = (0, 1, 2)
RX_STATES = (3, 4, 5)


@dataclass(frozen=True)
class Scorer:
    """Everything a worker needs to score layouts (sent once per worker)."""

    cache: SiteCache
    weights: FloatArray
    objective: Objective
    known: tuple[KnownPart, ...]

    @property
    def states(self) -> tuple[list[int], list[int], list[int]]:
        """(kept states in natural order, positions in it of the metric's TX / RX states)."""
        keep = [int(k) for k in kept_states(self.known)]
        metric = self.objective.metric
        tx = [i for i, k in enumerate(keep) if k in TX_STATES] if metric != "rx" else []
        rx = [i for i, k in enumerate(keep) if k in RX_STATES] if metric != "tx" else []
        return keep, tx, rx

    @cached_property
    def _selected(self) -> tuple[FloatArray, FloatArray | None]:
        """The cache's packed entries of the kept states (all of them when nothing is known)."""
        keep, _, _ = self.states
        n = len(keep)
        src_idx = packed_index(N_STATES)
        # the packing order of ldl.packed_index(n): (0,0), (1,0), (1,1), (2,0), …
        src = [src_idx[keep[i], keep[j]] for i in range(n) for j in range(i + 1)]
        if n == N_STATES:  # src is 0, 1, …, 27: no copy
            return self.cache.packed, self.cache.los
        los = None if self.cache.los is None else self.cache.los[src]
        return self.cache.packed[src], los

    @property
    def selected_packed(self) -> tuple[FloatArray, FloatArray | None]:
        """(site information [E, S, P], LOS [E, P] or ``None``) on the kept states, packed in
        :func:`ris_planner.ldl.packed_index` order (the certificates' relaxation reads it)."""
        return self._selected

    def metric(self, layouts: IntArray) -> FloatArray:
        """[B, P] metric bound (m) of each layout [B, L] and pair; ``inf`` for blind spots.

        Bit for bit what ``compute_bounds`` gives for the layout (same FIM sum, LOS first, and
        the core's inversion arithmetic, see :mod:`ris_planner.ldl`)."""
        layouts = np.atleast_2d(np.asarray(layouts, dtype=int))
        b_all, n_ris = layouts.shape
        p = self.cache.n_pairs
        out = np.empty((b_all, p))
        keep, tx, rx = self.states
        if n_observations(n_ris, self.cache.los is not None) < len(keep):  # as compute_bounds
            out[:] = np.inf
            return out
        n = len(keep)
        first = min(tx + rx)
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
            diag, _ = inverse_diagonal_from(a.reshape(len(packed), nb * p), n, first)
            val = self._bound(diag, [i - first for i in tx], [i - first for i in rx])
            block = val.reshape(nb, p)
            if any_deg:
                block[np.any(deg[lay], axis=1)] = np.inf
            out[b0 : b0 + nb] = block
        return out

    @staticmethod
    def _bound(diag: FloatArray, tx: list[int], rx: list[int]) -> FloatArray:
        """sqrt of the summed CRB diagonal in the core's order (``diag[:, cols].sum(axis=1)``)."""

        def peb(rows: list[int]) -> FloatArray:
            acc = diag[rows[0]].copy()
            for r in rows[1:]:
                acc += diag[r]
            return np.sqrt(acc)

        if tx and rx:
            return np.maximum(peb(tx), peb(rx))
        return peb(tx or rx)

    def loss(self, layouts: IntArray) -> FloatArray:
        """[B] loss (lower is better) of each layout: the objective, negated for coverage."""
        return loss_from_metric(self.objective, self.metric(layouts), self.weights)


def select_metric(metric: str, peb_tx: FloatArray | None, peb_rx: FloatArray) -> FloatArray:
    """The objective's metric from PEB_T and PEB_R arrays: ``rx``, ``tx`` or ``max``."""
    if metric == "rx":
        return peb_rx
    if peb_tx is None:
        raise ValueError(f"metric {metric!r} needs PEB_T, but the TX position is known")
    return peb_tx if metric == "tx" else np.maximum(peb_tx, peb_rx)


def weighted_quantile(values: FloatArray, weights: FloatArray, q: float | FloatArray) -> FloatArray:
    """Smallest v with Σ_{values ≤ v} w ≥ q·Σw per row of values [B, P] (``inf`` ranks last).

    weights : [P] shared by the rows, or [B, P] (each row's sum > 0);
    q : scalar or [Q]; returns [B] or [B, Q]."""
    idx = np.argsort(values, axis=1, kind="stable")
    w = np.broadcast_to(weights, values.shape)
    cw = np.cumsum(np.take_along_axis(w, idx, axis=1), axis=1)
    cw /= cw[:, -1:]
    qs = np.atleast_1d(np.asarray(q, dtype=float))
    # tolerance: the cumulative sums carry ~P·ε rounding; a quantile exactly on a step is kept
    pos = np.empty((values.shape[0], qs.size), dtype=int)
    for k, qk in enumerate(qs):
        pos[:, k] = np.argmax(cw >= qk - 1e-12, axis=1)
    rows = np.arange(values.shape[0])[:, None]
    out = values[rows, idx[rows, pos]]
    return out[:, 0] if np.ndim(q) == 0 else out


def objective_value(obj: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
    """[B] objective of metric values [B, P] with weights [P] summing to 1."""
    if obj.kind == "coverage":
        assert obj.threshold_m is not None
        return np.asarray(((metric <= obj.threshold_m) * weights).sum(axis=1))
    if obj.kind == "mean_capped":
        assert obj.cap_m is not None
        return np.asarray((np.minimum(metric, obj.cap_m) * weights).sum(axis=1))
    assert obj.q is not None
    return weighted_quantile(metric, weights, obj.q)


def loss_from_metric(obj: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
    """Lower-is-better form of :func:`objective_value` (coverage negated)."""
    val = objective_value(obj, metric, weights)
    return -val if obj.kind == "coverage" else val


def objective_from_loss(obj: Objective, loss: float) -> float:
    """The objective's value from a loss of :func:`loss_from_metric` (the inverse map)."""
    return -loss if obj.kind == "coverage" else loss


def score_chunk(scorer: Scorer, layouts: IntArray) -> FloatArray:
    """Executor task: losses of a chunk of layouts."""
    return scorer.loss(layouts)
