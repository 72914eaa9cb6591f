"""The ``ris-planner`` command line (batch scripts): the same JSON documents as the API.

Every subcommand lives in the module that owns its feature and registers itself through an
``add_cli(subparsers)`` function; this module only wires them and turns input errors into a
one-line message and exit status 2 (no traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import math
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from pydantic import ValidationError

from ris_planner.core.errors import RisPlannerError
from ris_planner.core.io_json import (
    format_validation_error,
    read_json_object,
    readable_json,
    validation_problems,
)
from ris_planner.model.scenario import PRESET_NAMES, Scenario, load_scenario

EXIT_INPUT_ERROR = 2

__all__ = [
    "EXIT_INPUT_ERROR",
    "finite_float",
    "format_validation_error",
    "main",
    "read_json_object",
    "validation_problems",
]


def finite_float(text: str) -> float:
    """argparse type: a finite number (``inf``/``nan`` refused with a message)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def positive_finite_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = finite_float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def int_in(low: int, high: int) -> Callable[[str], int]:
    """argparse type: an integer within [low, high]."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected an integer in [{low}, {high}], got {value}")
        return value

    parse.__name__ = f"integer in [{low}, {high}]"
    return parse


def add_document_arguments(parser: argparse.ArgumentParser) -> None:
    """``FILE`` or ``--preset NAME``, shared by commands that read a scenario document."""
    parser.add_argument("file", nargs="?", help="scenario JSON document ('-' for stdin)")
    parser.add_argument("--preset", choices=PRESET_NAMES, help="use a shipped preset instead")


def read_document(args: argparse.Namespace) -> dict[str, Any]:
    """The raw JSON document named by ``FILE`` / ``--preset`` (exactly one of them)."""
    from ris_planner.model.scenario import preset_document

    if (args.file is None) == (args.preset is None):
        raise RisPlannerError("give exactly one of FILE or --preset NAME")
    if args.preset is not None:
        return preset_document(args.preset)
    return read_json_object(args.file)


def read_scenario(args: argparse.Namespace) -> Scenario:
    """The scenario of ``FILE`` / ``--preset``; a document with a geographic ``frame`` is
    converted to local metres first (:func:`ris_planner.io.frames.to_local`)."""
    from ris_planner.io.frames import to_local

    return load_scenario(to_local(read_document(args))[0])


def print_json(obj: Any) -> None:
    """The result document on stdout (serialised first, so a failure prints nothing)."""
    text = readable_json(obj, indent=2)
    if sys.stdout is None or sys.stdout.closed:
        raise RisPlannerError("standard output is closed")
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _cmd_bounds(args: argparse.Namespace) -> int:
    from ris_planner.bounds.compute import bounds_document

    print_json(bounds_document(read_scenario(args)))
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


def _cmd_serve(args: argparse.Namespace) -> int:
    # the web service is loaded only when this command runs: the package never imports it
    serve: Callable[[argparse.Namespace], int] = importlib.import_module("api.cli").run_serve
    return serve(args)


def _add_serve(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve",
        help="run the REST service (settings from RIS_PLANNER_* environment variables)",
    )
    p.add_argument("--host", default="127.0.0.1", help="interface to listen on (default 127.0.0.1)")
    p.add_argument("--port", type=int_in(1, 65535), default=8000, help="TCP port (default 8000)")
    p.add_argument("--db", help="SQLite job database (overrides RIS_PLANNER_DB)")
    p.add_argument(
        "--workers",
        type=int_in(1, 64),
        help="job worker processes, 1–64 (overrides RIS_PLANNER_WORKERS)",
    )
    p.add_argument(
        "--log-level", default="info", choices=["critical", "error", "warning", "info", "debug"]
    )
    p.set_defaults(func=_cmd_serve)


REGISTRARS: dict[str, tuple[str, ...]] = {
    "ris_planner.cli.app:_add_core": ("bounds", "schema"),
    "ris_planner.cli.power:add_cli": ("power",),
    "ris_planner.cli.plan:add_cli": ("plan",),
    "ris_planner.cli.city:add_cli": ("city",),
    "ris_planner.cli.estimate:add_cli": ("simulate", "blind-area"),
    "ris_planner.cli.geo:add_cli": ("import", "sites"),
    "ris_planner.cli.app:_add_serve": ("serve",),
    "ris_planner.cli.warmup:add_cli": ("warmup",),
}
"""Every feature's ``add_cli`` ("module:function") and the subcommands it registers, in help
order. A run imports only the module of its own subcommand (``ris-planner bounds`` never loads
the planner); ``--help``, a usage error or an unknown command builds the whole parser."""


def _registrar(path: str) -> Callable[[argparse._SubParsersAction], None]:
    module, name = path.split(":")
    registrar: Callable[[argparse._SubParsersAction], None] = getattr(
        importlib.import_module(module), name
    )
    return registrar


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser with every subcommand, or only ``command``'s feature when it names one."""
    parser = argparse.ArgumentParser(
        prog="ris-planner",
        description="RIS deployment planning for sidelink positioning (CRB/PEB engine).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    wanted = [path for path, names in REGISTRARS.items() if command in names]
    for path in wanted or REGISTRARS:
        _registrar(path)(sub)
    return parser


def _command(argv: Sequence[str]) -> str | None:
    """The subcommand named by the first argument, when it is one (else None: full parser)."""
    first = argv[0] if argv else None
    known = {name for names in REGISTRARS.values() for name in names}
    return first if first in known else None


def _say(message: str) -> None:
    """One line on stderr (nothing when stderr itself is closed)."""
    stream = sys.stderr
    if stream is not None and not stream.closed:
        with contextlib.suppress(OSError, ValueError):
            print(message, file=stream)


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; every input error ends with one line on stderr and exit status 2."""
    from ris_planner.runtime import allocator

    allocator.tune_malloc()  # an entry point: the library itself never changes the process
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_command(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, argparse printed one line)
        return int(exc.code) if isinstance(exc.code, int) else EXIT_INPUT_ERROR
    try:
        status: int = args.func(args)
    except ValidationError as exc:
        _say(format_validation_error(exc))
        return EXIT_INPUT_ERROR
    except BrokenPipeError:  # output piped into `head` and closed early (before OSError)
        return 0
    except RecursionError:
        _say("error: the document is nested too deeply")
        return EXIT_INPUT_ERROR
    except MemoryError:
        _say("error: out of memory; the input needs more memory than this process may use")
        return EXIT_INPUT_ERROR
    except (RisPlannerError, ValueError, OSError) as exc:  # bad input, unusable path
        _say(f"error: {exc}")
        return EXIT_INPUT_ERROR
    except KeyboardInterrupt:
        _say("interrupted")
        return 130
    except Exception as exc:  # a last line of defence: one message, never a traceback
        _say(f"error: cannot process this input ({type(exc).__name__}: {exc})")
        return EXIT_INPUT_ERROR
    return status


FAST_EXIT = frozenset({"plan"})
"""Subcommands whose process ends without the interpreter's teardown once their files are
written and their streams flushed (:func:`run`): freeing every module, the compiled kernels and
their thread pool took ≈ 0.5 s after a plan's last file (a city block's end-to-end time,
docs/validation/benchmarks.md). They hold no child process by then (a plan's worker pool is
closed with its executor); ``serve`` and the others exit normally."""


_AS_PROCESS = {"yes": False}


def launched_as_process() -> bool:
    """Whether this process is the command line itself (:func:`run`), not a host that calls
    :func:`main` (a test, a script): only then is the process's age the command's start-up
    (``timing_s["startup"]`` of a plan)."""
    return _AS_PROCESS["yes"]


def run() -> NoReturn:
    """The ``ris-planner`` entry point and ``python -m ris_planner.cli``: :func:`main` on
    ``sys.argv``, then the exit (:data:`FAST_EXIT`)."""
    _AS_PROCESS["yes"] = True
    status = main()
    if _command(sys.argv[1:]) in FAST_EXIT:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None and not stream.closed:
                with contextlib.suppress(OSError, ValueError):
                    stream.flush()
        os._exit(status)
    sys.exit(status)


if __name__ == "__main__":  # pragma: no cover
    run()
