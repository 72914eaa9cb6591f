"""The ``ris-planner`` command line (batch scripts): the same JSON documents as the API.

Every subcommand lives in the module that owns its feature and registers itself through an
``add_cli(subparsers)`` function; this module only wires them and turns input errors into a
one-line message and exit status 2 (no traceback).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ris_planner.errors import RisPlannerError
from ris_planner.scenario import PRESET_NAMES, Scenario, load_scenario

EXIT_INPUT_ERROR = 2


def validation_problems(exc: ValidationError) -> list[str]:
    """One ``field.path: message`` per problem (``ris.1.position: ...``)."""
    return [
        f"{'.'.join(str(p) for p in err['loc']) or '(document)'}: {err['msg']}"
        for err in exc.errors()
    ]


def format_validation_error(exc: ValidationError) -> str:
    """One line per problem, naming the field path."""
    return "invalid document:\n  " + "\n  ".join(validation_problems(exc))


def add_document_arguments(parser: argparse.ArgumentParser) -> None:
    """``FILE`` or ``--preset NAME``, shared by commands that read a scenario document."""
    parser.add_argument("file", nargs="?", help="scenario JSON document ('-' for stdin)")
    parser.add_argument("--preset", choices=PRESET_NAMES, help="use a shipped preset instead")


def read_json_object(path: str | Path) -> dict[str, Any]:
    """A JSON object from a file (``-`` = stdin), with input errors as :class:`RisPlannerError`."""
    text = sys.stdin.read() if str(path) == "-" else Path(path).read_text()
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RisPlannerError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise RisPlannerError(f"{path}: the document must be a JSON object")
    return doc


def read_document(args: argparse.Namespace) -> dict[str, Any]:
    """The raw JSON document named by ``FILE`` / ``--preset`` (exactly one of them)."""
    from ris_planner.scenario import preset_document

    if (args.file is None) == (args.preset is None):
        raise RisPlannerError("give exactly one of FILE or --preset NAME")
    if args.preset is not None:
        return preset_document(args.preset)
    return read_json_object(args.file)


def read_scenario(args: argparse.Namespace) -> Scenario:
    """The scenario of ``FILE`` / ``--preset``; a document with a geographic ``frame`` is
    converted to local metres first (:func:`ris_planner.io.frames.to_local`)."""
    doc = read_document(args)
    if "frame" in doc:
        from ris_planner.io.frames import to_local

        doc = to_local(doc)[0]
    return load_scenario(doc)


def print_json(obj: Any) -> None:
    json.dump(obj, sys.stdout, indent=2, allow_nan=False)
    sys.stdout.write("\n")


def _cmd_bounds(args: argparse.Namespace) -> int:
    from ris_planner.bounds import compute_bounds

    scenario = read_scenario(args)
    result = compute_bounds(scenario)
    print_json(result.to_json(batch=scenario.is_batch))
    return 0


def _cmd_schema(args: argparse.Namespace) -> int:
    print_json(Scenario.model_json_schema())
    return 0


def _add_core(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bounds", help="PEB_T, PEB_R, CEB and channel bounds of a scenario")
    add_document_arguments(p)
    p.set_defaults(func=_cmd_bounds)
    p = sub.add_parser("schema", help="print the JSON schema of the scenario document")
    p.set_defaults(func=_cmd_schema)


def _registrars() -> list[Callable[[argparse._SubParsersAction], None]]:
    """Every feature's ``add_cli``: one line per feature (imported here, not at module load)."""
    from api.cli import add_cli as api_cli
    from ris_planner.estimation.cli import add_cli as estimation_cli
    from ris_planner.io.cli import add_cli as import_cli
    from ris_planner.planning.cli import add_cli as plan_cli
    from ris_planner.power.cli import add_cli as power_cli

    return [_add_core, power_cli, plan_cli, estimation_cli, import_cli, api_cli]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ris-planner",
        description="RIS deployment planning for sidelink positioning (CRB/PEB engine).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for register in _registrars():
        register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status: int = args.func(args)
    except ValidationError as exc:
        print(format_validation_error(exc), file=sys.stderr)
        return EXIT_INPUT_ERROR
    except BrokenPipeError:  # output piped into `head` and closed early (before OSError)
        return 0
    except (RisPlannerError, ValueError, OSError) as exc:  # bad input, unusable path
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
