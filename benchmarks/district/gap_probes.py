"""Where a district certificate's gap lies: probes of the headline's relaxation and search
(docs/validation/benchmarks.md, "Where the gap lies"; docs/concepts/district.md, "The
certificate").

0. **Separation rounds and integral sites** at the first of ``--counts``: the bound after each
   of ``--rounds`` rounds of separated cuts (no time budget), and HiGHS's MIP on the static
   rows with the sites binary for ``--mip-seconds`` (its value, its proven bound, and its
   layout's exact coverage).
1. **Information rows.** A covering layout's information on the metric's position alone must
   reach d²/θ² (the CRB's position block is at least the inverse of the information's, and
   tr A⁻¹ ≥ d²/tr A): per pair the row y_p ≤ Σ_s min(1, tr J_s / need_p) z_s, need_p =
   d²/θ² − tr J_LOS. The bounds at ``--counts`` without separation rounds, with and without
   these rows (``--quick``: the rows checked against every layout of up to three sites).
2. **Components** of the graph of pairs and their strong sets (the static cuts' sites).
3. **More search.** From the greedy path and one swap round at ``--ils-count`` sites, an
   iterated local search for ``--ils-seconds``: remove 2–6 random sites, refill by greedy steps,
   one swap round, back to the best when more than 0.01 below it.

    python benchmarks/district/bench_district.py --only headline --out DIR   # DIR/headline.json
    python benchmarks/district/gap_probes.py DIR/headline.json [--counts 40 60]
        [--rounds 12 --mip-seconds 240 --ils-count 40 --ils-seconds 900]
    python benchmarks/district/gap_probes.py --quick   # the suite's street site
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

SAFETY = 1e-4
"""The information rows' coefficients are raised by this share: a layout whose traces meet
the need only to rounding keeps its row met."""


def information_coefficients(problem: Any) -> FloatArray:
    """[E] min(1, tr J_e / need_p) per (pair, site) entry, on the metric's position rows."""
    from ris_planner.inversion.ldl import packed_slots

    slots = packed_slots(problem.n_kept)
    rows = [int(i) for i in problem.metric_rows]
    diag = [slots[(i, i)] for i in rows]
    trace = problem.info[:, diag].sum(axis=1)
    need = len(rows) ** 2 / problem.threshold**2 - problem.los[diag].sum(axis=0)
    per = need[problem.entry_pair]
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(per > 0, trace / per * (1 + SAFETY), 1.0)
    return np.asarray(np.minimum(1.0, c))


def information_rows(problem: Any, live: Any, coef: FloatArray) -> Any:
    """The rows of the live pairs no single site meets alone (a row with a coefficient 1 is
    implied by the non-cover cuts)."""
    from ris_planner.planning.certify.district_cuts import CutRows

    single = np.zeros(problem.n_pairs)
    np.maximum.at(single, problem.entry_pair, coef)
    keep = np.zeros(problem.n_pairs, dtype=bool)
    keep[live] = True
    keep &= single < 1.0
    ent = np.flatnonzero(keep[problem.entry_pair] & (coef > 0))
    pairs = np.unique(problem.entry_pair[ent])
    start = np.searchsorted(problem.entry_pair[ent], np.append(pairs, problem.n_pairs))
    return CutRows(
        pairs.astype(np.int64),
        np.ones(pairs.size),
        start.astype(np.int64),
        problem.entry_site[ent].astype(np.int64),
        coef[ent],
    ), int((single >= 1.0).sum())


def check_rows(problem: Any, coef: FloatArray, most: int = 3) -> int:
    """Every layout of up to ``most`` sites: each pair it covers meets its information row.
    The layouts checked."""
    from ris_planner.planning.scoring.sparse import LayoutState

    n = 0
    for k in range(1, most + 1):
        for layout in itertools.combinations(range(problem.n_sites), k):
            st = LayoutState(problem, list(layout))
            covered = st.metric <= problem.threshold
            member = np.isin(problem.entry_site, layout)
            got = np.bincount(problem.entry_pair[member], coef[member], problem.n_pairs)
            assert np.all(got[covered] >= 1.0), layout
            n += 1
    return n


