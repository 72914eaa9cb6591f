"""Beam patterns of a DIR and the DER beams (the paper's fig_RIS_profile_visualization, column 1):
|ωᵀ a_R(ξ, ζ)| over one period of the spatial frequencies, ξ, ζ ∈ [−1, 1] (with λ/2 spacing the
pattern repeats with period 2: the grating lobes), for RIS 1 of Table I.

The figure's caption puts the DIR maximum at (ξ, ζ) = (−0.4443, −0.5039) with TX angles
[−1.1071, −0.2200] rad and RX angles [0.4636, −0.2898] rad; those follow from RIS 1 at
[−4, 0, 2] with p_R = [2, 3, 0] and p_T = [−2, −4, 1] (not Table I's z = 0), used here.
The DER beams are the unit-modulus projections of eqs. sum_diff_beam_2, 3
(:mod:`ris_planner.physics.beams`). Writes ``beam_patterns.png`` and ``beam_patterns.csv`` (ξ, ζ and
the normalised gains) to ``--out``.

    python examples/beam_patterns.py --out out/
"""

from __future__ import annotations

import argparse
import csv
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ris_planner import load_scenario, preset_document
from ris_planner.physics import geometry
from ris_planner.physics.beams import (
    derivative_beams,
    directional_beams,
    project_unit_modulus,
    ris_element_positions,
)

TX_FIGURE = [-2.0, -4.0, 1.0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out"))
    parser.add_argument("--points", type=int, default=201, help="grid points per axis")
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, output in a temporary folder (seconds; tests/test_examples.py)",
    )
    args = parser.parse_args()
    if args.smoke:
        args.out, args.points = Path(tempfile.mkdtemp(prefix="ris-smoke-")), 21
    args.out.mkdir(parents=True, exist_ok=True)
    sc = load_scenario(preset_document("paper-table1") | {"tx": TX_FIGURE})
    ris, lam = sc.ris[0], sc.system.wavelength
    geo = geometry.ris_path_geometry(sc.tx_array, sc.rx_array, ris.position, ris.orientation)
    print(
        f"target ξ = {geo.xi[0]:.4f}, ζ = {geo.zeta[0]:.4f} (paper: −0.4443, −0.5039);"
        f" TX angles {geometry.angles(geo.t_tx)[0].round(4)}, RX angles"
        f" {geometry.angles(geo.t_rx)[0].round(4)}"
    )
    pos = ris_element_positions(ris, lam)
    w1 = directional_beams(pos, geo.xi, geo.zeta, lam)
    d_xi, d_zeta = derivative_beams(pos, geo.xi, geo.zeta, lam)
    beams = {
        "DIR ω1": w1[0],
        "DER ω2 (ξ)": project_unit_modulus(d_xi, w1)[0],
        "DER ω3 (ζ)": project_unit_modulus(d_zeta, w1)[0],
    }
    axis = np.linspace(-1, 1, args.points)
    gx, gz = np.meshgrid(axis, axis)
    # [points², N] steering vectors over the grid, one product per beam
    steer = geometry.steering_vector(pos, gx.ravel(), gz.ravel(), lam)
    gains = {name: np.abs(steer @ w).reshape(gx.shape) / pos.shape[0] for name, w in beams.items()}
    target = geometry.steering_vector(pos, geo.xi, geo.zeta, lam)[0]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    for ax, (name, g) in zip(axes, gains.items(), strict=True):
        im = ax.pcolormesh(gx, gz, g, shading="auto", cmap="viridis", vmin=0, vmax=1)
        ax.plot(geo.xi, geo.zeta, "r+", ms=12)
        ax.set(title=f"{name}: |ωᵀa_R(ξ,ζ)|/N", xlabel="ξ", ylabel="ζ")
        fig.colorbar(im, ax=ax)
        iy, ix = np.unravel_index(np.argmax(g), g.shape)
        at_target = abs(target @ beams[name]) / pos.shape[0]
        print(
            f"{name:12s} max {g.max():.3f} at ξ = {gx[iy, ix]:.3f}, ζ = {gz[iy, ix]:.3f};"
            f" normalised gain at the target {at_target:.3e}"
        )
    fig.tight_layout()
    fig.savefig(args.out / "beam_patterns.png", dpi=120)
    with open(args.out / "beam_patterns.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["xi", "zeta", *gains])
        for i in range(gx.size):
            w.writerow([gx.flat[i], gz.flat[i], *(g.flat[i] for g in gains.values())])
    print(f"wrote {args.out / 'beam_patterns.png'} and .csv")


if __name__ == "__main__":
    main()
