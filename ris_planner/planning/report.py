"""Plan reports: ``plan.json`` and PNG figures (top view, heatmap, CDFs per RIS count).

The top view and the heatmap draw the environment's obstacles (prisms as filled footprints,
walls as thick lines); the heatmap is a raster over the RX map (cells of about the map's point
spacing, each showing the worst bound of the RX points in it, blank where no point is or inside
a prism) on a diverging scale centred on the objective's level (green at or below it, red
above, purple where the layout is blind), with a colour bar in metres and a legend
(docs/concepts/diagnosis.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import readable_json
from ris_planner.environment import Scene
from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.model import Environment
from ris_planner.physics.geometry import rotation_matrix
from ris_planner.planning.objectives import objective_kind
from ris_planner.planning.result import PlanResult

FIGURE_NAMES = ("topview", "heatmap", "cdf")
SIZING_FIGURE = "sizing"
"""Written besides :data:`FIGURE_NAMES` when the plan answers the sizing question: objective
vs RIS size, one line per RIS count, the target line."""
SWEEP_FIGURE = "sweep"
"""Written besides :data:`FIGURE_NAMES` when the plan has a sweep: objective vs RIS count,
one line per sweep value."""

RASTER_MAX_CELLS = 400
"""Heatmap raster cells per axis at most (the cell grows beyond it)."""

SPACING_SAMPLE = 2000
"""RX points used to estimate the map's point spacing (median nearest-neighbour distance)."""

FloatArray = NDArray[np.float64]


def draw_obstacles(ax: Any, environment: Environment | None) -> None:
    """Prisms as filled footprints (darker = taller), walls as thick lines."""
    if environment is None or not environment.obstacles:
        return
    from matplotlib.patches import Polygon

    tops = [ob.top_m for ob in environment.obstacles]
    hi = max(tops)
    first = {"prism": True, "wall": True}
    for ob in environment.obstacles:
        shade = 0.75 - 0.4 * ob.top_m / hi
        if isinstance(ob, Prism):
            ax.add_patch(
                Polygon(
                    ob.vertices,
                    closed=True,
                    facecolor=str(shade),
                    edgecolor="k",
                    linewidth=0.6,
                    alpha=0.8,
                    zorder=1,
                    label="obstacle (prism)" if first["prism"] else None,
                )
            )
        else:  # walls (and any kind without an inside): its faces as thick lines
            faces = ob.faces()
            for s, e in zip(faces.start, faces.end, strict=True):
                ax.plot(
                    [s[0], e[0]],
                    [s[1], e[1]],
                    color=str(shade * 0.6),
                    linewidth=3.5,
                    solid_capstyle="butt",
                    zorder=1,
                    label="obstacle (wall)" if first.get(ob.kind, False) else None,
                )
                first[ob.kind] = False
        first[ob.kind] = False


def point_spacing(xy: FloatArray) -> float:
    """Median nearest-neighbour distance of distinct 2-D points (a subsample of them)."""
    pts = np.unique(xy, axis=0)
    if len(pts) < 2:
        return 1.0
    if len(pts) > SPACING_SAMPLE:
        pts = pts[np.random.default_rng(0).choice(len(pts), SPACING_SAMPLE, replace=False)]
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    return float(np.median(d.min(axis=1)))


