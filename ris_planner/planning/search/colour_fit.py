"""Layouts that fit the Γ time-orthogonal blocks their designed information was computed with
(docs/concepts/district-physics.md, "Many RISs on one pair").

A designed codebook's information depends on Γ (G̃ = G/Γ beams per block), so Γ is fixed
before the information is built and the searched layouts are held to it: a layout whose
profile colours (:func:`~ris_planner.planning.scoring.time_blocks.profile_colours`) exceed
Γ − 1 keeps the sites that find a colour below Γ − 1 (at least those DSatur coloured below it)
and is refilled greedily
(:class:`~ris_planner.planning.search.district.GainBook`: the largest covered-weight gain,
ties by the surrogate) from the sites that fit – a site fits when some colour below Γ − 1 is
free of every layout site it shares an audible pair with; the site takes the first such
colour. The held layout's colouring is built with it – its sites in the order of their DSatur
colour classes, each taking the first colour free of its neighbours (never more colours than
DSatur's), then each refilled site its free colour – so it is proper and below Γ − 1 by
construction, and it is the colouring the plan reports (DSatur run again on the held layout
could need more). A layout fails to be held only when no candidate with a free colour is
left. Each reported layout then fits in the one run; its
certificate (an upper bound over every layout of its count, coloured or not) still holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csc_matrix, csr_matrix

from ris_planner.planning.scoring.sparse import DistrictProblem, LayoutState
from ris_planner.planning.scoring.time_blocks import audible_incidence, profile_colours
from ris_planner.planning.search.district import GainBook

BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]


@dataclass(frozen=True)
class ColourFit:
    """A layout held to ``colours`` profile colours: the layout (sorted), the sites taken out
    and put in, whether it fits, and the colour of each of its sites (a proper colouring below
    ``colours`` where it fits). ``fits`` is False only where no candidate with a free colour is
    left to add (or the required sites alone need more colours): the layout is then returned
    as it was, with its DSatur colours."""

    layout: tuple[int, ...]
    removed: tuple[int, ...]
    added: tuple[int, ...]
    fits: bool
    colour: tuple[int, ...]


def fit_colours(
    problem: DistrictProblem,
    seen: DistrictProblem,
    layout: tuple[int, ...],
    colours: int,
    required: tuple[int, ...] = (),
    excluded: tuple[int, ...] = (),
    conflict: BoolArray | None = None,
    heard: csc_matrix | None = None,
) -> ColourFit:
    """``layout`` held to ``colours`` profile colours (module docstring); ``seen`` the problem
    the search ranks sites on, ``problem`` the one whose audible paths the colours separate."""
    heard = audible_incidence(problem) if heard is None else heard
    by_pair = heard.tocsr()
    ordered = tuple(sorted(int(s) for s in layout))
    dsatur = profile_colours(problem, ordered, heard)
    if dsatur.size == 0 or int(dsatur.max()) < colours:
        return ColourFit(ordered, (), (), True, tuple(int(c) for c in dsatur))
    unheld = ColourFit(ordered, (), (), False, tuple(int(c) for c in dsatur))
    fixed = set(required)
    # used[s, c]: a layout site of colour c shares an audible pair with candidate s
    used = np.zeros((problem.n_sites, colours), dtype=bool)
    colour_of: dict[int, int] = {}

    def place(site: int) -> bool:
        free = np.flatnonzero(~used[site])
        if free.size == 0:
            return False
        colour_of[site] = int(free[0])
        used[_neighbours(heard, by_pair, site), int(free[0])] = True
        return True

    # the layout's sites again, required first, then by their DSatur colour: greedy in the
    # order of a colouring's classes never needs more colours than it, so (required sites
    # aside) every site DSatur coloured below the limit keeps a place
    by_class = sorted(range(len(ordered)), key=lambda i: (ordered[i] not in fixed, dsatur[i]))
    for i in by_class:
        if not place(ordered[i]) and ordered[i] in fixed:
            return unheld
    keep = sorted(colour_of)
    removed = tuple(sorted(set(ordered) - set(keep)))
    book = GainBook(LayoutState(seen, keep))
    allowed = np.ones(problem.n_sites, dtype=bool)
    allowed[list(excluded)] = False
    allowed[list(ordered)] = False  # a removed site would need its colour again
    if conflict is not None:
        for s in keep:
            allowed &= ~conflict[s]
    added: list[int] = []
    while len(colour_of) < len(ordered):
        fits = allowed & ~used.all(axis=1)  # a colour below the limit is free of its pairs
        if not fits.any():
            return unheld
        pick = book.best(fits)
        book.set(pick, True)
        place(pick)
        added.append(pick)
        allowed[pick] = False
        if conflict is not None:
            allowed &= ~conflict[pick]
    held = tuple(sorted(colour_of))
    return ColourFit(held, removed, tuple(sorted(added)), True, tuple(colour_of[s] for s in held))


def _neighbours(heard: csc_matrix, by_pair: csr_matrix, site: int) -> IntArray:
    """The sites that share an audible pair with ``site`` (itself included); ``by_pair`` the
    same incidence row-compressed."""
    pairs = heard.indices[heard.indptr[site] : heard.indptr[site + 1]]
    sites = [by_pair.indices[by_pair.indptr[p] : by_pair.indptr[p + 1]] for p in pairs.tolist()]
    return np.unique(np.concatenate(sites)) if sites else np.array([site])
