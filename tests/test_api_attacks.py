"""Attacks on the service, each against a real uvicorn on 127.0.0.1 (``api.launch.served``,
stopped by its PID): request bodies of an undeclared media type and cross-origin writes, the
same ``Idempotency-Key`` retried at once, sizes above their limits in any field, a parse process
killed while idle or while it works, an unexpected error's answer, what the OpenAPI document
says of each operation's body, and what ``--log-level info`` shows
(docs/guides/service-operations.md)."""

from __future__ import annotations

import json
import os
import signal
import socket
import sqlite3
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from api_helpers import JSON
from test_api_faults import FINAL, _group_leader, children, poll, wait_gone
from test_api_plans import small_plan_doc
from waits import HANG_S

from api.auth import key_digest
from api.launch import Server, served

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")

UNDECLARED_MEDIA: list[str | None] = [
    "text/plain",
    "text/plain;charset=UTF-8",
    "application/x-www-form-urlencoded",
    "multipart/form-data; boundary=x",
    None,  # no Content-Type at all (a fetch() of a Blob without a type)
]
"""What a page on another origin can send without a CORS preflight: the three "simple"
media types of a form or a fetch(), or none."""

BIG_ENV = {"RIS_PLANNER_MAX_BODY_BYTES": "30000000"}
"""A body limit above the largest list the size tests send (a million points)."""


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """A keyless server with its defaults (a larger body limit)."""
    tmp = tmp_path_factory.mktemp("attacks")
    with served(tmp / "jobs.db", env=BIG_ENV, log=tmp / "server.log") as srv:
        yield srv


def jobs_total(url: str, headers: dict[str, str] | None = None) -> int:
    total: int = httpx.get(f"{url}/v1/jobs", headers=headers, timeout=HANG_S).json()["total"]
    return total


def operations(spec: dict[str, Any]) -> Iterator[tuple[str, str, dict[str, Any]]]:
    """(path, method, operation) of every operation of an OpenAPI document."""
    for path, item in spec["paths"].items():
        for method, op in item.items():
            if method in ("get", "post", "put", "patch", "delete"):
                yield path, method.upper(), op


def example_body(op: dict[str, Any]) -> tuple[str, bytes] | None:
    """The first example of an operation's request body as (media type, bytes), or None."""
    for media, content in op.get("requestBody", {}).get("content", {}).items():
        for example in content.get("examples", {}).values():
            value = example["value"]
            return media, (value.encode() if isinstance(value, str) else json.dumps(value).encode())
        if "example" in content:
            value = content["example"]
            return media, (value.encode() if isinstance(value, str) else json.dumps(value).encode())
    return None


def test_every_body_refuses_an_undeclared_media_type(server: Server) -> None:
    """Every operation that takes a body – walked from the OpenAPI document, so a route added
    later is held to it too – answers 415 to a body of a media type it does not declare (or of
    none), before any work: nothing is queued."""
    url = server.url
    spec = httpx.get(f"{url}/openapi.json", timeout=HANG_S).json()
    before = jobs_total(url)
    wrong = []
    undocumented = []
    taking = 0
    for path, method, op in operations(spec):
        if "requestBody" not in op:
            continue
        taking += 1
        if "415" not in op["responses"]:
            undocumented.append((method, path))
        example = example_body(op)
        body = example[1] if example is not None else json.dumps(small_plan_doc()).encode()
        for media in UNDECLARED_MEDIA:
            headers = {} if media is None else {"Content-Type": media}
            r = httpx.request(method, f"{url}{path}", content=body, headers=headers, timeout=HANG_S)
            if r.status_code != 415 or r.json().get("error") != "unsupported_media_type":
                wrong.append((method, path, media, r.status_code, r.text[:120]))
    assert wrong == [], "\n".join(map(str, wrong))
    assert jobs_total(url) == before
    assert taking >= 9  # bounds, plans, validate, power, import, sites, preview, candidates ×2
    assert undocumented == []  # the OpenAPI document lists the 415 of each


