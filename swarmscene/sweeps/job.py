"""A sweep's job in the process that runs it: the task function's multirun half.

Every launcher (basic, pool, joblib, Ray, submitit) runs the command's task function
(``swarmscene.cli._task``) in the process that runs a job; in a multirun it hands the launcher
task to :func:`launcher_task`, and the path goes one way from here:

    launcher_task   this launcher task's jobs: its first (Hydra's ``run_job`` set it up) and the
                    rest (:mod:`.task` composes each)
    job_from        one job's resolved config in the run directory ``HydraConfig`` names
    recorded_job    every exception of the job recorded in its run directory; the others run
    run_job         skip a job already complete for the same config, else fly and land it
                    (:mod:`swarmscene.runpath`, the path ``api.run`` and the command's run take)

A job's exception never ends the sweep: it is written to the job's ``error.json`` and its manifest
says ``failed``, so the sweep's table shows it. A Ctrl-C (or SIGTERM) writes what the job has,
marked incomplete, and raises KeyboardInterrupt to stop the sweep.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

from ..core import interrupts

DEBUG_ENV = "SWARMSCENE_DEBUG"
"""Set (to anything) for a traceback instead of one line."""


def launcher_task(cfg: Any) -> Any:
    """Run a launcher task: its first job (``cfg``) and the task's other jobs, if any, each as a
    job of its own (:mod:`.chunks` packs several jobs into one task). Returns the first job's
    objective, what Hydra's ``run_job`` records for it."""
    from . import task

    task.renumber_first()  # a launcher task of several jobs: this job's number, not the task's
    result = job_from(cfg)
    task.run_rest(lambda job_cfg, run_dir: job_from(job_cfg), cfg)
    return result


def job_from(cfg: Any) -> Any:
    """One job: ``cfg`` resolved (an interpolation that does not resolve is the job's error, with
    its key named) and run in the run directory ``HydraConfig`` names."""
    from hydra.core.hydra_config import HydraConfig
    from omegaconf import OmegaConf

    from ..composition.hydra_errors import resolution_error_line
    from ..core.errors import ConfigError

    run_dir = Path(HydraConfig.get().runtime.output_dir)
    try:
        data = cast("dict[str, Any]", OmegaConf.to_container(cfg, resolve=True))  # the root is a mapping
    except Exception as exc:
        line = resolution_error_line(exc)
        if line is None:
            raise
        raise ConfigError([line]) from exc
    return recorded_job(data, run_dir)


def recorded_job(data: dict[str, Any], run_dir: Path,
                 run: Callable[[dict[str, Any], Path], Any] | None = None) -> Any:
    """:func:`run_job` (or ``run``, the same contract: the batch launcher's landing of a world,
    :mod:`.batch`), with every exception but a stop request recorded in ``run_dir``
    (``error.json``, a manifest marked failed) and one line printed; the launcher runs the others."""
    from ..runs.rundir import RunFileError
    from .records import record_failure

    try:
        return (run or run_job)(data, run_dir)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # the job failed: record it, let the launcher run the others
        line = error_lines(exc)[0]
        try:
            record_failure(run_dir, exc, data)
        except RunFileError as refused:  # a planted link: nothing is written through it
            if str(refused) not in line:
                line += f" (its error.json not written: {refused})"
        except OSError as write_error:  # a full disk, a read-only directory: say so, go on
            line += f" (and its error.json could not be written in {run_dir}: {write_error.strerror or write_error})"
        print(f"swarmscene: job {run_dir.name} failed: {line}", file=sys.stderr)
        names = (data.get("output") or {}).get("objective") or []
        if names:  # a sweeper gets None (Optuna: a failed trial)
            return objective_from(names, {})
        return {"status": "failed", "error": str(exc)}


def run_job(data: dict[str, Any], run_dir: Path) -> Any:
    """Skip the job when ``run_dir`` already holds it complete for this config, else fly and land
    it. One plugin manager serves the job: it validates the scenario and the simulation owns it."""
    from ..runpath import run_and_write
    from ..runs.build import build, load, plugins
    from ..views.writers import extra_writers
    from .records import completed_metrics, write_overrides

    write_overrides(run_dir)  # the job's record of what it is, before anything can fail
    plugin_set = plugins()
    scenario = load(data, plugin_set[1])
    done = completed_metrics(run_dir, scenario.data)  # hashed over the effective configuration
    if done is not None:
        print(f"swarmscene: job {run_dir.name} already complete (same config hash): skipped", file=sys.stderr)
        return objective_from(scenario.config.output.objective, done)
    if interrupts.requested() is not None:  # came while the job was set up: stop before building
        raise KeyboardInterrupt
    sim = build(scenario, plugin_set)
    result, failed = run_and_write(sim, run_dir, extra_writers(sim), sweep=True)
    if not result.complete or interrupts.requested() is not None:
        raise KeyboardInterrupt  # outputs are written (marked incomplete if the run was cut); stop the sweep
    if failed is not None:
        raise failed  # recorded as a failed job (error.json, manifest), outputs kept
    return objective_from(sim.config.output.objective, result.metrics)


def objective_from(names: list[str], metrics: dict[str, Any]) -> Any:
    """The metrics a sweeper optimises (``output.objective``), or all metrics when none is named.

    None when a named metric is missing or not finite (a failed job, a run that blew up): Optuna's
    sweeper records that trial as failed and the study goes on. (It cannot take NaN: Optuna
    refuses the value, and the sweeper's second attempt to record the failure ends the study.)
    """
    if not names:
        return metrics
    values = []
    for name in names:
        value = metrics.get(name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return None
        values.append(float(value))
    return values[0] if len(values) == 1 else tuple(values)


def error_lines(exc: BaseException) -> list[str]:
    """The lines that say what went wrong, for a job's record and the command's exit: a
    configuration error's own lines, a refused file, a dead worker, Hydra's error in one line, an
    unwritable file, else the exception's first line."""
    from ..composition.hydra_errors import hydra_error_line
    from ..core.errors import ConfigError
    from ..core.raised import RunFailed
    from ..runs.rundir import RunFileError
    from .pool import WorkerDied

    if isinstance(exc, ConfigError):
        return exc.lines
    if isinstance(exc, RunFailed):  # its message is the engine's own line (the first non-finite state)
        return [str(exc)]
    cause = cause_of(exc, (ConfigError, RunFileError, WorkerDied))
    if isinstance(cause, ConfigError):  # raised inside Hydra (swarmscene.dir_name, scenario_files)
        return cause.lines
    if isinstance(cause, (RunFileError, WorkerDied)):
        return [str(cause)]
    line = hydra_error_line(exc)
    if line is not None:
        return [line]
    cause = cause_of(exc, (OSError,))
    if isinstance(cause, OSError) and cause.errno is not None and cause.filename is not None:
        return [f"{cause.filename}: cannot be written ({cause.strerror or cause})"]  # a full disk, read-only
    return [f"{type(exc).__name__}: {exc}".splitlines()[0] + f" (set {DEBUG_ENV}=1 for a traceback)"]


def cause_of(exc: BaseException | None, kinds: tuple[type, ...]) -> BaseException | None:
    """The first exception of ``kinds`` in ``exc``'s chain of causes, else None."""
    seen = 0
    while exc is not None and seen < 20:
        if isinstance(exc, kinds):
            return exc
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return None
