"""A long randomized schemathesis run against a real server (uvicorn on 127.0.0.1, a temporary
database): every operation of the OpenAPI document, ≥ 300 examples each, all checks, the
stateful phase following the documented links (POST a job → GET / DELETE it). Not
derandomized: each run explores new inputs (the seed is printed, to replay a failure).

    .venv/bin/python benchmarks/service/fuzz_api.py [--max-examples 300] [--seed N] [--quick]

``--quick``: 10 examples per operation.

Engine limits are set low (as in tests/test_api_schemathesis.py) so that the random valid
documents stay cheap; large ones must answer 413, never 5xx. Exit status: schemathesis's.
"""

from __future__ import annotations

import argparse
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from api.launch import served

LOW_LIMITS = {
    "RIS_PLANNER_MAX_PAIRS": "50",
    "RIS_PLANNER_MAX_ARRAY_ELEMENTS": "200000",
    "RIS_PLANNER_MAX_WORK": "2000000",
    "RIS_PLANNER_MAX_BODY_BYTES": "200000",
    "RIS_PLANNER_JOB_MEMORY_MB": "2048",
    "RIS_PLANNER_API_KEY": "fuzz-key",  # the authentication checks need a key to enforce
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--max-examples", type=int, default=300)
    parser.add_argument("--seed", type=int, default=None, help="default: a fresh random seed")
    parser.add_argument("--workers", type=int, default=1, help="schemathesis workers")
    parser.add_argument("--quick", action="store_true", help="10 examples per operation")
    args = parser.parse_args()
    if args.quick:
        args.max_examples = 10
    seed = random.SystemRandom().randrange(2**31) if args.seed is None else args.seed
    st = Path(sys.executable).with_name("st")
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "jobs.db"
        with served(db, workers=1, env=LOW_LIMITS, log=Path(tmp) / "server.log") as server:
            cmd = [
                str(st),
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
                "-H",
                f"X-API-Key: {LOW_LIMITS['RIS_PLANNER_API_KEY']}",
            ]
            print(f"seed {seed}: {' '.join(cmd)}", flush=True)
            t0 = time.perf_counter()
            code = subprocess.run(cmd, check=False).returncode
            print(f"schemathesis exit {code} after {time.perf_counter() - t0:.0f} s", flush=True)
            alive = server.process.poll() is None
            print(f"server still running after the run: {alive}", flush=True)
        log = (Path(tmp) / "server.log").read_text(errors="replace")
        print(f"server log: {log.count('Traceback')} tracebacks", flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
