"""The page's server side: ``GET /`` and the shipped static files, ``/docs`` and ``/redoc``
with local assets only, ``POST /v1/plans/validate`` (the submission's checks without a job) and
``GET /v1/jobs/{id}/events`` (server-sent progress)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from api_helpers import api_client
from api_job_kinds import TEST_KINDS
from test_api_plans import small_plan_doc

from api.routes.events import job_events
from api.routes.web import STATIC_DIR
from api.security import PAGE_CSP
from ris_planner.planning import SerialExecutor, plan_preset, run_plan

EXTERNAL_URL = re.compile(r"""(src|href)=["']?(https?:)?//""")
"""An asset reference to another origin in an HTML page."""


def parse_sse(text: str) -> list[tuple[str, dict[str, Any]]]:
    """(event name, JSON data) of each event of a text/event-stream body."""
    out = []
    for block in text.split("\n\n"):
        name, data = "message", []
        for line in block.splitlines():
            if line.startswith("event:"):
                name = line[6:].strip()
            elif line.startswith("data:"):
                data.append(line[5:].strip())
        if data:
            out.append((name, json.loads("\n".join(data))))
    return out


class TestPages:
    def test_index_and_static_files_are_local(self, tmp_path: Path) -> None:
        with api_client(tmp_path, workers=1) as client:
            r = client.get("/")
            assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
            assert r.headers["content-security-policy"] == PAGE_CSP
            assert not EXTERNAL_URL.search(r.text)
            refs = re.findall(r'(?:src|href)="(/static/[^"]+)"', r.text)
            for ref in refs:
                assert client.get(ref).status_code == 200, ref
            # the map library, vendored, loaded before the page's script
            assert refs.index("/static/vendor/leaflet/leaflet.js") < refs.index("/static/app.js")
            assert "/static/vendor/leaflet/leaflet.css" in refs
            assert (
                client.get("/static/app.js")
                .headers["content-type"]
                .startswith(("text/javascript", "application/javascript"))
            )
            assert client.get("/static/nothing.js").status_code == 404

    def test_docs_and_redoc_use_vendored_assets(self, tmp_path: Path) -> None:
        with api_client(tmp_path, workers=1) as client:
            for path, asset in (
                ("/docs", "/static/vendor/swagger-ui/swagger-ui-bundle.js"),
                ("/redoc", "/static/vendor/redoc/redoc.standalone.js"),
            ):
                page = client.get(path)
                assert page.status_code == 200 and asset in page.text
                assert not EXTERNAL_URL.search(page.text), path
                js = client.get(asset)
                assert js.status_code == 200 and len(js.content) > 100_000
            assert "/static/vendor/swagger-ui/swagger-ui.css" in client.get("/docs").text
            assert client.get("/docs/oauth2-redirect").status_code == 200
            paths = client.get("/openapi.json").json()["paths"]
            assert "/v1/plans/validate" in paths and "/v1/jobs/{job_id}/events" in paths
            assert "/" not in paths and "/docs" not in paths

    def test_vendored_files_are_listed_with_hashes(self) -> None:
        import hashlib

        listing = (STATIC_DIR / "vendor" / "VENDORED.md").read_text()
        for f in sorted((STATIC_DIR / "vendor").rglob("*.js")) + sorted(
            (STATIC_DIR / "vendor").rglob("*.css")
        ):
            digest = hashlib.sha256(f.read_bytes()).hexdigest()
            assert f"{digest}  {f.relative_to(STATIC_DIR / 'vendor')}" in listing, f.name


