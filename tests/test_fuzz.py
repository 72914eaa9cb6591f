"""Bounded fuzzing of every entry point: random JSON values as documents (CLI commands and
POST routes) and random argument lists (CLI). Whatever arrives, a CLI command ends with exit 0
or 2 and no traceback, a route with a JSON answer below 500 (hypothesis, ≤ 60 examples each).
"""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path
from typing import Any

import pytest
from api_helpers import api_client
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from waits import HANG_S

from ris_planner import preset_document
from ris_planner.cli import main

FUZZ = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=list(HealthCheck),
    derandomize=True,  # the same examples on every run (the benchmarks/ script explores)
)

SCALARS = (
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.sampled_from([0, -1, 1e308, -1e308, 1e-320, 2**63, "", "NaN", "inf"])
    | st.text(max_size=8)
)
JSON = st.recursive(
    SCALARS,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=12,
)
KEYS = ["system", "ris", "tx", "rx", "codebook", "known", "environment", "transmissions"]


@st.composite
def mutated_scenario(draw: st.DrawFn) -> dict[str, Any]:
    """The Table I preset with one top-level field (or a field of ``system``) replaced."""
    doc = preset_document("paper-table1")
    key = draw(st.sampled_from(KEYS))
    value = draw(JSON)
    if key == "transmissions":
        doc["system"] = dict(doc["system"]) | {key: value}
    else:
        doc[key] = value
    return doc


def run_cli(argv: list[str], stdin: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    old = sys.stdin
    sys.stdin = io.TextIOWrapper(io.BytesIO(stdin.encode("utf-8")))
    try:
        code = main(argv)
    finally:
        sys.stdin = old
    return code, capsys.readouterr().err


def assert_clean(code: int, err: str) -> None:
    assert code in (0, 2), err
    assert "Traceback" not in err and 'File "' not in err, err
    if code == 2:
        assert err.strip(), "an input error says why"


COMMANDS = ["bounds", "power", "plan", "simulate", "blind-area"]


@FUZZ
@given(command=st.sampled_from(COMMANDS), value=JSON)
def test_cli_any_json_document(
    command: str, value: Any, capsys: pytest.CaptureFixture[str], tmp_path_factory: Any
) -> None:
    code, err = run_cli([command, "-"], json.dumps(value), capsys)
    assert_clean(code, err)
    assert code == 2  # no random JSON value is a valid document of these commands


@FUZZ
@given(doc=mutated_scenario())
def test_cli_mutated_scenario(doc: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> None:
    code, err = run_cli(["bounds", "-"], json.dumps(doc), capsys)
    assert_clean(code, err)


TOKENS = [
    "--step",
    "--runs",
    "--seed",
    "--minima",
    "--powers-dbm",
    "--noise-figure-db",
    "--extent",
    "--rx",
    "--tx",
    "--objective",
    "--solver",
    "--workers",
    "--sigma",
    "--preset",
    "--out",
    "inf",
    "-inf",
    "nan",
    "1e309",
    "-1",
    "0",
    "99999",
    "1,2",
    "x",
    "",
    "paper-table1",
]


@FUZZ
@given(
    command=st.sampled_from([*COMMANDS, "schema", "serve", "nope"]),
    tokens=st.lists(st.sampled_from(TOKENS), max_size=5),
)
def test_cli_any_arguments(
    command: str, tokens: list[str], capsys: pytest.CaptureFixture[str], tmp_path_factory: Any
) -> None:
    bad = tmp_path_factory.getbasetemp() / "fuzz-bad.json"
    bad.write_text("[1")
    if command == "serve":  # never start a server: an invalid port makes every list fail
        tokens = [*tokens, "--port", "99999"]
    code, err = run_cli([command, *tokens, str(bad)], "", capsys)
    if command == "schema" and code == 0:
        return
    assert_clean(code, err)


def test_cli_entry_points_named_in_the_issue(capsys: pytest.CaptureFixture[str]) -> None:
    for argv, stdin in [
        (["simulate", "-"], '{"scenario": 5}'),
        (["blind-area", "--preset", "paper-table1", "--step", "inf"], ""),
        (["serve", "--port", "99999"], ""),
        (["bounds", "-"], "[" * 100_000 + "]" * 100_000),
    ]:
        code, err = run_cli(argv, stdin, capsys)
        assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) <= 8, err


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Any:
    with api_client(tmp_path_factory.mktemp("fuzz"), workers=1) as c:
        yield c


@FUZZ
@given(path=st.sampled_from(["/v1/bounds", "/v1/plans", "/v1/power-allocations"]), value=JSON)
def test_routes_any_json_body(client: Any, path: str, value: Any) -> None:
    r = client.post(path, content=json.dumps(value), headers={"content-type": "application/json"})
    assert r.status_code in (400, 413, 422), r.text
    body = r.json()
    assert body["status"] == r.status_code and body["message"]
    if r.status_code == 422:
        assert body["fields"] and all(f["field"] for f in body["fields"])


@FUZZ
@given(doc=mutated_scenario())
def test_route_mutated_scenario(client: Any, doc: dict[str, Any]) -> None:
    r = client.post("/v1/bounds", json=doc)
    assert r.status_code in (200, 413, 422), r.text
    if r.status_code == 422:
        assert r.json()["fields"]


def test_closed_stdin_and_stdout(tmp_path: Path) -> None:
    """Closed standard streams: one message, exit 2 (a real process, the streams really shut)."""
    import subprocess

    for redirect, text in [("<&-", "standard input is closed"), (">&-", "standard output")]:
        argv = "bounds -" if redirect == "<&-" else "bounds --preset paper-table1"
        cmd = f"{sys.executable} -m ris_planner.cli {argv} {redirect}"
        out = subprocess.run(cmd, shell=True, capture_output=True, text=True, timeout=HANG_S)
        assert out.returncode == 2 and text in out.stderr and "Traceback" not in out.stderr
