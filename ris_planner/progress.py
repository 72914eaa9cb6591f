"""Progress reporting shared by long jobs (CLI bars, API job progress).

A :data:`ProgressCallback` receives a fraction in [0, 1] and a short message. Library code
takes one as an optional keyword argument and never prints by itself.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

ProgressCallback = Callable[[float, str], None]


def no_progress(fraction: float, message: str) -> None:
    """The default callback: report nothing."""


class ProgressBar:
    """A text progress bar on stderr for the CLI (redraws at most every 0.1 s)."""

    def __init__(self, label: str, stream: TextIO | None = None, width: int = 30) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self._last = 0.0
        self._start = time.perf_counter()

    def __call__(self, fraction: float, message: str = "") -> None:
        now = time.perf_counter()
        if fraction < 1.0 and now - self._last < 0.1:
            return
        self._last = now
        frac = min(max(fraction, 0.0), 1.0)
        filled = round(frac * self.width)
        bar = "#" * filled + "-" * (self.width - filled)
        elapsed = now - self._start
        self.stream.write(f"\r{self.label} [{bar}] {frac:6.1%} {elapsed:6.1f}s {message[:40]:<40}")
        if frac >= 1.0:
            self.stream.write("\n")
        self.stream.flush()
