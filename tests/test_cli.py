"""The ``ris-planner`` command line: bounds, schema, input errors without tracebacks."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from waits import HANG_S

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_bounds_preset_matches_python_api(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "bounds", "--preset", "paper-table1")
    assert code == 0
    got = json.loads(out)
    ref = compute_bounds(load_scenario("paper-table1"))
    assert got["peb_rx_m"] == ref.peb_rx[0]
    assert {"peb_tx_m", "peb_rx_m", "ceb_m", "channel", "far_field"} <= set(got)
    assert [c["path"] for c in got["channel"]] == ["los", "ris1", "ris2"]


def test_bounds_file_batch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = preset_document("2-ris-L") | {
        "tx": [[-2, -4, 0], [0, 0, 0]],
        "rx": [[2, 3, 0], [1, 1, 0.5]],
    }
    f = tmp_path / "s.json"
    f.write_text(json.dumps(doc))
    code, out, _ = run(capsys, "bounds", str(f))
    assert code == 0
    got = json.loads(out)
    assert len(got["peb_rx_m"]) == 2 and len(got["far_field"]) == 2


def test_invalid_document_names_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = preset_document("paper-table1")
    doc["ris"][1]["position"] = [4, 0, "up"]
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(doc))
    code, out, err = run(capsys, "bounds", str(f))
    assert code == 2 and out == ""
    assert "ris.1.position.2" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("content", "message"),
    [("{not json", "not valid JSON"), ("[1, 2]", "JSON object")],
)
def test_unreadable_documents(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, message: str
) -> None:
    f = tmp_path / "x.json"
    f.write_text(content)
    code, _, err = run(capsys, "bounds", str(f))
    assert code == 2 and message in err


def test_missing_file_and_no_source(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "bounds", "/nonexistent/file.json")
    assert code == 2 and "No such file" in err
    code, _, err = run(capsys, "bounds")
    assert code == 2 and "exactly one of FILE or --preset" in err


def test_schema(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "schema")
    schema = json.loads(out)
    assert code == 0 and "ris" in schema["properties"] and "system" in schema["properties"]


def test_plan_from_stdin_and_unusable_output_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import io

    from ris_planner.planning import plan_preset

    doc = json.dumps(plan_preset("fig10-anchors") | {"ris_count": [4]})
    blocker = tmp_path / "taken"
    blocker.write_text("a file where the output folder should go")
    monkeypatch.setattr("sys.stdin", io.StringIO(doc))
    code, _, err = run(capsys, "plan", "-", "--out", str(blocker), "--workers", "1")
    assert code == 2 and "File exists" in err and "Traceback" not in err
    monkeypatch.setattr("sys.stdin", io.StringIO(doc))
    code, out, _ = run(capsys, "plan", "-", "--out", str(tmp_path / "ok"), "--workers", "1")
    assert code == 0 and "4 RIS: " in out
    assert "sites A1 (-4,0) [0], A2 (0,4) [1], A3 (4,0) [2], A4 (0,-4) [3]" in out
    assert json.loads((tmp_path / "ok" / "plan.json").read_text())["layouts"][0]["sites"] == [
        0,
        1,
        2,
        3,
    ]


LAZY_PROBE = """
import sys
from ris_planner.cli import app as cli
assert cli.main(["bounds", "--preset", "paper-table1"]) == 0
loaded = [m for m in ("ris_planner.planning", "ris_planner.power", "ris_planner.estimation",
                      "ris_planner.cli.geo", "api", "scipy.spatial") if m in sys.modules]
