"""A sweep's progress line: jobs done of the total, failures so far, time left, under any launcher."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

from ..views.summary import Progress


class SweepProgress:
    """Jobs done of the total, failures so far and the time left of a sweep, under any launcher.

    A daemon thread of the process that launched the sweep counts the job directories' records every
    ``period`` seconds (a manifest marks a finished job, ``error.json`` a failed one). The jobs may run
    in this process, in joblib workers or on Ray nodes writing to the same directory: watching the
    directory is what every launcher has in common. The total comes from the sweep's grid record
    (``sweep.json``); an optimising sweeper, which has none, shows the count alone. The time left is
    the jobs remaining divided by the rate of the jobs finished since the sweep started (jobs already
    complete when a sweep resumes do not count toward the rate).
    """

    PERIOD = 1.0

    def __init__(self, sweep_dir: Path, stream: Any = None, period: float | None = None) -> None:
        import threading

        self.sweep_dir = Path(sweep_dir)
        self.bar = Progress(stream=stream, delay=0.0)
        self.period = self.PERIOD if period is None else period
        self.stop_event = threading.Event()
        self.thread = threading.Thread(target=self._watch, name="swarmscene-sweep-progress", daemon=True)
        self.first: tuple[float, float] | None = None
        self.total: int | None = None  # read from sweep.json once it exists

    @classmethod
    def maybe(cls, sweep_dir: Path, mode: str = "auto") -> SweepProgress | None:
        """A started SweepProgress when asked for (``on``), or for ``auto`` on a terminal."""
        if mode == "off" or (mode == "auto" and not sys.stderr.isatty()):
            return None
        progress = cls(sweep_dir)
        progress.thread.start()
        return progress

    def counts(self) -> tuple[int, int, int | None]:
        """(jobs finished, of which failed, total jobs or None) as recorded in the directory now."""
        done = failed = 0
        if self.sweep_dir.is_dir():
            for job in self.sweep_dir.iterdir():
                if not job.is_symlink() and job.is_dir() and (job / "manifest.json").is_file():
                    done += 1
                    failed += (job / "error.json").is_file()
        if self.total is None:  # the grid record does not change once written
            from ..core.errors import ConfigError
            from .records import read_grid

            try:
                record = read_grid(self.sweep_dir)
            except ConfigError:  # damaged: the sweep refuses it; the count goes on without a total
                record = None
            self.total = len(record["jobs"]) if record is not None else None
        return done, failed, self.total

    def line(self, elapsed: float) -> str:
        """The progress line ``elapsed`` seconds in: jobs done and failed (a bar with a total)."""
        done, failed, total = self.counts()
        if self.first is None:
            self.first = (float(done), elapsed)
        text = f"{done}/{total} jobs done" if total else f"{done} jobs done"
        text += f", {failed} failed"
        if total:
            return self.bar.line(done, total, text, elapsed, since=self.first)
        return f"  {text} "

    def _watch(self) -> None:
        start = time.perf_counter()
        while not self.stop_event.wait(self.period):
            self.bar._show(self.line(time.perf_counter() - start))
            self.bar.shown = True
        self.bar._show(self.line(time.perf_counter() - start))

    def stop(self) -> None:
        """The last count, then a new line."""
        self.stop_event.set()
        self.thread.join(timeout=5)
        self.bar.shown = True
        self.bar.close()
