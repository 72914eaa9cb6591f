"""The paper's reference workloads and published curves (package data, for validation).

* :func:`fig10_pairs` – the 4753 TX–RX pairs of Fig. 10 (fig_multiple_RIS_cdf): UEs on the grid
  x, y ∈ {−3, …, 3} m, z ∈ {0, 0.5} m, every unordered pair of distinct points, the first point of
  a pair being the TX.
* :func:`paper_curve` – curves digitised from the paper source (its pgfplots tables), incl.
  Figs. 5 and 6 (fig_RIS_profiles_prior, fig_RIS_profiles_power_allocation).
"""

from __future__ import annotations

import csv
import itertools
from importlib import resources

import numpy as np
from numpy.typing import NDArray

FIG10_CURVES = (
    "2-ris-L",
    "2-ris-P",
    "3-ris",
    "4-ris",
    "2-ris-L-known-clock",
    "2-ris-L-known-height",
)
"""The six curves of Fig. 10; the known variants use the ``2-ris-L`` preset."""


def fig10_grid() -> NDArray[np.float64]:
    """The 98 grid points of Fig. 10 in x-major order, [98, 3]."""
    xs = np.arange(-3.0, 3.0 + 0.5, 1.0)
    zs = np.array([0.0, 0.5])
    return np.array([[x, y, z] for x in xs for y in xs for z in zs])


def fig10_pairs() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(tx, rx), each [4753, 3]: all C(98, 2) pairs of distinct grid points."""
    pts = fig10_grid()
    idx = np.array(list(itertools.combinations(range(len(pts)), 2)))
    return pts[idx[:, 0]], pts[idx[:, 1]]


def _read(name: str) -> list[dict[str, str]]:
    text = resources.files("ris_planner.model.paper_data").joinpath(name).read_text()
    return list(csv.DictReader(text.splitlines()))


def paper_curve(figure: str, curve: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(x, y) of a published curve.

    figure ``"fig10"``: curve in :data:`FIG10_CURVES`, x = ε [m], y = Pr(PEB_R < ε).
    figure ``"fig1"``: ``peb_tx``, ``peb_rx``, ``ceb`` or ``rmse_{tx,rx,clock}_{coarse,fine}``,
    x = transmit power [dBm], y = metres.
    figure ``"fig5"`` (PEB_R vs prior error): ``dir``, ``der_gamma_{0.1,0.5,5,opt}``,
    ``random``, x = σ_pri [m]; ``"fig6"`` (PEB_R vs γ_P): ``sigma_{0.01,0.1,1}_n{5,10,20}``
    (``sigma_0.01_n10``, ``sigma_0.1_n5``, ``sigma_0.1_n10``, ``sigma_0.1_n20``,
    ``sigma_1_n10``), x = γ_P; y = PEB_R [m].
    """
    files = {
        "fig10": "paper_fig10_cdf_peb_rx.csv",
        "fig1": "paper_fig1_position.csv",
        "fig5": "paper_fig5_fig6_power.csv",
        "fig6": "paper_fig5_fig6_power.csv",
    }
    if figure not in files:
        raise ValueError(f"unknown figure {figure!r}; choose one of {sorted(files)}")
    # every file: [figure,] curve, x, y (a shared file names the figure in its first column)
    rows = [
        r for r in _read(files[figure]) if r.get("figure", figure) == figure and r["curve"] == curve
    ]
    if not rows:
        raise ValueError(f"figure {figure} has no curve {curve!r}")
    keys = list(rows[0])
    x = np.array([float(r[keys[-2]]) for r in rows])
    y = np.array([float(r[keys[-1]]) for r in rows])
    return x, y