print("LOADED", loaded, file=sys.stderr)
"""


def test_a_command_loads_only_its_own_feature() -> None:
    """``ris-planner bounds`` builds the parser of its own subcommand only: the planner, the
    power and estimation features, the importers and the service are never imported (the
    whole parser, for --help, has them all: test_help_lists_every_command)."""
    out = subprocess.run(
        [sys.executable, "-c", LAZY_PROBE], capture_output=True, text=True, timeout=HANG_S
    )
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip().splitlines()[-1] == "LOADED []"


def test_help_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    from ris_planner.cli.app import REGISTRARS

    code, out, _ = run(capsys, "--help")
    assert code == 0
    for names in REGISTRARS.values():
        for name in names:
            assert name in out
    # the table names exactly what each feature registers (a run builds only its own)
    import argparse

    from ris_planner.cli.app import _registrar

    for path, names in REGISTRARS.items():
        parser = argparse.ArgumentParser()
        sub = parser.add_subparsers()
        _registrar(path)(sub)
        assert tuple(sub.choices) == names, path


def test_plan_process_exits_fast_with_its_status_and_output(tmp_path: Path) -> None:
    """``python -m ris_planner.cli plan`` ends without the interpreter's teardown
    (``app.FAST_EXIT``): its files are written, stdout and stderr arrive in full (flushed
    before the exit), and the status is the command's – 0 for a plan, 2 for bad input."""
    doc = tmp_path / "plan.json"
    ring = [
        {"position": [6 * math.cos(a), 6 * math.sin(a), 2.0], "orientation": [a + math.pi, 0.3, 0]}
        for a in (2 * math.pi * k / 5 for k in range(5))
    ]
    grid = {"grid": {"x": [-3, 3, 1.5], "y": [-3, 3, 1.5], "z": [0, 0, 1]}}
    doc.write_text(
        json.dumps(
            {
                "ris": {"rows": 6, "cols": 6},
                "candidates": ring,
                "tx_map": grid,
                "rx_map": grid,
                "pairs": {"sample": 60, "seed": 1},
                "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
                "ris_count": [2],
            }
        )
    )
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ris_planner.cli", "plan", str(doc), "--out", str(out)]
    ok = subprocess.run(cmd, capture_output=True, text=True, timeout=HANG_S, check=False)
    assert ok.returncode == 0, ok.stderr[-2000:]
    assert "2 RIS: " in ok.stdout  # the summary, flushed before the fast exit
    assert f"wrote {out / 'plan.json'}" in ok.stderr
    assert json.loads((out / "plan.json").read_text())["by_count"][0]["ris_count"] == 2
    bad = subprocess.run(
        [*cmd[:4], str(tmp_path / "missing.json"), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        check=False,
    )
    assert bad.returncode == 2 and bad.stderr.startswith("error:")


def test_readable_json_is_the_json_modules_document_one_member_per_line() -> None:
    """core.io_json.readable_json: the same value as json.dumps (keys of every kind, empty
    containers, nesting below the broken levels), strict (NaN refused), the outer levels one
    member per line."""
    import json

    from ris_planner.core.io_json import readable_json

    value = {"a": [1, 2.5, {"x": [1, None]}], "b": {"c": {"d": "é"}}, "e": [], "f": {}, 3: True}
    text = readable_json(value)
    assert json.loads(text) == json.loads(json.dumps(value))
    assert text.splitlines()[:3] == ["{", ' "a": [', "  1,"]
    assert '{"x": [1, null]}' in text  # level 2: one line
    for key in (1, 1.5, True, None):
        assert json.loads(readable_json({key: 0})) == json.loads(json.dumps({key: 0}))
    with pytest.raises(ValueError):
        readable_json({"x": float("nan")})


def test_plan_names_where_a_long_candidate_list_is_not_the_names() -> None:
    """A cause that counts 143 blocked candidates: the command line says where plan.json lists
    them (one line), never the 143 names."""
    from ris_planner.cli.plan import listed_lines

    entries = [
        {"index": i, "name": f"B{i}-f0-0-h4", "reason": "no_visible_point"} for i in range(143)
    ]
    diagnosis = {
        "verdict": "weak",
        "causes": [
            {"kind": "geometry", "message": "too few paths"},
            {
                "kind": "blocked",
                "message": "143 of 200 candidates serve no pair",
                "candidates": entries,
            },
        ],
    }
    (line,) = listed_lines(diagnosis, Path("out/plan.json"))
    assert "143 candidates of 'blocked'" in line
    assert "out/plan.json → diagnosis.causes[1].candidates" in line
    assert "B0-f0-0-h4" not in line
    assert listed_lines({**diagnosis, "verdict": "ok"}, Path("plan.json")) == []
