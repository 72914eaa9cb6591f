"""``ris-planner warmup`` (the cold start): it finds every numba kernel of the package,
compiles each with the signatures a plan uses, and a plan in a fresh process afterwards
compiles nothing; numba gets a writable cache folder wherever the package is installed."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import ris_planner
from ris_planner.cli.app import REGISTRARS, build_parser
from ris_planner.planning import warmup
from ris_planner.runtime import allocator

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = Path(ris_planner.__file__).resolve().parent


def njit_functions() -> set[str]:
    """``module.function`` of every function decorated with numba's njit/jit in the package's
    sources (an independent route: the syntax tree, not the imported dispatchers)."""
    found = set()
    for path in PACKAGE.rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        for node in tree.body:
            if not isinstance(node, ast.FunctionDef):
                continue
            for dec in node.decorator_list:
                target = dec.func if isinstance(dec, ast.Call) else dec
                attr = isinstance(target, ast.Attribute)
                name = target.attr if attr else getattr(target, "id", "")
                if name in ("njit", "jit"):
                    found.add(f"{module}.{node.name}")
    return found


def test_every_njit_function_is_a_warmup_kernel() -> None:
    expected = njit_functions()
    assert {
        "ris_planner.inversion._crb_jit.score_layouts",
        "ris_planner.environment._jit.walk",
    } <= expected
    assert set(warmup.kernels()) == expected


def run_python(code: str, timeout_s: float = 1500) -> str:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout_s, env=env
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout


def test_warmup_compiles_every_kernel_and_a_plan_then_compiles_nothing() -> None:
    """The CLI's warm-up covers every kernel of the syntax tree; a plan in another process
    afterwards (other sites, pairs, an obstacle, the max metric) misses numba's cache never."""
    report = json.loads(
        run_python("from ris_planner.cli import main; main(['warmup', '--json', '--quiet'])")
    )
    assert set(report["kernels"]) == njit_functions()
    assert all(n >= 1 for n in report["kernels"].values()), report["kernels"]
    plan = {
        **warmup._ring_plan(7, 300, ris_count=[2, 3]),
        "objective": {"kind": "coverage", "metric": "max", "threshold_m": 0.5},
        "environment": {
            "obstacles": [{"kind": "wall", "start": [-1, -6], "end": [-1, -5], "height_m": 2}]
        },
    }
    code = (
        "import json; from numba.core import event\n"
        "seen = []\n"
        "class L(event.Listener):\n"
        "    def on_start(self, ev): seen.append(ev.data['dispatcher'].py_func.__qualname__)\n"
        "    def on_end(self, ev): pass\n"
        "event.register('numba:compile', L())\n"
        "from ris_planner.planning import SerialExecutor, run_plan\n"
        "from ris_planner.inversion import crb\n"
        "import numpy as np\n"
        f"run_plan({plan!r}, executor=SerialExecutor())\n"
        "a = np.random.default_rng(1).standard_normal((4, 3, 7))\n"
        "crb.sqrt_crb_diagonal(a); crb.svd(a)\n"
        "print(json.dumps(seen))"
    )
    assert json.loads(run_python(code).strip().splitlines()[-1]) == []


def test_warmup_is_a_registered_subcommand() -> None:
    assert REGISTRARS["ris_planner.cli.warmup:add_cli"] == ("warmup",)
    args = build_parser("warmup").parse_args(["warmup", "--json"])
    assert args.command == "warmup" and args.json


def test_numba_cache_falls_back_to_a_writable_folder(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """No writable folder next to the sources nor in the user's home: a per-user folder under
    the temporary directory; NUMBA_CACHE_DIR, when set, always wins."""
    import numba
    from numba.core import caching

    def refuse(self: object) -> None:
        raise OSError("read-only")

    monkeypatch.setattr(caching.InTreeCacheLocator, "ensure_cache_path", refuse)
    monkeypatch.setattr(caching.UserWideCacheLocator, "ensure_cache_path", refuse)
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr("tempfile.tempdir", None)
    chosen = allocator.ensure_numba_cache(warmup.__file__)
    assert chosen is not None and Path(chosen).parent == tmp_path
    assert Path(chosen).is_dir() and chosen == numba.config.CACHE_DIR
    assert os.access(chosen, os.W_OK)
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "mine"))
    assert allocator.ensure_numba_cache(warmup.__file__) is None
    assert str(tmp_path / "mine") == numba.config.CACHE_DIR


def test_numba_keeps_its_own_choice_where_it_can_write() -> None:
    import numba

    if numba.config.CACHE_DIR:
        pytest.skip("NUMBA_CACHE_DIR is set in this environment")
    assert allocator.ensure_numba_cache(warmup.__file__) is None
    assert not numba.config.CACHE_DIR
