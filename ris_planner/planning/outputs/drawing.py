"""Drawing a site on a matplotlib axis: the environment's obstacles, as every plan figure
draws them (the top view, the heatmap, the district figure)."""

from __future__ import annotations

from typing import Any

from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.model import Environment


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
