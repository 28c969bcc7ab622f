"""The Hydra callback of every multirun (``hydra.callbacks.swarmscene_summary``): progress while
the jobs run, the sweep's tables and its exit status at the end."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback

from ..composition.hydra_internals import BASIC_SWEEPER
from .tables import exit_status, outcome_line, write_summary

SWARMSCENE_SWEEPER = "hydra_plugins.swarmscene_sweeper.SwarmsceneSweeper"
PROGRESS = ("auto", "on", "off")

_outcome: dict[str, int] = {}
_written: dict[str, Any] = {}
"""The summary written by the sweeper under its lock (:func:`write_under_lock`), by sweep directory:
its rows, or the exception that stopped it; the callback reports it rather than writing again."""
SUMMARY_TARGET = "swarmscene.sweeps.callback.SweepSummary"


def summary_wanted(config: Any) -> bool:
    """Whether this multirun's callbacks include the sweep summary (a user may remove it)."""
    try:
        callbacks = config.hydra.callbacks or {}
        return any((c or {}).get("_target_") == SUMMARY_TARGET for c in callbacks.values())
    except Exception:  # no callbacks node: no summary
        return False


def write_under_lock(sweep_dir: Path) -> None:
    """Write the sweep's tables while the sweeper still holds the directory's lock (called by
    :class:`~swarmscene.sweeps.sweeper.SwarmsceneSweeper` before it releases it): written after the
    release, a second sweep let into the directory could change its jobs under the tables being
    written. The outcome waits for the callback's ``on_multirun_end``, which reports it."""
    try:
        _written[str(sweep_dir)] = write_summary(sweep_dir)
    except Exception as exc:  # reported by the callback, like its own write's failure
        _written[str(sweep_dir)] = exc


_started: list[tuple[Any, Any]] = []
"""(callback, config) of the running multirun's end-of-sweep callbacks, for :func:`end_after_sweeper_error`."""
NO_COMPLETED_TRIAL = "No trials are completed yet"
"""Optuna's error when a study's best trial is asked for and every trial failed."""


def end_after_sweeper_error(exc: BaseException) -> int | None:
    """Hydra's Optuna sweeper asks for the study's best trial after the last one and raises
    ``ValueError: No trials are completed yet`` when every trial failed, before any callback's
    end: no table, and a bad-input exit status for jobs that did run. For that error, run the
    end-of-sweep callbacks it skipped (the tables, the falsifier's record) and return the exit
    status they set (1 when jobs failed, unless ``allow_failed``); None for any other exception."""
    if not (isinstance(exc, ValueError) and str(exc).startswith(NO_COMPLETED_TRIAL) and _started):
        return None
    ended, _started[:] = list(_started), []
    print("swarmscene: the sweeper stopped: every trial failed, so no best one (Optuna); the sweep's "
          "end follows", file=sys.stderr)
    for callback, config in ended:
        try:
            callback.on_multirun_end(config)
        except Exception as err:  # one callback's failure must not hide the others' outputs
            print(f"swarmscene: {type(callback).__name__}: {err}", file=sys.stderr)
    status = _outcome.pop("status", None)
    return 1 if status is None else status  # the tables' own status (allow_failed may keep it 0)


def started(callback: Any, config: Any) -> None:
    """Record an end-of-sweep callback of the multirun now starting (:func:`end_after_sweeper_error`)."""
    _started.append((callback, config))


def take_exit_status() -> int | None:
    """The exit status of the multirun that just ended (None: none ended since the last call),
    for the command line to end with: a callback reports, it does not end the process (a
    ``SystemExit`` here would skip the callbacks after it, e.g. MLflow's end of run)."""
    return _outcome.pop("status", None)


class SweepSummary(Callback):
    """Hydra callback of every multirun.

    While the jobs run it shows their progress (jobs done of the total, failures so far, time left;
    :class:`~swarmscene.sweeps.progress.SweepProgress`), whatever the launcher. At the end it writes
    the sweep directory's tables, prints how many jobs did not complete, and sets the exit status:
    1 when a job did not complete, unless ``allow_failed`` is true.

    At the start it puts swarmscene's sweeper in the place of Hydra's basic sweeper (Hydra's default
    multirun: same ``params`` and ``max_batch_size``), so every grid sweep has one check path
    (:mod:`swarmscene.sweeps.sweeper`).

    Args:
        allow_failed: keep exit status 0 when jobs failed (the summary still counts them).
        progress: ``auto`` (on a terminal), ``on`` or ``off``: the sweep's progress line.
    """

    def __init__(self, allow_failed: bool = False, progress: str = "auto") -> None:
        if progress not in PROGRESS:  # Hydra reports an exception here as the command's one line
            raise ValueError(f"hydra.callbacks.swarmscene_summary.progress: must be auto, on or off (got {progress!r})")
        self.allow_failed = bool(allow_failed)
        self.progress_mode = progress
        self.progress: Any = None

    def __getstate__(self) -> dict[str, Any]:
        # Launchers pickle the callbacks with each job; the watcher thread stays in this process.
        return {**self.__dict__, "progress": None}

    def on_multirun_start(self, config: Any, **kwargs: Any) -> None:
        """Before the first job: Hydra's basic sweeper becomes swarmscene's, and the progress
        line starts (``progress``)."""
        _outcome.pop("status", None)
        _written.clear()
        _started[:] = []
        started(self, config)
        self._replace_basic_sweeper(config)
        from .progress import SweepProgress

        try:
            sweep_dir = Path(config.hydra.sweep.dir)
        except Exception:  # e.g. a `name` the run-dir resolver refuses: the sweeper says so in one line
            return
        self.progress = SweepProgress.maybe(sweep_dir, self.progress_mode)

    def _replace_basic_sweeper(self, config: Any) -> None:
        """Hydra's basic sweeper becomes swarmscene's, with the same ``params`` and
        ``max_batch_size``: Hydra instantiates the sweeper from this very config right after this
        callback, and its basic sweeper composes every job in the main process (hydra#1324). Done
        here because a primary config's ``override hydra/sweeper`` would beat the presets that
        choose another sweeper (Optuna)."""
        from omegaconf import open_dict

        sweeper = config.hydra.sweeper
        if sweeper.get("_target_") != BASIC_SWEEPER:
            return
        with open_dict(sweeper):
            sweeper["_target_"] = SWARMSCENE_SWEEPER
            for key, value in (("validate", "each_value"), ("on_invalid", "stop"), ("cases", None), ("upfront", 1000),
                           ("jobs_per_task", "auto")):
                sweeper.setdefault(key, value)

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        """After the last job: the summary tables, the outcome line and the command's exit status."""
        _started[:] = [(c, cfg) for c, cfg in _started if c is not self]
        if self.progress is not None:
            self.progress.stop()
        sweep_dir = Path(config.hydra.sweep.dir)
        try:  # written by swarmscene's sweeper under its lock; another sweeper's (Optuna): here
            rows = _written.pop(str(sweep_dir)) if str(sweep_dir) in _written else write_summary(sweep_dir)
            if isinstance(rows, Exception):
                raise rows
        except Exception as exc:  # a table problem must not hide the jobs' own outputs
            print(f"swarmscene: could not write the sweep summary: {exc}", file=sys.stderr)
            _outcome["status"] = 1
            return
        status = exit_status(rows, self.allow_failed)
        kept = " (allow_failed: exit status 0)" if self.allow_failed and exit_status(rows) else ""
        print(f"swarmscene: {outcome_line(rows)}{kept}; summary in {sweep_dir / 'summary.md'}", file=sys.stderr)
        _outcome["status"] = status  # the command line ends with it (take_exit_status)
