"""Exact float64 scores of the finalists of a search on a float32 site cache (the cache's
memory budget): every layout the plan reports – the best ``top_k`` of a count and its listed
ties – is re-scored on a float64 cache of just its sites (:meth:`Scorer.exact_metric`), until the
reported set, ranked by the exact losses, holds no float32 score. The others keep their float32
scores (each above the reported layouts' exact ones, or it would have been re-scored)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ris_planner.planning.certify.relaxation import Certificate
from ris_planner.planning.outputs.decisions import MAX_TIES_LISTED, ties
from ris_planner.planning.scoring.scorer import Scorer
from ris_planner.planning.search.layouts import SearchOutcome


def rescore_finalists(
    scorer: Scorer, outcome: SearchOutcome, top_k: int, tie_rtol: float
) -> tuple[SearchOutcome, int]:
    """(the outcome with its reported layouts' losses float64-exact, how many were re-scored);
    the outcome itself with a float64 cache."""
    if scorer.cache.storage == "float64" or outcome.evaluated == 0:
        return outcome, 0
    losses = outcome.losses.copy()
    exact = np.zeros(losses.size, dtype=bool)
    while True:
        now = replace(outcome, losses=losses)
        n_ties, _ = ties(now, tie_rtol)
        todo = now.ranked_index(max(top_k, min(n_ties, MAX_TIES_LISTED)))
        todo = todo[~exact[todo]]
        if todo.size == 0:
            return now, int(exact.sum())
        losses[todo] = scorer.exact_loss(outcome.layouts[todo])
        exact[todo] = True


def exact_certificate(
    scorer: Scorer, certificate: Certificate | None, best_loss: float
) -> Certificate | None:
    """An exact certificate (exhaustive search, a finished branch-and-bound) of a float32
    cache names the optimum of the float32 scores: its value is the re-scored best's exact
    ``best_loss``, not the float32 loss it was taken from. Relaxation bounds are kept (they
    bound the float32-rounded problem; README "Site-cache memory")."""
    if certificate is None or not certificate.exact or scorer.cache.storage == "float64":
        return certificate
    return replace(certificate, loss_bound=best_loss)
