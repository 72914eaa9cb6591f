"""PNG figures of the estimator (matplotlib, Agg backend): the paper's Fig. 1 (RMSE of the
coarse and refined estimates next to PEB/CEB over power), the multipath CDF figure, and the
blind-area cost map."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray

from ris_planner.estimation.montecarlo import rmse

if TYPE_CHECKING:
    from ris_planner.estimation.blind_area import CostMap
    from ris_planner.estimation.montecarlo import MonteCarloResult


def plot_rmse_vs_power(result: MonteCarloResult, path: Path | str) -> None:
    """Fig. 1 (b): RMSE of p_T, p_R, B (coarse markers, refined lines) and PEB/CEB (dashed)."""
    powers = [p.power_dbm for p in result.powers]
    fine = np.array([p.rmse("refined") for p in result.powers])
    coarse = np.array([p.rmse("coarse") for p in result.powers])
    bounds = np.array([[p.peb_tx, p.peb_rx, p.ceb] for p in result.powers])
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    labels = (r"$\mathbf{p}_T$", r"$\mathbf{p}_R$", "$B$")
    names = ("PEB$_T$", "PEB$_R$", "CEB")
    for j, (colour, marker) in enumerate((("tab:blue", "o"), ("tab:red", "s"), ("k", "D"))):
        ax.semilogy(
            powers, coarse[:, j], marker, color=colour, mfc="none", label=f"{labels[j]} (coarse)"
        )
        ax.semilogy(powers, fine[:, j], "-", color=colour, label=f"{labels[j]} (refined)")
        ax.semilogy(powers, bounds[:, j], "--", color=colour, label=names[j])
    # below the SNR threshold the unconstrained MLE can run far away (the paper's Fig. 1 axis
    # stops at 10 m too): clip the axis at 30× the largest bound, the numbers stay in the CSV
    top = 30 * float(np.nanmax(bounds[np.isfinite(bounds)], initial=1.0))
    if np.nanmax(np.concatenate([fine.ravel(), coarse.ravel()])) > top:
        ax.set_ylim(top=top)
        ax.text(0.01, 0.99, "axis clipped; see CSV", transform=ax.transAxes, va="top", fontsize=7)
    ax.set_xlabel("Transmit power [dBm]")
    ax.set_ylabel("RMSE / PEB / CEB [m]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(ncol=3, fontsize=7)
    ax.set_title(f"Estimator vs CRB ({result.runs} runs per power)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_channel_rmse(result: MonteCarloResult, path: Path | str) -> None:
    """Fig. 1 (a): RMSE of the channel parameters (delays in metres, ξ/ζ unitless) against
    DEB/SEB over power; coarse markers, refined lines, bounds dashed."""
    powers = [p.power_dbm for p in result.powers]
    names = result.powers[0].channel_names
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, name in enumerate(names):
        c = colours[j % len(colours)]
        fine = [rmse(p.channel_refined[:, j]) for p in result.powers]
        coarse = [rmse(p.channel_coarse[:, j]) for p in result.powers]
        bound = [p.channel_bounds[name] for p in result.powers]
        ax.semilogy(powers, coarse, "o", color=c, mfc="none", ms=4)
        ax.semilogy(powers, fine, "-", color=c, label=name)
        ax.semilogy(powers, bound, "--", color=c)
    top = 30 * max(max(p.channel_bounds.values()) for p in result.powers)
    ax.set_ylim(top=top)
    ax.set_xlabel("Transmit power [dBm]")
    ax.set_ylabel("RMSE (markers coarse, lines refined) / bound (dashed)")
    ax.set_title("Channel parameters: delay [m], ξ, ζ [-]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_error_cdf(
    curves: dict[str, NDArray[np.float64]],
    bounds: dict[str, float],
    path: Path | str,
    xlabel: str = r"$\epsilon$ [m]",
) -> None:
    """CDFs of errors (one curve per label, log x) with vertical lines at the bounds."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for label, err in curves.items():
        e = np.sort(np.asarray(err))
        ax.semilogx(e, np.arange(1, e.size + 1) / e.size, label=label)
    for label, b in bounds.items():
        ax.axvline(b, ls="--", color="k", lw=0.8)
        ax.text(b, 0.02, label, rotation=90, fontsize=7, va="bottom")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(r"Pr(RX position error < $\epsilon$)")
    ax.set_ylim(0, 1)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_cost_map(cmap: CostMap, path: Path | str) -> None:
    """The noise-free cost J of eq. coarse_position_costFun over TX candidates (log scale),
    the true TX/RX, the RISs and the candidate TX/RX pairs at the local minima."""
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    finite = np.isfinite(cmap.cost)
    # colour range: from the 1st percentile of the positive costs (the true TX has J = 0)
    positive = cmap.cost[finite & (cmap.cost > 0)]
    floor = float(np.percentile(positive, 1)) if positive.size else 1e-6
    shown = np.where(finite, np.log10(np.maximum(cmap.cost, floor)), np.nan)
    im = ax.pcolormesh(cmap.x, cmap.y, shown.T, shading="nearest", cmap="viridis")
    fig.colorbar(im, ax=ax, label=r"$\log_{10} J$ [m]")
    for k, m in enumerate(cmap.minima):
        ax.plot(*m.tx[:2], "w^", ms=6)
        ax.plot(*m.rx[:2], "wv", ms=6)
        ax.plot([m.tx[0], m.rx[0]], [m.tx[1], m.rx[1]], "w:", lw=0.8)
        ax.annotate(str(k + 1), (float(m.tx[0]), float(m.tx[1])), color="w", fontsize=7)
    ax.plot(*cmap.true_tx[:2], "r^", ms=9, label="true TX")
    ax.plot(*cmap.true_rx[:2], "rv", ms=9, label="RX")
    for p in cmap.ris_positions:
        ax.plot(p[0], p[1], "ks", ms=7)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_title(f"Noise-free cost over TX candidates (z = {cmap.z:g} m)")
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
