"""Ranking and search decisions do not depend on rounding (planning.search.RANK_RTOL): layouts
whose losses differ by less than the bounds' accuracy are ranked by their sites, so a BLAS
kernel, SIMD dispatch or worker process that rounds differently recommends the same layout."""

from __future__ import annotations

import numpy as np

from ris_planner.planning.search.layouts import (
    RANK_RTOL,
    SearchOutcome,
    _site_keys,
    improves,
    ranked_order,
)


def test_rounding_does_not_reorder_the_ranking(rng: np.random.Generator) -> None:
    """Symmetric layouts (equal losses) perturbed by 1e-12 relative – far more than the
    kernels' measured 1e-14 – rank identically under every perturbation; distinct losses
    (1e-3 apart) keep their order."""
    layouts = np.array([[1, 3], [0, 2], [2, 3], [0, 1], [1, 2], [0, 3]])
    base = np.array([0.3256, 0.3256, 0.4839, 0.4839, 0.4839, 0.4839])
    base[2:] += np.arange(4) * 1e-3
    want = None
    for _ in range(50):
        noisy = base * (1 + rng.uniform(-1e-12, 1e-12, base.size))
        got = SearchOutcome(layouts, noisy).ranked_index(6)
        if want is None:
            want = got
        np.testing.assert_array_equal(got, want)
    assert want is not None
    assert [tuple(layouts[i]) for i in want[:2]] == [(0, 2), (1, 3)]  # by sites within a tie
    assert [tuple(layouts[i]) for i in want[2:]] == [(2, 3), (0, 1), (1, 2), (0, 3)]  # by loss


def test_ranked_order_groups_against_a_naive_reference(rng: np.random.Generator) -> None:
    """The grouped order against a naive loop: repeatedly take the smallest remaining loss,
    every remaining loss within RANK_RTOL of it, ordered by the key."""
    for _ in range(20):
        n = int(rng.integers(1, 60))
        losses = rng.choice([0.5, 0.5 * (1 + RANK_RTOL / 3), 0.7, np.inf, 0.9], size=n)
        losses = losses * (1 + rng.uniform(-1e-13, 1e-13, n))
        key = rng.permutation(n)
        got = ranked_order(losses, (key,))
        rest, want = list(range(n)), []
        while rest:
            m = min(losses[i] for i in rest)
            lim = m + (RANK_RTOL * abs(m) if np.isfinite(m) else 0.0)
            group = sorted((i for i in rest if losses[i] <= lim), key=lambda i: key[i])
            want += group
            rest = [i for i in rest if i not in group]
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(ranked_order(losses, (key,), 3), want[:3])


def test_a_step_must_gain_more_than_rounding() -> None:
    assert improves(0.99, 1.0)
    assert not improves(1.0 - 1e-9, 1.0)  # rounding, not an improvement
    assert improves(5.0, np.inf) and not improves(np.inf, np.inf)
    assert not improves(np.nan, 1.0)


def test_site_keys_order_layouts_lexicographically() -> None:
    lay = np.array([[2, 5], [0, 9], [0, 3], [1, 1]])
    np.testing.assert_array_equal(np.lexsort(_site_keys(lay)), [2, 1, 3, 0])
