"""The paper's multipath figure (fig:positioning_NLOS): CDF of the RX position error with SPs.

Table I geometry, noise figure 0 dB, random codebook (seed 0), ``--runs`` realisations
(default 200) per curve. Two clusters of 5 SPs in 1 m disks centred at [0, −3, h] (TX side)
and [0, 2, h] (RX side), redrawn with random gain phases in every realisation; 30 MPCs in
all. Curves: no MPCs; 30 dBm / 0.5 m² / 3 m; 30 dBm / 2 m² / 3 m; 30 dBm / 0.5 m² / 2 m;
40 dBm / 0.5 m² / 3 m; with PEB_R (no MPC) at 30 and 40 dBm. Writes ``multipath_cdf.png`` and
``multipath_cdf.csv`` (our CDF on the paper's ε grid next to the paper's) to ``--out``.

    python examples/multipath_cdf.py --out out/ [--runs 200]
"""

from __future__ import annotations

import argparse
import csv
import tempfile
import time
from pathlib import Path

import numpy as np

from ris_planner import preset_document
from ris_planner.estimation.document import SimulationDocument
from ris_planner.estimation.montecarlo import run_monte_carlo
from ris_planner.estimation.plots import plot_error_cdf
from ris_planner.model.scenario import load_scenario
from ris_planner.model.simulation import Multipath, paper_clusters
from ris_planner.runtime.progress import ProgressBar

# (label, power dBm, RCS m², height m or None) and the paper's CDF on its ε grid
CURVES = (
    ("Without MPCs", 30.0, None, None),
    ("MPCs (30 dBm / 0.5 m² / 3 m)", 30.0, 0.5, 3.0),
    ("MPCs (30 dBm / 2 m² / 3 m)", 30.0, 2.0, 3.0),
    ("MPCs (30 dBm / 0.5 m² / 2 m)", 30.0, 0.5, 2.0),
    ("MPCs (40 dBm / 0.5 m² / 3 m)", 40.0, 0.5, 3.0),
)
EPS = np.logspace(-3, np.log10(0.988360212830773), 20)
PAPER = {
    "Without MPCs": [
        0,
        0,
        0,
        0.002,
        0.004,
        0.008,
        0.026,
        0.058,
        0.162,
        0.324,
        0.564,
        0.788,
        0.944,
        0.99,
        1,
        1,
        1,
        1,
        1,
        1,
    ],
    "MPCs (30 dBm / 0.5 m² / 3 m)": [
        0.002,
        0.002,
        0.002,
        0.01,
        0.01,
        0.012,
        0.036,
        0.084,
        0.178,
        0.318,
        0.532,
        0.788,
        0.944,
        0.998,
        1,
        1,
        1,
        1,
        1,
        1,
    ],
    "MPCs (30 dBm / 2 m² / 3 m)": [
        0,
        0,
        0,
        0,
        0.002,
        0.002,
        0.012,
        0.048,
        0.124,
        0.282,
        0.476,
        0.666,
        0.8,
        0.854,
        0.86,
        0.86,
        0.86,
        0.86,
        0.86,
        0.86,
    ],
    "MPCs (30 dBm / 0.5 m² / 2 m)": [
        0,
        0,
        0,
        0,
        0,
        0,
        0.008,
        0.028,
        0.062,
        0.146,
        0.284,
        0.45,
        0.636,
        0.816,
        0.894,
        0.922,
        0.924,
        0.924,
        0.948,
        0.996,
    ],
    "MPCs (40 dBm / 0.5 m² / 3 m)": [
        0,
        0.002,
        0.004,
        0.016,
        0.064,
        0.172,
        0.322,
        0.526,
        0.782,
        0.942,
        0.986,
        1,
        1,
        1,
        1,
        1,
        1,
        1,
        1,
        1,
    ],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out"))
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, output in a temporary folder (seconds; tests/test_examples.py)",
    )
    args = parser.parse_args()
    curves: tuple[tuple[str, float, float | None, float | None], ...] = CURVES
    if args.smoke:
        args.out, args.runs, curves = Path(tempfile.mkdtemp(prefix="ris-smoke-")), 2, CURVES[:2]
    args.out.mkdir(parents=True, exist_ok=True)
    doc = preset_document("paper-table1")
    doc["system"]["noise_figure_db"] = 0.0
    scenario = load_scenario(doc)
    errors: dict[str, np.ndarray] = {}
    bounds: dict[str, float] = {}
    rows = []
    t0 = time.perf_counter()
    print(f"{'curve':32s} {'median':>8} {'p90':>8} {'>0.3 m':>7}  KS vs paper")
    for label, power, rcs, height in curves:
        if rcs is None or height is None:
            mp = Multipath()
        else:
            mp = paper_clusters(height_m=height, rcs_m2=rcs)
        sim = SimulationDocument(scenario=scenario, multipath=mp)
        res = run_monte_carlo(sim, [power], args.runs, args.seed, ProgressBar(label[:20]))
        p = res.powers[0]
        err = p.rx_errors()
        errors[label] = err
        bounds[f"PEB_R {power:g} dBm"] = p.peb_rx
        ours = np.array([np.mean(err < e) for e in EPS])
        ks = float(np.max(np.abs(ours - np.array(PAPER[label]))))
        print(
            f"{label:32s} {np.median(err):8.4f} {np.percentile(err, 90):8.4f}"
            f" {np.mean(err > 0.3):7.1%}  {ks:.3f}"
        )
        rows += [[label, e, o, q] for e, o, q in zip(EPS, ours, PAPER[label], strict=True)]
    with open(args.out / "multipath_cdf.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["curve", "epsilon_m", "cdf_ours", "cdf_paper"])
        w.writerows(rows)
    plot_error_cdf(errors, bounds, args.out / "multipath_cdf.png")
    print(f"PEB_R: {bounds}; {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
