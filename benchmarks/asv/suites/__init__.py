"""airspeed velocity suites of ris_planner's headline workloads (docs/validation/benchmarks.md).

asv imports the commit it benchmarks from its checkout (benchmarks/asv/asv_path.py); a
``PYTHONPATH`` pointing at a working tree would make every commit measure that tree instead,
so the suites refuse to run then.
"""

from __future__ import annotations

import os

import ris_planner

if os.environ.get("ASV") == "true" and "/.asv/env/" not in ris_planner.__file__:
    raise RuntimeError(
        f"asv imported ris_planner from {ris_planner.__file__}, not from the commit's checkout:"
        " run asv without PYTHONPATH"
    )
