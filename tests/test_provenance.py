"""Every JSON result names the package version and a hash of its input
(:mod:`ris_planner.runtime.provenance`): the same input gives the same hash through every route and
spelling, a changed input another."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from ris_planner import load_scenario, preset_document
from ris_planner.cli import main
from ris_planner.runtime.provenance import canonical_json, input_sha256, package_version, provenance


def test_hash_is_the_canonical_json_of_the_validated_document() -> None:
    doc = preset_document("paper-table1")
    sc = load_scenario(doc)
    text = canonical_json(sc)
    assert json.loads(text) == sc.model_dump(mode="json")
    assert input_sha256(sc) == hashlib.sha256(text.encode()).hexdigest()
    # key order and defaults written out do not matter; a changed number does
    reordered = dict(reversed(list(doc.items())))
    assert input_sha256(load_scenario(reordered)) == input_sha256(sc)
    moved = doc | {"tx": [-2.0, -4.0, 0.001]}
    assert input_sha256(load_scenario(moved)) != input_sha256(sc)
    assert provenance(sc) == {
        "package": "ris_planner",
        "version": package_version(),
        "input_sha256": input_sha256(sc),
    }
    assert package_version() != "unknown"  # installed (editable) as a distribution


def test_cli_results_carry_provenance(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bounds", "--preset", "paper-table1"]) == 0
    out = json.loads(capsys.readouterr().out)
    want = provenance(load_scenario(preset_document("paper-table1")))
    assert out["provenance"] == want
    doc = preset_document("paper-table1")
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc, indent=4))  # another spelling of the same document
    assert main(["bounds", str(f)]) == 0
    assert json.loads(capsys.readouterr().out)["provenance"] == want
