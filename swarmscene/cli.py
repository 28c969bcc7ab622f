"""The ``swarmscene`` command: Hydra composes, the engine validates and runs, a summary is printed.

    swarmscene                                    # the default scenario
    swarmscene scenario=cem_six_vehicle avoidance.K=1
    swarmscene --multirun avoidance.K=1,2,5       # a sweep (Hydra launchers)
    swarmscene --help | --cfg job | --info
    swarmscene --version | plugins                # what is installed (swarmscene.info)

Bad input prints one line per problem (``dotted.key: what is allowed (got value)``) and exits
with status 2, without a traceback (set ``SWARMSCENE_DEBUG=1`` for one) and without leaving a run
directory behind. In a multirun, a failing job is recorded with its error (the others run), a
job already complete for the same config is skipped, and the sweep directory gets summary.csv and
summary.md at the end (docs/sweeps.md). Ctrl-C writes what the run has, marked incomplete, and
exits with status 130; SIGTERM (a scheduler's cancel, ``kill``) does the same with status 143.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from .core import interrupts

if TYPE_CHECKING:  # pragma: no cover
    from .core.raised import RunFailed

# A launcher's worker process (joblib, ray, submitit) imports this module to run `_task`, with
# Hydra already loaded, and then resolves the job's directory and writes its `.hydra/` files
# (hydra_files.py): protect them now. The command itself does it in main(), after its signal
# handler is in place, so that a Ctrl-C during start-up is never a traceback. ("hydra" first:
# the plain command imports nothing more than before.)
if "hydra" in sys.modules:
    from .hydra_internals import save_config_loaded as _save_config_loaded

    if _save_config_loaded():
        from .hydra_files import install as _protect_run_dirs

        _protect_run_dirs()

EXIT_FAILED = 1  # the run started and failed (a non-finite state): its outputs say so
EXIT_CONFIG = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report a Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM
DEBUG_ENV = "SWARMSCENE_DEBUG"


def _interrupted_status() -> tuple[int, str]:
    """Exit status and word for the stop request received: SIGTERM (a scheduler's cancel, ``kill``)
    is handled like Ctrl-C, only the status differs."""
    import signal

    if interrupts.requested() == signal.SIGTERM:
        return EXIT_TERMINATED, "terminated"
    return EXIT_INTERRUPTED, "interrupted"


def _exit_interrupted(what: str = "") -> None:
    status, word = _interrupted_status()
    print(f"swarmscene: {word} {what}".rstrip(), file=sys.stderr)
    sys.exit(status)


EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, as a shell reports a writer whose reader went away


def main() -> None:
    """Console entry point."""
    _freeze_at_exit()
    try:
        _dispatch()
    except BrokenPipeError:  # `swarmscene --help | head`: the reader left, nothing went wrong here
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        sys.exit(EXIT_BROKEN_PIPE)


def _freeze_at_exit() -> None:
    """At the process's exit, leave the interpreter's shutdown garbage collections nothing to scan
    (``gc.freeze``): every file is written and closed by then, and those collections, over the
    ~170,000 objects of Hydra, OmegaConf and numba a run leaves, took ~0.4 s of every command
    while freeing nothing that outlives the process. Registered once per process, at the start of
    :func:`main`, so it runs after the exit handlers registered later (atexit runs them last in,
    first out)."""
    import atexit
    import gc

    if not _FROZEN_AT_EXIT:
        _FROZEN_AT_EXIT.append(True)
        atexit.register(gc.freeze)


_FROZEN_AT_EXIT: list[bool] = []


def _dispatch() -> None:
    if sys.argv[1:] in (["--version"], ["plugins"]):  # not Hydra overrides: answered without composing
        from . import info

        sys.exit(info.command(sys.argv[1]))
    # First of all: from here on SIGINT/SIGTERM are recorded, and acted on at the next point
    # where the run can stop cleanly (core/interrupts.py), never raised inside compiled code.
    # The previous handlers come back afterwards (main() called in a process that goes on: tests).
    interrupts.clear()
    with interrupts.handle_stop_signals():
        _main()


def _main() -> None:
    import hydra

    from .searchpath import plain_command_line, register_search_path

    register_search_path()
    _show_deprecations()
    # Plain `key=value` for every documented option, before Hydra parses the command line
    # (searchpath.plain_overrides: `a.b=v` -> `++a.b=v`).
    from .core.errors import ConfigError

    try:
        sys.argv[1:] = plain_command_line(sys.argv[1:])
    except ConfigError as exc:  # an override without a key
        _report(exc.lines)
    sys.argv[1:] = [*sys.argv[1:], *_named_output_dirs(sys.argv[1:])]
    debug = bool(os.environ.get(DEBUG_ENV)) or bool(os.environ.get("HYDRA_FULL_ERROR"))
    if debug:
        os.environ[DEBUG_ENV] = "1"  # the task reads it too
    # With HYDRA_FULL_ERROR Hydra raises composition errors instead of printing them with its own
    # multi-line wording, so they reach the one-line formatting below. Put back afterwards: a
    # caller in the same process (a test, a notebook) must not hand it to its later subprocesses,
    # which would then print tracebacks instead of one line.
    before = os.environ.get("HYDRA_FULL_ERROR")
    os.environ["HYDRA_FULL_ERROR"] = "1"
    app = hydra.main(config_path="pkg://swarmscene.scenarios", config_name="config", version_base="1.3")(
        _task
    )
    try:
        app()
    except KeyboardInterrupt:  # a sweep's job stopped, or a second Ctrl-C
        _exit_interrupted()
    except BrokenPipeError:
        raise
    except Exception as exc:  # every user-fixable problem becomes one line
        ended = _sweep_end_after(exc)
        if ended is not None:  # a sweeper that stopped after its jobs ran: their tables are written
            sys.exit(ended)
        if debug:
            raise
        _report(_error_lines(exc), _error_status(exc))
    finally:
        if before is None:
            os.environ.pop("HYDRA_FULL_ERROR", None)
        else:
            os.environ["HYDRA_FULL_ERROR"] = before
    if interrupts.requested() is not None:  # came after the last job was written
        _exit_interrupted("after the outputs were written")
    sweep_status = _multirun_status()
    if sweep_status:
        sys.exit(sweep_status)


def _named_output_dirs(argv: list[str]) -> list[str]:
    """``hydra.run.dir`` and ``hydra.sweep.dir`` as the shipped config names them (outputs/<name>/
    <time>, multirun/<name>/<time>) for a primary config that sets neither: a recorded run's
    ``config.yaml`` or the falsifier's ``worst_case.yaml`` (``--config-path DIR --config-name
    NAME``) holds no ``hydra`` node, and Hydra's own default wrote to outputs/<date>/<time>. Left
    alone when the file sets its own or the command line names them."""
    import re

    path, name = _option(argv, ("-cp", "--config-path")), _option(argv, ("-cn", "--config-name"))
    if path is None or name is None:
        return []
    file = Path(path) / (name if name.endswith(".yaml") else f"{name}.yaml")
    try:
        if not file.is_file() or re.search(r"^hydra:", file.read_text(errors="replace"), flags=re.M):
            return []
    except OSError:
        return []  # Hydra says what is wrong with it
    shipped = _shipped_hydra_dirs()
    given = {a.split("=", 1)[0].lstrip("+") for a in argv if "=" in a}
    return [f"++{key}='{value}'" for key, value in shipped.items() if key not in given]  # quoted: interpolations


def _shipped_hydra_dirs() -> dict[str, str]:
    """The shipped config's run and sweep directory patterns (scenarios/config.yaml)."""
    from importlib.resources import files

    import yaml

    hydra = yaml.safe_load(files("swarmscene.scenarios").joinpath("config.yaml").read_text())["hydra"]
    return {"hydra.run.dir": hydra["run"]["dir"], "hydra.sweep.dir": hydra["sweep"]["dir"]}


