"""Reading JSON documents and formatting input errors: shared by the command line, the engine's
file readers (plan presets) and the service's job workers, so none of them imports another's
front end.

Every reader turns what can go wrong with untrusted input into :class:`RisPlannerError` with one
line: not JSON, not an object, nested deeper than :data:`MAX_JSON_DEPTH` (``RecursionError``
otherwise), a closed stdin, bytes that are not UTF-8.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ris_planner.core.errors import LimitExceededError, RisPlannerError

MAX_JSON_DEPTH = 64
"""Deepest nesting of arrays/objects a document may have (the deepest real field, a list of
points inside a map inside a plan, is 5 levels); deeper input is refused before validation."""


MAX_NUMBER_DIGITS = 4300
"""Longest integer literal a document may hold (Python's own conversion limit; a real field
needs a few dozen digits): longer ones are refused with this limit (413 in the service)."""


class MalformedJsonError(RisPlannerError):
    """Text that is not a usable JSON value: not JSON, not UTF-8, nested too deeply (the
    service answers 400 on every route, the command line exit status 2)."""


def json_depth(value: Any) -> int:
    """Nesting depth of a decoded JSON value (scalars 0), without recursion."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(value, 0)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children: Any = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        depth += 1
        if depth > MAX_JSON_DEPTH:
            return depth
        deepest = max(deepest, depth)
        stack.extend((c, depth) for c in children)
    return deepest


def check_depth(value: Any, what: str = "document") -> None:
    """Raise :class:`RisPlannerError` when ``value`` nests deeper than :data:`MAX_JSON_DEPTH`."""
    if json_depth(value) > MAX_JSON_DEPTH:
        raise MalformedJsonError(f"{what}: nested deeper than {MAX_JSON_DEPTH} levels")


def parse_json(text: str | bytes, what: str = "document") -> Any:
    """A JSON value from text, nested at most :data:`MAX_JSON_DEPTH` deep; every failure a
    one-line :class:`MalformedJsonError`, an integer longer than :data:`MAX_NUMBER_DIGITS`
    digits a :class:`~ris_planner.core.errors.LimitExceededError` (never the interpreter's own
    message)."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise MalformedJsonError(f"{what}: not valid JSON ({exc})") from None
    except UnicodeDecodeError:
        raise MalformedJsonError(f"{what}: not UTF-8 text") from None
    except RecursionError:
        raise MalformedJsonError(f"{what}: nested deeper than {MAX_JSON_DEPTH} levels") from None
    except ValueError:  # int("…" * 5000): Python's limit on integer text, the only other case
        raise LimitExceededError(
            f"{what}: a number with more than {MAX_NUMBER_DIGITS} digits; write it with an"
            " exponent (1e5000 is still refused as out of range) or fewer digits",
            MAX_NUMBER_DIGITS,
        ) from None
    check_depth(value, what)
    return value


def parse_json_object(text: str | bytes, what: str = "document") -> dict[str, Any]:
    """A JSON object from text, every failure a one-line :class:`RisPlannerError`."""
    doc = parse_json(text, what)
    if not isinstance(doc, dict):
        raise MalformedJsonError(f"{what}: the document must be a JSON object")
    return doc


def read_json_object(path: str | Path) -> dict[str, Any]:
    """A JSON object from a file (``-`` = stdin), with input errors as :class:`RisPlannerError`."""
    if str(path) == "-":
        if sys.stdin is None or sys.stdin.closed:
            raise RisPlannerError("-: standard input is closed")
        text = sys.stdin.buffer.read() if hasattr(sys.stdin, "buffer") else sys.stdin.read()
        return parse_json_object(text, "-")
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise RisPlannerError(f"{path}: cannot read ({exc.strerror or exc})") from None
    return parse_json_object(data, str(path))


def field_path(loc: tuple[int | str, ...] | list[int | str]) -> str:
    """Dotted field path of a pydantic error location (``ris.1.position``)."""
    return ".".join(str(p) for p in loc) or "(document)"


def validation_problems(exc: ValidationError) -> list[str]:
    """One ``field.path: message`` per problem (``ris.1.position: ...``)."""
    return [f"{field_path(err['loc'])}: {err['msg']}" for err in exc.errors()]


def format_validation_error(exc: ValidationError) -> str:
    """One line per problem, naming the field path."""
    return "invalid document:\n  " + "\n  ".join(validation_problems(exc))


def one_line_validation_error(exc: ValidationError) -> str:
    """The problems of a validation error on one line (job messages)."""
    return "invalid document: " + "; ".join(validation_problems(exc))


_ONE_LINE = json.JSONEncoder(allow_nan=False, separators=(", ", ": "))
"""The encoder of :func:`readable_json`'s one-line parts (one instance: ``json.dumps`` with
options builds an encoder per call, a third of the time for 90 000 small features)."""


def _key(key: Any) -> str:
    """An object key as the json module writes it (strings as they are, numbers and
    booleans by their JSON text)."""
    return json.dumps(key if isinstance(key, str) else json.dumps(key))


def readable_json(value: Any, levels: int = 2, indent: int = 1) -> str:
    """Strict JSON (no NaN/inf) for people and programs alike: the outer ``levels`` of objects
    and arrays one member per line, indented by ``indent`` per level, everything deeper on one
    line. The deeper parts go through the json module's C encoder: ``json.dumps(indent=…)``
    encodes in Python throughout, ≈ 50× slower (a plan with 90 000 map points spent seconds
    writing plan.geojson; docs/validation/resources.md)."""

    def encode(item: Any, level: int) -> str:
        if level >= levels or not isinstance(item, dict | list) or not item:
            return _ONE_LINE.encode(item)
        pad = " " * (indent * (level + 1))
        if isinstance(item, dict):
            inner = [f"{pad}{_key(k)}: {encode(v, level + 1)}" for k, v in item.items()]
            open_, close = "{", "}"
        else:
            inner = [f"{pad}{encode(v, level + 1)}" for v in item]
            open_, close = "[", "]"
        return open_ + "\n" + ",\n".join(inner) + "\n" + " " * (indent * level) + close

    return encode(value, 0)


def finite_or_none(x: float | None) -> float | None:
    """A number as JSON has it: a finite value as a float, ``None`` (null) for ``inf``, ``nan``
    or no value (JSON has no infinity; plan.json and the service's answers write null)."""
    return None if x is None or not math.isfinite(x) else float(x)
