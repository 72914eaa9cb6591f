"""Obstacle kinds are one module each behind a registry (docs/concepts/environment.md, "Obstacle
kinds"): the document model and the visibility engine take their kinds from
``ris_planner.environment.kinds.KINDS``; an unknown kind fails loudly – in a document (a
validation error naming the known kinds, 422 over REST), on the CLI (exit 2) and in the engine
(an obstacle model that is not registered) – never silently as a wall."""

from __future__ import annotations

import json
from pathlib import Path
from typing import ClassVar, Literal

import numpy as np
import pytest
from pydantic import ValidationError
from test_api import api_client

from ris_planner import preset_document
from ris_planner.cli import main as cli_main
from ris_planner.environment.kinds import KINDS, UnknownObstacleKindError, kind_of, register
from ris_planner.environment.kinds.base import DRAW_SHAPES, ObstacleModel
from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.kinds.wall import WallObstacle
from ris_planner.environment.model import Environment
from ris_planner.environment.scene import Scene

CYLINDER = {"kind": "cylinder", "center": [0, 0], "radius_m": 1, "height_m": 3}


def test_registry_holds_the_documented_kinds_with_their_models() -> None:
    assert sorted(KINDS) == ["prism", "wall"]
    assert KINDS["prism"].model is Prism and KINDS["wall"].model is WallObstacle
    assert KINDS["prism"].solid and not KINDS["wall"].solid
    env = Environment.model_validate(
        {
            "obstacles": [
                {"kind": "wall", "start": [0, 0], "end": [1, 0], "height_m": 2},
                {"kind": "prism", "footprint": [[0, 0], [1, 0], [1, 1]], "height_m": 2},
            ]
        }
    )
    assert [kind_of(o).name for o in env.obstacles] == ["wall", "prism"]


def test_unknown_kind_in_a_document_names_the_known_kinds() -> None:
    with pytest.raises(ValidationError) as err:
        Environment.model_validate({"obstacles": [CYLINDER]})
    text = str(err.value)
    assert "unknown obstacle kind" in text and "known kinds: prism, wall" in text
    assert err.value.errors()[0]["loc"] == ("obstacles", 0)


def test_unknown_kind_over_rest_is_422_with_the_message(tmp_path: Path) -> None:
    doc = preset_document("paper-table1")
    doc["environment"] = {"obstacles": [CYLINDER]}
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["error"] == "validation_error"
    assert any(
        f["field"] == "environment.obstacles.0" and "known kinds: prism, wall" in f["message"]
        for f in body["fields"]
    ), body
    assert "Traceback" not in r.text


def test_unknown_kind_on_the_cli_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = preset_document("paper-table1")
    doc["environment"] = {"obstacles": [CYLINDER]}
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc))
    assert cli_main(["bounds", str(f)]) == 2
    err = capsys.readouterr().err
    assert "known kinds: prism, wall" in err and "Traceback" not in err


class _Cylinder(ObstacleModel):
    """A kind that is not registered (a model someone forgot to add to KINDS)."""

    kind_name: ClassVar[str] = "cylinder"
    kind: Literal["cylinder"] = "cylinder"


def test_an_unregistered_obstacle_model_fails_in_the_engine() -> None:
    wall = WallObstacle(start=[0, 0], end=[1, 0], height_m=2)
    env = Environment.model_construct(obstacles=[wall, _Cylinder(height_m=3)])
    scene = Scene(env, engine="numpy")
    with pytest.raises(
        UnknownObstacleKindError, match=r"unknown obstacle kind 'cylinder'.*prism, wall"
    ):
        scene.blocked(np.array([0.5, -1, 1]), np.array([0.5, 1, 1]))
    with pytest.raises(UnknownObstacleKindError):
        kind_of(_Cylinder(height_m=3))
    # a registered kind's name on a model that is not that kind's model is refused too
    fake = _Cylinder.model_construct(kind="wall", height_m=3)
    with pytest.raises(UnknownObstacleKindError):
        kind_of(fake)


def test_engine_groups_by_kind_and_answers_per_kind() -> None:
    """A wall and a prism in one scene: each leg is decided by its obstacle's own narrow phase."""
    env = Environment.model_validate(
        {
            "obstacles": [
                {"kind": "wall", "start": [0, -1], "end": [0, 1], "height_m": 2},
                {"kind": "prism", "footprint": [[3, -1], [5, -1], [5, 1], [3, 1]], "height_m": 2},
            ]
        }
    )
    a = np.array([[-1, 0, 1], [2, 0, 1], [2, 0, 3], [-1, 0, 1]])
    b = np.array([[1, 0, 1], [6, 0, 1], [6, 0, 3], [-1, 5, 1]])
    for engine in ("numpy", "numba"):
        got = Scene(env, engine=engine).blocked(a, b)
        assert got.tolist() == [True, True, False, False]
    assert Scene(env).inside(np.array([[4, 0, 1], [0, 0, 1]])).tolist() == [1, -1]


def test_service_lists_the_kinds_with_their_drawing(tmp_path: Path) -> None:
    """``GET /v1/obstacle-kinds``: every registered kind, whether it is solid, and the drawing
    spec the web page draws it from (docs/guides/adding-an-obstacle-kind.md)."""
    with api_client(tmp_path) as client:
        r = client.get("/v1/obstacle-kinds")
    assert r.status_code == 200, r.text
    kinds = {k["kind"]: k for k in r.json()["kinds"]}
    assert sorted(kinds) == sorted(KINDS)
    assert kinds["prism"] == {
        "kind": "prism",
        "solid": True,
        "draw": {"shape": "polygon", "points": "footprint", "label": "building"},
    }
    assert kinds["wall"]["draw"] == {
        "shape": "polyline",
        "points": ["start", "end"],
        "label": "wall",
    }


def test_every_kind_draws_with_a_known_shape_and_fields_of_its_model() -> None:
    for kind in KINDS.values():
        spec = dict(kind.draw)
        assert isinstance(spec.pop("label", ""), str)  # the legend's name of the kind, optional
        members = DRAW_SHAPES[spec.pop("shape")]
        assert sorted(spec) == sorted(members), kind.name
        for value in spec.values():
            for field in [value] if isinstance(value, str) else value:
                assert field in kind.model.model_fields, (kind.name, field)
        for path in kind.point_fields:
            assert path[0] in kind.model.model_fields, (kind.name, path)


def test_registering_twice_or_a_mismatched_model_is_refused() -> None:
    with pytest.raises(ValueError, match="registered already"):
        register(KINDS["prism"])

    class Mismatch:
        name = "other"
        model = Prism

    with pytest.raises(ValueError, match="kind_name differs"):
        register(Mismatch())  # type: ignore[arg-type]
    assert "other" not in KINDS