def _option(argv: list[str], names: tuple[str, ...]) -> str | None:
    """The value of a ``-x value`` / ``--xx=value`` option of ``argv``, else None."""
    for k, arg in enumerate(argv):
        if arg in names and k + 1 < len(argv):
            return argv[k + 1]
        for name in names:
            if arg.startswith(f"{name}="):
                return arg.split("=", 1)[1]
    return None


def _show_deprecations() -> None:
    """Show swarmscene's deprecation warnings (an old option name, a hook reading a removed attribute
    of the run view), each distinct one once: Python hides DeprecationWarnings raised outside
    ``__main__``, so a command-line user would otherwise meet the removal unwarned. A ``-W`` or
    ``PYTHONWARNINGS`` setting of the user's is left to decide."""
    import warnings

    from .core.errors import SwarmsceneDeprecationWarning

    if not sys.warnoptions:
        warnings.filterwarnings("once", category=SwarmsceneDeprecationWarning)


def _sweep_end_after(exc: BaseException) -> int | None:
    """The exit status of a multirun whose sweeper raised after its jobs ran (Optuna when every
    trial failed), once the end-of-sweep callbacks it skipped have run; None for any other error."""
    callback = sys.modules.get("swarmscene.sweeps.callback")
    return callback.end_after_sweeper_error(exc) if callback is not None else None


def _multirun_status() -> int | None:
    """The exit status the sweep callback set at the end of a multirun (1: a job did not
    complete), None after a single run (the callback's module was never imported)."""
    callback = sys.modules.get("swarmscene.sweeps.callback")
    return callback.take_exit_status() if callback is not None else None


