"""Accuracy of the squared-form inversion vs the square-root route (ris_planner.inversion.crb)
on the planning benchmark's layout-pairs (30 candidates on a square, 3 RISs, 4753 Fig. 10 pairs).

Prints the distribution of trace(F̂⁻¹) (F̂ = F scaled to unit diagonal) on the plain
[p_T, p_R, B] coordinates and on the LOS-referenced ones (B' = B + d_TR), and, per decade of the
plain trace, the worst relative error of PEB_R from the LDLᵀ of the plain F against the SVD of
the square-root factor – the measurement behind ``crb.FAST_TRACE_LIMIT``.

    python examples/crb_accuracy.py [--layouts 100] [--sample 20000]
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from fixtures import square_plan

from ris_planner.inversion import crb, ldl
from ris_planner.planning import PlanDocument
from ris_planner.planning.inputs.sites import expand_sites
from ris_planner.planning.inputs.ue_maps import build_map, build_pairs
from ris_planner.planning.scoring.site_cache import SiteCache, build_site_cache


def scaled_trace(a: np.ndarray) -> np.ndarray:
    """trace(F̂⁻¹) for square-root factors a [n, r, 7] (via the SVD: no squaring)."""
    col = np.linalg.norm(a, axis=1)
    s = np.linalg.svd(a / col[:, None, :], compute_uv=False)
    return np.asarray((1 / s**2).sum(axis=1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layouts", type=int, default=100)
    ap.add_argument("--sample", type=int, default=20000)
    ap.add_argument("--smoke", action="store_true", help="5 layouts, 500 sampled pairs")
    args = ap.parse_args()
    if args.smoke:
        args.layouts, args.sample = 5, 500
    doc = PlanDocument.model_validate(square_plan())
    sites = expand_sites(doc)
    pairs = build_pairs(build_map(doc.tx_map, "tx"), build_map(doc.rx_map, "rx"), doc.pairs, 10**5)
    plain = build_site_cache(doc.system, sites, pairs, known=("clock",))  # plain coordinates
    ref = build_site_cache(doc.system, sites, pairs)  # LOS-referenced
    lays = np.array(list(itertools.combinations(range(len(sites)), 3)))
    lays = lays[:: max(1, len(lays) // args.layouts)][: args.layouts]
    n = lays.shape[0] * pairs.size
    pick = np.random.default_rng(1).choice(n, min(args.sample, n), replace=False)
    b, p = np.divmod(pick, pairs.size)

    def factor(c: SiteCache) -> np.ndarray:
        assert c.los_factor is not None
        parts = [c.los_factor[p]] + [c.factor_rows(lays[b, j], p) for j in range(3)]
        return np.concatenate(parts, axis=1)

    a_plain, a_ref = factor(plain), factor(ref)
    t_plain, t_ref = scaled_trace(a_plain), scaled_trace(a_ref)
    for name, t in (("plain [p_T, p_R, B]", t_plain), ("LOS-referenced", t_ref)):
        q = np.quantile(t, [0.5, 0.9, 0.99])
        print(f"{name:22s} trace(F̂⁻¹) median {q[0]:.3g}, p90 {q[1]:.3g}, p99 {q[2]:.3g}")
    f = a_plain.transpose(0, 2, 1) @ a_plain
    diag_ldl, singular = ldl.inverse_diagonal_from(ldl.pack(f), 7)
    diag_svd, _ = crb.sqrt_crb_diagonal(a_plain)
    ok = ~singular & np.all(np.isfinite(diag_svd), axis=1)
    err = np.abs(diag_ldl[3:6, ok].sum(0) / diag_svd[ok, 3:6].sum(1) - 1) / 2  # PEB: sqrt
    t = t_plain[ok]
    print("plain-coordinate LDLᵀ vs square-root SVD, relative error of PEB_R per trace decade:")
    for lo in 10.0 ** np.arange(2, 14):
        m = (t >= lo) & (t < 10 * lo)
        if np.any(m):
            print(
                f"  trace {lo:7.0e}: {m.sum():6d} pairs, max error {err[m].max():.1e},"
                f" max error/trace {(err[m] / t[m]).max():.1e}"
            )


if __name__ == "__main__":
    main()
