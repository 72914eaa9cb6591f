"""``python -m ris_planner.cli``: the command line."""

from ris_planner.cli import run

run()
