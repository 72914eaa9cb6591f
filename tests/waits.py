"""The suite's one rule for waiting (docs/validation/robustness.md, "A loaded machine").

A test waits for an event – a job's status, a process's end, a page's element, a file – and
never for a fixed time; a wait has an upper limit only to end a hang, so generous that a machine
many times slower or busier than the development one never reaches it. No test bounds how long
something takes: how fast the code is belongs to benchmarks/ (docs/validation/benchmarks.md).
A timeout *mechanism* of the code is tested by what it does (a deadline fires, a refusal comes
before the work), not by the seconds it took.
"""

from __future__ import annotations

HANG_S = 900.0
"""A wait that has not ended after this long hangs (seconds)."""

HANG_MS = int(HANG_S * 1000)
"""The same in milliseconds (Playwright's waits)."""
