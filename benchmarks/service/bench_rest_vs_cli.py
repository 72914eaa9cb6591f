"""Benchmark: the same plan over REST and on the command line, in the same run (service
jobs use the cores; docs/guides/service-operations.md "Plan jobs use the cores").

* ``cli`` – ``ris-planner plan --preset NAME`` in a fresh process (its local pool, one worker
  per core), wall time of the process;
* ``rest`` – ``POST /v1/plans`` of the same document to a real server (``ris-planner serve``
  on 127.0.0.1, one job worker, stopped by its PID), wall time from the POST to the job's
  ``succeeded`` (polled every 50 ms); the job runs on the same local pool;
* ``rest-serial`` – the same with ``RIS_PLANNER_PLAN_WORKERS=1``: the job computes in its one
  process, as every plan job did before (the reference).

The runs alternate (cli, rest, rest-serial, …) so that a change in the machine's load hits
each alike; printed per run and as medians with the ratios rest / cli and rest-serial / rest.
Kernels should be compiled first (``ris-planner warmup``). Absolute seconds need a quiet
machine; the ratios are the figures to compare.

    python benchmarks/service/bench_rest_vs_cli.py                 # the hall, 1 round
    python benchmarks/service/bench_rest_vs_cli.py --repeats 3 --json out.json
    python benchmarks/service/bench_rest_vs_cli.py --preset fig10-anchors
    python benchmarks/service/bench_rest_vs_cli.py --file block.json   # a plan document
    python benchmarks/service/bench_rest_vs_cli.py --quick   # the fixtures' smoke plan, 1 round
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

from api.launch import served
from ris_planner.planning import plan_preset

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import ROOT, smoke_document


def cli_plan(source: list[str], out: Path) -> float:
    """Wall seconds of ``ris-planner plan SOURCE`` (``--preset NAME`` or a file) in a fresh
    process."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    cmd = [sys.executable, "-m", "ris_planner.cli", "plan", *source, "--out", str(out)]
    t0 = time.perf_counter()
    run = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=path))
    wall = time.perf_counter() - t0
    if run.returncode != 0:
        raise RuntimeError(f"the command line failed: {run.stderr[-2000:]}")
    return wall


def rest_plan(url: str, document: dict[str, Any], timeout_s: float = 1800) -> tuple[float, dict]:
    """Wall seconds from ``POST /v1/plans`` to the job's success, and its result."""
    with httpx.Client(base_url=url, timeout=60) as client:
        t0 = time.perf_counter()
        job = client.post("/v1/plans", json=document)
        job.raise_for_status()
        job_id = job.json()["id"]
        while True:
            view = client.get(f"/v1/jobs/{job_id}").json()
            if view["status"] in ("succeeded", "failed", "cancelled"):
                break
            if time.perf_counter() - t0 > timeout_s:
                raise RuntimeError(f"job {job_id} not done after {timeout_s} s")
            time.sleep(0.05)
        wall = time.perf_counter() - t0
    if view["status"] != "succeeded":
        raise RuntimeError(f"job {job_id} {view['status']}: {view.get('error')}")
    return wall, view["result"]


def measure(preset: str, repeats: int, file: Path | None = None) -> dict[str, Any]:
    """The three routes, alternating, ``repeats`` rounds; the figures (of the plan document
    ``file`` when given, else of the preset)."""
    document = plan_preset(preset) if file is None else json.loads(file.read_text())
    source = ["--preset", preset] if file is None else [str(file)]
    times: dict[str, list[float]] = {"cli": [], "rest": [], "rest-serial": []}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        with (
            served(root / "pool.db", env={"RIS_PLANNER_PLAN_WORKERS": "0"}) as pool_server,
            served(root / "serial.db", env={"RIS_PLANNER_PLAN_WORKERS": "1"}) as serial_server,
        ):
            # one untimed job per server first: the forkserver starts with the server and
            # preloads the engine, matplotlib and numba (api/preload.py), ≈ 2 s of CPU that
            # would otherwise land on the first timed round of every route
            for server in (pool_server, serial_server):
                rest_plan(server.url, document)
            for r in range(repeats):
                times["cli"].append(cli_plan(source, root / f"cli-{r}"))
                times["rest"].append(rest_plan(pool_server.url, document)[0])
                times["rest-serial"].append(rest_plan(serial_server.url, document)[0])
                print(
                    f"round {r + 1}: cli {times['cli'][-1]:.2f} s, rest {times['rest'][-1]:.2f} s,"
                    f" rest-serial {times['rest-serial'][-1]:.2f} s",
                    flush=True,
                )
    med = {k: statistics.median(v) for k, v in times.items()}
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {
        "plan": preset if file is None else str(file),
        "cores": os.cpu_count(),
        "seconds": {k: [round(x, 3) for x in v] for k, v in times.items()},
        "median_s": {k: round(v, 3) for k, v in med.items()},
        "rest_over_cli": round(med["rest"] / med["cli"], 3),
        "serial_over_rest": round(med["rest-serial"] / med["rest"], 3),
        "load_average_1min": round(load, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="hall", help="the plan preset (default: hall)")
    parser.add_argument("--file", type=Path, help="a plan document instead of the preset")
    parser.add_argument("--repeats", type=int, default=1, help="rounds of the three routes")
    parser.add_argument("--json", type=Path, help="write the figures here")
    parser.add_argument("--quick", action="store_true", help="a seconds-long plan, one round")
    args = parser.parse_args()
    if args.quick:
        args.file = Path(tempfile.mkdtemp(prefix="bench-rest-vs-cli-")) / "smoke.json"
        args.file.write_text(json.dumps(smoke_document()))
        args.repeats = 1
    res = measure(args.preset, args.repeats, args.file)
    med = res["median_s"]
    print(
        f"{res['plan']}: cli {med['cli']:.2f} s, rest {med['rest']:.2f} s (rest / cli"
        f" {res['rest_over_cli']}), rest with a serial job {med['rest-serial']:.2f} s"
        f" ({res['serial_over_rest']}× the pooled job); load average {res['load_average_1min']}"
    )
    if args.json:
        args.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
