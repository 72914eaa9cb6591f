"""Benchmark: ``/healthz`` latency while the service is loaded (docs/guides/service-operations.md
"Liveness under load"), against a real uvicorn server on 127.0.0.1 (``ris-planner serve``, a
temporary database, stopped by its PID).

Each load runs while a prober asks ``GET /healthz`` every 50 ms on its own connection; printed
per load: the probes' p50, p99 and max latency and the load's answers by status.

* ``plans`` – N concurrent ``POST /v1/plans`` (a small plan document each);
* ``prisms`` – one ``POST /v1/plans`` with P prisms (above the obstacle limit: refused before
  validation) and one with P/2 (validated);
* ``import`` – a GeoJSON import of V building vertices (``POST /v1/import``);
* ``events`` – S job event streams open (``GET /v1/jobs/{id}/events``) for a few seconds;
* ``idle`` – no load at all, first: the probes' own latency in the same run (the reference).

    python benchmarks/service/bench_service_liveness.py            # 300 plans, 100 001 prisms, 400k
                                                           #   vertices, 100 streams
    python benchmarks/service/bench_service_liveness.py --smoke    # 30 plans, 20k prisms, 40k, 20
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx

from api.launch import served

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from test_api_plans import small_plan_doc

PROBE_S = 0.05


def percentile(values: list[float], q: float) -> float:
    """Nearest-rank percentile (q in 0–100)."""
    ordered = sorted(values)
    k = max(0, min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1))
    return ordered[k]


class Prober:
    """``GET /healthz`` every :data:`PROBE_S` on its own connection, latencies recorded."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.latencies: list[float] = []
        self.statuses: Counter[int] = Counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        with httpx.Client(base_url=self.url, timeout=30) as client:
            while not self._stop.is_set():
                t0 = time.perf_counter()
                r = client.get("/healthz")
                self.latencies.append(time.perf_counter() - t0)
                self.statuses[r.status_code] += 1
                self._stop.wait(PROBE_S)

    def __enter__(self) -> Prober:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(60)


