"""Import layering: every import of the package against the layer table of the docs
(docs/reference/layers.md), no import circle between modules, and the processes that must not
load the web service or the command line do not (``serve`` loads the service when it runs)."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest
from waits import HANG_S

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "docs" / "reference" / "layers.md"


def layer_table() -> dict[str, int]:
    """Package → rank, read from the docs' table (the rule lives there)."""
    rows = re.findall(r"^\|\s*(\d+)\s*\|\s*`([\w.]+)`\s*\|", TABLE.read_text(), re.M)
    return {name: int(rank) for rank, name in rows}


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path) -> set[str]:
    """Every module a file imports: module level, inside functions, under TYPE_CHECKING."""
    return imports_in(path.read_text(), module_name(path), path.name == "__init__.py")


def imports_in(text: str, name: str, is_package: bool) -> set[str]:
    """The modules of the package and the service that source ``text`` of module ``name``
    imports (relative imports resolved against its package)."""
    package = name if is_package else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            found.add(module)
            # "from package import submodule" imports the submodule
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return {m for m in found if m.split(".")[0] in {"ris_planner", "api"}}


def known_modules() -> set[str]:
    files = [*ROOT.joinpath("ris_planner").rglob("*.py"), *ROOT.joinpath("api").rglob("*.py")]
    return {module_name(p) for p in files}


def rank_of(module: str, table: dict[str, int]) -> int | None:
    best = max(
        (p for p in table if module == p or module.startswith(p + ".")), key=len, default=None
    )
    return None if best is None else table[best]


def package_files() -> list[Path]:
    return sorted(
        [*ROOT.joinpath("ris_planner").rglob("*.py"), *ROOT.joinpath("api").rglob("*.py")]
    )


def test_the_table_names_every_package() -> None:
    table = layer_table()
    assert len(table) >= 12 and len(set(table.values())) == len(table)  # a strict order
    unplaced = sorted(
        module_name(p)
        for p in package_files()
        if module_name(p) != "ris_planner" and rank_of(module_name(p), table) is None
    )
    assert unplaced == [], f"modules in no layer of docs/reference/layers.md: {unplaced}"


def test_no_import_goes_up_a_layer() -> None:
    table = layer_table()
    modules = known_modules()
    upward = []
    for path in package_files():
        name = module_name(path)
        if name == "ris_planner":
            continue  # the public surface, at the top
        upward += upward_imports(name, imports_of(path), table, modules)
    assert upward == [], "\n".join(upward)


def upward_imports(
    name: str, targets: set[str], table: dict[str, int], modules: set[str]
) -> list[str]:
    """The imports of module ``name`` that go up a layer (or to the public surface)."""
    mine = rank_of(name, table)
    assert mine is not None
    found = []
    for target in sorted(targets):
        if target not in modules:
            continue  # a name imported from a module, already counted as the module
        if target == "ris_planner":
            found.append(f"{name} imports the public surface ris_planner")
            continue
        theirs = rank_of(target, table)
        if theirs is not None and theirs > mine:
            found.append(f"{name} (layer {mine}) imports {target} (layer {theirs})")
    return found


def test_no_import_circle() -> None:
    modules = known_modules()
    graph = {
        module_name(p): {t for t in imports_of(p) if t in modules and t != module_name(p)}
        for p in package_files()
    }
    # a package's __init__ re-exporting its own modules is not a circle of the modules themselves
    for name, targets in graph.items():
        graph[name] = {t for t in targets if not name.startswith(t + ".")}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert circles == [], f"import circles: {circles}"


@pytest.mark.parametrize(
    ("source", "is_package"),
    [
        ("def f():\n    from ris_planner.planning.search import layouts\n", False),
        (
            "from typing import TYPE_CHECKING\n"
            "if TYPE_CHECKING:\n    import ris_planner.io.frames\n",
            False,
        ),
        ("from ..planning.search import layouts\n", False),  # relative, two levels up
        ("from ris_planner import planning\n", True),  # "from package import submodule"
    ],
)
def test_the_checker_sees_an_upward_import(source: str, is_package: bool) -> None:
    """The rule can fail: the real import reader (:func:`imports_of`'s) and the real upward
    check catch a function-level, a TYPE_CHECKING, a relative and a submodule import of a layer
    above physics, written in a physics module."""
    name = "ris_planner.physics" if is_package else "ris_planner.physics.geometry"
    targets = imports_in(source, name, is_package)
    found = upward_imports(name, targets, layer_table(), known_modules())
    assert found, targets


def test_the_reader_reads_a_real_module() -> None:
    """:func:`imports_of` on a package file finds its function-level and module-level imports."""
    found = imports_of(ROOT / "ris_planner" / "planning" / "pipeline.py")
    # a function-level import and module-level ones
    want = {"ris_planner.planning.outputs.diagnosis", "ris_planner.planning.prepare"}
    assert want <= found


@pytest.mark.parametrize(
    ("module", "forbidden"),
    [
        ("ris_planner.cli.app", "api"),  # also after building the parser (every subcommand)
        ("ris_planner.planning.inputs.presets", "ris_planner.cli.app"),
        ("ris_planner.planning", "ris_planner.cli.app"),
        ("api.worker", "ris_planner.cli.app"),
        ("api.main", "ris_planner.cli.app"),
    ],
)
def test_import_does_not_load(module: str, forbidden: str) -> None:
    code = (
        f"import sys, importlib; m = importlib.import_module({module!r});"
        " getattr(m, 'build_parser', lambda: None)();"
        f" f = {forbidden!r};"
        " bad = [n for n in sys.modules if n == f or n.startswith(f + '.')];"
        " print(','.join(bad))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_S
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"{module} loads {out.stdout.strip()}"
