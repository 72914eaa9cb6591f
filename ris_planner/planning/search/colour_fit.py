"""Layouts that fit the Γ time-orthogonal blocks their designed information was computed with
(docs/concepts/district-physics.md, "Many RISs on one pair").

A designed codebook's information depends on Γ (G̃ = G/Γ beams per block), so Γ is fixed
before the information is built and the searched layouts are held to it: a layout whose
profile colours (:func:`~ris_planner.planning.scoring.time_blocks.profile_colours`) exceed
Γ − 1 keeps the sites DSatur coloured below Γ − 1 and is refilled greedily
(:class:`~ris_planner.planning.search.district.GainBook`: the largest covered-weight gain,
ties by the surrogate) from the sites that fit – a site fits when some colour below Γ − 1 is
free of every layout site it shares an audible pair with, and DSatur's colouring of the
grown layout stays within Γ − 1. Where none of the :data:`FIT_TRIES` best does, the step
takes the best site that shares no audible pair with the layout: DSatur colours it 0 and
leaves every other colour as it was, so it always fits, and a layout can only fail to be held
when no candidate is left at all. Each reported layout then fits in the one run; its
certificate (an upper bound over every layout of its count, coloured or not) still holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csc_matrix, csr_matrix

from ris_planner.planning.scoring.sparse import DistrictProblem, LayoutState
from ris_planner.planning.scoring.time_blocks import audible_incidence, profile_colours
from ris_planner.planning.search.district import GAIN_TIE, GainBook

BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int_]

FIT_TRIES = 64
"""Candidates a refill step tries (by gain) before giving up on a step: each checked by
DSatur on the grown layout."""


@dataclass(frozen=True)
class ColourFit:
    """A layout held to ``colours`` profile colours: the layout, the sites taken out and put
    in, and whether it fits (False only where no candidate is left to add, or the required
    sites alone need more colours: the layout is then returned as it was)."""

    layout: tuple[int, ...]
    removed: tuple[int, ...]
    added: tuple[int, ...]
    fits: bool


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
    colour = profile_colours(problem, layout, heard)
    if colour.size == 0 or int(colour.max()) < colours:
        return ColourFit(tuple(layout), (), (), True)
    fixed = set(required)
    keep = [s for s, c in zip(layout, colour, strict=True) if c < colours or s in fixed]
    removed = tuple(sorted(set(layout) - set(keep)))
    book = GainBook(LayoutState(seen, keep))
    allowed = np.ones(problem.n_sites, dtype=bool)
    allowed[list(excluded)] = False
    allowed[list(layout)] = False  # a removed site would need its colour again
    if conflict is not None:
        for s in keep:
            allowed &= ~conflict[s]
    # used[s, c]: a layout site of colour c shares an audible pair with candidate s;
    # touched[s]: some layout site does
    used = np.zeros((problem.n_sites, colours), dtype=bool)
    touched = np.zeros(problem.n_sites, dtype=bool)
    kept_colour = profile_colours(problem, keep, heard)
    for s, c in zip(keep, kept_colour, strict=True):
        near = _neighbours(heard, by_pair, s)
        touched[near] = True
        if c < colours:
            used[near, c] = True
    added: list[int] = []
    while len(keep) < len(layout):
        key = np.where(allowed & ~used.all(axis=1), book.gain_c + GAIN_TIE * book.gain_s, -np.inf)
        order = np.argsort(-key, kind="stable")[:FIT_TRIES]
        pick = None
        for s in order[np.isfinite(key[order])].tolist():
            if int(profile_colours(problem, [*keep, s], heard).max()) < colours:
                pick = s
                break
            allowed[s] = False  # DSatur needs more colours with it: not tried again
        if pick is None:  # a site no layout site shares a pair with always fits
            lone = allowed & ~touched
            if not lone.any():
                return ColourFit(tuple(layout), (), (), False)
            pick = book.best(lone)
        book.set(pick, True)
        keep.append(pick)
        added.append(pick)
        allowed[pick] = False
        if conflict is not None:
            allowed &= ~conflict[pick]
        near = _neighbours(heard, by_pair, pick)
        touched[near] = True
        free = np.flatnonzero(~used[pick])
        if free.size:
            used[near, int(free[0])] = True
    held = tuple(sorted(keep))
    if int(profile_colours(problem, held, heard).max()) >= colours:  # a required site's
        return ColourFit(tuple(layout), (), (), False)
    return ColourFit(held, removed, tuple(sorted(added)), True)


def _neighbours(heard: csc_matrix, by_pair: csr_matrix, site: int) -> IntArray:
    """The sites that share an audible pair with ``site`` (itself included); ``by_pair`` the
    same incidence row-compressed."""
    pairs = heard.indices[heard.indptr[site] : heard.indptr[site + 1]]
    sites = [by_pair.indices[by_pair.indptr[p] : by_pair.indptr[p + 1]] for p in pairs.tolist()]
    return np.unique(np.concatenate(sites)) if sites else np.array([site])