class TestValidatePlan:
    def test_valid_document_previews_without_a_job(self, tmp_path: Path) -> None:
        doc = plan_preset("fig10-anchors")
        with api_client(tmp_path, workers=1) as client:
            r = client.post("/v1/plans/validate", json=doc)
            assert r.status_code == 200, r.text
            body = r.json()
            assert client.get("/v1/jobs").json()["total"] == 0
        res = run_plan(doc, executor=SerialExecutor())
        assert body["valid"] is True
        assert body["sites"] == len(res.sites) == 4
        assert body["pairs"] == res.pairs.size == 4753
        assert body["layouts"] == {"2": 6, "3": 4, "4": 1}
        assert body["methods"] == {"2": "exhaustive", "3": "exhaustive", "4": "exhaustive"}
        assert [c["position"] for c in body["candidates"]] == [
            c["position"] for c in res.to_json()["candidates"]
        ]
        assert body["rx_map"]["total"] == 98 and body["rx_map"]["stride"] == 1
        assert body["rx_map"]["points"] == res.rx_map.points.tolist()

    def test_bad_field_is_422_with_its_path(self, tmp_path: Path) -> None:
        doc = small_plan_doc(ris={"rows": 0, "cols": 10})
        with api_client(tmp_path, workers=1) as client:
            r = client.post("/v1/plans/validate", json=doc)
            assert r.status_code == 422
            fields = r.json()["fields"]
            assert [f["field"] for f in fields] == ["ris.rows"]
            assert "greater than or equal to 1" in fields[0]["message"]
            # the same document is refused by job submission with the same field
            sub = client.post("/v1/plans", json=doc)
            assert sub.status_code == 422 and sub.json()["fields"] == fields

    def test_engine_checks_before_work(self, tmp_path: Path) -> None:
        """What a job would fail on at its start is answered now: too many RISs for the sites
        (422) and more pairs than max_pairs (413)."""
        with api_client(tmp_path, workers=1) as client:
            r = client.post("/v1/plans/validate", json=small_plan_doc(ris_count=[7]))
            assert r.status_code == 422
            body = r.json()
            assert body["message"] == "ris_count: ris_count 7 exceeds the 5 candidate sites"
            assert [f["field"] for f in body["fields"]] == ["ris_count"]
            big = small_plan_doc(pairs="all", max_pairs=100)
            r = client.post("/v1/plans/validate", json=big)
            assert r.status_code == 413 and "max_pairs" in r.json()["message"]
            assert client.get("/v1/jobs").json()["total"] == 0

    def test_preview_lists_only_the_points_the_plan_keeps(self, tmp_path: Path) -> None:
        """UE map points inside a building are dropped by the plan: the preview lists the
        points it keeps (the page draws those) and counts the dropped ones per map."""
        grid = {"grid": {"x": [-4, 4, 1], "y": [-4, 4, 1], "z": [1, 1, 1]}}
        box = {
            "kind": "prism",
            "name": "box",
            "footprint": [[-1.5, -1.5], [1.5, -1.5], [1.5, 1.5], [-1.5, 1.5]],
            "base_m": 0,
            "height_m": 3,
        }
        doc = small_plan_doc(
            tx_map=grid, rx_map=grid, environment={"obstacles": [box]}, ris_count=[2]
        )
        with api_client(tmp_path, workers=1) as client:
            body = client.post("/v1/plans/validate", json=doc).json()
        inside = 9  # x, y in −1 … 1: more than 1 cm inside the 3 m × 3 m box
        assert body["dropped"] == {"tx": inside, "rx": inside}
        assert body["rx_map"]["total"] == 81 - inside == len(body["rx_map"]["points"])
        assert all(max(abs(p[0]), abs(p[1])) > 1.5 for p in body["rx_map"]["points"])
        res = run_plan(doc, executor=SerialExecutor())
        assert body["rx_map"]["points"] == res.rx_map.points.tolist()

    def test_large_map_preview_is_strided(self, tmp_path: Path) -> None:
        grid = {"grid": {"x": [0, 99, 1], "y": [0, 99, 1], "z": [0, 0, 1]}}
        doc = small_plan_doc(tx_map=grid, rx_map=grid, pairs={"sample": 100, "seed": 0})
        with api_client(tmp_path, workers=1) as client:
            body = client.post("/v1/plans/validate", json=doc).json()
        assert body["rx_map"]["total"] == 10_000 and body["rx_map"]["stride"] == 2
        assert len(body["rx_map"]["points"]) == 5000
        assert body["rx_map"]["points"][1] == [0.0, 2.0, 0.0]


