"""Import layering: the package never loads the web service at import time (``serve`` loads it
when it runs), and neither the engine nor the job workers import a command-line module."""

from __future__ import annotations

import subprocess
import sys

import pytest


@pytest.mark.parametrize(
    ("module", "forbidden"),
    [
        ("ris_planner.cli", "api"),  # also after building the parser (every subcommand)
        ("ris_planner.planning.presets", "ris_planner.cli"),
        ("ris_planner.planning", "ris_planner.cli"),
        ("api.worker", "ris_planner.cli"),
        ("api.main", "ris_planner.cli"),
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
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"{module} loads {out.stdout.strip()}"
