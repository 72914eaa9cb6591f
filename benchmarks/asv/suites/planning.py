"""Planning workloads beyond the headline hall, one asv benchmark each
(docs/validation/benchmarks.md):

* ``District.time_street_plan``: the district search on the suite's street site (14 facade
  candidates, 300 sidelink pairs at most 30 m apart along the streets, 32 × 32 RISs, 2–3 RISs;
  ``run_plan``, serial executor);
* ``District.time_city``: that site as a city of four 40 m cells (its pairs drawn once, each
  cell planned by the district search, the city stitched; serial executor);
* ``Block.time_kamppi_plan``: the Kamppi block – the committed ``examples/helsinki`` site
  (OSM buildings, 26 facade candidates, 1000 sampled pairs, 64 × 64 RISs, 2–4 RISs) –
  planned in local metres (``run_plan``, serial executor): the interactive plan of
  ``benchmarks/planning/bench_interactive.py`` without the process start, figures and files.

The workloads come from ``benchmarks/fixtures.py``. A commit without the district search or
the city raises in ``setup``, and asv skips the benchmark there.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: the fixtures

from fixtures import helsinki_block, street_document


class District:
    """The district search on a street site, and the same site as a city of four cells."""

    timeout = 600.0
    number = 1
    repeat = (1, 5, 60.0)

    def setup(self) -> None:
        self.doc = street_document(counts=(2, 3), sample=300)
        self.time_street_plan()  # compiled kernels loaded (or compiled) outside the timing

    def time_street_plan(self) -> None:
        from ris_planner.planning import SerialExecutor, run_plan

        run_plan(self.doc, executor=SerialExecutor())

    def time_city(self) -> None:
        from ris_planner.planning.city import plan_city, split_city

        plan_city(split_city(street_document(counts=(4, 6), sample=400), 40.0))


class Block:
    """The Kamppi block, planned in local metres."""

    timeout = 600.0
    number = 1
    repeat = (1, 5, 60.0)

    def setup(self) -> None:
        from ris_planner.io.frames import to_local

        self.doc: dict[str, Any] = to_local(helsinki_block(1000))[0]
        self.time_kamppi_plan()  # compiled kernels loaded (or compiled) outside the timing

    def time_kamppi_plan(self) -> None:
        from ris_planner.planning import SerialExecutor, run_plan

        run_plan(self.doc, executor=SerialExecutor())