def _report(lines: list[str], status: int = EXIT_CONFIG) -> None:
    for line in lines:
        print(f"swarmscene: {line}", file=sys.stderr)
    sys.exit(status)


def _error_status(exc: BaseException) -> int:
    """The exit status of an error: 1 when a pool launcher's worker died (the jobs written are kept
    and a re-run resumes, as after a job that did not complete), else :data:`EXIT_CONFIG`."""
    from .sweeps.pool import WorkerDied

    return 1 if _cause_of(exc, (WorkerDied,)) is not None else EXIT_CONFIG


def _error_lines(exc: BaseException) -> list[str]:
    from .core.errors import ConfigError
    from .core.raised import RunFailed
    from .hydra_errors import hydra_error_line
    from .rundir import RunFileError
    from .sweeps.pool import WorkerDied

    if isinstance(exc, ConfigError):
        return exc.lines
    if isinstance(exc, RunFailed):  # its message is the engine's own line (the first non-finite state)
        return [str(exc)]
    cause = _cause_of(exc, (ConfigError, RunFileError, WorkerDied))
    if isinstance(cause, ConfigError):  # raised inside Hydra (swarmscene.dir_name, scenario_files)
        return cause.lines
    if isinstance(cause, (RunFileError, WorkerDied)):
        return [str(cause)]
    line = hydra_error_line(exc)
    if line is not None:
        return [line]
    cause = _cause_of(exc, (OSError,))
    if isinstance(cause, OSError) and cause.errno is not None and cause.filename is not None:
        return [f"{cause.filename}: cannot be written ({cause.strerror or cause})"]  # a full disk, read-only
    return [f"{type(exc).__name__}: {exc}".splitlines()[0] + f" (set {DEBUG_ENV}=1 for a traceback)"]


def _cause_of(exc: BaseException | None, kinds: tuple[type, ...]) -> BaseException | None:
    """The first exception of ``kinds`` in ``exc``'s chain of causes, else None."""
    seen = 0
    while exc is not None and seen < 20:
        if isinstance(exc, kinds):
            return exc
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return None


def _task(cfg: Any) -> Any:
    """Hydra task: validate, run, write the run directory, print the summary.

    In a multirun every exception of the job is caught and recorded in its run directory
    (``error.json``, and a manifest with status ``failed``), so the other jobs still run and the
    sweep table shows the error; a job whose directory already holds a complete manifest with the
    same config hash is skipped (resume). A Ctrl-C writes what the run has, marked incomplete, and
    ends the process with status 130. A launcher task of several sweep jobs
    (:mod:`swarmscene.sweeps.chunks`) runs them one after another, each as a job of its own
    (:mod:`swarmscene.sweeps.task`).
    """
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from .sweeps import task

    if HydraConfig.get().mode != RunMode.MULTIRUN:
        return _one(cfg)
    task.renumber_first()  # a launcher task of several jobs: this job's number, not the task's
    result = _one(cfg)
    task.run_rest(lambda job_cfg, run_dir: _one(job_cfg), cfg)  # the task's other jobs, if any
    return result


