"""Plan reports: ``plan.json`` and PNG figures (top view, heatmap, CDFs per RIS count)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ris_planner.geometry import rotation_matrix
from ris_planner.planning.plan import PlanResult

FIGURE_NAMES = ("topview", "heatmap", "cdf")
SWEEP_FIGURE = "sweep"
"""Written besides :data:`FIGURE_NAMES` when the plan has a sweep: objective vs RIS count,
one line per sweep value."""


def _metric_label(result: PlanResult) -> str:
    return {"rx": "PEB_R", "tx": "PEB_T", "max": "max(PEB_T, PEB_R)"}[
        result.document.objective.metric
    ]


def write_plan_json(plan: dict[str, Any], out_dir: Path) -> Path:
    """``out_dir/plan.json`` from :meth:`PlanResult.to_json` (strict JSON: no NaN/inf)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "plan.json"
    path.write_text(json.dumps(plan, indent=1, allow_nan=False))
    return path


def write_figures(result: PlanResult, out_dir: Path) -> dict[str, Path]:
    """Write the figures as PNGs; returns name → path (``topview``, ``heatmap``, ``cdf``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {name: out_dir / f"{name}.png" for name in FIGURE_NAMES}
    label = _metric_label(result)

    # top view: UE maps (marker size ∝ weight), candidates, chosen RISs with facing arrows
    fig, ax = plt.subplots(figsize=(9, 6))
    for pm, colour, name in (
        (result.tx_map, "tab:blue", "TX map"),
        (result.rx_map, "tab:green", "RX map"),
    ):
        w = pm.weights / pm.weights.max()
        ax.scatter(pm.points[:, 0], pm.points[:, 1], s=4 + 16 * w, c=colour, alpha=0.3, label=name)
    pos = np.array([s.ris.position for s in result.sites])
    flagged = ~np.all(result.cache.far_field, axis=1)
    for mask, colour, name in (
        (~flagged, "grey", "candidates"),
        (flagged, "tab:orange", "candidates (near field for part of the map)"),
    ):
        if np.any(mask):
            ax.scatter(
                pos[mask, 0],
                pos[mask, 1],
                marker="s",
                facecolors="none",
                edgecolors=colour,
                label=name,
            )
    span = float(np.ptp(np.vstack([pos[:, :2], result.rx_map.points[:, :2]]), axis=0).max() or 1.0)
    markers = ["o", "^", "D", "v", "P", "X", "*", "h"]
    for k, cr in enumerate(result.counts):
        lay = cr.ranked[0][0]
        for j, s in enumerate(lay):
            ris = result.sites[s].ris
            face = rotation_matrix(ris.orientation)[:, 0]
            p = ris.position
            ax.scatter(
                p[0],
                p[1],
                marker=markers[k % len(markers)],
                s=220 / (1 + 0.9 * k) ** 2,  # shrinking: a site chosen for several counts
                zorder=3 + k,  # shows every count's marker nested inside the previous ones
                edgecolors="k",
                linewidths=0.5,
                color=f"C{k + 3}",
                label=f"best {cr.ris_count} RIS" if j == 0 else None,
            )
            ax.annotate(
                "",
                xy=(p[0] + 0.08 * span * face[0], p[1] + 0.08 * span * face[1]),
                xytext=(p[0], p[1]),
                arrowprops={"arrowstyle": "->", "color": f"C{k + 3}"},
            )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("UE maps, candidate sites and chosen RISs (arrows: facing)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.tight_layout()
    fig.savefig(paths["topview"], dpi=110)
    plt.close(fig)

    # heatmap of the bound over the RX map for the best layout of the largest count
    pts, vals, lay = result.heatmap()
    fig, ax = plt.subplots(figsize=(7, 6))
    finite = np.isfinite(vals)
    from matplotlib.colors import LogNorm

    if np.any(finite):
        lo, hi = np.nanmin(vals[finite]), np.nanmax(vals[finite])
        sc = ax.scatter(
            pts[finite, 0],
            pts[finite, 1],
            c=vals[finite],
            s=30,
            cmap="viridis",
            norm=LogNorm(vmin=lo, vmax=max(hi, lo * 1.01)),
        )
        fig.colorbar(sc, ax=ax, label=f"{label} [m]")
    blind = np.isinf(vals)
    if np.any(blind):
        ax.scatter(pts[blind, 0], pts[blind, 1], marker="x", c="red", s=30, label="blind spot")
        ax.legend(fontsize=7)
    for s in lay:
        p = result.sites[s].ris.position
        ax.scatter(p[0], p[1], marker="s", c="k", s=50)
    tx_txt = "fixed TX" if result.document.heatmap_tx is not None else "weighted median over TX map"
    ax.set_title(f"{label} over the RX map\nbest {len(lay)}-RIS layout, {tx_txt}", fontsize=10)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    fig.tight_layout()
    fig.savefig(paths["heatmap"], dpi=110)
    plt.close(fig)

    # weighted CDFs of the bound per RIS count (best layout of each)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    w = result.pairs.weights
    for cr in result.counts:
        m = cr.best_metric
        order = np.argsort(m)
        cw = np.cumsum(w[order])
        fin = np.isfinite(m[order])
        ax.step(
            m[order][fin],
            cw[fin],
            where="post",
            label=f"{cr.ris_count} RIS {list(cr.ranked[0][0])}",
        )
    obj = result.document.objective
    if obj.kind == "coverage" and obj.threshold_m is not None:
        ax.axvline(obj.threshold_m, color="k", ls="--", lw=0.8, label="coverage threshold")
    ax.set_xscale("log")
    ax.set_xlabel(f"{label} ε [m]")
    ax.set_ylabel(f"Pr({label} ≤ ε) (weighted)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(paths["cdf"], dpi=110)
    if result.sweep is not None:
        paths[SWEEP_FIGURE] = write_sweep_figure(result, out_dir / f"{SWEEP_FIGURE}.png")
    plt.close(fig)
    return paths


def write_sweep_figure(result: PlanResult, path: Path) -> Path:
    """Objective vs RIS count, one line per sweep value (the base run dashed)."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    assert result.sweep is not None
    sweep = result.sweep
    fig, ax = plt.subplots(figsize=(7, 4.5))
    keys: list[tuple[str, bool]] = []
    for row in sweep["table"]:
        k = (str(row["value"]), bool(row["base"]))
        if k not in keys:
            keys.append(k)
    for value, base in keys:
        rows = [r for r in sweep["table"] if str(r["value"]) == value and r["base"] == base]
        xs = [r["ris_count"] for r in rows]
        ys = [np.nan if r["objective"] is None else r["objective"] for r in rows]
        label = f"{sweep['parameter']} = {value}" + (" (document)" if base else "")
        ax.plot(xs, ys, "--o" if base else "-o", label=label)
    obj = result.document.objective
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("RIS count")
    ax.set_ylabel(
        f"{obj.kind} of {_metric_label(result)}" + ("" if obj.kind == "coverage" else " [m]")
    )
    if obj.target is not None:
        level = obj.target.min if obj.target.min is not None else obj.target.max
        assert level is not None
        ax.axhline(level, color="k", lw=0.8, ls=":", label="target")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
