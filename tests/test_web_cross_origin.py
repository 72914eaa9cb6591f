"""A page of another origin attacks the keyless local server, in a real headless Chromium
(the fixtures of ``test_web``): it auto-submits a ``text/plain`` form whose body is a plan
document, and sends the same with ``fetch()`` in ``no-cors`` mode (a text body, and a Blob
without a type) – requests a browser sends without asking the server first. None of them
queues a job. The attacking page is served by a small HTTP server on another loopback port of
the test process (another origin), stopped when the test ends."""

# ruff: noqa: F811  (the fixtures of test_web, imported by name, are the tests' parameters)
from __future__ import annotations

import html
import json
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import httpx
import pytest
from test_api_plans import small_plan_doc
from test_web import (  # noqa: F401  (fixtures: browser, page, server)
    WAIT_MS,
    Console,
    Page,
    browser,
    page,
    server,
)
from waits import HANG_S


def attack_page(target: str) -> str:
    """A page that posts a plan to ``target`` three ways: the form (auto-submitted last, it
    navigates away) and two no-cors fetches."""
    doc = json.dumps(small_plan_doc(description="x"))
    # a text/plain form sends "name=value\r\n": the name is the document up to the opening quote
    # of its last string, the value its closing quote and brace – together, the document
    cut = doc.rindex('"x"') + 1
    name, value = doc[:cut], doc[cut + 1 :]
    return f"""<!doctype html><html><body>
<form id="f" method="POST" action="{target}/v1/plans" enctype="text/plain">
<input type="hidden" name="{html.escape(name)}" value="{html.escape(value)}"></form>
<script>
window.attack = async () => {{
  const body = {json.dumps(doc)};
  await fetch("{target}/v1/plans", {{method: "POST", mode: "no-cors", body}}).catch(() => null);
  await fetch("{target}/v1/plans", {{method: "POST", mode: "no-cors", body: new Blob([body])}})
    .catch(() => null);
  document.getElementById("f").submit();
}};
</script></body></html>"""


@pytest.fixture
def attacker(server: str) -> Iterator[str]:
    """The attacking page on another origin (127.0.0.1, another port)."""
    text = attack_page(server).encode()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(text)))
            self.end_headers()
            self.wfile.write(text)

        def log_message(self, format: str, *args: object) -> None:
            pass

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}"
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join(10)


def test_a_cross_origin_page_queues_no_job(
    page: tuple[Page, Console], server: str, attacker: str
) -> None:
    pg, console = page
    console.allow(r"status of 4(03|15)")  # the browser logs the refusals it receives
    before = httpx.get(f"{server}/v1/jobs", timeout=HANG_S).json()["total"]
    pg.goto(attacker + "/")
    with pg.expect_response(
        lambda r: (
            r.url == f"{server}/v1/plans"
            and r.request.method == "POST"
            and r.request.resource_type == "document"
        ),
        timeout=WAIT_MS,
    ) as sent:
        pg.evaluate("window.attack()")
    assert sent.value.status in (403, 415), sent.value.status
    assert httpx.get(f"{server}/v1/jobs", timeout=HANG_S).json()["total"] == before