class TestJobEvents:
    def test_stream_reports_every_change_and_ends(self, tmp_path: Path) -> None:
        with api_client(tmp_path, kinds=TEST_KINDS, workers=1) as client:
            app: Any = client.app
            job = app.state.store.create("count", {"steps": 4, "sleep_s": 0.3})
            app.state.runner.submit(job.id)
            with client.stream("GET", f"/v1/jobs/{job.id}/events") as r:
                assert r.status_code == 200
                assert r.headers["content-type"].startswith("text/event-stream")
                text = "".join(r.iter_text())
        events = parse_sse(text)
        names = [n for n, _ in events]
        assert names[-1] == "end" and set(names[:-1]) == {"progress"}
        assert events[-1][1]["status"] == "succeeded" and events[-1][1]["progress"] == 1.0
        progress = [d["progress"] for _, d in events]
        assert progress == sorted(progress)
        states = [(d["status"], d["progress"], d["message"]) for _, d in events]
        assert len(set(states)) == len(states)  # an event only when something changed
        assert text.startswith("retry: ")

    def test_ended_job_gives_one_end_event_and_unknown_job_404(self, tmp_path: Path) -> None:
        with api_client(tmp_path, kinds=TEST_KINDS, workers=1) as client:
            app: Any = client.app
            job = app.state.store.create("count", {"steps": 1})
            app.state.store.cancel(job.id)
            r = client.get(f"/v1/jobs/{job.id}/events")
            assert r.status_code == 200
            events = parse_sse(r.text)
            assert [(n, d["status"]) for n, d in events] == [("end", "cancelled")]
            missing = client.get(f"/v1/jobs/{'0' * 32}/events")
            assert missing.status_code == 404 and missing.json()["error"] == "not_found"

    def test_generator_checks_at_its_interval(self, tmp_path: Path) -> None:
        """Without changes the stream only reads the store every check interval: over 0.5 s at
        0.1 s a running job is read ≈ 5 times and yields a single event."""
        import anyio

        from api.store import JobStore

        store = JobStore(tmp_path / "j.db")
        job = store.create("count", {})
        store.start(job.id)
        reads = 0
        head = store.head

        def counting_head(job_id: str) -> Any:
            nonlocal reads
            reads += 1
            return head(job_id)

        store.head = counting_head  # type: ignore[method-assign]
        got: list[str] = []

        async def run() -> None:
            with anyio.move_on_after(0.5):
                async for chunk in job_events(store, job.id, check_s=0.1):
                    got.append(chunk)

        anyio.run(run)
        assert 3 <= reads <= 7
        assert sum(c.startswith("id:") for c in got) == 1

    def test_stream_closes_when_uvicorn_is_stopping(self, tmp_path: Path) -> None:
        """uvicorn waits for open responses before it stops: a stream must end once the
        server's signal handler (``Server.handle_exit``) has set ``should_exit``."""
        import signal

        import anyio

        from api.store import JobStore

        class FakeServer:
            should_exit = False

            def handle_exit(self, sig: int, frame: Any) -> None:
                self.should_exit = True

        store = JobStore(tmp_path / "j.db")
        job = store.create("count", {})
        store.start(job.id)
        fake = FakeServer()
        previous = signal.signal(signal.SIGINT, fake.handle_exit)
        chunks: list[str] = []

        async def run() -> bool:
            with anyio.move_on_after(5.0) as scope:
                async for chunk in job_events(store, job.id, check_s=0.05):
                    chunks.append(chunk)
                    if len(chunks) == 2:  # retry + the first event: now ask the server to stop
                        fake.handle_exit(signal.SIGINT, None)
            return not scope.cancelled_caught

        try:
            assert anyio.run(run)  # the generator returned by itself, well before 5 s
        finally:
            signal.signal(signal.SIGINT, previous)
        assert len(chunks) == 2