def _one(cfg: Any) -> Any:
    """One run or one sweep job, in the run directory ``HydraConfig`` names."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    from .core.errors import ConfigError
    from .hydra_errors import resolution_error_line

    hydra_cfg = HydraConfig.get()
    run_dir = Path(hydra_cfg.runtime.output_dir)
    try:
        data = cast("dict[str, Any]", OmegaConf.to_container(cfg, resolve=True))  # the root is a mapping
    except Exception as exc:  # an interpolation that does not resolve: name its key
        line = resolution_error_line(exc)
        if line is None:
            raise
        if hydra_cfg.mode == RunMode.MULTIRUN:
            raise ConfigError([line]) from exc
        _remove_unfinished(run_dir)
        _report([line])
    if hydra_cfg.mode != RunMode.MULTIRUN:
        return _single(data, run_dir)
    return _sweep_job(data, run_dir)


def _sweep_job(data: dict[str, Any], run_dir: Path) -> Any:
    """A sweep job: every exception recorded in its run directory (module docstring of _task)."""
    from .rundir import RunFileError
    from .sweeps.records import record_failure

    try:
        return _job(data, run_dir)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # the job failed: record it, let the launcher run the others
        line = _error_lines(exc)[0]
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
            return _objective_from(names, {})
        return {"status": "failed", "error": str(exc)}


def _single(data: dict[str, Any], run_dir: Path) -> Any:
    from . import api
    from .core.errors import ConfigError

    _stop_if_requested(run_dir)  # a signal during start-up or composition
    try:
        sim = api.build(data)
        writers = api.extra_writers(sim)  # a missing optional package fails now, not after the run
    except ConfigError as exc:
        if os.environ.get(DEBUG_ENV):
            raise
        _remove_unfinished(run_dir)
        # Exit here: an exception would pass through Hydra's job runner, which adds its own line.
        _report(exc.lines)
    except BaseException:
        _remove_unfinished(run_dir)
        raise
    _stop_if_requested(run_dir)  # a signal while the plugins were built (and kernels compiled)
    try:
        result, failed = _run_and_write(sim, run_dir, writers, sweep=False)
    except OSError as exc:  # a full disk, a read-only directory: its files were removed (outputs.py)
        _remove_unfinished(run_dir)
        if os.environ.get(DEBUG_ENV):
            raise
        _report(_error_lines(exc))
    except Exception:
        _remove_unfinished(run_dir)  # nothing written: no `.hydra/`-only directory left behind
        raise
    if not result.complete:
        status, word = _interrupted_status()
        print(f"swarmscene: {word} at t = {result.metrics['duration']:.2f} s; "
              f"partial outputs (marked incomplete) in {run_dir}", file=sys.stderr)
        sys.exit(status)
    if interrupts.requested() is not None:  # the run ended; the request came while writing
        from .rundir import RunDir, RunFileError

        try:
            complete = RunDir(run_dir).manifest().get("complete") is True
        except RunFileError:
            complete = False
        marked = "complete (the request came after the last file)" if complete else "marked incomplete"
        _exit_interrupted(f"while the outputs were written; they are {marked} in {run_dir}")
    if failed is not None:
        from .sweeps.records import record_failure

        record_failure(run_dir, failed, sim.scenario.data)
        print(f"swarmscene: {result.error}; outputs up to then (marked failed) in {run_dir}", file=sys.stderr)
        sys.exit(EXIT_FAILED)
    return _objective(sim, result)


def _stop_if_requested(run_dir: Path) -> None:
    """Act on a stop request that came before the run started: no run directory is left."""
    if interrupts.requested() is not None:
        _remove_unfinished(run_dir)
        _exit_interrupted("before the run started (no run directory written)")


def _job(data: dict[str, Any], run_dir: Path) -> Any:
    """One job of a sweep: skip when already complete for this config, else run and write.

    One plugin manager serves the job: it validates the scenario and the simulation owns it.
    """
    from . import api
    from .sweeps.records import completed_metrics, write_overrides

    write_overrides(run_dir)  # the job's record of what it is, before anything can fail
    plugin_set = api.plugins()
    scenario = api.load(data, plugin_set[1])
    done = completed_metrics(run_dir, scenario.data)  # hashed over the effective configuration
    if done is not None:
        print(f"swarmscene: job {run_dir.name} already complete (same config hash): skipped", file=sys.stderr)
        return _objective_from(scenario.config.output.objective, done)
    if interrupts.requested() is not None:  # came while the job was set up: stop before building
        raise KeyboardInterrupt
    sim = api.build(scenario, plugin_set)
    result, failed = _run_and_write(sim, run_dir, api.extra_writers(sim), sweep=True)
    if not result.complete or interrupts.requested() is not None:
        raise KeyboardInterrupt  # outputs are written (marked incomplete if the run was cut); stop the sweep
    if failed is not None:
        raise failed  # recorded as a failed job (error.json, manifest), outputs kept
    return _objective(sim, result)


def _run_and_write(sim: Any, run_dir: Path, writers: list[Any], sweep: bool) -> tuple[Any, RunFailed | None]:
    """Run and write the run directory (:mod:`swarmscene.runpath`, as ``api.run`` does), print the
    summary of a run that flew; return the result and, for a run that failed (a non-finite state, a
    plugin's exception), the error to record."""
    from .runpath import fly, land
    from .summary import Progress, summary_text

    output = sim.config.output
    flight = fly(sim, Progress.maybe(output.progress, enabled=not sweep), gather_warnings=True)
    failed = land(sim, flight, run_dir, writers)  # the manifest, last, lists every file
    if failed is None and output.summary and not sweep:
        print(summary_text(sim, flight.result, run_dir))
    # A run that did not fly to its end gets no verdicts: its one line (the caller prints it) says why.
    return flight.result, failed


def _objective(sim: Any, result: Any) -> Any:
    return _objective_from(sim.config.output.objective, result.metrics)


def _objective_from(names: list[str], metrics: dict[str, Any]) -> Any:
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


def _remove_unfinished(run_dir: Path) -> None:
    """Remove the directory Hydra made for a run that never started (it holds only .hydra/)."""
    try:
        if run_dir.is_dir() and not run_dir.is_symlink() and all(p.name == ".hydra" for p in run_dir.iterdir()):
            shutil.rmtree(run_dir)
            parent = run_dir.parent  # outputs/<name>/, made for this run alone
            if parent.is_dir() and not any(parent.iterdir()):
                parent.rmdir()
    except OSError:
        pass  # a read-only directory, a mount point: what could not be removed stays, unfinished
