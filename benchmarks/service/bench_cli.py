"""Whole-process time of ``ris-planner bounds --preset paper-table1`` against
``python -c "import numpy"`` measured in the same run (warm caches: one discarded warm-up
each), and the import-time state of the process (no malloc tuning at import).

    python benchmarks/service/bench_cli.py [--repeats 15] [--quick]

The target (docs/validation/benchmarks.md) is ≤ 0.4 s for the command on the 2-core machine;
the ratio to the bare numpy import is the machine-independent figure. ``--quick``: 2 repeats.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from harness import median_time


def run(cmd: list[str]) -> None:
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="2 repeats")
    args = ap.parse_args(argv)
    if args.quick:
        args.repeats = 2
    exe = shutil.which("ris-planner") or str(Path(sys.executable).with_name("ris-planner"))
    bounds = [exe, "bounds", "--preset", "paper-table1"]
    numpy_only = [sys.executable, "-c", "import numpy"]
    t_np = median_time(lambda: run(numpy_only), args.repeats)
    t_cli = median_time(lambda: run(bounds), args.repeats)
    print(f"python -c 'import numpy'              {t_np * 1e3:7.1f} ms (median of {args.repeats})")
    print(f"ris-planner bounds --preset paper-table1 {t_cli * 1e3:7.1f} ms")
    print(f"ratio                                   {t_cli / t_np:7.2f}×")
    return 0


if __name__ == "__main__":
    sys.exit(main())