def test_cross_origin_writes_are_refused(server: Server) -> None:
    """A write sent by a page of another origin (its Origin header, or Sec-Fetch-Site where a
    browser sends no Origin) is refused with 403 before its body is read, and so is any request
    that reaches the loopback server under a host name that is not a loopback one (DNS
    rebinding: the attacker's name resolving to 127.0.0.1); the server's own origin passes."""
    url = server.url
    host = url.removeprefix("http://")
    port = host.rsplit(":", 1)[1]
    doc = small_plan_doc()
    before = jobs_total(url)
    refused = [
        ("POST", "/v1/plans", {"Origin": "http://evil.example"}),
        ("POST", "/v1/plans", {"Origin": "null"}),
        ("POST", "/v1/plans", {"Origin": f"http://127.0.0.1:{int(port) + 1}"}),
        ("POST", "/v1/plans", {"Sec-Fetch-Site": "cross-site"}),
        ("POST", "/v1/bounds", {"Origin": "http://evil.example"}),
        (
            "POST",
            "/v1/plans",
            {"Host": f"evil.example:{port}", "Origin": f"http://evil.example:{port}"},
        ),
        ("GET", "/v1/jobs", {"Host": f"evil.example:{port}"}),
    ]
    for method, path, headers in refused:
        body = doc if method == "POST" else None
        r = httpx.request(method, f"{url}{path}", json=body, headers=headers, timeout=HANG_S)
        assert r.status_code == 403, (headers, r.status_code, r.text[:200])
        assert r.json()["error"] == "forbidden" and r.headers["x-content-type-options"] == "nosniff"
    assert jobs_total(url) == before
    for headers in (
        {"Origin": f"http://{host}"},
        {"Origin": f"http://localhost:{port}", "Host": f"localhost:{port}"},
        {},
    ):
        r = httpx.post(f"{url}/v1/plans/validate", json=doc, headers=headers, timeout=HANG_S)
        assert r.status_code == 200, (headers, r.text[:200])


