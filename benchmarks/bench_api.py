"""Benchmark: 50 concurrent ``POST /v1/bounds`` (Table I scenario) against a real uvicorn
server on 127.0.0.1, started with ``ris-planner serve`` on a free port and a temporary database.

Each round sends ``--concurrency`` requests at once (one asyncio task each, one connection
each) and waits for all; every answer must be 200 and equal, number for number, to the
in-process ``compute_bounds(...).to_json()`` (what ``ris-planner bounds`` prints). Printed per
round: requests/s (requests / wall time of the round), p50/p95/max latency. The reference
measured in the same run is the in-process engine time of one request (validation + bounds +
JSON), i.e. the cost without HTTP, threads or serialisation.

    python benchmarks/bench_api.py [--concurrency 50] [--rounds 5]
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
from threadpoolctl import threadpool_limits

from api.launch import served
from ris_planner import compute_bounds, load_scenario, preset_document

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from tolerance import BOUND_ACCURACY, assert_close


async def one_round(url: str, doc: dict[str, Any], n: int) -> tuple[float, list[float], list]:  # type: ignore[type-arg]
    limits = httpx.Limits(max_connections=n, max_keepalive_connections=n)
    async with httpx.AsyncClient(base_url=url, limits=limits, timeout=60.0) as client:

        async def request() -> tuple[float, httpx.Response]:
            t0 = time.perf_counter()
            r = await client.post("/v1/bounds", json=doc)
            return time.perf_counter() - t0, r

        t0 = time.perf_counter()
        results = await asyncio.gather(*(request() for _ in range(n)))
        wall = time.perf_counter() - t0
    return wall, [lat for lat, _ in results], [r for _, r in results]


def percentile(values: list[float], q: float) -> float:
    """Nearest-rank percentile (q in 0–100)."""
    ordered = sorted(values)
    k = max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))
    return ordered[k]


def engine_time(doc: dict[str, Any], expected: dict[str, Any], repeats: int = 50) -> float:
    """Median in-process time of one request's work (validation, bounds, JSON)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        got = compute_bounds(load_scenario(doc)).to_json(batch=False)
        times.append(time.perf_counter() - t0)
        assert got == expected  # the same process and route: the same bits
    return statistics.median(times)


def serve_rounds(doc: dict[str, Any], expected: dict[str, Any], n: int, rounds: int, blas: int):  # type: ignore[no-untyped-def]
    """Start a server with RIS_PLANNER_BLAS_THREADS=blas; median req/s and p95 over rounds."""
    env = {"RIS_PLANNER_BLAS_THREADS": str(blas)}
    with tempfile.TemporaryDirectory() as tmp, served(Path(tmp) / "jobs.db", env=env) as server:
        print(f"server {server.url} (ris-planner serve, 1 uvicorn process, BLAS threads {blas})")
        asyncio.run(one_round(server.url, doc, 5))  # warm-up: imports, thread pool
        rates, p95s = [], []
        for i in range(rounds):
            wall, lat, responses = asyncio.run(one_round(server.url, doc, n))
            bad = [r.status_code for r in responses if r.status_code != 200]
            assert not bad, f"non-200 answers: {bad}"
            for r in responses:  # another process: the bounds' accuracy rule (tests/tolerance.py)
                body = {k: v for k, v in r.json().items() if k != "provenance"}  # the server's own
                assert_close(body, expected, accuracy=BOUND_ACCURACY, where="answer")
            rates.append(n / wall)
            p95s.append(percentile(lat, 95))
            print(
                f"  round {i + 1}: {n} concurrent, all 200 and equal to the CLI;"
                f" {n / wall:6.1f} req/s, latency p50 {percentile(lat, 50) * 1e3:6.1f} ms,"
                f" p95 {percentile(lat, 95) * 1e3:6.1f} ms, max {max(lat) * 1e3:6.1f} ms"
            )
    return statistics.median(rates), statistics.median(p95s)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--concurrency", type=int, default=50)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()

    doc = preset_document("paper-table1")
    expected = compute_bounds(load_scenario(doc)).to_json(batch=False)
    cores = os.cpu_count() or 1
    with threadpool_limits(limits=1):
        engine = engine_time(doc, expected)
    print(
        f"in-process reference, 1 BLAS thread (validate + compute_bounds + to_json):"
        f" {engine * 1e3:.2f} ms per request = {1 / engine:.0f} requests/s on one core"
    )
    print(f"in-process, default BLAS threads: {engine_time(doc, expected) * 1e3:.2f} ms")
    rate, p95 = serve_rounds(doc, expected, args.concurrency, args.rounds, blas=1)
    rate_n, p95_n = serve_rounds(doc, expected, args.concurrency, args.rounds, blas=cores)
    print(
        f"median over {args.rounds} rounds of {args.concurrency} concurrent requests:"
        f" {rate:.1f} requests/s, p95 latency {p95 * 1e3:.1f} ms (BLAS threads 1, the default);"
        f" {rate_n:.1f} requests/s, p95 {p95_n * 1e3:.1f} ms with {cores} BLAS threads"
        f" (x{rate / rate_n:.2f}); HTTP rate / in-process 1-core rate = {rate * engine:.2f}"
        f" on {cores} cores"
    )


if __name__ == "__main__":
    main()
