"""A long randomized schemathesis run against a real server (uvicorn on 127.0.0.1, a temporary
database): every operation of the OpenAPI document, ≥ 300 examples each, every check, the
stateful phase following the documented links (POST a job → GET / DELETE it). Not
derandomized: each run explores new inputs (the seed is printed, to replay a failure).

    .venv/bin/python benchmarks/service/fuzz_api.py [--max-examples 300] [--seed N]
        [--json FILE] [--quick]

``--quick``: 10 examples per operation.

Engine limits are set low (as in tests/test_api_schemathesis.py) so that the random valid
documents stay cheap; large ones must answer 413, never 5xx. At the end it prints the run's
figures – the date, the command, operations, test cases, failures by check (server errors
and response-schema mismatches apart) – from schemathesis's JSON report, and the server log's
tracebacks; ``--json`` writes them to a file. Exit status: schemathesis's.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from api.launch import served

LOW_LIMITS = {
    "RIS_PLANNER_MAX_PAIRS": "50",
    "RIS_PLANNER_MAX_ARRAY_ELEMENTS": "200000",
    "RIS_PLANNER_MAX_WORK": "2000000",
    "RIS_PLANNER_MAX_BODY_BYTES": "200000",
    "RIS_PLANNER_JOB_MEMORY_MB": "2048",
    "RIS_PLANNER_API_KEY": "fuzz-key",  # the authentication checks need a key to enforce
}

HOOKS = """import schemathesis

for dxf in ("application/dxf", "image/vnd.dxf", "image/x-dxf"):
    schemathesis.serializer.alias(dxf, "application/octet-stream")
for xml in ("application/xml", "text/xml", "application/osm+xml"):
    schemathesis.serializer.alias(xml, "text/plain")
"""
"""Schemathesis hooks: the import's bodies are the files themselves – DXF as bytes, OSM XML as
its text (schemathesis would otherwise wrap a string in an XML element of its own)."""

CONFIG = """[checks.negative_data_rejection]
expected-statuses = ["400", "401", "403", "404", "405", "406", "409", "413", "415", "422",
                     "428", "429"]
"""
"""Schemathesis configuration: a 413 is the service's refusal of a size above its limit
(tests/test_api_schemathesis.py counts it as a rejection too)."""

SERVER_ERRORS = ("ST101", "ST102")
"""Schemathesis's codes of a 5xx answer (server error) and of a request that timed out."""
SCHEMA_MISMATCHES = ("ST301", "ST302", "ST303", "ST304", "ST305")
"""Its codes of an answer that does not match the OpenAPI document: status code, content type,
headers, body schema, …"""


def summarize(report: dict[str, Any]) -> dict[str, Any]:
    """The figures of schemathesis's JSON report: operations, test cases, failures by code."""
    failures = {f"{f['code']} {f['title']}": f["count"] for f in report.get("failures", [])}
    by_code = {f["code"]: f["count"] for f in report.get("failures", [])}
    return {
        "operations": report.get("operations", {}).get("tested"),
        "cases": report.get("test_cases", {}).get("generated"),
        "failures": failures,
        "failing_operations": {
            f["code"]: f.get("operations", []) for f in report.get("failures", [])
        },
        "server_errors": sum(by_code.get(c, 0) for c in SERVER_ERRORS),
        "schema_mismatches": sum(by_code.get(c, 0) for c in SCHEMA_MISMATCHES),
        "errors": len(report.get("errors", [])),
        "warnings": {k: v for k, v in report.get("warnings", {}).items() if v},
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--max-examples", type=int, default=300)
    parser.add_argument("--seed", type=int, default=None, help="default: a fresh random seed")
    parser.add_argument("--workers", type=int, default=1, help="schemathesis workers")
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    parser.add_argument("--quick", action="store_true", help="10 examples per operation")
    args = parser.parse_args()
    if args.quick:
        args.max_examples = 10
    seed = random.SystemRandom().randrange(2**31) if args.seed is None else args.seed
    st = Path(sys.executable).with_name("st")
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "jobs.db"
        (Path(tmp) / "fuzz_hooks.py").write_text(HOOKS)
        (Path(tmp) / "schemathesis.toml").write_text(CONFIG)
        report_path = Path(tmp) / "report.json"
        env = dict(os.environ) | {"SCHEMATHESIS_HOOKS": "fuzz_hooks", "PYTHONPATH": tmp}
        with served(db, workers=1, env=LOW_LIMITS, log=Path(tmp) / "server.log") as server:
            cmd = [
                str(st),
                "--config-file",
                str(Path(tmp) / "schemathesis.toml"),
                "run",
                f"{server.url}/openapi.json",
                "--checks",
                "all",
                "--max-examples",
                str(args.max_examples),
                "--phases",
                "examples,coverage,fuzzing,stateful",
                "--seed",
                str(seed),
                "--workers",
                str(args.workers),
                "--request-timeout",
                "60",
                "--no-color",
                "--report",
                "json",
                "--report-json-path",
                str(report_path),
                "-H",
                f"X-API-Key: {LOW_LIMITS['RIS_PLANNER_API_KEY']}",
            ]
            shown = " ".join(["st", *cmd[1:]]).replace(server.url, "http://127.0.0.1:PORT")
            shown = shown.replace(tmp, "TMP")
            print(f"seed {seed}: {shown}", flush=True)
            started = datetime.now(UTC)
            t0 = time.perf_counter()
            # in the temporary folder: schemathesis keeps a cache of the failures it found in
            # its working folder (.schemathesis/) and replays them in a later run
            code = subprocess.run(cmd, check=False, env=env, cwd=tmp).returncode
            took = time.perf_counter() - t0
            print(f"schemathesis exit {code} after {took:.0f} s", flush=True)
            alive = server.process.poll() is None
            print(f"server still running after the run: {alive}", flush=True)
        log = (Path(tmp) / "server.log").read_text(errors="replace")
        report = json.loads(report_path.read_text()) if report_path.exists() else {}
    out = {
        "date": started.date().isoformat(),
        "command": f"python benchmarks/service/fuzz_api.py --max-examples {args.max_examples}"
        f" --seed {seed}",
        "schemathesis": shown,
        "exit": code,
        "seconds": round(took),
        "server_alive": alive,
        "tracebacks": log.count("Traceback"),
        **summarize(report),
    }
    print(json.dumps(out, indent=2), flush=True)
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=2) + "\n")
    return code


if __name__ == "__main__":
    sys.exit(main())
