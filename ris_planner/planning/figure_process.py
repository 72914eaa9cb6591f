"""A command-line plan's figures, drawn by a helper process beside the parent's last stages
(docs/concepts/planning.md, "Pipeline").

``ris-planner plan`` is one fresh process. Importing matplotlib (≈ 0.5 s) and drawing the
three figures (≈ 0.8 s) used to run on its main thread after the fields, on one core, before
plan.json and the GIS files. :class:`FigureProcess` is started when the command starts: a
child interpreter (``python -m ris_planner.planning.figure_process``) that imports
matplotlib
and the figure code while the parent reads the document and searches (when one core is idle),
then waits on its stdin. :meth:`FigureProcess.submit` hands it the plan result once the
fields are in; it draws the figures into the output folder while the parent settles the
checks and writes plan.json's content and the GIS files, and :meth:`FigureProcess.files`
collects their paths. The same function draws them (:func:`~ris_planner.planning.outputs.report.
write_figures`), so the files are those an in-process plan writes (tested).

A plan never fails for the helper: if it did not start, died, or failed to draw, the parent
draws the figures itself and :attr:`FigureProcess.note` says why. The helper ends with its
one plan or when its stdin closes (the parent gone), and the parent stops it by its PID when
the plan fails (:meth:`FigureProcess.close`). The service's jobs draw in their own process:
their forkserver has matplotlib loaded already (docs/guides/service-operations.md).
"""

from __future__ import annotations

import contextlib
import dataclasses
import pickle
import struct
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Any, cast

import numpy as np
from numpy.typing import NDArray

from ris_planner.planning.outputs.result import PlanResult
from ris_planner.planning.scoring.layout_scorer import LayoutScorer

_HEADER = struct.Struct("<Q")
"""Each message: its length (8 bytes, little-endian), then a pickle."""

STOP_TIMEOUT_S = 5.0
""":meth:`FigureProcess.close` waits this long for the helper to end after SIGTERM, then kills
it."""


def _send(stream: IO[bytes], obj: Any) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)
    stream.flush()


def _receive(stream: IO[bytes]) -> Any:
    """The next message, or ``None`` at the end of the stream."""
    head = stream.read(_HEADER.size)
    if len(head) < _HEADER.size:
        return None
    (size,) = _HEADER.unpack(head)
    data = stream.read(size)
    if len(data) < size:
        return None
    return pickle.loads(data)  # from our own parent (or helper), over a private pipe


@dataclass(frozen=True)
class _ScorerView:
    """What the figures read of a plan's scorer
    (:class:`~ris_planner.planning.scoring.layout_scorer.LayoutScorer`): each site's
    near-field weight and the metric's column weights – not the information itself (hundreds of
    MB for a large plan)."""

    near: NDArray[np.float64]
    metric_weights: NDArray[np.float64]
    mirror: bool

    def near_field_by_site(self, weights: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.near


def figure_job(result: PlanResult) -> PlanResult:
    """``result`` as the helper needs it: without its pending checks (they stay here), without
    the search's state kept for the sizing (a district plan's problem, search view and
    relaxation: 355 MB at 5000 pairs, docs/validation/benchmarks.md "District physics"; the
    sizing has run by now) and with a view of its scorer that holds only what the figures
    read (:class:`_ScorerView`), so the hand-over's size follows the maps and fields, not the
    information."""
    scorer = result.scorer
    near = scorer.near_field_by_site(result.pairs.weights)
    view = _ScorerView(near, scorer.metric_weights, scorer.mirror)
    return dataclasses.replace(
        result, pending_checks=None, sizing_state=None, scorer=cast(LayoutScorer, view)
    )


def _draw(result: PlanResult, out_dir: Path) -> dict[str, Path]:
    from ris_planner.planning.outputs.report import write_figures

    return write_figures(result, out_dir)


class FigureProcess:
    """The helper process of one command-line plan (module docstring); a context manager
    that stops it on the way out."""

    def __init__(self) -> None:
        self.note: str | None = None
        """Why the figures were drawn in the parent after all (``None``: by the helper)."""
        # the helper's stderr, for the note if it fails; closed with this object
        self._log = tempfile.TemporaryFile()  # noqa: SIM115
        self._job: tuple[PlanResult, Path] | None = None
        self._proc: subprocess.Popen[bytes] | None
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "ris_planner.planning.figure_process"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=self._log,
            )
        except OSError as exc:
            self._proc = None
            self.note = f"the figure process did not start ({exc})"

    @property
    def pid(self) -> int | None:
        """The helper's PID while it runs (``None`` once it ended or never started)."""
        return None if self._proc is None or self._proc.poll() is not None else self._proc.pid

    def submit(self, result: PlanResult, out_dir: Path) -> None:
        """Hand the helper the figures of ``result`` (:func:`figure_job`: what they read) to
        draw into ``out_dir``; returns at once."""
        job = figure_job(result)
        self._job = (job, out_dir)
        if self._proc is None or self._proc.stdin is None:
            return
        try:
            _send(self._proc.stdin, (job, out_dir))
            self._proc.stdin.close()
        except (OSError, ValueError, pickle.PicklingError) as exc:
            self._failed(f"the figure process could not take the plan ({exc})")

    def files(self) -> dict[str, Path]:
        """The figures' paths once drawn
        (:func:`~ris_planner.planning.outputs.report.write_figures`'s
        answer); drawn here instead when the helper could not (:attr:`note` says why)."""
        if self._job is None:
            raise RuntimeError("FigureProcess.files() before submit()")
        reply = None
        if self._proc is not None and self._proc.stdout is not None:
            try:
                reply = _receive(self._proc.stdout)
            except (OSError, EOFError, pickle.UnpicklingError) as exc:
                self._failed(f"the figure process's answer was unreadable ({exc})")
        if isinstance(reply, dict):
            self.close()
            return {name: Path(path) for name, path in reply.items()}
        if isinstance(reply, str):
            self._failed(f"the figure process failed: {reply}")
        elif self._proc is not None:
            self._failed("the figure process ended without drawing")
        self.close()
        return _draw(*self._job)

    def _failed(self, why: str) -> None:
        if self.note is None:
            self._log.seek(0)
            tail = self._log.read().decode("utf-8", "replace").strip().splitlines()[-3:]
            self.note = why + (": " + " | ".join(tail) if tail else "")
        self.close()

    def close(self) -> None:
        """Stop the helper by its PID if it still runs (SIGTERM, then SIGKILL after
        :data:`STOP_TIMEOUT_S`) and reap it."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        for stream in (proc.stdin, proc.stdout):
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()

    def __enter__(self) -> FigureProcess:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
        self._log.close()


def main() -> int:
    """The helper: import the figure code, wait for one plan on stdin, draw it, answer with the
    paths (or the error's one line) on stdout."""
    from ris_planner.planning.warmup import prepare_figures

    prepare_figures()  # while the parent reads the document and searches

    job = _receive(sys.stdin.buffer)
    if job is None:  # the parent went away or drew the figures itself
        return 0
    result, out_dir = job
    try:
        files = _draw(result, out_dir)
    except Exception as exc:  # reported to the parent, which draws instead
        _send(sys.stdout.buffer, f"{type(exc).__name__}: {exc}")
        return 1
    _send(sys.stdout.buffer, {name: str(path) for name, path in files.items()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
