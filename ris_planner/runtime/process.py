"""This process's age: the ``startup`` entry of a command-line plan's ``timing_s`` (the
interpreter's start, the imports and the reading of the document before the plan's first
stage; docs/concepts/planning.md, "Output")."""

from __future__ import annotations

import os
import time


def process_age_s() -> float | None:
    """Seconds since this process started (Linux: its start time in ``/proc/self/stat``
    against the boot-time clock, to the kernel's clock tick, 10 ms); ``None`` where that is
    not available."""
    try:
        with open("/proc/self/stat", encoding="ascii") as f:
            stat = f.read()
        # the fields after the command name "(…)": state is field 3, starttime field 22
        start_ticks = int(stat.rsplit(")", 1)[1].split()[19])
        now = time.clock_gettime(time.CLOCK_BOOTTIME)
        return max(0.0, now - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return None
