"""The RIS-count figure of a district plan (docs/concepts/district.md): the objective against
the RIS count – the greedy path, each listed count's layout and its certified upper bound, so
the gap is visible at every count, the servable and coverable pairs, and the sizing goal – and
a top view of the buildings, the candidates, the pairs' UEs and the largest count's layout."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ris_planner.model.objectives import objective_kind
from ris_planner.planning.outputs.drawing import draw_obstacles
from ris_planner.planning.outputs.result import PlanResult
from ris_planner.planning.scoring.scorer import objective_from_loss

FIGURE_DPI = 120
"""Resolution of district.png."""


def _level_axis(result: PlanResult) -> str:
    """The y label: the objective kind's label and its screen level (the coverage threshold a
    district plan searches at), as a fraction of every pair."""
    spec = result.document.objective
    kind = objective_kind(spec.kind)
    level = kind.screen_level(spec)
    return kind.label + (f" (PEB ≤ {level:g} m)" if level is not None else "") + ", of all pairs"


def district_figure(result: PlanResult, out_dir: Path) -> dict[str, Path]:
    """Write ``district.png`` into ``out_dir``; returns ``{"district": path}``. The sizing
    goal's line is plan.json's ``sizing.goal`` (the one value the answer is judged against)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "district.png"
    obj = result.document.objective
    fig, (ax, top) = plt.subplots(1, 2, figsize=(12, 5))
    steps = result.search_details.get("path") or []
    ax.plot(
        [s["ris_count"] for s in steps],
        [s["coverage"] for s in steps],
        "-",
        color="0.6",
        label="greedy path",
    )
    counts = [cr.ris_count for cr in result.counts]
    found = [objective_from_loss(obj, cr.ranked[0][1]) for cr in result.counts]
    bound = [
        np.nan if cr.certificate is None else objective_from_loss(obj, cr.certificate.loss_bound)
        for cr in result.counts
    ]
    ax.plot(counts, found, "o", color="C0", label="layout found")
    ax.plot(counts, bound, "v", color="C3", label="certified upper bound")
    summary = result.pairs_summary
    if summary is not None:
        ax.axhline(summary.servable_weight, color="C2", ls="-", lw=0.8, label=_share(summary))
        if summary.coverable_weight is not None:
            cov = summary.coverable_weight
            ax.axhline(cov, color="C2", ls="--", label=f"coverable at this RIS size ({cov:.2f})")
    sizing: dict[str, Any] | None = result.sizing
    if sizing is not None and sizing.get("goal", {}).get("min") is not None:
        goal = sizing["goal"]["min"]
        ax.axhline(goal, color="C1", ls=":", label=f"sizing goal ({goal:.3f})")
    ax.set_xlabel("RIS count")
    ax.set_ylabel(_level_axis(result))
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    draw_obstacles(top, result.document.environment)
    sites = np.array([s.ris.position for s in result.sites])
    pairs = result.pairs
    top.plot(pairs.tx[:, 0], pairs.tx[:, 1], ".", ms=1, color="0.75", label="UEs of pairs")
    top.plot(sites[:, 0], sites[:, 1], "s", ms=2, color="0.4", label="candidates")
    if result.counts:
        last = result.counts[-1]
        chosen = sites[list(last.ranked[0][0])]
        top.plot(chosen[:, 0], chosen[:, 1], "^", ms=7, color="C3", label=f"{last.ris_count} RISs")
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=FIGURE_DPI)
    plt.close(fig)
    return {"district": path}


def _share(summary: Any) -> str:
    return f"servable pairs ({summary.servable_weight:.2f}: the 100 % of every share)"
