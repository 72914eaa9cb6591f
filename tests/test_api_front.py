"""The front middleware's fast path of ``POST /v1/bounds`` (api/front.py) answers as the route
does: every request below is sent to an application with the fast path and to one without
(``create_app(fast_paths=False)``, every request through FastAPI's route), and the status,
headers and JSON bodies must be the same – 200, 400, 401, 413 (declared, streamed, pairs),
422 (document, empty body, engine rule, unknown query parameter), 500, and the bare 400 of a
client gone before its body."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from tolerance import BOUND_ACCURACY, assert_close

import api.routes.bounds
from api.front import FrontMiddleware
from api.main import create_app
from api.settings import Settings
from ris_planner import preset_document

KEY = "front-test-key"
JSON = {"content-type": "application/json"}
AUTH = {"x-api-key": KEY}


def settings(tmp_path: Path, name: str) -> Settings:
    return Settings(
        db=tmp_path / f"{name}.db", api_key=KEY, max_body_bytes=4096, max_pairs=5, workers=1
    )


@pytest.fixture
def clients(tmp_path: Path) -> Iterator[tuple[TestClient, TestClient]]:
    """(fast path, route only), the same settings: an admin key, 4096 bytes, 5 pairs."""
    with ExitStack() as stack:
        fast, route = (
            stack.enter_context(
                TestClient(
                    create_app(settings(tmp_path, name), fast_paths=fast_paths),
                    raise_server_exceptions=False,
                )
            )
            for name, fast_paths in (("fast", True), ("route", False))
        )
        yield fast, route


def doc_with(**changes: Any) -> dict[str, Any]:
    doc = preset_document("paper-table1")
    doc.update(changes)
    return doc


def chunks(body: bytes) -> Callable[[], Iterator[bytes]]:
    def gen() -> Iterator[bytes]:
        for i in range(0, len(body), 512):
            yield body[i : i + 512]

    return gen


def bad_document() -> dict[str, Any]:
    doc = preset_document("paper-table1")
    doc["ris"][1]["position"] = [4, 0, "up"]
    doc["system"]["subcarriers"] = 0
    return doc


SIX_PAIRS = doc_with(tx=[[-2.0, -4.0, 0.0]] * 6, rx=[[2.0, 3.0, 0.0]] * 6)
LARGE = json.dumps(doc_with(description="x" * 5000)).encode()
ENGINE_RULE = {  # G = 1 cannot hold L + 1 = 2 orthogonal blocks (a ValueError of the engine)
    "ris": [{"position": [0.0, 0.0, 1.0]}],
    "tx": [0.0, 0.0, 0.0],
    "rx": [1.0, 0.0, 0.0],
    "system": {"transmissions": 1, "los": False},
}

CASES: dict[str, tuple[int, dict[str, Any]]] = {
    "table1": (200, {"json": preset_document("paper-table1"), "headers": AUTH}),
    "3-ris": (200, {"json": preset_document("3-ris"), "headers": AUTH}),
    "batch": (200, {"json": doc_with(tx=[[-2.0, -4.0, 0.0]] * 3, rx=[[2.0, 3.0, 0.0]] * 3),
                    "headers": AUTH}),
    "no key": (401, {"json": preset_document("paper-table1")}),
    "wrong key": (401, {"json": preset_document("paper-table1"), "headers": {"x-api-key": "no"}}),
    "not json": (400, {"content": b"{not json", "headers": JSON | AUTH}),
    "too deep": (400, {"content": b"[" * 1500 + b"]" * 1500, "headers": JSON | AUTH}),
    "bad content-length": (400, {"content": b"{}", "headers": AUTH | {"content-length": "ten"}}),
    "declared too large": (413, {"content": LARGE, "headers": JSON | AUTH}),
    "streamed too large": (413, {"content": chunks(LARGE), "headers": JSON | AUTH}),
    "too many pairs": (413, {"json": SIX_PAIRS, "headers": AUTH}),
    "invalid document": (422, {"json": bad_document(), "headers": AUTH}),
    "empty body": (422, {"content": b"", "headers": JSON | AUTH}),
    "a list": (422, {"content": b"[1, 2]", "headers": JSON | AUTH}),
    "engine rule": (422, {"json": ENGINE_RULE, "headers": AUTH}),
    "unknown query": (422, {"json": preset_document("paper-table1"), "headers": AUTH,
                            "params": {"limt": "5"}}),
}  # fmt: skip


def send(client: TestClient, request: dict[str, Any]) -> Any:
    request = dict(request)
    if callable(request.get("content")):
        request["content"] = request["content"]()  # a fresh generator per request
    return client.post("/v1/bounds", **request)


@pytest.mark.parametrize("case", list(CASES))
def test_fast_path_answers_as_the_route(clients: tuple[TestClient, TestClient], case: str) -> None:
    status, request = CASES[case]
    fast_client, route_client = clients
    fast, route = send(fast_client, request), send(route_client, request)
    assert fast.status_code == route.status_code == status, (case, fast.text[:300])
    for name in ("content-type", "x-content-type-options", "www-authenticate", "allow"):
        assert fast.headers.get(name) == route.headers.get(name), (case, name)
    assert fast.headers["x-content-type-options"] == "nosniff"
    assert_close(fast.json(), route.json(), accuracy=BOUND_ACCURACY, where=case)
    if status != 200:
        assert fast.json()["status"] == status and "Traceback" not in fast.text


def test_unexpected_error_is_the_same_500(
    clients: tuple[TestClient, TestClient], monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(scenario: object) -> None:
        raise KeyError("internal detail")

    monkeypatch.setattr(api.routes.bounds, "bounds_document", broken)
    answers = [c.post("/v1/bounds", json=preset_document("paper-table1"), headers=AUTH)
               for c in clients]  # fmt: skip
    for r in answers:
        assert r.status_code == 500 and r.json()["error"] == "internal_error", r.text
        assert "internal detail" not in r.text
    assert {r.json()["message"].split(" (id")[0] for r in answers} == {"unexpected server error"}


def test_fast_path_is_taken_and_the_route_still_documented(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """POST /v1/bounds goes through the fast path, a request with a query string (the route's
    422) does not; the OpenAPI document lists the route with its error answers."""
    taken: list[str] = []
    fast_bounds = FrontMiddleware._bounds

    async def spy(self: FrontMiddleware, scope: Any, receive: Any, send: Any) -> None:
        taken.append(scope["path"])
        await fast_bounds(self, scope, receive, send)

    monkeypatch.setattr(FrontMiddleware, "_bounds", spy)
    with TestClient(create_app(settings(tmp_path, "fast")), raise_server_exceptions=False) as c:
        doc = preset_document("paper-table1")
        assert c.post("/v1/bounds", json=doc, headers=AUTH).status_code == 200
        assert taken == ["/v1/bounds"]
        r = c.post("/v1/bounds", json=doc, headers=AUTH, params={"x": "1"})
        assert r.status_code == 422 and taken == ["/v1/bounds"]
        assert c.post("/v1/bounds", json=doc).status_code == 401 and len(taken) == 1
        ops = c.get("/openapi.json").json()["paths"]["/v1/bounds"]["post"]
        assert {"200", "400", "401", "413", "422"} <= set(ops["responses"])
        assert ops["requestBody"]["content"]["application/json"]


def test_client_gone_before_its_body_is_the_same_400(tmp_path: Path) -> None:
    """A client that announces a body and disconnects first: one log line and a bare 400 from
    both paths (driven through the ASGI interface: a test client cannot disconnect)."""
    import asyncio

    from starlette.types import Message

    async def post(fast_paths: bool) -> list[Message]:
        app = create_app(settings(tmp_path, f"gone{fast_paths}"), fast_paths=fast_paths)
        scope = {
            "type": "http",
            "asgi": {"version": "3.0"},
            "http_version": "1.1",
            "method": "POST",
            "scheme": "http",
            "path": "/v1/bounds",
            "raw_path": b"/v1/bounds",
            "root_path": "",
            "query_string": b"",
            "headers": [
                (b"host", b"127.0.0.1:8000"),
                (b"content-type", b"application/json"),
                (b"content-length", b"600"),
                (b"x-api-key", KEY.encode()),
            ],
            "client": ("127.0.0.1", 5000),
            "server": ("127.0.0.1", 8000),
        }
        sent: list[Message] = []

        async def receive() -> Message:
            return {"type": "http.disconnect"}

        async def send(message: Message) -> None:
            sent.append(message)

        async with app.router.lifespan_context(app):
            await app(scope, receive, send)
        return sent

    fast, route = (asyncio.run(post(f)) for f in (True, False))
    assert [m["type"] for m in fast] == [m["type"] for m in route]
    assert fast[0]["status"] == route[0]["status"] == 400
    assert fast[0]["headers"] == route[0]["headers"]
    assert b"".join(m.get("body", b"") for m in fast[1:]) == b""


@pytest.mark.parametrize(
    ("inline_work", "pairs", "threaded"),
    [
        (1_000_000, 1, []),  # Table I: parsed, checked and answered on the event loop
        (10, 1, ["scenario_answer"]),  # parsed on the loop, its work above the setting
        (0, 1, ["bounds_answer"]),  # 0: always a worker thread
        (1_000_000, 2500, ["bounds_answer"]),  # a body above 64 KiB: parsed in the thread
    ],
)
def test_small_requests_are_answered_on_the_event_loop(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    inline_work: int,
    pairs: int,
    threaded: list[str],
) -> None:
    """The fast path answers a request of at most ``bounds_inline_work`` (and a body of at
    most 64 KiB) without a worker thread – the hand-off cost more than Table I's work – and
    everything else in one; the answers are the same numbers either way."""
    import anyio.to_thread

    from ris_planner import compute_bounds, load_scenario

    calls: list[str] = []
    real = anyio.to_thread.run_sync

    async def counting(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        calls.append(fn.__name__)
        return await real(fn, *args, **kwargs)

    monkeypatch.setattr(anyio.to_thread, "run_sync", counting)
    doc = doc_with(tx=[[-2.0, -4.0, 0.0]] * pairs, rx=[[2.0, 3.0, 0.0]] * pairs)
    body = json.dumps(doc).encode()
    assert (len(body) > 64 * 1024) == (pairs > 1)
    config = Settings(db=tmp_path / "jobs.db", bounds_inline_work=inline_work, workers=1)
    with TestClient(create_app(config)) as client:
        calls.clear()  # the application's start-up may use threads
        r = client.post("/v1/bounds", content=body, headers=JSON)
    assert r.status_code == 200, r.text
    assert [c for c in calls if c in ("scenario_answer", "bounds_answer")] == threaded
    want = compute_bounds(load_scenario(doc)).peb_rx
    assert_close(r.json()["peb_rx_m"], want.tolist(), accuracy=BOUND_ACCURACY)
