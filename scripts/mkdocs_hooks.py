"""MkDocs hook: pages generated from the code at build time, so they cannot go stale.

A page that contains a marker line ``<!-- generated: NAME -->`` gets the text of
``GENERATORS[NAME]()`` in its place:

* ``schemas``: the JSON schemas of the scenario, plan and simulation documents (the pydantic
  models' ``model_json_schema()``, what ``ris-planner schema`` prints for the scenario);
* ``rest-operations``: the operations of the REST service from ``api.main``'s OpenAPI document;
* ``settings``: the service's environment variables from ``api.settings.Settings`` and the
  engine's own ``RIS_PLANNER_*`` variables;
* ``cli``: the ``--help`` of every ``ris-planner`` subcommand.

The hook imports the package, so the build runs from the repository root with it importable
(``make docs``, or ``PYTHONPATH=. mkdocs build --strict``).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

MARKER = re.compile(r"^<!-- generated: ([a-z-]+) -->$", re.MULTILINE)


def _json_block(obj: Any) -> str:
    return "```json\n" + json.dumps(obj, indent=2, ensure_ascii=False) + "\n```\n"


def _indent(text: str) -> str:
    return "\n".join("    " + line for line in text.splitlines())


def _cell(text: object) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def documents() -> list[tuple[str, Any, str]]:
    """(title, pydantic model, what reads it) of each JSON document."""
    from ris_planner.estimation.document import SimulationDocument
    from ris_planner.model.plan import PlanDocument
    from ris_planner.model.scenario import Scenario

    return [
        ("Scenario document", Scenario, "`ris-planner bounds`, `power`, `POST /v1/bounds`"),
        ("Plan document", PlanDocument, "`ris-planner plan`, `POST /v1/plans`"),
        ("Simulation document", SimulationDocument, "`ris-planner simulate`"),
    ]


def schema_models() -> dict[str, tuple[dict[str, Any], list[str]]]:
    """Every model of the documents' JSON schemas by name (a document's own model included):
    (its schema without ``$defs``, the titles of the documents that use it)."""
    models: dict[str, tuple[dict[str, Any], list[str]]] = {}
    for title, model, _ in documents():
        schema = model.model_json_schema()
        defs = schema.pop("$defs", {})
        for name, part in [(model.__name__, schema), *defs.items()]:
            known = models.setdefault(name, (part, []))
            if known[0] != part:
                raise ValueError(f"two JSON schemas named {name!r}")
            known[1].append(title)
    return models


def _model_path(name: str) -> str | None:
    """The Python path of the package's pydantic model of that name (the class a schema of
    that name was made from)."""
    import pydantic

    found = set()
    stack: list[type] = [pydantic.BaseModel]
    while stack:
        cls = stack.pop()
        stack += cls.__subclasses__()
        if cls.__name__ == name and cls.__module__.startswith("ris_planner."):
            found.add(f"{cls.__module__}.{cls.__qualname__}")
    return found.pop() if len(found) == 1 else None


def schemas() -> str:
    """The documents and, one section each, the JSON schema of every model they are made of
    (the fields, their types, defaults and units are on the Python API pages)."""
    models = schema_models()
    rows = ["| document | read by | model |", "|---|---|---|"]
    for title, model, where in documents():
        rows.append(f"| {title} | {where} | [{model.__name__}](#{model.__name__.lower()}) |")
    parts = ["\n".join(rows) + "\n", "## Models\n"]
    for name in sorted(models, key=str.lower):
        schema, used_by = models[name]
        refs = sorted(set(re.findall(r'"\$ref": "#/\$defs/(\w+)"', json.dumps(schema))))
        path = _model_path(name)
        lines = [f"### {name}\n", f"Used in: {', '.join(used_by)}."]
        if path is not None:
            lines.append(f"Fields, types, defaults and units: [`{path}`][{path}].")
        if refs:
            lines.append("Refers to: " + ", ".join(f"[{r}](#{r.lower()})" for r in refs) + ".")
        parts.append(
            "\n".join(lines)
            + f'\n\n??? note "JSON schema of {name}"\n\n'
            + _indent(_json_block(schema))
            + "\n"
        )
    return "\n".join(parts)


def rest_operations() -> str:
    from api.main import create_app
    from api.settings import Settings

    spec = create_app(Settings()).openapi()
    rows = [
        "| method | path | operation id | summary | parameters | responses |",
        "|---|---|---|---|---|---|",
    ]
    for path, item in spec["paths"].items():
        for method, op in item.items():
            if method not in {"get", "post", "put", "patch", "delete"}:
                continue
            codes = ", ".join(sorted(op.get("responses", {})))
            params = [f"`{p['name']}` ({p['in']})" for p in op.get("parameters", [])]
            if "requestBody" in op:
                params.append("body: " + ", ".join(f"`{m}`" for m in op["requestBody"]["content"]))
            rows.append(
                f"| `{method.upper()}` | `{path}` | `{op.get('operationId', '')}` | "
                f"{_cell(op.get('summary', ''))} | {_cell(', '.join(params)) or '–'} | {codes} |"
            )
    info = spec["info"]
    head = (
        f"OpenAPI {spec['openapi']}, *{_cell(info['title'])}* version {info['version']}: "
        f"{len(rows) - 2} operations.\n\n"
    )
    return head + "\n".join(rows) + "\n"


ENGINE_VARIABLES = (
    (
        "RIS_PLANNER_CACHE_MEMORY_MB",
        "CACHE_MEMORY_MB_DEFAULT",
        "Site-cache byte budget of a plan [MiB] (CLI and service): the first storage tier that"
        " fits is used, a plan above the last tier is refused (concepts/scoring.md).",
    ),
    (
        "RIS_PLANNER_MALLOC_TUNING",
        "on",
        "`0` leaves glibc's malloc thresholds alone (the engine sets mmap 32 MiB, trim 64 MiB at"
        " import; glibc's own `MALLOC_MMAP_THRESHOLD_`/`MALLOC_TRIM_THRESHOLD_` take precedence).",
    ),
    (
        "RIS_PLANNER_CHROMIUM",
        "`/usr/bin/chromium`",
        "Tests only: the Chromium binary of the browser tests (`make test CHROMIUM=…` sets it).",
    ),
    (
        "RIS_PLANNER_SCREENSHOTS",
        "unset",
        "Tests only: `1` keeps the browser tests' screenshots in `out/web/`.",
    ),
)


def settings() -> str:
    from api.settings import Settings

    rows = ["| variable | default | meaning |", "|---|---|---|"]
    for name, field in Settings.model_fields.items():
        default = "unset" if field.default is None else f"`{field.default}`"
        rows.append(
            f"| `RIS_PLANNER_{name.upper()}` | {default} | {_cell(field.description or '')} |"
        )
    service = "\n".join(rows)
    rows = ["| variable | default | meaning |", "|---|---|---|"]
    from ris_planner.model import limits

    for name, default, meaning in ENGINE_VARIABLES:
        if default.isupper():  # a constant of ris_planner.model.limits
            default = f"`{getattr(limits, default)}`"
        rows.append(f"| `{name}` | {default} | {_cell(meaning)} |")
    return (
        "## Service (`api.settings.Settings`)\n\n"
        "Read from the environment at start-up (`ris-planner serve --db/--workers` override the"
        " first two). Generated from the settings model.\n\n"
        + service
        + "\n\n## Engine and tests\n\n"
        + "\n".join(rows)
        + "\n"
    )


def _subparsers(parser: argparse.ArgumentParser) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            yield from action.choices.items()


def cli() -> str:
    from ris_planner.cli.app import build_parser

    os.environ["COLUMNS"] = "100"
    parser = build_parser()
    parts = ["## `ris-planner`\n\n```text\n" + parser.format_help() + "```\n"]

    def walk(prefix: str, p: argparse.ArgumentParser) -> None:
        for name, sub in _subparsers(p):
            title = f"{prefix} {name}"
            parts.append(f"## `{title}`\n\n```text\n" + sub.format_help() + "```\n")
            walk(title, sub)

    walk("ris-planner", parser)
    return "\n".join(parts)


GENERATORS: dict[str, Callable[[], str]] = {
    "schemas": schemas,
    "rest-operations": rest_operations,
    "settings": settings,
    "cli": cli,
}


def generate(markdown: str) -> str:
    """``markdown`` with every marker line replaced by its generated text."""
    return MARKER.sub(lambda m: GENERATORS[m.group(1)](), markdown)


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    return generate(markdown)
