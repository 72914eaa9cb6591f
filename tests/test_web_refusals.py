"""The planner page with a plan too large for the server's memory budget, in headless Chromium
against a real uvicorn on 127.0.0.1 (the fixtures of ``test_web``): the factory hall with
512 × 512 RISs (the schema's largest), given as an uploaded file or typed into the form's RIS
size, is refused before any job with the server's 413 message (the codebook checks and the
largest RIS that fits), never as an internal problem, and nothing is queued."""

# ruff: noqa: F811  (the fixtures of test_web, imported by name, are the tests' parameters)
from __future__ import annotations

import json
import re

import httpx
from test_memory_refusals import big_ris_doc
from test_web import (  # noqa: F401  (fixtures: browser, page, server, shots)
    WAIT_MS,
    Console,
    Page,
    Shots,
    browser,
    expect,
    load_preset,
    open_page,
    page,
    server,
    shots,
)
from waits import HANG_S

REFUSAL = re.compile(r"dominated by the codebook checks \(512 × 512 elements per RIS")
FITS = re.compile(r"the largest RIS that fits is (\d+) × \1")


def _refused_without_a_job(pg: Page, server: str) -> None:
    """The page lists the server's refusal in full and says the job was not submitted."""
    other = pg.locator("#other-errors")
    expect(other).to_contain_text("Too large for this server:", timeout=WAIT_MS)
    expect(other).to_contain_text(REFUSAL)
    expect(other).to_contain_text(FITS)
    side = int(FITS.search(other.inner_text()).group(1))  # type: ignore[union-attr]
    assert 1 <= side < 512
    status = pg.locator("#validation-status")
    expect(status).to_contain_text("Not submitted: the run needs an estimated", timeout=WAIT_MS)
    expect(status).to_contain_text("codebook checks")
    body = pg.locator("body").inner_text()
    assert "internal problem" not in body and "Traceback" not in body, body
    assert pg.evaluate("window.risPlanner.state.job") is None
    assert httpx.get(f"{server}/v1/jobs", timeout=HANG_S).json()["total"] == 0  # nothing was queued


def test_an_uploaded_plan_too_large_is_refused_with_the_ris_that_fits(
    page: tuple[Page, Console], server: str, shots: Shots
) -> None:
    pg, console = page
    console.allow(r"status of 413")  # the browser logs each 413 answer it receives
    open_page(pg, server)
    pg.set_input_files(
        "#upload",
        files={
            "name": "hall-512.json",
            "mimeType": "application/json",
            "buffer": json.dumps(big_ris_doc()).encode(),
        },
    )
    expect(pg.locator("#doc-name")).to_contain_text("hall-512.json")
    # the validation after the upload shows the refusal already
    expect(pg.locator("#other-errors")).to_contain_text(REFUSAL, timeout=WAIT_MS)
    assert pg.input_value("#f-ris-rows") == "512" and pg.input_value("#f-ris-cols") == "512"
    pg.click("#submit")
    _refused_without_a_job(pg, server)
    shots.take(pg, "13-too-large", full_page=False)


def test_a_ris_size_typed_in_the_form_is_refused_the_same_way(
    page: tuple[Page, Console], server: str
) -> None:
    pg, console = page
    console.allow(r"status of 413")
    open_page(pg, server)
    load_preset(pg, "hall")
    pg.fill("#f-ris-rows", "512")
    pg.fill("#f-ris-cols", "512")
    pg.click("#submit")
    _refused_without_a_job(pg, server)
