"""asv's install step for ris_planner, offline (benchmarks/asv/asv.conf.json).

``python asv_path.py BUILD_DIR`` (run by asv with the benchmark environment's python): a
``.pth`` file in that environment puts the commit's checkout (BUILD_DIR, the source tree asv
checked out) first on the path and the shared virtual environment's packages after it, so
no wheel is built and nothing is downloaded. ``--remove`` deletes the file. The shared
packages are those of ``$RIS_PLANNER_ASV_SITE`` if set, else of the ``asv`` found on PATH
(its interpreter's ``purelib``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

PTH = Path(sysconfig.get_paths()["purelib"]) / "ris_planner_asv.pth"


def shared_site() -> str:
    """The shared virtual environment's site-packages."""
    if os.environ.get("RIS_PLANNER_ASV_SITE"):
        return os.environ["RIS_PLANNER_ASV_SITE"]
    asv = shutil.which("asv")
    if asv is None:
        sys.exit("asv_path.py: set RIS_PLANNER_ASV_SITE or put the venv's bin/ (with asv) on PATH")
    python = Path(asv).read_text().splitlines()[0].removeprefix("#!").strip()
    code = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    return subprocess.run(
        [python, "-c", code], check=True, capture_output=True, text=True
    ).stdout.strip()


def main() -> None:
    if sys.argv[1:] == ["--remove"]:
        PTH.unlink(missing_ok=True)
        return
    (build_dir,) = sys.argv[1:]
    PTH.write_text(f"{Path(build_dir).resolve()}\n{shared_site()}\n")


if __name__ == "__main__":
    main()
