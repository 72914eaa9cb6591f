"""Progress reporting shared by long jobs (CLI bars, API job progress).

A :data:`ProgressCallback` receives a fraction in [0, 1] and a short message. Library code
takes one as an optional keyword argument and never prints by itself.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from typing import Protocol, TextIO

ProgressCallback = Callable[[float, str], None]


def no_progress(fraction: float, message: str) -> None:
    """The default callback: report nothing."""


class ProgressBar:
    """A text progress bar on stderr for the CLI (redraws at most every 0.1 s, and always at a
    new stage: the part of the message before its first ``:``, :class:`Stages`)."""

    def __init__(self, label: str, stream: TextIO | None = None, width: int = 30) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self._last = 0.0
        self._stage: str | None = None
        self._start = time.perf_counter()

    def __call__(self, fraction: float, message: str = "") -> None:
        now = time.perf_counter()
        stage = message.split(":", 1)[0]
        if fraction < 1.0 and now - self._last < 0.1 and stage == self._stage:
            return
        self._last = now
        self._stage = stage
        frac = min(max(fraction, 0.0), 1.0)
        filled = round(frac * self.width)
        bar = "#" * filled + "-" * (self.width - filled)
        elapsed = now - self._start
        self.stream.write(f"\r{self.label} [{bar}] {frac:6.1%} {elapsed:6.1f}s {message[:40]:<40}")
        if frac >= 1.0:
            self.stream.write("\n")
        self.stream.flush()


LAST_BEFORE_END = 0.999
"""The largest fraction :class:`Stages` reports before :meth:`Stages.finish` (1.0 only at the
end)."""


class StageTimer(Protocol):
    """What :class:`Stages` needs of a plan's clock
    (:class:`StageClock`)."""

    def between(self) -> AbstractContextManager[None]:
        """Time the block as the reports between stages, unless a stage is timing it."""
        ...


class Stages:
    """A progress callback split over consecutive named stages, each holding a share of the bar
    proportional to its estimated work (seconds,
    :mod:`ris_planner.planning.resources.time_estimate`).

    ``stages.callback(name)`` is the callback of one stage: its own fraction f ∈ [0, 1] maps
    to ``start + f · share`` and its message becomes ``"name: message"``. Fractions never go
    back (a later stage's call below an earlier one repeats the earlier fraction), stay below
    1 (at most :data:`LAST_BEFORE_END`) until :meth:`finish` reports 1.0, so a bar shows 100 %
    only once everything – figures and exports included – is written. Stages may be nested:
    an inner :class:`Stages` on an outer stage's callback finishes at that stage's end.

    ``clock``: the plan's; a report made between its stages (a stage's start is reported
    before the stage's own timer runs, the end after the last) is timed by it too – a service
    job writes every report to its store, so plan.json's ``timing_s`` still sums to the
    plan's time."""

    def __init__(
        self, progress: ProgressCallback, work: dict[str, float], clock: StageTimer | None = None
    ) -> None:
        self.progress = progress
        self.clock = clock
        total = sum(max(w, 0.0) for w in work.values())
        self.start: dict[str, float] = {}
        self.share: dict[str, float] = {}
        at = 0.0
        for name, w in work.items():
            share = max(w, 0.0) / total if total > 0 else 1.0 / len(work)
            self.start[name], self.share[name] = at, share
            at += share
        self.fraction = 0.0

    def report(self, name: str, fraction: float, message: str = "") -> None:
        """Report stage ``name`` at its own ``fraction``."""
        f = self.start[name] + self.share[name] * min(max(fraction, 0.0), 1.0)
        self.fraction = max(self.fraction, min(f, LAST_BEFORE_END))
        with self._timed():
            self.progress(self.fraction, f"{name}: {message}" if message else name)

    def _timed(self) -> AbstractContextManager[None]:
        return self.clock.between() if self.clock is not None else nullcontext()

    def callback(self, name: str) -> ProgressCallback:
        """The progress callback of stage ``name`` (reports its start at once)."""
        self.report(name, 0.0)

        def on_stage(fraction: float, message: str = "") -> None:
            self.report(name, fraction, message)

        return on_stage

    def finish(self, message: str = "done") -> None:
        """Report the end: 1.0."""
        self.fraction = 1.0
        with self._timed():
            self.progress(1.0, message)


BETWEEN_STAGES = "progress"
"""The ``timing_s`` entry of the progress reports made between stages (each stage's start is
reported before its timer runs): a service job writes every report to its store."""


class StageClock:
    """Wall seconds per named stage (plan.json ``timing_s``) and this process's CPU seconds
    in each (``cpu``: the time estimate's calibration on a busy machine,
    docs/validation/resources.md); a stage timed twice adds up."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.cpu: dict[str, float] = {}
        self._depth = 0  # stages being timed now (nested: an inner one adds to its own too)

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block under ``name``."""
        t0, c0 = time.perf_counter(), time.process_time()
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            self.add(name, time.perf_counter() - t0, time.process_time() - c0)

    @contextmanager
    def between(self) -> Iterator[None]:
        """Time the block under :data:`BETWEEN_STAGES` unless a stage is timing it already
        (:class:`~ris_planner.runtime.progress.Stages` reports a stage's start before it)."""
        if self._depth:
            yield
        else:
            with self.stage(BETWEEN_STAGES):
                yield

    def add(self, name: str, seconds: float, cpu: float = 0.0) -> None:
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds
        self.cpu[name] = self.cpu.get(name, 0.0) + cpu
