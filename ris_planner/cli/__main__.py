"""``python -m ris_planner.cli.main``: the command line."""

from ris_planner.cli.main import main

raise SystemExit(main())
