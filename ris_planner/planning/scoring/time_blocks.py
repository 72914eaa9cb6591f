"""Time-orthogonal profile blocks for many RISs (docs/concepts/district-physics.md, "Many
RISs on one pair").

The time-orthogonal profiles (eq. orthogonal_profiles) separate the paths a receiver hears by
the columns of B: the LOS takes column 0 and each RIS one more, so one pair with L RISs needs
Γ ≥ L + 1 blocks. In a district no pair hears most RISs: two RISs need different columns only
when some pair hears both, so RISs that share no pair may share a column – a colouring of the
RIS conflict graph (RISs adjacent when a pair hears both audibly: a path below the noise over
the whole pilot needs no column of its own). Γ is then the smallest
divisor of G at least one more than the colours (:func:`~ris_planner.model.profiles.
block_count` of the colour count), not of the RIS count, and each RIS has G/Γ beams per block.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csc_matrix

from ris_planner.planning.scoring.sparse import DistrictProblem

IntArray = NDArray[np.int_]


def audible_incidence(problem: DistrictProblem) -> csc_matrix:
    """[P, S] 1 where the pair hears the site audibly (:data:`~ris_planner.planning.scoring.
    sparse.AUDIBLE_SNR_DB`), column-compressed: a layout's conflict graph is the product of
    its columns."""
    keep = problem.audible
    return csc_matrix(
        (np.ones(int(keep.sum())), (problem.entry_pair[keep], problem.entry_site[keep])),
        shape=(problem.n_pairs, problem.n_sites),
    )


def conflict_graph(
    problem: DistrictProblem, layout: Sequence[int], heard: csc_matrix | None = None
) -> NDArray[np.bool_]:
    """[L, L] whether some pair hears two sites of ``layout`` audibly (their paths must be
    separated: :data:`~ris_planner.planning.scoring.sparse.AUDIBLE_SNR_DB`; False on the
    diagonal). ``heard``: :func:`audible_incidence` of the problem, when the caller has it."""
    heard = audible_incidence(problem) if heard is None else heard
    m = heard[:, [int(s) for s in layout]]
    adjacent = np.asarray((m.T @ m).toarray() > 0)
    np.fill_diagonal(adjacent, False)
    return adjacent


def profile_colours(
    problem: DistrictProblem, layout: Sequence[int], heard: csc_matrix | None = None
) -> IntArray:
    """[L] a column of B per site of ``layout`` (0-based, the LOS's column aside) such that no
    pair hears two sites of one colour: DSatur's greedy colouring of the conflict graph
    (:func:`dsatur`). Never more colours than sites, and at least the most sites any one pair
    hears (they form a clique)."""
    return dsatur(conflict_graph(problem, layout, heard))


def dsatur(adjacent: NDArray[np.bool_]) -> IntArray:
    """DSatur's greedy colouring of the graph ``adjacent`` [n, n]: the uncoloured vertex with
    the most distinctly coloured neighbours next, ties by degree, then index; the smallest
    colour no neighbour has."""
    n = adjacent.shape[0]
    colour = np.full(n, -1)
    degree = adjacent.sum(axis=1)
    for _ in range(n):
        open_ = np.flatnonzero(colour < 0)
        saturation = np.array([len({int(c) for c in colour[adjacent[v]] if c >= 0}) for v in open_])
        key = np.lexsort((open_, -degree[open_], -saturation))
        v = int(open_[key[0]])
        taken = {int(c) for c in colour[adjacent[v]] if c >= 0}
        colour[v] = next(c for c in range(n) if c not in taken)
    return colour
