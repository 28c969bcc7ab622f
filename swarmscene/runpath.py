"""The one path from a built simulation to its run directory (issue #35).

``api.run``, ``api.run_batch``, the command line's run and every sweep job take it:

* :func:`fly` runs the simulation with its progress line (or the caller's callback) and keeps what
  a plugin's exception left behind, so that the run's records are written either way;
* :func:`land` writes the run directory: ``config.yaml``, the trajectory, ``metrics.json``, the
  observers' own files, the optional outputs asked for (plots, replay, ROS 2 bag) and the manifest
  last, which lists them all; it returns the error a run that failed leaves to record.

The callers differ only in what follows: ``api.run`` raises a plugin's exception again, the command
line prints the summary or exits with the run's status, a sweep job records the failure and lets the
launcher go on (:func:`swarmscene.sweeps.records.record_failure` writes ``error.json``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .core.raised import PluginRaised, RunFailed

if TYPE_CHECKING:
    from .core.result import RunResult
    from .core.simulation import Simulation


def utc_now() -> str:
    """The current time, UTC, ISO 8601 (the manifest's ``started_at``)."""
    return datetime.now(UTC).isoformat(timespec="seconds")


@dataclass
class Flight:
    """A run that ended: its result, when it started, and the exception a plugin raised (if one did).

    Attributes:
        result: what the run recorded (up to the exception, for a run a plugin stopped).
        started_at: the run's start, UTC, ISO 8601 (the manifest's ``started_at``).
        raised: the :class:`~swarmscene.core.raised.PluginRaised` that ended the run, or None.
        cause: the plugin's own exception (``raised.__cause__``; a batch world's failure).
    """

    result: RunResult
    started_at: str
    raised: PluginRaised | None = None
    cause: BaseException | None = None

    @property
    def failure(self) -> RunFailed | None:
        """The error to record for a run that did not fly to its end (a non-finite state, a plugin's
        exception), or None."""
        return None if self.result.error is None else RunFailed.of(self.result, self.cause)


def fly(sim: Simulation, progress: Callable[[Simulation], None] | None = None,
        gather_warnings: bool = False) -> Flight:
    """Run ``sim`` to its end; a plugin's exception ends it with what it recorded (not raised here).

    Args:
        sim: the built simulation.
        progress: called after every tick: the engine's progress line
            (:class:`~swarmscene.views.summary.Progress`, closed when the run ends, before the warnings are
            shown) or the caller's callback.
        gather_warnings: hold the run's warnings and show each distinct one once at its end
            (:class:`~swarmscene.views.summary.RunWarnings`; the command line's habit), numpy's numeric
            ones left out for a run that stopped on a non-finite state, which said so already.
    """
    from contextlib import nullcontext

    from .views.summary import Progress, RunWarnings

    started_at = utc_now()
    raised: PluginRaised | None = None
    seen = RunWarnings() if gather_warnings else None
    with seen if seen is not None else nullcontext():
        try:
            result = sim.run(progress=progress)
        except PluginRaised as exc:  # what the run recorded is kept, and written by land()
            result, raised = exc.result, exc
        finally:
            if isinstance(progress, Progress):
                progress.close()
    if seen is not None:
        seen.show(failed=result.error is not None)
    return Flight(result, started_at, raised, raised.__cause__ if raised is not None else None)


def land(sim: Simulation, flight: Flight, run_dir: Path,
         writers: Sequence[Callable[..., Any]] = ()) -> RunFailed | None:
    """Write ``flight``'s run directory (module docstring); return the error it leaves to record.

    ``writers`` are the optional outputs (``api.extra_writers``), each called with the directory,
    the simulation and the result before the manifest is written.
    """
    result = flight.result
    extras = [lambda directory, write=write: write(directory, sim=sim, result=result) for write in writers]
    write_outputs(sim, result, run_dir, extras, started_at=flight.started_at)
    return flight.failure


def write_outputs(
    sim: Simulation,
    result: RunResult,
    run_dir: Path,
    extras: Sequence[Callable[[Path], Any]] = (),
    started_at: str | None = None,
) -> None:
    """Write config, trajectory, metrics and manifest of a finished run into ``run_dir``;
    ``extras(run_dir)`` (plots, replay) write theirs before the manifest, which lists them, after
    the files observers hand back (``run_files()``, :func:`~swarmscene.runs.outputs.write_observer_files`).

    ``config.yaml`` is the effective configuration (``sim.scenario.data``); ``started_at`` is the
    run's start (UTC, ISO 8601) for the manifest.
    """
    from .runs.outputs import write_observer_files, write_run_dir

    write_run_dir(
        run_dir,
        data=sim.scenario.data,
        metrics=result.metrics,
        trajectory=result.trajectory,
        complete=result.complete,
        seed=sim.config.seed,
        # each observer's own files (its run_files(): swarmlab.npz), then the pictures asked for
        extras=[lambda directory: write_observer_files(directory, result.observers), *extras],
        started_at=started_at,
    )
    result.run_dir = run_dir


def run_and_write(sim: Simulation, run_dir: Path, writers: Sequence[Callable[..., Any]], sweep: bool
                  ) -> tuple[RunResult, RunFailed | None]:
    """The command's run and a sweep job's: fly with the progress line (not in a sweep, whose line is
    the sweep's), land, print the summary of a run that flew (not in a sweep); return the result and,
    for a run that failed (a non-finite state, a plugin's exception), the error to record."""
    from .views.summary import Progress, summary_text

    output = sim.config.output
    flight = fly(sim, Progress.maybe(output.progress, enabled=not sweep), gather_warnings=True)
    failed = land(sim, flight, run_dir, writers)  # the manifest, last, lists every file
    if failed is None and output.summary and not sweep:
        print(summary_text(sim, flight.result, run_dir))
    # A run that did not fly to its end gets no verdicts: its one line (the caller prints it) says why.
    return flight.result, failed
