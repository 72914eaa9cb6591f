"""What a plan's result reads of the scoring that searched it (docs/concepts/planning.md,
"Search methods"): one protocol, whatever holds the information – the dense site cache of the
enumerating searches (:class:`~ris_planner.planning.scoring.scorer.Scorer`) or the district
search's sparse (pair, serving site) entries
(:class:`~ris_planner.planning.scoring.sparse.SparseScorer`). The result's statistics,
per-pair figures, warnings, diagnosis and storage line read it through these members only."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int_]
BoolArray = NDArray[np.bool_]


class LayoutScorer(Protocol):
    """A plan's scoring, as its result reads it."""

    @property
    def mirror(self) -> bool:
        """Unordered pairs counted in both directions (the metric has [2P] columns)."""
        ...

    @property
    def metric_weights(self) -> FloatArray:
        """Weights of the metric's columns ([P], or [2P] halves with :attr:`mirror`)."""
        ...

    def exact_metric(self, layouts: IntArray) -> FloatArray:
        """[B, P] (or [B, 2P]) the objective's metric [m] of each layout [B, L], float64-exact
        (``inf``: blind)."""
        ...

    def far_field_of(self, layout: Sequence[int]) -> BoolArray:
        """[P] whether every site of ``layout`` has the pair in its far field."""
        ...

    def near_field_by_site(self, weights: FloatArray) -> FloatArray:
        """[S] per candidate site the weight (of ``weights`` [P]) of the pairs it has in its
        near field."""
        ...

    def serves(self, layout: Sequence[int]) -> BoolArray:
        """[L, P] whether each site of ``layout`` has a RIS path to each pair."""
        ...

    def idle_sites(self) -> IntArray:
        """The candidate sites that serve no pair (no RIS path to any)."""
        ...

    def servable(self) -> BoolArray:
        """[P] the pairs some layout can locate: a finite bound with every candidate in
        place (whatever the RIS size, for the planar counting rule)."""
        ...

    def storage_json(self) -> dict[str, Any]:
        """plan.json ``site_cache``: how the information is held and its bytes."""
        ...


@dataclass(frozen=True)
class PairsSummary:
    """What the candidates can give the pairs at all (plan.json ``pairs_summary``;
    docs/concepts/scoring.md, "One denominator"): the *servable* pairs – a finite bound with
    every candidate in place, whatever the RIS size under the planar counting rule – are the
    denominator of every coverage share and target; the *coverable* ones – within the
    objective's level with every candidate – depend on the RIS size."""

    pairs: int
    servable_weight: float
    blind_pairs: int
    """Pairs no layout can locate (too few paths with every candidate)."""
    coverable_weight: float | None
    """Weight within the objective's level with every candidate (``None``: the objective has
    no level)."""
    above_level_pairs: int | None
    """Servable pairs that every candidate together still leaves above the level."""

    def share(self, value: float) -> float | None:
        """``value`` (a weighted fraction of every pair) as a share of the servable pairs."""
        return value / self.servable_weight if self.servable_weight > 0 else None

    def to_json(self) -> dict[str, Any]:
        coverable = self.coverable_weight
        return {
            "pairs": self.pairs,
            "denominator": "servable pairs",
            "servable_weight": self.servable_weight,
            "blind_everywhere": {
                "pairs": self.blind_pairs,
                "weight": max(0.0, 1.0 - self.servable_weight),
            },
            "coverable_weight": coverable,
            "coverable_share": None if coverable is None else self.share(coverable),
            "above_level_everywhere": None
            if self.above_level_pairs is None
            else {
                "pairs": self.above_level_pairs,
                "weight": max(0.0, self.servable_weight - (coverable or 0.0)),
            },
        }


def pairs_summary(
    scorer: LayoutScorer, weights: FloatArray, n_sites: int, level: float | None
) -> PairsSummary:
    """The :class:`PairsSummary` of a plan's pairs (``weights`` [P]) under ``scorer``:
    :meth:`LayoutScorer.servable`, and with a ``level`` (the objective's threshold) the weight
    that every candidate together brings within it."""
    servable = scorer.servable()
    servable_weight = float(min(1.0, weights[servable].sum()))
    coverable = above = None
    if level is not None and n_sites > 0:
        metric = scorer.exact_metric(np.arange(n_sites)[None])[0]  # every candidate
        w = scorer.metric_weights
        within = metric <= level
        coverable = float(min(servable_weight, w[within].sum()))
        n = weights.size
        pair_within = within[:n] & (within[n:] if within.size > n else True)
        above = int((servable & ~pair_within).sum())
    return PairsSummary(weights.size, servable_weight, int((~servable).sum()), coverable, above)
