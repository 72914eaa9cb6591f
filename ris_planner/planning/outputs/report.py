"""Plan reports: ``plan.json`` and PNG figures (top view, heatmap, CDFs per RIS count).

The top view and the heatmap draw the environment's obstacles (prisms as filled footprints,
walls as thick lines) and label the chosen sites with their candidate index, each label
placed where it overlaps no other (:func:`place_labels`); the top view lists the chosen sites'
names in a table beside the map (:func:`text_table`). The heatmap has two panels over the RX
map (cells of about the map's point spacing, blank where no point is or inside a prism): the
fraction of each point's TX partners the layout serves (the worst point of a cell; where the
plan works, even when it mostly does not), and the bound (the worst bound of the cell's
points) on a diverging scale centred on the objective's level (green at or below it, red
above, purple where the layout is blind), each with a colour bar, and a legend
(docs/concepts/diagnosis.md)."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.io_json import readable_json
from ris_planner.environment import Scene
from ris_planner.model.objectives import objective_kind
from ris_planner.physics.geometry import rotation_matrix
from ris_planner.planning.outputs.drawing import draw_obstacles
from ris_planner.planning.outputs.result import PlanResult

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
    points: FloatArray,
    values: FloatArray,
    scene: Scene | None,
    worst: Literal["max", "min"] = "max",
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """(x edges [nx+1], y edges [ny+1], worst value per cell [ny, nx], no-value mask).

    Cells are squares of the point spacing centred on the lattice of the first point; a cell's
    value is the worst of its points' values – the largest for a bound (``inf`` = blind), the
    smallest with ``worst="min"`` (a served fraction) –, NaN points are ignored; cells without
    a value or whose centre lies inside a prism (at the points' median height) are masked."""
    sign = 1.0 if worst == "max" else -1.0
    xy = points[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    cell = max(point_spacing(xy), float((hi - lo).max()) / (RASTER_MAX_CELLS - 1), 1e-6)
    n = np.floor((hi - lo) / cell + 0.5).astype(int) + 1
    idx = np.floor((xy - lo) / cell + 0.5).astype(int)
    grid = np.full((n[1], n[0]), -np.inf)
    ok = ~np.isnan(values)
    np.maximum.at(grid, (idx[ok, 1], idx[ok, 0]), sign * values[ok])
    empty = grid == -np.inf
    grid = sign * grid
    if scene is not None and not scene.empty:
        cx, cy = np.meshgrid(lo[0] + cell * np.arange(n[0]), lo[1] + cell * np.arange(n[1]))
        z = np.full(cx.size, float(np.median(points[:, 2])))
        inside = scene.inside(np.column_stack([cx.ravel(), cy.ravel(), z]), margin=0.0) >= 0
        empty |= inside.reshape(grid.shape)
    x_edges = lo[0] + cell * (np.arange(n[0] + 1) - 0.5)
    y_edges = lo[1] + cell * (np.arange(n[1] + 1) - 0.5)
    return x_edges, y_edges, grid, empty


METRIC_LABELS = {"rx": "PEB_R", "tx": "PEB_T", "max": "max(PEB_T, PEB_R)"}
"""The bound each objective metric names (figure labels)."""
ERROR_LABELS = {
    "rx": "RX position error",
    "tx": "TX position error",
    "max": "max(TX, RX) position error",
}
"""The estimator's error each metric's bound limits (the validation figure's labels)."""


def _metric_label(result: PlanResult) -> str:
    return METRIC_LABELS[result.document.objective.metric]


FIGURE_DPI = 110
"""The figures' resolution: they are laid out (label placement measures texts) at the
resolution they are saved with."""

SITE_LABEL_GID = "site-label"
"""The ``gid`` of the chosen sites' labels on the map panels (:func:`place_labels`)."""

LABEL_RINGS_PT = (2.0, 7.0, 14.0, 24.0, 38.0, 56.0)
"""Distances [pt] beyond the marker at which :func:`place_labels` tries a label, nearest first."""

LABEL_DIRECTIONS_DEG = (45, 135, -45, -135, 90, -90, 0, 180)
"""Directions (from +x, counter-clockwise) tried on each ring, in order of preference."""

LABEL_PAD_PX = 2.0
"""Clearance [px] kept between a label and other labels, markers and the axes' edge."""


def _renderer(fig: Any) -> Any:
    """The figure's Agg renderer (texts measured as ``savefig`` draws them)."""
    return fig.canvas.get_renderer()


def _overlaps(a: FloatArray, b: FloatArray) -> FloatArray:
    """[A, B] overlap areas of display-space boxes a [A, 4] and b [B, 4] (x0, y0, x1, y1; 0
    where they do not intersect)."""
    w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    return np.asarray(np.clip(w, 0.0, None) * np.clip(h, 0.0, None))


def place_labels(
    ax: Any,
    anchors: Sequence[tuple[float, float]],
    texts: Sequence[str],
    *,
    marker_pt: float = 6.0,
    fontsize: float = 7.0,
    avoid: Sequence[tuple[tuple[float, float], tuple[float, float]]] = (),
) -> list[Any]:
    """Label each anchor (data coordinates) with its text, placed by greedy displacement: the
    labels in turn, each at the first offset (:data:`LABEL_RINGS_PT` beyond a marker of
    radius ``marker_pt`` × :data:`LABEL_DIRECTIONS_DEG`) where its box overlaps no label
    placed before, no anchor's marker and no box of ``avoid`` (corner pairs in data
    coordinates: the facing arrows) and stays inside the axes – else where it overlaps
    least. A label set off beyond the first ring gets a thin leader line to its anchor.

    Call once the axes' limits and size are final (the texts are measured in display space);
    returns the :class:`~matplotlib.text.Text` objects (``gid`` :data:`SITE_LABEL_GID`)."""
    from matplotlib.transforms import Bbox, offset_copy

    fig = ax.figure
    ax.set_xlim(ax.get_xlim())  # freeze the limits: later artists must not move the labels
    ax.set_ylim(ax.get_ylim())
    ax.apply_aspect()
    renderer = _renderer(fig)
    px_per_pt = fig.dpi / 72.0
    frame = ax.get_window_extent(renderer).padded(-LABEL_PAD_PX)
    r_px = marker_pt * px_per_pt
    xy = ax.transData.transform(np.asarray(anchors, dtype=float).reshape(-1, 2))
    boxes = [np.column_stack([xy - r_px, xy + r_px])]  # [n, 4] x0, y0, x1, y1 of the markers
    for a, b in avoid:
        (x0, y0), (x1, y1) = ax.transData.transform(np.array([a, b], dtype=float))
        box = Bbox.from_extents(min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))
        box = box.padded(LABEL_PAD_PX)  # a straight arrow's box has no width
        boxes.append(np.array([[box.x0, box.y0, box.x1, box.y1]]))
    taken = np.concatenate(boxes)
    edge = np.array([frame.x0, frame.y0, frame.x1, frame.y1])
    # every offset tried, nearest ring first: (ring, dx, dy [px], ha, va, points offset)
    tries = []
    for ring in LABEL_RINGS_PT:
        for deg in LABEL_DIRECTIONS_DEG:
            c, s_ = math.cos(math.radians(deg)), math.sin(math.radians(deg))
            dist = marker_pt + ring
            ha = "left" if c > 0.1 else "right" if c < -0.1 else "center"
            va = "bottom" if s_ > 0.1 else "top" if s_ < -0.1 else "center"
            tries.append((ring, dist * c, dist * s_, ha, va))
    shift = {"left": 0.0, "center": 0.5, "right": 1.0, "bottom": 0.0, "top": 1.0}
    out = []
    for (x, y), (px, py), text in zip(anchors, xy, texts, strict=True):
        label = ax.text(
            x,
            y,
            text,
            fontsize=fontsize,
            zorder=20,
            gid=SITE_LABEL_GID,
            clip_on=False,
            ha="left",
            va="bottom",
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "alpha": 0.8, "lw": 0},
        )
        # the label's box at its anchor, measured once; each offset moves it as a whole
        ext = label.get_window_extent(renderer)
        w, h = ext.width, ext.height
        x0 = np.array([px + dx * px_per_pt - shift[ha] * w for _, dx, _, ha, _ in tries])
        y0 = np.array([py + dy * px_per_pt - shift[va] * h for _, _, dy, _, va in tries])
        cand = np.column_stack([x0, y0, x0 + w, y0 + h])  # [T, 4]
        cand += [-LABEL_PAD_PX, -LABEL_PAD_PX, LABEL_PAD_PX, LABEL_PAD_PX]
        cost = _overlaps(cand, taken).sum(axis=1)
        inside = _overlaps(cand, edge[None])[:, 0]
        cost += (cand[:, 2] - cand[:, 0]) * (cand[:, 3] - cand[:, 1]) - inside  # outside
        free = np.flatnonzero(cost == 0)
        k = int(free[0]) if free.size else int(np.argmin(cost))
        ring, dx, dy, ha, va = tries[k]
        trans = offset_copy(ax.transData, fig=fig, x=dx, y=dy, units="points")
        label.set(transform=trans, ha=ha, va=va)
        box = label.get_window_extent(renderer).padded(LABEL_PAD_PX)
        taken = np.vstack([taken, [box.x0, box.y0, box.x1, box.y1]])
        out.append(label)
        if ring > LABEL_RINGS_PT[0]:
            centre = ((box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2)
            cx, cy = ax.transData.inverted().transform(centre)
            ax.plot(
                [x, cx],
                [y, cy],
                color="0.3",
                lw=0.5,
                zorder=19,
                scalex=False,
                scaley=False,
            )
    return out


def text_table(
    headers: Sequence[str], rows: Sequence[Sequence[str]], width: int, wrap: int
) -> list[str]:
    """A plain-text table (for a monospaced font): the header line, then each row on as many
    lines as its column ``wrap`` needs. Every column is as wide as its widest header or cell,
    so no header or other cell is ever broken; the ``wrap`` column takes what ``width``
    characters leave (at least its header and its longest word) and wraps at spaces only."""
    gap = 2
    cols = len(headers)
    widths = [max([len(h)] + [len(r[c]) for r in rows]) for c, h in enumerate(headers)]
    rest = width - sum(w for c, w in enumerate(widths) if c != wrap) - gap * (cols - 1)
    longest_word = max([len(w) for r in rows for w in r[wrap].split()] + [len(headers[wrap])])
    widths[wrap] = max(min(widths[wrap], rest), longest_word)

    def line(cells: Sequence[str]) -> str:
        return (" " * gap).join(c.ljust(w) for c, w in zip(cells, widths, strict=True)).rstrip()

    out = [line(headers)]
    for r in rows:
        parts = textwrap.wrap(
            r[wrap], widths[wrap], break_long_words=False, break_on_hyphens=False
        ) or [""]
        for k, part in enumerate(parts):
            out.append(line([part if c == wrap else r[c] if k == 0 else "" for c in range(cols)]))
    return out


def write_plan_json(plan: dict[str, Any], out_dir: Path) -> Path:
    """``out_dir/plan.json`` from :meth:`PlanResult.to_json` (strict JSON: no NaN/inf)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "plan.json"
    path.write_text(readable_json(plan))
    return path


TOPVIEW_MARGINS = {"left": 0.07, "right": 0.62, "bottom": 0.09, "top": 0.94}
"""Fixed margins of the top view (figure fractions; the legend and the site table sit in the
right 38 %). A plan's figures are laid out by fixed margins, not ``tight_layout``: that draws
every figure once more to measure its texts (≈ 1 s of a city block's plan,
docs/validation/benchmarks.md)."""
HEATMAP_MARGINS = {"left": 0.05, "right": 0.97, "bottom": 0.24, "top": 0.86, "wspace": 0.12}
"""Fixed margins of the heatmap's two panels: the title lines above, the legend's rows and the
site key below."""
CDF_MARGINS = {"left": 0.12, "right": 0.97, "bottom": 0.12, "top": 0.96}
"""Fixed margins of the CDF figure."""

SITE_TABLE_HEADERS = ("#", "site", "height", "tilt", "chosen for")
"""Columns of the top view's table of chosen sites."""
SITE_TABLE_FONTSIZE = 6.5
SITE_TABLE_LINE_SPACING = 1.2
"""The site table's line height in font sizes (matplotlib's default line spacing); the
table keeps to the room under the legend, a closing line says how many lines it left out."""
MONO_ADVANCE_EM = 0.602
"""Advance width of a monospaced glyph (DejaVu Sans Mono), in ems: the site table's width in
characters from the room beside the map."""


def chosen_sites(result: PlanResult) -> dict[int, list[int]]:
    """Site index → the RIS counts whose best layout has it (sorted by site)."""
    out: dict[int, list[int]] = {}
    for cr in result.counts:
        for s in cr.ranked[0][0]:
            out.setdefault(int(s), []).append(cr.ris_count)
    return dict(sorted(out.items()))


def site_table_rows(result: PlanResult, sites: dict[int, list[int]]) -> list[list[str]]:
    """One row per site: index, name, height, tilt, the counts it is chosen for."""
    rows = []
    for s, counts in sites.items():
        site = result.sites[s]
        rows.append(
            [
                str(s),
                site.name,
                f"{site.ris.position[2]:g} m",
                f"{np.degrees(site.ris.orientation[1]):.0f}°",
                ", ".join(str(c) for c in counts) + " RIS",
            ]
        )
    return rows


def _site_labels(
    result: PlanResult, sites: Sequence[int]
) -> tuple[list[tuple[float, float]], list[str]]:
    """(anchors, texts): one label per map position, sites above each other share it."""
    by_xy: dict[tuple[float, float], list[str]] = {}
    for s in sites:
        p = result.sites[s].ris.position
        by_xy.setdefault((round(float(p[0]), 2), round(float(p[1]), 2)), []).append(str(s))
    return list(by_xy), [", ".join(v) for v in by_xy.values()]


def topview_figure(result: PlanResult) -> Any:
    """The top view: obstacles, UE maps (marker size ∝ weight), candidates, each count's best
    sites (nested markers, facing arrows), their indices placed without overlap
    (:func:`place_labels`) and, beside the map under the legend, the table of the chosen
    sites' names, heights, tilts and counts (:func:`text_table`)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10.5, 6), dpi=FIGURE_DPI)
    fig.subplots_adjust(**TOPVIEW_MARGINS)
    draw_obstacles(ax, result.document.environment)
    for pm, colour, name in (
        (result.tx_map, "tab:blue", "TX map"),
        (result.rx_map, "tab:green", "RX map"),
    ):
        w = pm.weights / pm.weights.max()
        ax.scatter(pm.points[:, 0], pm.points[:, 1], s=4 + 16 * w, c=colour, alpha=0.3, label=name)
    pos = np.array([s.ris.position for s in result.sites])
    flagged = result.scorer.near_field_by_site(result.pairs.weights) > 0
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
    arrows: list[tuple[tuple[float, float], tuple[float, float]]] = []
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
            tip = (float(p[0] + 0.08 * span * face[0]), float(p[1] + 0.08 * span * face[1]))
            ax.annotate(
                "",
                xy=tip,
                xytext=(p[0], p[1]),
                arrowprops={"arrowstyle": "->", "color": f"C{k + 3}"},
            )
            arrows.append(((float(p[0]), float(p[1])), tip))
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("UE maps, candidate sites and chosen RISs (arrows: facing; labels: site #)")
    legend = ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    sites = chosen_sites(result)
    anchors, texts = _site_labels(result, list(sites))
    place_labels(ax, anchors, texts, marker_pt=9.0, fontsize=7, avoid=arrows)
    # the table of the chosen sites, under the legend, as wide as the room beside the map
    renderer = _renderer(fig)
    box = legend.get_window_extent(renderer).transformed(fig.transFigure.inverted())
    x0 = box.x0
    room_px = (0.99 - x0) * fig.bbox.width
    width = int(room_px / (MONO_ADVANCE_EM * SITE_TABLE_FONTSIZE * fig.dpi / 72.0))
    lines = text_table(SITE_TABLE_HEADERS, site_table_rows(result, sites), width, wrap=1)
    top = box.y0 - 0.03
    line_px = SITE_TABLE_LINE_SPACING * SITE_TABLE_FONTSIZE * fig.dpi / 72.0
    fit = int((top - 0.01) * fig.bbox.height / line_px) - 1  # below the table's title line
    if len(lines) > fit:
        more = len(lines) - fit + 1
        lines = [*lines[: fit - 1], f"… {more} more lines (plan.json candidates)"]
    fig.text(
        x0,
        top,
        "chosen sites\n" + "\n".join(lines),
        family="monospace",
        fontsize=SITE_TABLE_FONTSIZE,
        linespacing=SITE_TABLE_LINE_SPACING,
        va="top",
        ha="left",
        gid="site-table",
    )
    return fig


def write_figures(result: PlanResult, out_dir: Path) -> dict[str, Path]:
    """Write the figures as PNGs; returns name → path (``topview``, ``heatmap``, ``cdf``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {name: out_dir / f"{name}.png" for name in FIGURE_NAMES}
    label = _metric_label(result)

    fig = topview_figure(result)
    fig.savefig(paths["topview"], dpi=FIGURE_DPI)
    plt.close(fig)

    # the served fraction and the bound over the RX map for the best layout of the largest count
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
    fig.savefig(paths["cdf"], dpi=FIGURE_DPI)
    if result.sweep is not None:
        paths[SWEEP_FIGURE] = write_sweep_figure(result, out_dir / f"{SWEEP_FIGURE}.png")
    plt.close(fig)
    if result.beams:
        paths["beams"] = write_beams_figure(result, out_dir / "beams.png")
    if result.sizing is not None:
        paths[SIZING_FIGURE] = write_sizing_figure(result, out_dir / f"{SIZING_FIGURE}.png")
    if result.validation is not None:
        paths["validation"] = write_validation_figure(result.validation, out_dir / "validation.png")
    if result.search_details.get("path") is not None:  # a path over the counts: the district's
        from ris_planner.planning.outputs.district_figure import district_figure

        paths.update(district_figure(result, out_dir))
    return paths


BLIND_COLOUR = "#5b2a86"
"""Heatmap cells where the layout is blind (no finite bound): a colour outside the diverging
scale, named in the legend."""

NONE_SERVED_COLOUR = "#4d4d4d"
"""Served-fraction cells where no TX partner is served: outside the sequential scale (any
partner served shows in colour), named in the legend."""

SERVED_FLOOR = 1e-9
"""Served fractions below this are drawn as :data:`NONE_SERVED_COLOUR`."""

SERVED_COLOURS = (
    "#d73027",
    "#f46d43",
    "#fdae61",
    "#fee08b",
    "#d9ef8b",
    "#a6d96a",
    "#66bd63",
    "#1a9850",
)
"""The served fraction's scale, 0 → red to 1 → green (the bound panel's colours of bad and
good): ``RdYlGn``'s classes without its pale centre, which a white map would swallow."""


def heatmap_level(result: PlanResult, finite: FloatArray) -> float:
    """The bound [m] the heatmap's diverging scale is centred on: the objective's reference
    level (threshold, cap, quantile target: :func:`ris_planner.planning.outputs.diagnosis.
    reference_level`), else the geometric mean of the finite values shown."""
    from ris_planner.planning.outputs.diagnosis import reference_level

    level = reference_level(result.document.objective)
    if np.isfinite(level):
        return float(level)
    return float(np.exp(np.mean(np.log(finite)))) if finite.size else 1.0


def served_title(result: PlanResult) -> str:
    """What the served-fraction panel counts as served: the bound at or below the level, or
    any finite bound (:func:`~ris_planner.planning.outputs.rx_fields.served_level`)."""
    from ris_planner.planning.outputs.rx_fields import served_level

    label = _metric_label(result)
    level = served_level(result.document)
    return f"{label} ≤ {level:.3g} m" if np.isfinite(level) else f"finite {label}"


def _draw_sites(ax: Any, result: PlanResult, lay: Sequence[int], legend: bool) -> None:
    """The candidates (small hollow squares) and the layout's sites (black squares)."""
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
        label="candidate sites" if legend else None,
    )
    chosen = pos[list(lay)]
    ax.scatter(
        chosen[:, 0],
        chosen[:, 1],
        marker="s",
        c="k",
        s=50,
        zorder=5,
        label=f"chosen sites ({len(lay)} RIS)" if legend else None,
    )


SITE_KEY_WIDTH = 190
"""Characters per line of the heatmap's site key (the names of the layout's sites)."""
SITE_KEY_MAX_LINES = 4


def pack_entries(entries: Sequence[str], width: int, max_lines: int) -> list[str]:
    """The entries on lines of at most ``width`` characters (3 spaces between entries, an entry
    never split; one longer than ``width`` alone on its line), at most ``max_lines`` lines – the
    last then says how many entries were left out."""
    lines: list[str] = []
    for k, entry in enumerate(entries):
        if lines and len(lines[-1]) + 3 + len(entry) <= width:
            lines[-1] += "   " + entry
            continue
        if len(lines) == max_lines:
            lines[-1] += f"   … {len(entries) - k} more"
            break
        lines.append(entry)
    return lines


def heatmap_figure(result: PlanResult) -> Any:
    """The best layout of the largest count over the RX map, two panels: left, the fraction of
    each point's TX partners the layout serves
    (:attr:`~ris_planner.planning.outputs.rx_fields.RxField.
    served`; red few to green all, none served in :data:`NONE_SERVED_COLOUR`); right, the bound
    on a diverging scale centred (in log) on the objective's level – green at or below it,
    red above – blind cells in :data:`BLIND_COLOUR`. Colour bars for both, a shared legend of
    the obstacles, the candidates, the layout's sites and the colours, the sites' names
    below it. No UE markers are drawn over the cells (the rasters show every point's value)."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import LinearSegmentedColormap, Normalize, TwoSlopeNorm
    from matplotlib.patches import Patch
    from matplotlib.ticker import FuncFormatter, PercentFormatter

    label = _metric_label(result)
    pts, vals, lay = result.heatmap()
    served = result.rx_field(lay).served
    fig, (sx, ax) = plt.subplots(1, 2, figsize=(15, 6.6), dpi=FIGURE_DPI)
    fig.subplots_adjust(**HEATMAP_MARGINS)  # before the colour bars, which take their room

    # left: the served fraction (the worst point of each cell)
    x_edges, y_edges, frac, empty_s = raster(pts, served, result.scene, worst="min")
    served_cmap = LinearSegmentedColormap.from_list("served", SERVED_COLOURS).with_extremes(
        under=NONE_SERVED_COLOUR
    )
    mesh = sx.pcolormesh(
        x_edges,
        y_edges,
        np.ma.masked_array(frac, mask=empty_s),
        cmap=served_cmap,
        norm=Normalize(vmin=SERVED_FLOOR, vmax=1.0),
        shading="flat",
        zorder=0,
    )
    bar = fig.colorbar(mesh, ax=sx, extend="min", shrink=0.85, pad=0.02)
    bar.set_label("fraction of TX partners served (weighted)")
    bar.ax.yaxis.set_major_formatter(PercentFormatter(1.0))
    sx.set_title(f"Where it works: TX partners served ({served_title(result)})", fontsize=10)

    # right: the bound (the worst point of each cell)
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
    tx_txt = "fixed TX" if result.document.heatmap_tx is not None else "weighted median over TX"
    ax.set_title(f"{label} ({tx_txt})", fontsize=10)

    anchors, texts = _site_labels(result, sorted(int(s) for s in lay))
    for panel, first in ((sx, True), (ax, False)):
        draw_obstacles(panel, result.document.environment)
        _draw_sites(panel, result, lay, legend=first)
        panel.set_aspect("equal")
        panel.set_xlabel("x [m]")
        panel.set_ylabel("y [m]")
    for panel in (sx, ax):
        place_labels(panel, anchors, texts, marker_pt=4.0, fontsize=7)

    handles, _ = sx.get_legend_handles_labels()
    handles.append(Patch(color=NONE_SERVED_COLOUR, label="no TX partner served"))
    handles.append(Patch(color=BLIND_COLOUR, label="blind (no finite bound)"))
    handles.append(Patch(color=cmap(0.2), label=f"{label} ≤ {level:.3g} m"))
    handles.append(Patch(color=cmap(0.8), label=f"{label} > {level:.3g} m"))
    entries = [f"{s}: {result.sites[s].name}" for s in sorted(int(s) for s in lay)]
    key = fig.text(
        0.5,
        0.01,
        "\n".join(pack_entries(["sites –", *entries], SITE_KEY_WIDTH, SITE_KEY_MAX_LINES)),
        ha="center",
        va="bottom",
        fontsize=7,
        gid="site-key",
    )
    top = key.get_window_extent(_renderer(fig)).y1 / fig.bbox.height
    fig.legend(
        handles=handles, fontsize=7, loc="lower center", bbox_to_anchor=(0.5, top + 0.01), ncol=5
    )
    title = f"Best {len(lay)}-RIS layout {list(lay)} over the RX map"
    diagnosis = result.diagnosis
    if diagnosis is not None and diagnosis["verdict"] != "ok":
        title += (
            f"\n{diagnosis['verdict'].upper()}: serves"
            f" {100 * diagnosis['served_fraction']:.1f} % of the pair weight"
        )
    fig.suptitle(title, fontsize=11)
    return fig


def write_heatmap(result: PlanResult, path: Path) -> Path:
    """``heatmap.png``: :func:`heatmap_figure`."""
    import matplotlib.pyplot as plt

    fig = heatmap_figure(result)
    fig.savefig(path, dpi=FIGURE_DPI)
    plt.close(fig)
    return path


def write_sizing_figure(result: PlanResult, path: Path) -> Path:
    """The sizing question: the RIS count each RIS size needs (elements per RIS, log axis,
    ticks rows×cols) – the count found, and down to the certified lower count where the
    method certifies one – and the answer ringed."""
    import matplotlib.pyplot as plt

    assert result.sizing is not None
    sizing = result.sizing
    fig, ax = plt.subplots(figsize=(7, 4.5))
    rows = sizing["sizes"]
    for r in rows:
        x = r["ris_size"][0] * r["ris_size"][1]
        if r["count"] is not None:
            ax.plot([x], [r["count"]], "o", color="C0")
        if r["lower_bound"] is not None:
            top = r["count"] if r["count"] is not None else r["lower_bound"]
            ax.plot([x, x], [r["lower_bound"], top], "-", color="C3", lw=2)
            ax.plot([x], [r["lower_bound"]], "_", color="C3", ms=14)
    ax.plot([], [], "o", color="C0", label="RISs found to reach the goal")
    ax.plot([], [], "-", color="C3", lw=2, label="down to the certified lower count")
    ticks = [tuple(r["ris_size"]) for r in rows]
    ax.set_xscale("log")
    ax.set_xticks([a * b for a, b in ticks])
    ax.set_xticklabels([f"{a}×{b}" for a, b in ticks], fontsize=7, rotation=30)
    ax.minorticks_off()
    answer = sizing["answer"]
    if answer is not None:
        ax.scatter(
            [answer["ris_size"][0] * answer["ris_size"][1]],
            [answer["count"]],
            s=180,
            facecolors="none",
            edgecolors="k",
            linewidths=1.5,
            zorder=5,
            label=f"answer: {answer['count']} × {answer['ris_size'][0]}×{answer['ris_size'][1]}",
        )
    ax.set_xlabel("RIS size (elements per RIS)")
    ax.set_ylabel("RIS count")
    ax.set_title(f"Sizing: {sizing['message']}", fontsize=8, wrap=True)
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


def write_validation_figure(validation: dict[str, Any], path: Path) -> Path:
    """``validation.png`` of plan.json's ``validation``
    (:func:`~ris_planner.planning.outputs.estimator_check.run_estimator_check`):
    :func:`validation_figure`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = validation_figure(validation)
    fig.savefig(path, dpi=FIGURE_DPI)
    plt.close(fig)
    return path


def validation_figure(validation: dict[str, Any]) -> Any:
    """Error vs bound per pair (log–log, the 1× and 1.5× lines) and the CDFs of error and
    bound per layout, each axis naming its quantity (the metric's position error, its bound:
    :data:`ERROR_LABELS`, :data:`METRIC_LABELS`); a figure without one finite value says so."""
    import matplotlib.pyplot as plt

    error = ERROR_LABELS[validation["metric"]]
    bound = METRIC_LABELS[validation["metric"]]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.5))
    finite: list[float] = []
    for k, lay in enumerate(validation["layouts"]):
        colour = f"C{k}"
        label = f"{lay['ris_count']} RIS"
        pts = [(p["bound_m"], p["error_m"]) for p in lay["pairs"] if p["bound_m"] is not None]
        b = np.array([p[0] for p in pts], dtype=float)
        e = np.array([np.inf if p[1] is None else p[1] for p in pts], dtype=float)
        finite += list(b[np.isfinite(b)]) + list(e[np.isfinite(e)])
        ok = np.isfinite(e)
        ax.scatter(b[ok], e[ok], s=14, color=colour, label=label)
        if np.any(~ok):
            ax.scatter(b[~ok], np.full((~ok).sum(), np.nan), color=colour)
        for vals, style, name in ((e, "-", "estimator"), (b, "--", "bound")):
            v = np.sort(vals)
            prob = np.arange(1, v.size + 1) / max(v.size, 1)
            bx.step(
                v[np.isfinite(v)],
                prob[np.isfinite(v)],
                style,
                color=colour,
                where="post",
                label=f"{label} {name}",
            )
    if finite:
        lo, hi = max(min(finite) / 2, 1e-6), max(finite) * 2
        xs = np.array([lo, hi])
        ax.plot(xs, xs, "k-", lw=0.8, label="error = bound")
        ax.plot(xs, 1.5 * xs, "k:", lw=0.8, label="1.5 × bound")
    thr = validation["threshold_m"]
    ax.axvline(thr, color="grey", lw=0.6)
    ax.axhline(thr, color="grey", lw=0.6)
    bx.axvline(thr, color="grey", lw=0.6)
    ax.set(
        xscale="log",
        yscale="log",
        xlabel=f"bound: {bound} [m]",
        ylabel=f"estimator RMSE: {error} [m]",
        title=f"{error} vs its bound ({bound}) per pair",
    )
    bx.set(
        xscale="log",
        xlabel=f"{error} (solid) / {bound} (dashed) [m]",
        ylabel="fraction of sampled pairs",
        title=f"CDF of the {error} and of {bound}",
    )
    if not finite:
        for panel in (ax, bx):
            panel.text(
                0.5,
                0.5,
                "no sampled pair has a finite error or bound",
                transform=panel.transAxes,
                ha="center",
                va="center",
                fontsize=9,
                color="0.3",
            )
    ax.legend(fontsize=7)
    bx.legend(fontsize=7)
    fig.tight_layout()
    return fig
