"""The figure of a district plan (docs/concepts/district.md): coverage against the RIS count –
the greedy path, each listed count's layout after swaps and the certified upper bound, so the
gap is visible at every count – and a top view of the candidates, the pairs and the largest
count's layout."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ris_planner.model.objectives import objective_kind
from ris_planner.model.plan import Objective
from ris_planner.planning.inputs.plan_inputs import PlanInputs

FIGURE_DPI = 120
"""Resolution of district.png."""


def _level_axis(objective: dict[str, Any]) -> str:
    """The y label: the objective kind's label and its screen level (the coverage threshold a
    district plan searches at)."""
    spec = Objective.model_validate(objective)
    kind = objective_kind(spec.kind)
    level = kind.screen_level(spec)
    return kind.label + (f" (PEB ≤ {level:g} m)" if level is not None else "")


def district_figure(plan: dict[str, Any], out_dir: Path, inputs: PlanInputs) -> dict[str, Path]:
    """Write ``district.png`` into ``out_dir``; returns ``{"district": path}``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "district.png"
    fig, (ax, top) = plt.subplots(1, 2, figsize=(12, 5))
    steps = plan["path"]
    ax.plot(
        [s["ris_count"] for s in steps],
        [s["coverage"] for s in steps],
        "-",
        color="0.6",
        label="greedy path",
    )
    rows = plan["by_count"]
    counts = [r["ris_count"] for r in rows]
    ax.plot(counts, [r["objective"] for r in rows], "o", color="C0", label="layout (after swaps)")
    ax.plot(counts, [r["upper_bound"] for r in rows], "v", color="C3", label="certified bound")
    coverable = plan["pairs_summary"]["coverable_weight"]
    ax.axhline(coverable, color="C2", ls="--", label=f"coverable pairs ({coverable:.2f})")
    if "sizing" in plan:
        ax.axhline(plan["sizing"]["target"] * coverable, color="C1", ls=":", label="sizing target")
    ax.set_xlabel("RIS count")
    ax.set_ylabel(_level_axis(plan["objective"]))
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    sites = np.array([s.ris.position for s in inputs.sites])
    pairs = inputs.pairs
    top.plot(pairs.tx[:, 0], pairs.tx[:, 1], ".", ms=1, color="0.75", label="UEs of pairs")
    top.plot(sites[:, 0], sites[:, 1], "s", ms=2, color="0.4", label="candidates")
    if rows:
        chosen = sites[rows[-1]["site_indices"]]
        top.plot(
            chosen[:, 0],
            chosen[:, 1],
            "^",
            ms=7,
            color="C3",
            label=f"{rows[-1]['ris_count']} RISs",
        )
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=FIGURE_DPI)
    plt.close(fig)
    return {"district": path}
