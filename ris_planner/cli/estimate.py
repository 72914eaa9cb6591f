"""``ris-planner simulate`` and ``ris-planner blind-area``."""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from ris_planner.cli.app import (
    add_document_arguments,
    finite_float,
    int_in,
    positive_finite_float,
    print_json,
    read_document,
)
from ris_planner.core.errors import RisPlannerError
from ris_planner.runtime.progress import ProgressBar
from ris_planner.runtime.provenance import provenance


def _floats(text: str, what: str, count: int | None = None) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip() != ""]
    except ValueError:
        raise RisPlannerError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if not vals or (count is not None and len(vals) != count):
        n = "" if count is None else f" {count}"
        raise RisPlannerError(f"{what}: expected{n} comma-separated numbers, got {text!r}")
    if not all(np.isfinite(vals)):
        raise RisPlannerError(f"{what}: numbers must be finite, got {text!r}")
    return vals


def _simulation_document(args: argparse.Namespace) -> dict[str, object]:
    doc = read_document(args)
    sim: dict[str, object] = dict(doc) if "scenario" in doc else {"scenario": doc}
    for key, part in (
        ("scenario", sim["scenario"]),
        ("estimator", sim.get("estimator", {})),
        ("multipath", sim.get("multipath", {})),
    ):
        if not isinstance(part, dict):
            raise RisPlannerError(f"{key}: must be a JSON object")
    scenario = dict(sim["scenario"])  # type: ignore[call-overload]
    if not isinstance(scenario.get("system", {}), dict):
        raise RisPlannerError("scenario.system: must be a JSON object")
    if args.noise_figure_db is not None:
        scenario["system"] = dict(scenario.get("system", {})) | {
            "noise_figure_db": args.noise_figure_db
        }
    sim["scenario"] = scenario
    if args.sigma is not None:
        sim["estimator"] = dict(sim.get("estimator", {})) | {"sigma": args.sigma}  # type: ignore[call-overload]
    return sim


def _cmd_simulate(args: argparse.Namespace) -> int:
    from ris_planner.estimation.document import load_simulation
    from ris_planner.estimation.montecarlo import run_monte_carlo

    doc = load_simulation(_simulation_document(args))
    powers = _floats(args.powers_dbm, "--powers-dbm")
    result = run_monte_carlo(doc, powers, args.runs, args.seed, ProgressBar("simulate"))
    out = result.to_json() | {"provenance": provenance(doc)}
    if args.out is not None:
        out["files"] = write_outputs(result, Path(args.out))
    print_json(out)
    return 0


def write_outputs(result: object, out_dir: Path) -> list[str]:
    """Per-run errors (CSV), the RMSE-vs-power figure and the RX-error CDF (PNG)."""
    from ris_planner.estimation.montecarlo import MonteCarloResult
    from ris_planner.estimation.plots import (
        plot_channel_rmse,
        plot_error_cdf,
        plot_rmse_vs_power,
    )

    assert isinstance(result, MonteCarloResult)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / "errors.csv"
    with csv_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            ["power_dbm", "run", "stage", "tx_x", "tx_y", "tx_z", "rx_x", "rx_y", "rx_z", "clock"]
        )
        for p in result.powers:
            for stage, arr in (("refined", p.refined), ("coarse", p.coarse)):
                for run, row in enumerate(arr):
                    w.writerow([p.power_dbm, run, stage, *[f"{v:.6g}" for v in row]])
    rmse_png = out_dir / "rmse_vs_power.png"
    plot_rmse_vs_power(result, rmse_png)
    chan_png = out_dir / "channel_rmse_vs_power.png"
    plot_channel_rmse(result, chan_png)
    cdf_png = out_dir / "rx_error_cdf.png"
    plot_error_cdf(
        {f"{p.power_dbm:g} dBm": p.rx_errors() for p in result.powers},
        {f"PEB_R {p.power_dbm:g} dBm": p.peb_rx for p in result.powers},
        cdf_png,
    )
    return [str(csv_path), str(rmse_png), str(chan_png), str(cdf_png)]


def _cmd_blind_area(args: argparse.Namespace) -> int:
    from ris_planner.estimation.blind_area import cost_map
    from ris_planner.estimation.plots import plot_cost_map
    from ris_planner.model.scenario import load_scenario

    scenario = load_scenario(read_document(args))
    if scenario.is_batch and len(scenario.tx_array) > 1:
        raise RisPlannerError("blind-area takes a scenario with one TX–RX pair")
    rx = None if args.rx is None else _floats(args.rx, "--rx", 3)
    tx = None if args.tx is None else _floats(args.tx, "--tx", 3)
    extent = None
    if args.extent is not None:
        e = _floats(args.extent, "--extent", 4)
        extent = (e[0], e[1], e[2], e[3])
    cmap = cost_map(
        scenario,
        rx=rx,
        tx=tx,
        extent=extent,
        step_m=args.step,
        n_minima=args.minima,
    )
    out = cmap.to_json() | {"provenance": provenance(scenario)}
    if args.out is not None:
        path = Path(args.out)
        path.parent.mkdir(parents=True, exist_ok=True)
        plot_cost_map(cmap, path)
        out["file"] = str(path)
    print_json(out)
    return 0


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be ≥ 1, got {v}")
    return v


def add_cli(sub: argparse._SubParsersAction) -> None:
    """Register ``simulate`` and ``blind-area``."""
    p = sub.add_parser(
        "simulate",
        help="Monte-Carlo RMSE of the two-stage estimator (Alg. 1 + 2) against PEB/CEB",
        description="FILE is a scenario document or a simulation document"
        ' {"scenario": ..., "multipath": ..., "estimator": ...}.',
    )
    add_document_arguments(p)
    p.add_argument("--runs", type=_positive_int, default=100, help="realisations per power")
    p.add_argument("--powers-dbm", default="20,30", help="comma-separated transmit powers")
    p.add_argument(
        "--seed", type=int_in(0, 2**63 - 1), default=0, help="seed of phases, SPs and noise"
    )
    p.add_argument("--out", help="directory for errors.csv and PNG figures")
    p.add_argument("--noise-figure-db", type=finite_float, help="override system.noise_figure_db")
    p.add_argument("--sigma", choices=["identity", "crb"], help="Σ of the position MLE")
    p.set_defaults(func=_cmd_simulate)
    p = sub.add_parser(
        "blind-area",
        help="noise-free coarse cost map over TX candidates and its local minima",
    )
    add_document_arguments(p)
    p.add_argument("--rx", help="true RX X,Y,Z (default: the document's rx)")
    p.add_argument("--tx", help="true TX X,Y,Z (default: the document's tx)")
    p.add_argument("--extent", help="XMIN,XMAX,YMIN,YMAX of the map [m]")
    p.add_argument("--step", type=positive_finite_float, default=0.05, help="grid step [m]")
    p.add_argument("--minima", type=_positive_int, default=5, help="local minima to list")
    p.add_argument("--out", help="PNG file of the map")
    p.set_defaults(func=_cmd_blind_area)
