"""Shipped plan documents (``ris_planner/model/presets/plans/NAME.json``) and reading plan files."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Any

from ris_planner.core.errors import RisPlannerError
from ris_planner.core.io_json import read_json_object
from ris_planner.model.scenario import with_defaults

PLAN_PRESET_NAMES = ("fig10-anchors", "junction", "hall")
"""``fig10-anchors``: the four Fig. 10 anchor sites over the Fig. 10 pairs, 2–4 RISs;
``junction``: a road junction with UEs on the roads, its four corner buildings as prisms and
their road-facing walls as candidates; ``hall``: a factory hall (walls, a machine row, two
aisles of forklifts) with candidates on its four walls facing inwards."""


def plan_preset(name: str) -> dict[str, Any]:
    """The JSON document of a shipped plan, its ``system`` written out from Table I
    (:func:`ris_planner.model.scenario.with_defaults`)."""
    if name not in PLAN_PRESET_NAMES:
        raise RisPlannerError(
            f"unknown plan preset {name!r}; choose one of {', '.join(PLAN_PRESET_NAMES)}"
        )
    text = resources.files("ris_planner.model.presets").joinpath(f"plans/{name}.json").read_text()
    doc: dict[str, Any] = json.loads(text)
    return {**doc, "system": with_defaults(doc)["system"]}


def inline_csv(doc: dict[str, Any], base_dir: Path) -> dict[str, Any]:
    """Replace ``"csv": "file.csv"`` in ``tx_map``/``rx_map`` (paths relative to base_dir) by
    the file's text as ``csv_text`` – the document model itself never reads files."""
    out = dict(doc)
    for key in ("tx_map", "rx_map"):
        m = out.get(key)
        if isinstance(m, dict) and "csv" in m:
            m = dict(m)
            path = base_dir / str(m.pop("csv"))
            try:
                m["csv_text"] = path.read_text()
            except OSError as exc:
                raise RisPlannerError(f"{key}.csv: cannot read {path} ({exc.strerror})") from None
            out[key] = m
    return out


def load_plan_file(path: str | Path) -> dict[str, Any]:
    """A plan document from a JSON file (``-`` = stdin), CSV maps inlined (relative to the
    file, or to the working directory for stdin)."""
    doc = read_json_object(path)
    return inline_csv(doc, Path.cwd() if str(path) == "-" else Path(path).parent)