def run_load(url: str, name: str, load: Callable[[str], Counter[int]]) -> dict[str, Any]:
    """Run ``load`` under the prober; its figures as a dict (also printed)."""
    with Prober(url) as prober:
        time.sleep(0.3)
        t0 = time.perf_counter()
        answers = load(url)
        wall = time.perf_counter() - t0
        time.sleep(0.2)
    lat = prober.latencies
    out = {
        "load": name,
        "seconds": round(wall, 2),
        "answers": dict(answers),
        "probes": len(lat),
        "health_statuses": dict(prober.statuses),
        "p50_s": round(percentile(lat, 50), 4),
        "p99_s": round(percentile(lat, 99), 4),
        "max_s": round(max(lat), 4),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    print(
        f"{name:<34} {wall:6.1f} s  answers {dict(answers)}  /healthz: {len(lat)} probes,"
        f" p50 {out['p50_s'] * 1e3:6.1f} ms, p99 {out['p99_s'] * 1e3:6.1f} ms,"
        f" max {out['max_s'] * 1e3:6.1f} ms (load average {out['load_average_1min']})",
        flush=True,
    )
    return out


def concurrent_posts(path: str, bodies: list[bytes], workers: int) -> Callable[[str], Counter[int]]:
    def load(url: str) -> Counter[int]:
        with httpx.Client(
            base_url=url, timeout=300, limits=httpx.Limits(max_connections=workers)
        ) as c:

            def post(body: bytes) -> int:
                h = {"Content-Type": "application/json"}
                return c.post(path, content=body, headers=h).status_code

            with ThreadPoolExecutor(workers) as pool:
                return Counter(pool.map(post, bodies))

    return load


def prism_doc(n: int) -> bytes:
    doc = small_plan_doc()
    prism = {"kind": "prism", "footprint": [[50, 50], [51, 50], [51, 51]], "height_m": 3}
    doc["environment"] = {"obstacles": [prism] * n}
    return json.dumps(doc).encode()


def geojson_buildings(vertices: int, per_building: int = 100) -> bytes:
    features = []
    for b in range(max(1, vertices // per_building)):
        cx, cy = 24.0 + (b % 100) * 0.0005, 60.0 + (b // 100) * 0.0005
        ring = [
            [
                cx + 0.0001 * math.cos(2 * math.pi * k / per_building),
                cy + 0.0001 * math.sin(2 * math.pi * k / per_building),
            ]
            for k in range(per_building)
        ]
        ring.append(ring[0])
        features.append(
            {
                "type": "Feature",
                "properties": {"building": "yes", "height": 10},
                "geometry": {"type": "Polygon", "coordinates": [ring]},
            }
        )
    return json.dumps({"type": "FeatureCollection", "features": features}).encode()


def event_streams(n: int, seconds: float) -> Callable[[str], Counter[int]]:
    def load(url: str) -> Counter[int]:
        with httpx.Client(base_url=url, timeout=60) as c:
            job = c.post("/v1/plans", json=small_plan_doc(ris_count=[2, 3, 4])).json()["id"]
        statuses: Counter[int] = Counter()
        stop = threading.Event()

        def stream() -> None:
            with (
                httpx.Client(base_url=url, timeout=60) as c,
                c.stream("GET", f"/v1/jobs/{job}/events") as r,
            ):
                statuses[r.status_code] += 1
                for _ in r.iter_lines():
                    if stop.is_set():
                        return

        threads = [threading.Thread(target=stream, daemon=True) for _ in range(n)]
        for t in threads:
            t.start()
        time.sleep(seconds)
        stop.set()
        return statuses

    return load


def idle(seconds: float) -> Callable[[str], Counter[int]]:
    """No load: the probes alone (the reference of the same run)."""

    def load(url: str) -> Counter[int]:
        time.sleep(seconds)
        return Counter()

    return load


P99_BOUND_S = 0.5
"""The liveness criterion: ``/healthz`` answers 99 % of its probes within this under each load
(docs/guides/service-operations.md, "Liveness under load"); a bound on speed, so it is this
benchmark's, not the test suite's (tests/test_api_hardening.py checks that it answers)."""


def measure(smoke: bool, only: str | tuple[str, ...] | None = None) -> list[dict[str, Any]]:
    """Every load (those whose name contains ``only`` or one of its texts) against one server;
    the figures."""
    wanted = (only,) if isinstance(only, str) else only
    n_plans, n_prisms, n_vertices, n_streams = (
        (30, 20_000, 40_000, 20) if smoke else (300, 100_001, 400_000, 100)
    )
    env = {"RIS_PLANNER_MAX_BODY_BYTES": "50000000", "RIS_PLANNER_WORKERS": "1"}
    results = []
    with tempfile.TemporaryDirectory() as tmp, served(Path(tmp) / "jobs.db", env=env) as server:
        url = server.url
        plan = json.dumps(small_plan_doc()).encode()
        loads: list[tuple[str, Callable[[], Callable[[str], Counter[int]]]]] = [
            ("idle server (no load, the reference)", lambda: idle(3.0 if smoke else 10.0)),
            (
                f"{n_plans} concurrent plan submissions",
                lambda: concurrent_posts("/v1/plans", [plan] * n_plans, n_plans),
            ),
            (
                f"plan with {n_prisms} prisms",
                lambda: concurrent_posts("/v1/plans", [prism_doc(n_prisms)], 1),
            ),
            (
                f"validation of {n_prisms // 2} prisms",
                lambda: concurrent_posts("/v1/plans/validate", [prism_doc(n_prisms // 2)], 1),
            ),
            (
                f"import of {n_vertices} vertices",
                lambda: concurrent_posts(
                    "/v1/import?format=geojson", [geojson_buildings(n_vertices)], 1
                ),
            ),
            (
                f"{n_streams} event streams",
                lambda: event_streams(n_streams, 3.0 if smoke else 10.0),
            ),
        ]
        for name, make in loads:
            if wanted is not None and not any(text in name for text in wanted):
                continue
            results.append(run_load(url, name, make()))
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="small loads (the test suite's)")
    parser.add_argument("--json", type=Path, help="write the figures here")
    parser.add_argument("--only", help="run only the loads whose name contains this text")
    parser.add_argument(
        "--parse-times", action="store_true", help="only time json.loads of the large bodies"
    )
    args = parser.parse_args()
    if args.parse_times:
        bodies = {
            "20 000 prisms": prism_doc(20_000),
            "100 001 prisms": prism_doc(100_001),
            "400 000 vertices": geojson_buildings(400_000),
        }
        for name, body in bodies.items():
            t0 = time.perf_counter()
            json.loads(body)
            took = time.perf_counter() - t0
            print(f"json.loads of {name}: {len(body) / 1e6:.1f} MB in {took:.2f} s")
        return
    results = measure(args.smoke, args.only)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    slow = [r["load"] for r in results if r["p99_s"] >= P99_BOUND_S]
    verdict = "no: " + ", ".join(slow) if slow else "yes"
    print(f"/healthz p99 below {P99_BOUND_S} s under every load: {verdict}")
    if slow:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