def probe_rows(problem: Any, needs: Any, cons: Any, counts: list[int], quick: bool) -> None:
    import ris_planner.planning.certify.district_lp as dl

    coef = information_coefficients(problem)
    if quick:
        print(f"information rows hold on all {check_rows(problem, coef)} layouts of ≤ 3 sites")
    rounds = dl.SEPARATION_ROUNDS
    dl.SEPARATION_ROUNDS = 0
    try:
        for with_rows in (False, True):
            t0 = time.perf_counter()
            m = dl.build_relaxation(problem, needs, *cons)
            note = ""
            if with_rows:
                rows, met = information_rows(problem, m.live, coef)
                m.add_cuts(rows)
                note = f" (+{rows.n_rows} information rows; {met} pairs met by one site alone)"
            got = [m.coverage(c) for c in counts]
            cells = ", ".join(f"{c} RISs ≤ {r.bound:.4f}" for c, r in zip(counts, got, strict=True))
            print(
                f"bounds {'with' if with_rows else 'without'} information rows{note}: {cells}"
                f" [{time.perf_counter() - t0:.1f} s]"
            )
    finally:
        dl.SEPARATION_ROUNDS = rounds


def coverage_model(problem: Any, needs: Any, cons: Any, count: int) -> tuple[Any, Any]:
    """The district relaxation with its static cuts and its HiGHS model set up as
    :meth:`~ris_planner.planning.certify.district_lp.DistrictRelaxation.coverage` sets it for
    ``count`` sites (objective −Σ w y, the count row fixed): (relaxation, model)."""
    import ris_planner.planning.certify.district_lp as dl

    m = dl.build_relaxation(problem, needs, *cons)
    h = m._model()
    h.changeColsCost(m.n_var, np.arange(m.n_var, dtype=np.int32), -m.w)
    h.changeRowBounds(m.count_row, float(count), float(count))
    return m, h


def probe_rounds(problem: Any, needs: Any, cons: Any, count: int, rounds: int) -> None:
    """The bound at ``count`` after each of ``rounds`` separation rounds."""
    m, _ = coverage_model(problem, needs, cons, count)
    t0 = time.perf_counter()
    for i, (status, _, x, duals) in enumerate(m._solves(rounds)):
        m.multipliers.append(m._clipped(duals))
        print(
            f"  round {i}: {status}, bound {m.bound_at(count):.4f},"
            f" {m.separated_rows} separated rows, {time.perf_counter() - t0:.1f} s",
            flush=True,
        )
        if i == 0:
            z, y = x[: problem.n_sites], m._pairs_of(x)
            print(
                f"  its site weights: {int((z > 1e-6).sum())} sites above 0, the largest"
                f" {z.max():.3f}; the pairs with y = 1 weigh"
                f" {problem.weights[y > 1 - 1e-6].sum():.3f}"
            )


def probe_mip(problem: Any, needs: Any, cons: Any, count: int, seconds: float) -> None:
    """HiGHS's MIP on the static rows at ``count`` with the site variables binary (none for
    ``seconds`` ≤ 0)."""
    if seconds <= 0:
        return
    from ris_planner.planning.scoring.sparse import exact_coverage

    _, h = coverage_model(problem, needs, cons, count)
    n = problem.n_sites
    h.changeColsIntegrality(n, np.arange(n, dtype=np.int32), np.ones(n, dtype=np.uint8))
    h.setOptionValue("solver", "choose")
    h.setOptionValue("presolve", "on")
    h.setOptionValue("time_limit", seconds)
    h.setOptionValue("mip_rel_gap", 0.01)
    t0 = time.perf_counter()
    h.run()
    info = h.getInfo()
    x = np.asarray(h.getSolution().col_value)
    layout = np.flatnonzero(x[:n] > 0.5).tolist() if x.size else []
    print(
        f"MIP at {count} RISs ({h.modelStatusToString(h.getModelStatus())},"
        f" {time.perf_counter() - t0:.0f} s): value {-info.objective_function_value:.4f},"
        f" proven ≤ {-info.mip_dual_bound:.4f}; its layout of {len(layout)} sites covers"
        f" {exact_coverage(problem, layout):.4f}"
    )


