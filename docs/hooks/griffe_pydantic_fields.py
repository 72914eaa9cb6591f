"""Griffe extension for the Python API pages: every pydantic model of the package (the scenario,
plan and simulation documents and each model they are made of) gets a table of its fields –
name, type, default, unit, limits and description – read from the model itself
(``model_fields``) when the site is built, so the page cannot drift from the code. The table
ends the class's docstring, and a line links the model's JSON schema on the schemas page
(``scripts/mkdocs_hooks.py``, one section per model).

* **type**: the annotation, nested models as cross-references to their own entries;
* **default**: JSON (``null``, ``"auto"``, ``[2, 3]``), ``{}`` for a nested model whose fields
  all keep their defaults, *required* where the document must give it;
* **unit**: from the field's name (``_m``, ``_deg``, ``_dbm``, …) or a unit in brackets in its
  description (``[m]``);
* **limits**: the field's bounds (``≥ 1``, ``≤ 1000``, at most 16 items).

Configured in mkdocs.yml (``extensions`` of the python handler), after
``griffe_docstrings.py``, whose rewrites are for the docstrings' own text.
"""

from __future__ import annotations

import functools
import html
import importlib
import importlib.util
import json
import re
import types
import typing
from pathlib import Path
from typing import Any

import annotated_types
from griffe import Class, Docstring, Extension, GriffeLoader, Module
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined, to_jsonable_python

SCHEMAS_PAGE = "../schemas.md"
"""The JSON schemas page, relative to the API pages (docs/reference/api/)."""

NAME_UNITS = {
    "_m": "m",
    "_m2": "m²",
    "_deg": "°",
    "_rad": "rad",
    "_dbm": "dBm",
    "_db": "dB",
    "_dbm_hz": "dBm/Hz",
    "_hz": "Hz",
    "_s": "s",
    "_mib": "MiB",
    "_mb": "MiB",
}
"""Unit of a field whose name ends with the key (the package's naming rule,
docs/concepts/conventions.md)."""

UNITS = {"m", "m²", "deg", "°", "rad", "dB", "dBm", "dBm/Hz", "Hz", "s", "MiB", "m/s"}
"""Units a description may give in brackets (``Road width [m]``)."""

BRACKETED = re.compile(r"\[([^\]]+)\]")


def field_unit(name: str, info: FieldInfo) -> str:
    """The unit of a field: its name's suffix, else the first unit in brackets in its
    description; ``""`` for a number without a unit or a field that is not a quantity."""
    for suffix in sorted(NAME_UNITS, key=len, reverse=True):
        if name.endswith(suffix):
            return NAME_UNITS[suffix]
    for candidate in BRACKETED.findall(info.description or ""):
        if candidate.strip() in UNITS:
            return "°" if candidate.strip() == "deg" else candidate.strip()
    return ""


def field_default(info: FieldInfo) -> str:
    """The default as the document writes it (JSON), ``{}`` for a nested model of defaults,
    ``required`` when there is none."""
    if info.default is PydanticUndefined and info.default_factory is None:
        return "required"
    value = info.get_default(call_default_factory=True)
    if isinstance(value, BaseModel):
        value = value.model_dump(mode="json", exclude_defaults=True)
    return json.dumps(to_jsonable_python(value), ensure_ascii=False)


def field_limits(info: FieldInfo) -> str:
    """The field's bounds (``≥ 0``, ``≤ 1000``, ``at most 16 items``, ``at most 200
    characters``)."""
    text = typing.get_origin(info.annotation) is None and info.annotation is str
    text = text or str in typing.get_args(info.annotation)
    items = "characters" if text else "items"
    out = []
    for m in info.metadata:
        if isinstance(m, annotated_types.Ge):
            out.append(f"≥ {m.ge}")
        elif isinstance(m, annotated_types.Gt):
            out.append(f"> {m.gt}")
        elif isinstance(m, annotated_types.Le):
            out.append(f"≤ {m.le}")
        elif isinstance(m, annotated_types.Lt):
            out.append(f"< {m.lt}")
        elif isinstance(m, annotated_types.MinLen) and m.min_length:
            out.append(f"at least {m.min_length} {items}")
        elif isinstance(m, annotated_types.MaxLen):
            out.append(f"at most {m.max_length} {items}")
    return ", ".join(out)


def _model_ref(model: type[BaseModel]) -> str:
    path = f"{model.__module__}.{model.__qualname__}"
    code = f"<code>{html.escape(model.__name__)}</code>"
    return f'<autoref identifier="{html.escape(path)}" optional>{code}</autoref>'


def type_text(tp: Any) -> str:
    """An annotation as the table shows it (HTML: nested models link to their entries)."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is type(None):
        return "None"
    if origin is typing.Annotated:
        return type_text(args[0])
    if origin in (typing.Union, types.UnionType):
        return " \\| ".join(type_text(a) for a in args)
    if origin is typing.Literal:
        return " \\| ".join(html.escape(json.dumps(a)) for a in args)
    if origin is not None:
        name = getattr(origin, "__name__", str(origin))
        return f"{name}[{', '.join(type_text(a) for a in args)}]"
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return _model_ref(tp)
    if isinstance(tp, type):
        return html.escape(tp.__name__)
    return html.escape(str(tp).replace("typing.", ""))


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def fields_table(model: type[BaseModel]) -> str:
    """The Markdown of a model's fields (the module docstring's columns)."""
    rows = [
        "| field | type | default | unit | limits | description |",
        "|---|---|---|---|---|---|",
    ]
    for name, info in model.model_fields.items():
        default = field_default(info)
        shown_default = "*required*" if default == "required" else f"`{default}`"
        rows.append(
            f"| `{name}` | {type_text(info.annotation)} | {_cell(shown_default)}"
            f" | {field_unit(name, info)} | {field_limits(info)}"
            f" | {_cell(info.description or '')} |"
        )
    schema = ""
    if model.__name__ in schema_names():
        schema = f" (JSON schema: [{model.__name__}]({SCHEMAS_PAGE}#{model.__name__.lower()}))"
    return f"**Fields of `{model.__name__}`**{schema}:\n\n" + "\n".join(rows)


@functools.cache
def _sibling(name: str, folder: str = "docs/hooks") -> Any:
    """A module of the site's build code by its file (mkdocs and griffe load these by path:
    they are no package)."""
    path = Path(__file__).resolve().parents[2] / folder / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@functools.cache
def schema_names() -> frozenset[str]:
    """The models with a section on the schemas page (``schema_models`` of
    scripts/mkdocs_hooks.py, which writes that page)."""
    return frozenset(_sibling("mkdocs_hooks", "scripts").schema_models())


def _runtime(path: str) -> Any:
    module, _, name = path.rpartition(".")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError):
        return None


class PydanticFields(Extension):
    """Appends :func:`fields_table` to the docstring of every pydantic model of a loaded
    package (see the module docstring)."""

    def on_package(self, *, pkg: Module, loader: GriffeLoader, **kwargs: Any) -> None:
        for obj in _sibling("griffe_docstrings").package_objects(pkg):
            if not isinstance(obj, Class):
                continue
            model = _runtime(obj.path)
            if isinstance(model, type) and issubclass(model, BaseModel) and model.model_fields:
                table = fields_table(model)
                if obj.docstring is None:
                    obj.docstring = Docstring(table, parent=obj)
                else:
                    obj.docstring.value = obj.docstring.value.rstrip() + "\n\n" + table
