"""Griffe extension for the Python API pages: the package's docstrings are written for readers of
the source (Sphinx roles, ``name : description`` entries), mkdocstrings renders Markdown.

* Sphinx roles (``:func:`x```, ``:class:``, ``:mod:``, ``:meth:``, ``:attr:``, ``:data:``,
  ``:exc:``, ``:obj:``, with or without ``py:`` and ``~``) become cross-references: the name is
  resolved in the scope of the documented object and emitted as an *optional* autoref (a link
  when the target is on an API page, plain code otherwise – never a broken link, never the raw
  role).
* In numpy sections (``Attributes``, ``Parameters``, …) an entry ``name : text`` whose text is
  not a type (the package writes ``peb_tx : [P] position error bound [m]``) is rewritten as
  ``name`` with ``text`` as its description, so the text is not shown in the Type column.
* An RST literal-block marker ``::`` ending a paragraph becomes ``:``.
* Adjacent bracket groups outside code (shapes such as ``[lon, lat] [N, 2]``) are not read as
  Markdown reference links: the second ``[`` is escaped.

Configured in mkdocs.yml (``extensions`` of the python handler).
"""

from __future__ import annotations

import html
import re
from collections.abc import Iterator
from typing import Any

from griffe import Alias, Extension, GriffeLoader, Module, Object

ROLE = re.compile(r":(?:py:)?(func|class|mod|meth|attr|data|exc|obj|const|type):`(~?)([^`<>]+?)`")
SECTION_TITLES = {
    "attributes",
    "parameters",
    "other parameters",
    "returns",
    "yields",
    "raises",
    "warns",
    "receives",
}
ENTRY = re.compile(r"^(?P<names>[A-Za-z_*][\w*]*(?:\s*,\s*[A-Za-z_*][\w*]*)*)\s+:\s+(?P<text>.+)$")
TYPE_LIKE = re.compile(
    r"^[A-Za-z_][\w.]*(?:\[[\w., |\[\]]*\])?(?:\s*\|\s*[A-Za-z_][\w.]*(?:\[[\w., |\[\]]*\])?)*"
    r"(?:,\s*optional)?$"
)


def _lookup(obj: Object | Alias, path: str) -> Object | Alias | None:
    try:
        return obj.modules_collection.get_member(path)  # type: ignore[no-any-return]
    except Exception:
        pass
    try:
        return obj.modules_collection[path]  # type: ignore[no-any-return]
    except Exception:
        return None


def _resolve(obj: Object, name: str) -> str | None:
    """The full path of ``name`` as seen from ``obj``, or None."""
    name = name.strip().rstrip("()")
    candidates = []
    if name.startswith("ris_planner"):
        candidates.append(name)
    head, _, rest = name.partition(".")
    scope: Object | None = obj
    while scope is not None:
        try:
            full = scope.resolve(head)
        except Exception:
            full = None
        if full:
            candidates.append(full + ("." + rest if rest else ""))
            break
        scope = scope.parent
    module = obj.module
    candidates += [f"{module.path}.{name}"]
    if module.parent is not None:
        candidates.append(f"{module.parent.path}.{name}")
    for path in candidates:
        if _lookup(obj, path) is not None:
            return path
    return None


def _roles(obj: Object, text: str) -> str:
    def replace(match: re.Match[str]) -> str:
        _, tilde, name = match.groups()
        shown = name.rsplit(".", 1)[-1] if tilde else name
        code = f"<code>{html.escape(shown)}</code>"
        target = _resolve(obj, name)
        if target is None:
            return f"`{shown}`"
        return f'<autoref identifier="{html.escape(target)}" optional>{code}</autoref>'

    return ROLE.sub(replace, text)


def _sections(text: str) -> str:
    lines = text.split("\n")
    out: list[str] = []
    in_section = False
    for i, line in enumerate(lines):
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if line.strip().lower() in SECTION_TITLES and re.fullmatch(r"\s*-{3,}\s*", nxt):
            in_section = True
            out.append(line)
            continue
        if in_section and line and not line.startswith(" ") and not re.fullmatch(r"-{3,}", line):
            match = ENTRY.match(line)
            if match and not TYPE_LIKE.match(match["text"].strip()):
                out.append(match["names"])
                out.append("    " + match["text"].strip())
                continue
        out.append(line)
    return "\n".join(out)


def _literal_markers(text: str) -> str:
    return re.sub(r"(?<=\S)::(?=\n\s*\n)", ":", text)


CODE_SPAN = re.compile(r"(`+)(?:.|\n)*?\1")
ADJACENT = re.compile(r"\](\s?)\[")


def _brackets(text: str) -> str:
    out, last = [], 0
    for match in CODE_SPAN.finditer(text):
        out.append(ADJACENT.sub(r"]\1\\[", text[last : match.start()]))
        out.append(match.group(0))
        last = match.end()
    out.append(ADJACENT.sub(r"]\1\\[", text[last:]))
    return "".join(out)


def package_objects(pkg: Module) -> Iterator[Object]:
    """Every object of a loaded package once – its modules, classes, functions and attributes;
    an alias is left to its target."""
    seen: set[int] = set()
    stack: list[Object] = [pkg]
    while stack:
        obj = stack.pop()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        yield obj
        stack += [m for m in obj.members.values() if not isinstance(m, Alias)]


class SphinxToMarkdown(Extension):
    """Rewrites the docstrings of a loaded package (see the module docstring)."""

    def on_package(self, *, pkg: Module, loader: GriffeLoader, **kwargs: Any) -> None:
        for obj in package_objects(pkg):
            if obj.docstring is not None and obj.docstring.value:
                value = obj.docstring.value
                value = _sections(value)
                value = _literal_markers(value)
                value = _brackets(value)
                value = _roles(obj, value)
                obj.docstring.value = value
