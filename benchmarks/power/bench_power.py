"""Benchmark: power control for G = 192 (Γ = 3, G̃ = 64), L = 2 RISs with LOS, 16 sampled prior
positions (the paper's Table I geometry, DIR+DER codebook, σ = 0.1 m).

* SDP with Clarabel (the product's formulation: one whitened LMI per position, Σ γ_g S_g as one
  matrix product, identical beams merged) — target ≤ 1 s on the 2-core machine – handed to
  Clarabel as its cone program directly (the default) and, in the same run, stated through
  cvxpy (the speed-up of the direct program is printed);
* the same problem with SCS (through cvxpy);
* the naive formulation of the appendix measured in the same run: Σ γ_g S_g as a Python sum of
  G̃ terms per position, three LMIs per position (eq. problem_all_sub2_), no beam merging;
* the γ_P search (grid + bounded Brent on the stacked information, the answer re-evaluated
  by compute_bounds, as run_power does) — target ≤ 0.5 s — next to the same search with
  compute_bounds for every evaluation and a naive dense grid (241 points, 1/40 decade) of
  compute_bounds evaluations.

    python benchmarks/power/bench_power.py [--repeats 5] [--skip-naive] [--quick]

``--quick``: one repeat, no naive reference.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import cvxpy as cp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import table1_document

from ris_planner import load_scenario
from ris_planner.physics.beams import codebook_block, gamma_p_powers
from ris_planner.power.gamma import search_gamma_p
from ris_planner.power.information import BeamInformation, beam_information
from ris_planner.power.report import design_objective
from ris_planner.power.sdp import mean_trace_bound, solve_power_sdp, whitening

T = TypeVar("T")


def timed(fn: Callable[[], T], repeats: int) -> tuple[float, T]:
    out = fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def naive_sdp(info: BeamInformation) -> tuple[float, float]:
    """The appendix as written: per position Σ_g γ_g S_g as a Python sum and three scalar
    LMIs [[F, e_l], [e_lᵀ, u_l]] ⪰ 0 (l = 4, 5, 6), no beam merging (one S_g per slot);
    whitened like the product (without whitening Clarabel fails on this problem). Returns
    (objective [m²], seconds)."""
    stack = info.stack[:, info.beam_group]
    rx_index = info.rx_index
    n_pos, g_tilde = stack.shape[:2]
    uniform = np.ones(g_tilde)
    w, _ = whitening(info, uniform)  # full rank on this layout
    scaled = w[:, None] @ stack @ w[:, None].transpose(0, 1, 3, 2)
    scaled = 0.5 * (scaled + scaled.transpose(0, 1, 3, 2))
    c = mean_trace_bound(info, uniform, rx_index)
    gam = cp.Variable(g_tilde, nonneg=True)
    cons: list[cp.Constraint] = [cp.sum(gam) == g_tilde]
    u = cp.Variable((n_pos, 3))
    for p in range(n_pos):
        fp = sum(gam[g] * scaled[p, g] for g in range(g_tilde))
        for j, idx in enumerate(rx_index):
            e = (w[p][:, idx] / np.sqrt(c))[:, None]
            cons.append(cp.bmat([[fp, e], [e.T, cp.reshape(u[p, j], (1, 1), order="C")]]) >> 0)
    prob = cp.Problem(cp.Minimize(cp.sum(u) / n_pos), cons)
    t0 = time.perf_counter()
    prob.solve(solver="CLARABEL")
    return float(prob.value) * c, time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--skip-naive", action="store_true")
    parser.add_argument("--quick", action="store_true", help="one repeat, no naive reference")
    args = parser.parse_args()
    if args.quick:
        args.repeats, args.skip_naive = 1, True

    doc = table1_document()
    doc["codebook"] = {
        "kind": "directional_derivative",
        "prior": {"sigma_m": 0.1, "samples": 16, "seed": 0},
    }
    sc = load_scenario(doc)
    block = codebook_block(sc)
    print(
        f"G = {sc.system.transmissions}, G̃ = {block.beam_types.size}, L = {len(sc.ris)},"
        f" positions = {block.tx.shape[0]}, N = {sc.ris[0].elements}"
    )
    t_info, info = timed(
        lambda: beam_information(sc, block.tx, block.rx, block.profiles), args.repeats
    )
    print(f"beam information stack {info.stack.shape}: {t_info * 1e3:.1f} ms")

    evaluate = design_objective(sc, block.tx, block.rx, block.profiles, "rx")
    uniform = evaluate(np.ones(block.beam_types.size))
    runs = [("CLARABEL", "direct"), ("CLARABEL", "cvxpy"), ("SCS", "cvxpy")]
    took: dict[str, float] = {}
    for solver, modeller in runs:
        t, res = timed(
            lambda s=solver, m=modeller: solve_power_sdp(info, solver=s, modeller=m), args.repeats
        )
        took[f"{solver} {modeller}"] = t
        assert res.powers is not None and res.objective is not None
        recomputed = evaluate(res.powers)
        print(
            f"SDP {solver:8s} {modeller:6s}: {t:.3f} s (median of {args.repeats}, building"
            f" incl.; solver's own {res.solver_time_s or float('nan'):.3f} s), status"
            f" {res.status}, objective {res.objective:.6e} m², recomputed"
            f" {recomputed:.6e} m², uniform {uniform:.6e} m²"
        )
    print(
        "Clarabel given the cone program directly vs through cvxpy: speed-up"
        f" {took['CLARABEL cvxpy'] / took['CLARABEL direct']:.2f}x"
    )

    def fast_search() -> float:
        """What run_power does: search on the stacked information, re-evaluate the answer."""
        res = search_gamma_p(lambda p: mean_trace_bound(info, p, info.rx_index), block.beam_types)
        return evaluate(res.powers)

    t_g, fast_obj = timed(fast_search, args.repeats)
    t_cb, search = timed(lambda: search_gamma_p(evaluate, block.beam_types), args.repeats)
    print(
        f"γ_P search (stacked information + one compute_bounds): {t_g:.3f} s, objective"
        f" {fast_obj:.6e} m²; with compute_bounds for every evaluation: {t_cb:.3f} s,"
        f" γ_P = {search.value:.4f}, objective {search.objective:.6e} m²,"
        f" {len(search.evaluations)} evaluations"
    )
    grid = 10 ** np.linspace(-3, 3, 241)
    t0 = time.perf_counter()
    dense = [evaluate(gamma_p_powers(block.beam_types, g)) for g in grid]
    t_dense = time.perf_counter() - t0
    print(
        f"naive dense γ_P grid (241 points): {t_dense:.3f} s, best {min(dense):.6e} m²"
        f" -> search speed-up {t_dense / t_g:.1f}x"
    )

    if not args.skip_naive:
        obj, t_naive = naive_sdp(beam_information(sc, block.tx, block.rx, block.profiles))
        t_fast, fast = timed(lambda: solve_power_sdp(info), 1)
        assert fast.powers is not None and fast.objective is not None
        print(
            f"naive appendix SDP (Python sum, 3 LMIs/position): {t_naive:.3f} s,"
            f" objective {obj:.6e} m² -> speed-up {t_naive / t_fast:.1f}x"
        )
        ratio = mean_trace_bound(info, fast.powers, info.rx_index) / evaluate(fast.powers)
        print(
            f"check: naive objective / fast {obj / fast.objective:.8f};"
            f" stacked FIM vs compute_bounds at the SDP powers {ratio:.10f}"
        )


if __name__ == "__main__":
    main()
