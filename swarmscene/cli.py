"""The ``swarmscene`` command: Hydra composes, the engine validates and runs, a summary is printed.

    swarmscene                                    # the default scenario
    swarmscene scenario=cem_six_vehicle avoidance.K=1
    swarmscene --multirun avoidance.K=1,2,5       # a sweep (Hydra launchers)
    swarmscene --help | --cfg job | --info
    swarmscene --version | plugins                # what is installed (swarmscene.tools.info)

Bad input prints one line per problem (``dotted.key: what is allowed (got value)``) and exits
with status 2, without a traceback (set ``SWARMSCENE_DEBUG=1`` for one) and without leaving a run
directory behind. In a multirun, a failing job is recorded with its error (the others run), a
job already complete for the same config is skipped, and the sweep directory gets summary.csv and
summary.md at the end (docs/sweeps.md). Ctrl-C writes what the run has, marked incomplete, and
exits with status 130; SIGTERM (a scheduler's cancel, ``kill``) does the same with status 143.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from typing import Any, NoReturn, cast

from .core import interrupts
from .sweeps.job import DEBUG_ENV

# A launcher's worker process (joblib, ray, submitit) imports this module to run `_task`, with
# Hydra already loaded, and then resolves the job's directory and writes its `.hydra/` files
# (composition/hydra_files.py): protect them now. The command itself does it in main(), after its signal
# handler is in place, so that a Ctrl-C during start-up is never a traceback. ("hydra" first:
# the plain command imports nothing more than before.)
if "hydra" in sys.modules:
    from .composition.hydra_internals import save_config_loaded as _save_config_loaded

    if _save_config_loaded():
        from .composition.hydra_files import install as _protect_run_dirs

        _protect_run_dirs()

EXIT_FAILED = 1  # the run started and failed (a non-finite state): its outputs say so
EXIT_CONFIG = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report a Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM


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
        from .tools import info

        sys.exit(info.command(sys.argv[1]))
    # First of all: from here on SIGINT/SIGTERM are recorded, and acted on at the next point
    # where the run can stop cleanly (core/interrupts.py), never raised inside compiled code.
    # The previous handlers come back afterwards (main() called in a process that goes on: tests).
    interrupts.clear()
    with interrupts.handle_stop_signals():
        _main()


def _main() -> None:
    import hydra

    from .composition.searchpath import plain_command_line, register_search_path

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
        from .sweeps.job import error_lines

        _report(error_lines(exc), _error_status(exc))
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


def _report(lines: list[str], status: int = EXIT_CONFIG) -> NoReturn:
    for line in lines:
        print(f"swarmscene: {line}", file=sys.stderr)
    sys.exit(status)


def _error_status(exc: BaseException) -> int:
    """The exit status of an error: 1 when a pool launcher's worker died (the jobs written are kept
    and a re-run resumes, as after a job that did not complete), else :data:`EXIT_CONFIG`."""
    from .sweeps.job import cause_of
    from .sweeps.pool import WorkerDied

    return 1 if cause_of(exc, (WorkerDied,)) is not None else EXIT_CONFIG


def _task(cfg: Any) -> Any:
    """Hydra's task: the command's run (validate, run, write the run directory, print the summary),
    or in a multirun the launcher task of sweep jobs (:func:`swarmscene.sweeps.job.launcher_task`:
    every exception of a job recorded in its run directory, a job already complete skipped). A
    Ctrl-C writes what the run has, marked incomplete, and ends the process with status 130."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if HydraConfig.get().mode == RunMode.MULTIRUN:
        from .sweeps.job import launcher_task

        return launcher_task(cfg)
    return _single(_resolved(cfg), Path(HydraConfig.get().runtime.output_dir))


def _resolved(cfg: Any) -> dict[str, Any]:
    """The run's config resolved; an interpolation that does not resolve ends the command with its
    key named, and no run directory left."""
    from hydra.core.hydra_config import HydraConfig
    from omegaconf import OmegaConf

    from .composition.hydra_errors import resolution_error_line

    try:
        return cast("dict[str, Any]", OmegaConf.to_container(cfg, resolve=True))  # the root is a mapping
    except Exception as exc:
        line = resolution_error_line(exc)
        if line is None:
            raise
        _remove_unfinished(Path(HydraConfig.get().runtime.output_dir))
        _report([line])


def _single(data: dict[str, Any], run_dir: Path) -> Any:
    """The command's one run: built, flown and landed in ``run_dir``; bad input, a stop request, a
    failed run or an unwritable directory ends the command with its line and status."""
    from . import api
    from .core.errors import ConfigError
    from .runpath import run_and_write
    from .sweeps.job import objective_from

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
        result, failed = run_and_write(sim, run_dir, writers, sweep=False)
    except OSError as exc:  # a full disk, a read-only directory: its files were removed (runs/outputs.py)
        _remove_unfinished(run_dir)
        if os.environ.get(DEBUG_ENV):
            raise
        from .sweeps.job import error_lines

        _report(error_lines(exc))
    except Exception:
        _remove_unfinished(run_dir)  # nothing written: no `.hydra/`-only directory left behind
        raise
    if not result.complete:
        status, word = _interrupted_status()
        print(f"swarmscene: {word} at t = {result.metrics['duration']:.2f} s; "
              f"partial outputs (marked incomplete) in {run_dir}", file=sys.stderr)
        sys.exit(status)
    if interrupts.requested() is not None:  # the run ended; the request came while writing
        from .runs.rundir import RunDir, RunFileError

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
    return objective_from(sim.config.output.objective, result.metrics)


def _stop_if_requested(run_dir: Path) -> None:
    """Act on a stop request that came before the run started: no run directory is left."""
    if interrupts.requested() is not None:
        _remove_unfinished(run_dir)
        _exit_interrupted("before the run started (no run directory written)")


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