def probe_components(problem: Any, needs: Any) -> None:
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from ris_planner.planning.certify.district_cuts import static_cuts

    rows = static_cuts(problem, needs.need).rows
    pair = np.repeat(rows.pair, np.diff(rows.start))
    n_p, n = problem.n_pairs, problem.n_pairs + problem.n_sites
    graph = csr_matrix((np.ones(pair.size), (pair, n_p + rows.site)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    cut_pairs = np.unique(rows.pair)
    comps, sizes = np.unique(label[cut_pairs], return_counts=True)
    big = comps[np.argmax(sizes)]
    strong = np.unique(rows.site)
    print(
        f"components with pairs: {comps.size}; the largest holds {sizes.max()} of the"
        f" {cut_pairs.size} pairs with a cut (weight"
        f" {problem.weights[cut_pairs[label[cut_pairs] == big]].sum():.3f}) and"
        f" {int((label[n_p + strong] == big).sum())} of the {strong.size} strong sites"
    )


def probe_search(problem: Any, cons: Any, count: int, seconds: float, seed: int) -> None:
    from ris_planner.planning.scoring.sparse import LayoutState, exact_coverage
    from ris_planner.planning.search.district import (
        GAIN_TIE,
        LOOKAHEAD,
        SEARCH_SITES,
        GainBook,
        greedy_path,
        improve,
    )

    required, excluded, conflict = cons
    seen = problem.strongest(SEARCH_SITES)
    t0 = time.perf_counter()
    start = greedy_path(seen, count, required=required, excluded=excluded, conflict=conflict)
    layout, _ = improve(seen, start[-1].sites, required, excluded, 1, conflict)
    first = exact_coverage(problem, layout)
    book = GainBook(LayoutState(seen, list(layout)))
    st = book.state
    banned = np.zeros(problem.n_sites, dtype=bool)
    banned[list(excluded)] = True
    fixed = set(required)

    def free() -> Any:
        ok = ~(st.member | banned)
        if conflict is not None:
            ok &= ~conflict[:, st.member].any(axis=1)
        return ok

    rng = np.random.default_rng(seed)
    best_layout, best = tuple(layout), st.coverage()
    it = 0
    while time.perf_counter() - t0 < seconds:
        it += 1
        movable = [s for s in np.flatnonzero(st.member).tolist() if s not in fixed]
        out = rng.choice(movable, size=min(len(movable), int(rng.integers(2, 7))), replace=False)
        for s in out:
            book.set(int(s), False)
        while int(st.member.sum()) < len(best_layout):
            ok = free()
            ok[out] = False
            if not ok.any():
                break
            for s in book.best_step(ok, conflict, LOOKAHEAD)[
                : len(best_layout) - int(st.member.sum())
            ]:
                book.set(int(s), True)
        for s in [s for s in np.flatnonzero(st.member).tolist() if s not in fixed]:
            book.set(s, False)
            gain = book.gain_c.copy()
            ok = free()
            ok[s] = False
            gain[~ok] = -np.inf
            t = int(np.argmax(gain))
            book.set(t if np.isfinite(gain[t]) and gain[t] > GAIN_TIE else s, True)
        now = st.coverage()
        if now > best + GAIN_TIE:
            best, best_layout = now, tuple(np.flatnonzero(st.member).tolist())
            print(f"  {time.perf_counter() - t0:.0f} s, {it} iterations: {best:.4f}", flush=True)
        elif now < best - 0.01:
            for s in np.flatnonzero(st.member).tolist():
                book.set(s, False)
            for s in best_layout:
                book.set(s, True)
    last = exact_coverage(problem, best_layout)
    print(
        f"search at {count} RISs: greedy path and one swap round {first:.4f}; after"
        f" {time.perf_counter() - t0:.0f} s ({it} iterations) {last:.4f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plan", type=Path, nargs="?", help="a district plan document")
    ap.add_argument("--counts", type=int, nargs="+", default=[40, 60], help="bound counts")
    ap.add_argument("--rounds", type=int, default=12, help="separation rounds probed")
    ap.add_argument("--mip-seconds", type=float, default=240.0, help="the MIP's time limit")
    ap.add_argument("--ils-count", type=int, default=40, help="the search probe's count")
    ap.add_argument("--ils-seconds", type=float, default=900.0, help="the search probe's time")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="the suite's small street site")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from fixtures import district_inputs, quick_street_plan

    if args.quick:
        args.plan = quick_street_plan("gap-probes-")
        args.counts, args.ils_count, args.ils_seconds = [2, 3], 3, 3.0
        args.rounds, args.mip_seconds = 2, 5.0
    elif args.plan is None:
        ap.error("a plan document is needed (or --quick)")

    from ris_planner.planning.certify.district_lp import sites_needed
    from ris_planner.planning.district_plan import constraints_of
    from ris_planner.planning.scoring.sparse import build_problem

    inputs = district_inputs(args.plan)
    problem = build_problem(inputs)
    needs = sites_needed(problem)
    cons = constraints_of(inputs)
    print(
        f"# Gap probes ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}): {args.plan.name},"
        f" {problem.n_sites} candidates, {problem.n_pairs} pairs"
    )
    probe_rounds(problem, needs, cons, args.counts[0], args.rounds)
    probe_mip(problem, needs, cons, args.counts[0], args.mip_seconds)
    probe_rows(problem, needs, cons, args.counts, args.quick)
    probe_components(problem, needs)
    probe_search(problem, cons, args.ils_count, args.ils_seconds, args.seed)


if __name__ == "__main__":
    main()