def _concurrent_posts(
    url: str, doc: dict[str, Any], headers: dict[str, str], n: int
) -> list[httpx.Response]:
    """``n`` POST /v1/plans sent at once (a barrier releases them together)."""
    barrier = threading.Barrier(n)
    answers: list[httpx.Response | None] = [None] * n

    def send(i: int) -> None:
        with httpx.Client(timeout=HANG_S) as client:
            barrier.wait(60)
            answers[i] = client.post(f"{url}/v1/plans", json=doc, headers=headers)

    threads = [threading.Thread(target=send, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(180)
    assert all(a is not None for a in answers)
    return [a for a in answers if a is not None]


@pytest.mark.parametrize("keyed", [False, True], ids=["keyless", "keyed"])
def test_concurrent_idempotent_retries_create_one_job(tmp_path: Path, keyed: bool) -> None:
    """Eight retries of one submission at once, three rounds: every answer is 202 with the one
    job the first of them created (the others say Idempotent-Replayed), with or without API
    keys, on a file database."""
    env = {"RIS_PLANNER_API_KEYS": f"alice:{key_digest('alice-key')}"} if keyed else {}
    auth = {"X-API-Key": "alice-key"} if keyed else {}
    with served(tmp_path / "jobs.db", env=env, log=tmp_path / "server.log") as srv:
        for round_ in range(3):
            doc = small_plan_doc(description=f"round {round_}")
            key = {"Idempotency-Key": f"retry-{round_}"}
            answers = _concurrent_posts(srv.url, doc, auth | key, 8)
            statuses = [a.status_code for a in answers]
            assert statuses == [202] * 8, [(a.status_code, a.text[:200]) for a in answers]
            assert len({a.json()["id"] for a in answers}) == 1
            replayed = [a.headers.get("idempotent-replayed") for a in answers]
            assert replayed.count("true") == 7, replayed
        assert jobs_total(srv.url, auth) == 3
        if keyed:  # the media-type rule holds behind the key too
            r = httpx.post(
                f"{srv.url}/v1/plans",
                content=json.dumps(small_plan_doc()),
                headers=auth | {"Content-Type": "text/plain"},
                timeout=HANG_S,
            )
            assert r.status_code == 415, r.text[:200]


OLD_SCHEMA = """
CREATE TABLE jobs (
    id TEXT PRIMARY KEY, kind TEXT NOT NULL, status TEXT NOT NULL, progress REAL NOT NULL
    DEFAULT 0, message TEXT NOT NULL DEFAULT '', request TEXT NOT NULL, result TEXT, error TEXT,
    figures TEXT NOT NULL DEFAULT '{}', seq INTEGER NOT NULL, created_at TEXT NOT NULL,
    started_at TEXT, finished_at TEXT, owner TEXT, idempotency_key TEXT, estimate TEXT
);
CREATE INDEX jobs_seq ON jobs (seq);
CREATE INDEX jobs_status ON jobs (status);
CREATE UNIQUE INDEX jobs_idempotency ON jobs (owner, idempotency_key)
    WHERE idempotency_key IS NOT NULL;
CREATE INDEX jobs_owner ON jobs (owner, seq);
"""
"""The job table as the service created it before idempotency keys held without API keys."""


def test_an_old_database_is_migrated_to_one_job_per_key(tmp_path: Path) -> None:
    """A database of the earlier schema holding three keyless jobs under one Idempotency-Key
    (what concurrent retries made of it): opened by the server, the first keeps the key, the
    others lose it (they stay as jobs), and from then on the key is unique without API keys."""
    db = tmp_path / "jobs.db"
    con = sqlite3.connect(db)
    con.executescript(OLD_SCHEMA)
    for seq in (1, 2, 3):
        con.execute(
            "INSERT INTO jobs (id, kind, status, request, seq, created_at, idempotency_key,"
            " finished_at, error) VALUES (?, 'plan', 'failed', '{}', ?, ?, 'k', ?, 'old')",
            (f"{seq:032x}", seq, f"2025-01-0{seq}", f"2025-01-0{seq}"),
        )
    con.commit()
    con.close()
    with served(db, log=tmp_path / "server.log") as srv:
        r = httpx.post(
            f"{srv.url}/v1/plans",
            json=small_plan_doc(),
            headers={"Idempotency-Key": "k"},
            timeout=HANG_S,
        )
        assert r.status_code == 409 and f"{1:032x}" in r.json()["message"], r.text[:300]
        assert jobs_total(srv.url) == 3
    con = sqlite3.connect(db)
    try:
        keys = con.execute("SELECT id, idempotency_key FROM jobs ORDER BY seq").fetchall()
        assert keys == [(f"{1:032x}", "k"), (f"{2:032x}", None), (f"{3:032x}", None)]
        with pytest.raises(sqlite3.IntegrityError):
            con.execute(
                "INSERT INTO jobs (id, kind, status, request, seq, created_at, idempotency_key)"
                " VALUES ('x', 'plan', 'queued', '{}', 9, 'now', 'k')"
            )
    finally:
        con.close()


def _plan(**maps: Any) -> dict[str, Any]:
    return small_plan_doc(**maps)


def _grid(nx: int, ny: int) -> dict[str, Any]:
    return {"grid": {"x": [0, nx - 1, 1], "y": [0, ny - 1, 1], "z": [0, 0, 1]}}


def _candidates(n: int) -> list[dict[str, Any]]:
    return [{"position": [float(i % 100), float(i // 100), 3.0]} for i in range(n)]


SIZE_CASES: dict[str, tuple[int, list[str], Any]] = {
    # name: (limit, routes, document)
    "grid points": (
        1_000_000,
        ["/v1/plans", "/v1/plans/validate", "/v1/site/preview"],
        lambda: _plan(tx_map=_grid(1001, 1000)),
    ),
    "map points and grid together": (
        1_000_000,
        ["/v1/plans", "/v1/plans/validate", "/v1/site/preview"],
        lambda: _plan(rx_map={"grid": _grid(1000, 900)["grid"], "points": [[0, 0, 0]] * 100_001}),
    ),
    "map points": (
        1_000_000,
        ["/v1/plans", "/v1/plans/validate", "/v1/site/preview"],
        lambda: _plan(tx_map={"points": [[0, 0, 0]] * 1_000_001}),
    ),
    "obstacles": (
        100_000,
        ["/v1/plans", "/v1/plans/validate", "/v1/site/preview"],
        lambda: _plan(
            environment={
                "obstacles": [
                    {"kind": "prism", "footprint": [[0, 0], [1, 0], [1, 1]], "height_m": 3}
                ]
                * 100_001
            }
        ),
    ),
    "candidates": (
        10_000,
        ["/v1/plans", "/v1/plans/validate"],
        lambda: _plan(candidates=_candidates(10_001)),
    ),
    "sampled pairs": (
        500_000,
        ["/v1/plans", "/v1/plans/validate"],
        lambda: _plan(pairs={"sample": 500_001, "seed": 1}),
    ),
    "pairs limit": (
        500_000,
        ["/v1/plans", "/v1/plans/validate"],
        lambda: _plan(max_pairs=500_001),
    ),
    "candidates to convert": (
        10_000,
        ["/v1/candidates/convert"],
        lambda: {"local": _candidates(10_001)},
    ),
    "candidates to write": (
        10_000,
        ["/v1/candidates/geojson"],
        lambda: {"frame": {"origin": [24.94, 60.17, 0.0]}, "local": _candidates(10_001)},
    ),
}


def test_every_size_limit_is_413_with_its_limit(server: Server) -> None:
    """A document above a size limit – grid points, map points, obstacles, candidates, pairs,
    whichever field carries it – is a 413 naming the limit, on every route that takes the
    document, never a 422 without it; nothing is queued."""
    url = server.url
    before = jobs_total(url)
    wrong = []
    for name, (limit, routes, make) in SIZE_CASES.items():
        body = json.dumps(make()).encode()
        for route in routes:
            r = httpx.post(f"{url}{route}", content=body, headers=JSON, timeout=HANG_S)
            answer = r.json()
            if r.status_code != 413 or answer.get("limit") != limit:
                wrong.append((name, route, r.status_code, answer.get("limit"), r.text[:200]))
    assert wrong == [], "\n".join(map(str, wrong))
    assert jobs_total(url) == before


def _arrays(schema: Any, name: str = "") -> Iterator[tuple[str, dict[str, Any]]]:
    """(property name, array schema) of every array property in a JSON schema."""
    if isinstance(schema, dict):
        if schema.get("type") == "array" and name:
            yield name, schema
        for key, value in schema.items():
            if key == "properties" and isinstance(value, dict):
                for prop, sub in value.items():
                    yield from _arrays(sub, prop)
            else:
                yield from _arrays(value, name)
    elif isinstance(schema, list):
        for value in schema:
            yield from _arrays(value, name)


def _properties(schema: Any) -> Iterator[tuple[str, dict[str, Any]]]:
    if isinstance(schema, dict):
        for key, value in schema.items():
            if key == "properties" and isinstance(value, dict):
                yield from value.items()
            yield from _properties(value)
    elif isinstance(schema, list):
        for value in schema:
            yield from _properties(value)


def test_every_size_limit_of_the_schema_is_a_registered_size() -> None:
    """The size limits are one class: every list of the request bodies that may hold 1000
    items or more (variable length) is registered with its limit (refused by the pre-scan before
    validation, and reported as a size if a model refuses it), and every count named in the
    registry has the registry's maximum – a bulk list added to a document later is held to it
    (this fails until it is registered)."""
    from api.errors import BULK_LISTS
    from api.main import create_app
    from api.settings import Settings
    from ris_planner.model.limits import COUNT_LIMITS

    spec = create_app(Settings(db=Path("unused.db"))).openapi()
    unregistered = []
    for name, array in _arrays(spec["components"]["schemas"]):
        limit = array.get("maxItems")
        if limit is None or limit < 1000 or array.get("minItems") == limit:
            continue
        if BULK_LISTS.get(name, (None,))[0] != limit:
            unregistered.append((name, limit))
    assert unregistered == []
    counts = {
        (name, prop.get("maximum"))
        for name, prop in _properties(spec["components"]["schemas"])
        if name in COUNT_LIMITS and prop.get("type") == "integer"
    }
    assert counts == {(name, limit) for name, (limit, _) in COUNT_LIMITS.items()}


def parse_pids(server_pid: int) -> list[int]:
    """The parse processes: the forkserver's children that lead no process group (the job
    workers do)."""
    return [p for fs in children(server_pid) for p in children(fs) if not _group_leader(p)]


def cpu_ticks(pid: int) -> int:
    """utime + stime of a process [clock ticks] (fields 14 and 15 of /proc/PID/stat)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])


def wait_until(condition: Any, what: Any, timeout_s: float = 60.0) -> Any:
    """``condition()`` once it is true; fails with ``what`` (or ``what()``, for the state it
    saw) after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not (found := condition()):
        assert time.monotonic() < deadline, what() if callable(what) else what
        time.sleep(0.05)
    return found


POOL_ENV = {"RIS_PLANNER_PARSE_CONCURRENCY": "2"}


def test_a_dead_idle_parse_process_fails_no_request(tmp_path: Path) -> None:
    """A parse process killed while idle: every later request is answered as if nothing had
    happened, and the pool is whole again."""
    with served(tmp_path / "jobs.db", env=POOL_ENV, log=tmp_path / "server.log") as srv:
        r = httpx.post(f"{srv.url}/v1/plans/validate", json=small_plan_doc(), timeout=HANG_S)
        assert r.status_code == 200, r.text[:200]
        pids = wait_until(lambda: len(p := parse_pids(srv.process.pid)) == 2 and p, "2 parsers")
        os.kill(pids[0], signal.SIGKILL)
        wait_gone([pids[0]])
        for _ in range(4):
            r = httpx.post(f"{srv.url}/v1/plans/validate", json=small_plan_doc(), timeout=HANG_S)
            assert r.status_code == 200, r.text[:300]
        wait_until(lambda: len(parse_pids(srv.process.pid)) == 2, "the pool rebuilt")


def _prisms(n: int) -> dict[str, Any]:
    """A plan of ``n`` small prisms: seconds of validation in a parse process."""
    doc = small_plan_doc()
    doc["environment"] = {
        "obstacles": [
            {
                "kind": "prism",
                "footprint": [
                    [100 + i % 100 * 3, 100 + i // 100 * 3],
                    [101 + i % 100 * 3, 100 + i // 100 * 3],
                    [101 + i % 100 * 3, 101 + i // 100 * 3],
                ],
                "height_m": 3,
            }
            for i in range(n)
        ]
    }
    return doc


def test_a_parse_process_death_fails_only_its_request(tmp_path: Path) -> None:
    """Two documents parsed at once, one parse process killed while it works: that request
    alone fails (500, with the security headers and a message, no traceback to the client),
    the other is answered, and the pool is rebuilt for the next ones."""
    with served(tmp_path / "jobs.db", env=POOL_ENV, log=tmp_path / "server.log") as srv:
        url = srv.url
        assert httpx.post(f"{url}/v1/plans/validate", json=small_plan_doc(), timeout=HANG_S)
        pids = wait_until(lambda: len(p := parse_pids(srv.process.pid)) == 2 and p, "2 parsers")
        base = {p: cpu_ticks(p) for p in pids}
        body = json.dumps(_prisms(50_000)).encode()
        answers: list[httpx.Response] = []

        def send() -> None:
            answers.append(
                httpx.post(f"{url}/v1/plans/validate", content=body, headers=JSON, timeout=HANG_S)
            )

        threads = [threading.Thread(target=send) for _ in range(2)]
        for t in threads:
            t.start()
        hz = os.sysconf("SC_CLK_TCK")
        wait_until(lambda: all(cpu_ticks(p) - base[p] > 0.3 * hz for p in pids), "both busy")
        os.kill(pids[0], signal.SIGKILL)
        for t in threads:
            t.join(300)
        statuses = sorted(a.status_code for a in answers)
        assert statuses == [200, 500], [a.text[:300] for a in answers]
        failed = next(a for a in answers if a.status_code == 500)
        assert failed.headers["x-content-type-options"] == "nosniff"
        assert failed.json()["error"] == "internal_error"
        assert "parse process" in failed.json()["message"], failed.text
        r = httpx.post(f"{url}/v1/plans/validate", json=small_plan_doc(), timeout=HANG_S)
        assert r.status_code == 200, r.text[:300]
        wait_until(lambda: len(parse_pids(srv.process.pid)) == 2, "the pool rebuilt")


def test_unexpected_errors_carry_the_security_headers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An error no handler expects (here: a route's function raising) is a 500 with an error id
    and the same security headers as every other answer (in-process: nothing a client sends
    reaches this on purpose)."""
    from api_helpers import api_client

    import api.routes.meta

    def broken(name: str) -> Any:
        raise RuntimeError("broken on purpose")

    with api_client(tmp_path) as client:
        monkeypatch.setattr(api.routes.meta, "preset_document", broken)
        r = client.get("/v1/presets")
        assert r.status_code == 500 and r.json()["error"] == "internal_error", r.text
        assert r.headers["x-content-type-options"] == "nosniff"


def _path_values(path: str, job_id: str) -> str:
    return path.replace("{job_id}", job_id).replace("{name}", "topview")


def test_openapi_declares_every_request_body(server: Server) -> None:
    """Each operation gets exactly what the OpenAPI document says: its declared example body
    with its declared media type (answered 2xx), or no body where it declares none (never a
    complaint about a missing body); a job's operations take the id of a job it queued."""
    url = server.url
    spec = httpx.get(f"{url}/openapi.json", timeout=HANG_S).json()
    ops = sorted(
        operations(spec),
        key=lambda o: (o[1] == "DELETE", o[0] != "/v1/plans", "{" in o[0], o[0], o[1]),
    )
    job_id = ""
    problems = []
    for path, method, op in ops:
        target = f"{url}{_path_values(path, job_id)}"
        if "requestBody" in op:
            example = example_body(op)
            if example is None:
                problems.append((method, path, "declares a body without an example"))
                continue
            media, body = example
            r = httpx.request(
                method, target, content=body, headers={"Content-Type": media}, timeout=HANG_S
            )
            if not 200 <= r.status_code < 300:
                problems.append((method, path, r.status_code, r.text[:200]))
            if path == "/v1/plans" and r.status_code == 202:
                job_id = r.json()["id"]
                poll(url, job_id, FINAL)
            continue
        if path.endswith("/events"):
            with httpx.stream(method, target, timeout=HANG_S) as r:
                status, complaint = r.status_code, None
        else:
            r = httpx.request(method, target, timeout=HANG_S)
            status = r.status_code
            complaint = r.json() if r.headers.get("content-type") == "application/json" else None
        if str(status) not in op["responses"]:
            problems.append((method, path, status, "status not documented"))
        body_fields = [f for f in (complaint or {}).get("fields", []) if f["location"] == "body"]
        if status == 415 or (status == 422 and body_fields):
            problems.append((method, path, status, "a body the document does not declare"))
    assert problems == [], "\n".join(map(str, problems))
    assert job_id, "POST /v1/plans queued no job"


def test_info_log_shows_the_services_own_lines(tmp_path: Path) -> None:
    """``ris-planner serve --log-level info`` logs the service's own lines beside uvicorn's: a
    job's start and end, a client gone before its body arrived."""
    log = tmp_path / "server.log"
    with served(tmp_path / "jobs.db", log=log, log_level="info") as srv:
        r = httpx.post(f"{srv.url}/v1/plans", json=small_plan_doc(), timeout=HANG_S)
        job = r.json()["id"]
        assert poll(srv.url, job, FINAL)["status"] == "succeeded"
        host, port = srv.url.removeprefix("http://").split(":")
        with socket.create_connection((host, int(port)), timeout=HANG_S) as s:
            head = f"POST /v1/plans HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n"
            s.sendall(f"{head}Content-Length: 1000\r\n\r\n".encode() + b'{"a": 1')
        wait_until(lambda: "client disconnected" in log.read_text(), "the disconnect's line")
        pids = [srv.process.pid]
    wait_gone(pids)
    text = log.read_text()
    assert f"job {job} (plan) started" in text, text[-3000:]
    assert f"job {job} (plan) succeeded" in text, text[-3000:]
    assert "client disconnected during POST /v1/plans" in text