def raster(
    points: FloatArray, values: FloatArray, scene: Scene | None
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """(x edges [nx+1], y edges [ny+1], worst value per cell [ny, nx], no-value mask).

    Cells are squares of the point spacing centred on the lattice of the first point; a cell's
    value is the largest (worst) bound of its points (``inf`` = blind), NaN points are ignored;
    cells without a value or whose centre lies inside a prism (at the points' median height)
    are masked."""
    xy = points[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    cell = max(point_spacing(xy), float((hi - lo).max()) / (RASTER_MAX_CELLS - 1), 1e-6)
    n = np.floor((hi - lo) / cell + 0.5).astype(int) + 1
    idx = np.floor((xy - lo) / cell + 0.5).astype(int)
    grid = np.full((n[1], n[0]), -np.inf)
    ok = ~np.isnan(values)
    np.maximum.at(grid, (idx[ok, 1], idx[ok, 0]), values[ok])
    empty = grid == -np.inf
    if scene is not None and not scene.empty:
        cx, cy = np.meshgrid(lo[0] + cell * np.arange(n[0]), lo[1] + cell * np.arange(n[1]))
        z = np.full(cx.size, float(np.median(points[:, 2])))
        inside = scene.inside(np.column_stack([cx.ravel(), cy.ravel(), z]), margin=0.0) >= 0
        empty |= inside.reshape(grid.shape)
    x_edges = lo[0] + cell * (np.arange(n[0] + 1) - 0.5)
    y_edges = lo[1] + cell * (np.arange(n[1] + 1) - 0.5)
    return x_edges, y_edges, grid, empty


def _site_label(result: PlanResult, s: int) -> str:
    ris = result.sites[s].ris
    return f"{s}: {ris.position[2]:g} m, tilt {np.degrees(ris.orientation[1]):.0f}°"


def _metric_label(result: PlanResult) -> str:
    return {"rx": "PEB_R", "tx": "PEB_T", "max": "max(PEB_T, PEB_R)"}[
        result.document.objective.metric
    ]


def write_plan_json(plan: dict[str, Any], out_dir: Path) -> Path:
    """``out_dir/plan.json`` from :meth:`PlanResult.to_json` (strict JSON: no NaN/inf)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "plan.json"
    path.write_text(readable_json(plan))
    return path


TOPVIEW_MARGINS = {"left": 0.08, "right": 0.70, "bottom": 0.09, "top": 0.94}
"""Fixed margins of the top view (figure fractions; the legend sits in the right 30 %). A
plan's figures are laid out by fixed margins, not ``tight_layout``: that draws every figure
once more to measure its texts (≈ 1 s of a city block's plan, docs/validation/benchmarks.md)."""
HEATMAP_MARGINS = {"left": 0.09, "right": 0.97, "bottom": 0.17, "top": 0.87}
"""Fixed margins of the heatmap: three title lines above, the legend's rows below."""
CDF_MARGINS = {"left": 0.12, "right": 0.97, "bottom": 0.12, "top": 0.96}
"""Fixed margins of the CDF figure."""


def write_figures(result: PlanResult, out_dir: Path) -> dict[str, Path]:
    """Write the figures as PNGs; returns name → path (``topview``, ``heatmap``, ``cdf``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {name: out_dir / f"{name}.png" for name in FIGURE_NAMES}
    label = _metric_label(result)

    env = result.document.environment
    # top view: obstacles, UE maps (marker size ∝ weight), candidates, chosen RISs with facing
    # arrows and labels (index: height, tilt)
    fig, ax = plt.subplots(figsize=(9, 6))
    draw_obstacles(ax, env)
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
    chosen = sorted({s for cr in result.counts for s in cr.ranked[0][0]})
    by_xy: dict[tuple[float, float], list[str]] = {}  # sites above each other: one label
    for s in chosen:
        p = result.sites[s].ris.position
        by_xy.setdefault((round(p[0], 2), round(p[1], 2)), []).append(_site_label(result, s))
    for (x, y), texts in by_xy.items():
        ax.annotate(
            "\n".join(texts),
            (x, y),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=6,
            zorder=20,
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "alpha": 0.7, "lw": 0},
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("UE maps, candidate sites and chosen RISs (arrows: facing)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.subplots_adjust(**TOPVIEW_MARGINS)
    fig.savefig(paths["topview"], dpi=110)
    plt.close(fig)

    # heatmap of the bound over the RX map for the best layout of the largest count
    write_heatmap(result, paths["heatmap"])

    # weighted CDFs of the bound per RIS count (best layout of each)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    w = result.metric_weights
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
    level, level_label = objective_kind(obj.kind).level_label(obj)
    if level is not None:
        ax.axvline(level, color="k", ls="--", lw=0.8, label=level_label)
    ax.set_xscale("log")
    ax.set_xlabel(f"{label} ε [m]")
    ax.set_ylabel(f"Pr({label} ≤ ε) (weighted)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.subplots_adjust(**CDF_MARGINS)
    fig.savefig(paths["cdf"], dpi=110)
    if result.sweep is not None:
        paths[SWEEP_FIGURE] = write_sweep_figure(result, out_dir / f"{SWEEP_FIGURE}.png")
    plt.close(fig)
    if result.beams:
        paths["beams"] = write_beams_figure(result, out_dir / "beams.png")
    if result.sizing is not None:
        paths[SIZING_FIGURE] = write_sizing_figure(result, out_dir / f"{SIZING_FIGURE}.png")
    if result.validation is not None:
        from ris_planner.planning.estimator_check import write_validation_figure

        paths["validation"] = write_validation_figure(result.validation, out_dir / "validation.png")
    return paths


BLIND_COLOUR = "#5b2a86"
"""Heatmap cells where the layout is blind (no finite bound): a colour outside the diverging
scale, named in the legend."""


def heatmap_level(result: PlanResult, finite: FloatArray) -> float:
    """The bound [m] the heatmap's diverging scale is centred on: the objective's reference
    level (threshold, cap, quantile target: :func:`ris_planner.planning.diagnosis.
    reference_level`), else the geometric mean of the finite values shown."""
    from ris_planner.planning.diagnosis import reference_level

    level = reference_level(result.document.objective)
    if np.isfinite(level):
        return float(level)
    return float(np.exp(np.mean(np.log(finite)))) if finite.size else 1.0


def write_heatmap(result: PlanResult, path: Path) -> Path:
    """The bound over the RX map for the best layout of the largest count: a raster with a
    diverging colour scale centred (in log) on the objective's level – green at or below it,
    red above – blind cells in :data:`BLIND_COLOUR`, a colour bar in metres, and a legend of
    the obstacles, the candidates and the layout's sites. No UE markers are drawn over the
    cells (the raster itself shows every point's value)."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.patches import Patch
    from matplotlib.ticker import FuncFormatter

    label = _metric_label(result)
    pts, vals, lay = result.heatmap()
    fig, ax = plt.subplots(figsize=(8.5, 6))
    fig.subplots_adjust(**HEATMAP_MARGINS)  # before the colour bar, which takes its room
    x_edges, y_edges, grid, empty = raster(pts, vals, result.scene)
    finite = np.isfinite(grid) & ~empty
    blind = np.isinf(grid) & ~empty
    level = heatmap_level(result, grid[finite])
    zc = float(np.log10(level))
    z = np.log10(np.where(finite, grid, level))
    zlo = min(float(z[finite].min()) if np.any(finite) else zc, zc - 0.5)
    zhi = max(float(z[finite].max()) if np.any(finite) else zc, zc + 0.5)
    cmap = plt.get_cmap("RdYlGn_r").with_extremes(over=BLIND_COLOUR)
    shown = np.ma.masked_array(np.where(blind, zhi + 1.0, z), mask=empty)
    mesh = ax.pcolormesh(
        x_edges,
        y_edges,
        shown,
        cmap=cmap,
        norm=TwoSlopeNorm(vcenter=zc, vmin=zlo, vmax=zhi),
        shading="flat",
        zorder=0,
    )
    bar = fig.colorbar(mesh, ax=ax, extend="max", shrink=0.85, pad=0.02)
    bar.set_label(f"{label} [m] (log scale; centre = {level:.3g} m)")
    bar.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{10**v:.3g}"))
    bar.ax.axhline(zc, color="k", lw=1.2)
    draw_obstacles(ax, result.document.environment)
    pos = np.array([s.ris.position for s in result.sites])
    ax.scatter(
        pos[:, 0],
        pos[:, 1],
        marker="s",
        s=14,
        facecolors="none",
        edgecolors="0.35",
        linewidths=0.6,
        zorder=4,
        label="candidate sites",
    )
    for j, s in enumerate(lay):
        p = result.sites[s].ris.position
        ax.scatter(
            p[0],
            p[1],
            marker="s",
            c="k",
            s=50,
            zorder=5,
            label=f"chosen sites ({len(lay)} RIS)" if j == 0 else None,
        )
        ax.annotate(str(s), (p[0], p[1]), xytext=(4, 4), textcoords="offset points", fontsize=7)
    handles, _ = ax.get_legend_handles_labels()
    handles.append(Patch(color=BLIND_COLOUR, label="blind (no finite bound)"))
    handles.append(Patch(color=cmap(0.2), label=f"≤ {level:.3g} m"))
    handles.append(Patch(color=cmap(0.8), label=f"> {level:.3g} m"))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.1), ncol=3)
    tx_txt = "fixed TX" if result.document.heatmap_tx is not None else "weighted median over TX map"
    title = f"{label} over the RX map\nbest {len(lay)}-RIS layout, {tx_txt}"
    diagnosis = result.diagnosis
    if diagnosis is not None and diagnosis["verdict"] != "ok":
        title += (
            f"\n{diagnosis['verdict'].upper()}: serves"
            f" {100 * diagnosis['served_fraction']:.1f} % of the pair weight"
        )
    ax.set_title(title, fontsize=10)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_sizing_figure(result: PlanResult, path: Path) -> Path:
    """The sizing question: objective vs RIS size (elements per RIS, log axis, ticks
    rows×cols), one line per RIS count, the target as a dotted line and the answer ringed."""
    import matplotlib.pyplot as plt

    assert result.sizing is not None
    sizing = result.sizing
    obj = result.document.objective
    fig, ax = plt.subplots(figsize=(7, 4.5))
    table = sizing["table"]
    for count in sorted({r["count"] for r in table}):
        rows = [r for r in table if r["count"] == count]
        xs = [r["rows"] * r["cols"] for r in rows]
        ys = [np.nan if r["objective"] is None else r["objective"] for r in rows]
        ax.plot(xs, ys, "-o", label=f"{count} RIS")
    ticks = sorted({(r["rows"], r["cols"]) for r in table}, key=lambda t: t[0] * t[1])
    ax.set_xscale("log")
    ax.set_xticks([a * b for a, b in ticks])
    ax.set_xticklabels([f"{a}×{b}" for a, b in ticks], fontsize=7, rotation=30)
    ax.minorticks_off()
    ax.axhline(sizing["target"]["objective"], color="k", lw=0.8, ls=":", label="target")
    answer = sizing["answer"]
    if answer is not None:
        ax.scatter(
            [answer["rows"] * answer["cols"]],
            [answer["objective"]],
            s=180,
            facecolors="none",
            edgecolors="k",
            linewidths=1.5,
            zorder=5,
            label=f"answer: {answer['count']} × {answer['rows']}×{answer['cols']}",
        )
    ax.set_xlabel("RIS size (elements per RIS)")
    ax.set_ylabel(f"{obj.kind} of {_metric_label(result)}" + objective_kind(obj.kind).unit_suffix)
    ax.set_title("Sizing: best layout per RIS size and count", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


BEAM_CURVES = (
    ("random_mean", "random (mean over seeds, bar: min–max)"),
    ("expected_random", "expected_random (search score)"),
    ("directional", "DIR"),
    ("dir_der_gamma_p", "DIR+DER + best γ_P"),
    ("dir_der_sdp", "DIR+DER + SDP"),
)


def write_beams_figure(result: PlanResult, path: Path) -> Path:
    """The plan objective of the best layout per RIS count under each beam design."""
    import matplotlib.pyplot as plt

    counts = [cr for cr in result.counts if cr.ranked[0][0] in result.beams]
    x = np.array([cr.ris_count for cr in counts], dtype=float)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for k, (key, name) in enumerate(BEAM_CURVES):
        vals = [result.beams[cr.ranked[0][0]].objective.get(key) for cr in counts]
        y = np.array([np.nan if v is None else v for v in vals], dtype=float)
        shift = (k - 2) * 0.04  # side by side, so error bars and markers do not hide others
        if key == "random_mean":
            lo = [result.beams[cr.ranked[0][0]].objective.get("random_min") for cr in counts]
            hi = [result.beams[cr.ranked[0][0]].objective.get("random_max") for cr in counts]
            err = np.array(
                [
                    [np.nan if a is None else yv - a for a, yv in zip(lo, y, strict=True)],
                    [np.nan if b is None else b - yv for b, yv in zip(hi, y, strict=True)],
                ]
            )
            ax.errorbar(x + shift, y, yerr=err, marker="o", capsize=3, label=name)
        else:
            ax.plot(x + shift, y, marker="os^vD"[k], label=name)
    obj = result.document.objective
    better = objective_kind(obj.kind).better
    ax.set_xticks(x)
    ax.set_xlabel("RIS count (best layout of each)")
    ax.set_ylabel(f"plan objective ({obj.kind}, {better} is better)")
    ax.set_title("Beam designs re-evaluated on all pairs", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


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
    ax.set_ylabel(f"{obj.kind} of {_metric_label(result)}" + objective_kind(obj.kind).unit_suffix)
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
