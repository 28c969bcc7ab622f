"""The pool launcher (``hydra/launcher=pool``): a sweep's jobs on this machine's cores, in worker
processes that start warm.

A worker process that starts cold pays, before its first job ends, ~2 s of CPU that no later job
pays: the interpreter, Hydra and the engine imported, its plugins registered, the first
composition, numba's compiled kernels loaded from its cache (or compiled, on a fresh machine) and
the libraries a method loads when it first acts (CEM's ``scipy.optimize``, at the first failure).
Hydra's joblib launcher starts every worker so (loky spawns fresh interpreters), and on a small
sweep that start is most of the sweep: 100 seeds of ``cem_six_vehicle`` are ~8 s of jobs on one
core, and two joblib workers add ~4 s of start to them.

This launcher pays that start once, whatever the number of workers. At its setup, while the main
process still checks the grid, it starts Python's fork server (``multiprocessing``'s
``forkserver`` start method) with :mod:`swarmscene.sweeps.warm` preloaded: the fork server imports
the engine and runs the sweep's own scenario briefly (its events moved early, nothing written), so
every module, kernel and library a job of this sweep loads is loaded there once. Each worker is
then forked from that warm process and runs its first job as fast as its last. A worker is forked
from the fork server, not from the main process, so it inherits no thread and no lock of the main
process's (forking a threaded process is unsafe); the fork server is a fresh single-threaded
process.

Every worker receives the sweep's config, Hydra's state and the task function once (the pool's
initializer), and each task (one or several jobs, :mod:`.chunks`) is sent as its overrides only;
each job is composed and run exactly as under Hydra's joblib launcher (``run_job``, the same run
directory, ``hydra.job.id`` ``<name>_<n>``), so its numbers are the basic launcher's bit for bit.

A stop request (Ctrl-C, SIGTERM sent to the main process alone) cancels the tasks not started and
is passed on to the workers, whose jobs stop between two ticks and write what they have, marked
incomplete (:mod:`swarmscene.core.interrupts`); a second request ends the workers at once. A worker
that dies (killed, out of memory) ends the sweep with one line naming what to do; the jobs already
written stay, and the same command resumes the rest.

Options (``hydra.launcher.*``): ``n_jobs`` (the workers; null: every core this process may use;
-1 all, -2 all but one, as joblib counts) and ``warm`` (true: the fork server runs the sweep's
scenario before forking; false: it only imports the engine).
"""

from __future__ import annotations

import io
import json
import logging
import multiprocessing
import os
import pickle
import signal
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from hydra.plugins.launcher import Launcher

from ..core import interrupts

log = logging.getLogger(__name__)

WARM_ENV = "SWARMSCENE_POOL_WARM"
"""The scenario the fork server runs before forking (JSON), read by :mod:`.warm` at its import."""
GRACE_S = 60.0
"""s the workers get, after a stop request, to stop their jobs between ticks and write them."""


class WorkerDied(RuntimeError):
    """A worker process ended while it ran a task (killed, out of memory, a crash in native code)."""


class PoolLauncher(Launcher):
    """Hydra launcher: jobs on this machine's cores in workers forked from a warm fork server."""

    def __init__(self, n_jobs: int | None = None, warm: bool = True) -> None:
        if n_jobs is not None and (isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs == 0):
            raise ValueError(f"hydra.launcher.n_jobs: must be null, an integer >= 1 or a negative count "
                             f"(-1: all cores) (got {n_jobs!r})")
        if not isinstance(warm, bool):
            raise ValueError(f"hydra.launcher.warm: must be true or false (got {warm!r})")
        self.n_jobs = n_jobs
        self.warm = warm
        self.config: Any = None
        self.task_function: Any = None
        self.hydra_context: Any = None
        self._executor: ProcessPoolExecutor | None = None
        self._context: Any = None
        self._known: set[Any] = set()  # this process's children before the pool's: not its workers

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        """Hydra's call before the first launch: keep what the workers need and start the warm
        fork server now, so it loads while the main process checks the grid."""
        self.config = config
        self.task_function = task_function
        self.hydra_context = hydra_context
        self._context = start_fork_server(warm_scenario(config) if self.warm else None)

    def workers(self) -> int:
        """The number of worker processes (``n_jobs`` resolved against this process's cores)."""
        from .chunks import workers_for

        return workers_for(self.n_jobs)

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[Any]:
        """Run a batch of tasks on the pool; their ``JobReturn`` in the batch's order."""
        from hydra.core.utils import configure_log, filter_overrides, setup_globals

        setup_globals()
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        sweep_dir.mkdir(parents=True, exist_ok=True)
        log.info(f"Pool launcher: {self.workers()} workers, {len(job_overrides)} tasks; sweep output dir: {sweep_dir}")
        for idx, overrides in enumerate(job_overrides):
            log.info(f"\t#{initial_job_idx + idx} : {' '.join(filter_overrides(overrides))}")
        calls = [(_run_task, (initial_job_idx + idx, list(overrides))) for idx, overrides in enumerate(job_overrides)]
        return self._run_on_pool(calls, sweep_dir)

    def _run_on_pool(self, calls: Sequence[tuple[Callable[..., bytes], tuple[Any, ...]]], sweep_dir: Path) -> list[Any]:
        """Each ``(function, args)`` of ``calls`` run on the pool; what each returned, unpickled
        (our own workers' JobReturns), in the calls' order. Ctrl-C stops the workers
        (:meth:`_stop`) and goes on up; a worker that dies ends the launch with one line
        (:class:`WorkerDied`), the jobs written kept."""
        executor = self._pool()
        futures: list[Future[bytes]] = []
        try:
            for function, args in calls:
                futures.append(executor.submit(function, *args))
            return [pickle.loads(future.result()) for future in futures]
        except KeyboardInterrupt:
            self._stop(futures)
            raise
        except BrokenProcessPool:
            self._executor = None
            raise WorkerDied(f"{sweep_dir}: a worker process died (killed, or out of memory); the jobs "
                             f"written are kept: run the same command to resume the others") from None

    def _pool(self) -> ProcessPoolExecutor:
        """The batch's pool: made at the first launch, kept for the sweep's later batches."""
        if self._executor is None:
            from ..composition.hydra_internals import hydra_singletons
            from .compose import compositions

            self._known = set(multiprocessing.active_children())
            sweep = dumps((hydra_singletons(), self.hydra_context, self.config, self.task_function, compositions()))
            self._executor = ProcessPoolExecutor(
                max_workers=self.workers(), mp_context=self._context, initializer=_start_worker, initargs=(sweep,),
            )
        return self._executor

    def close(self) -> None:
        """End the pool once the sweep's last batch is done (the sweeper calls it): its workers
        are idle and leave at once. Left to the interpreter's exit, the executor's manager thread
        could write to its wake-up pipe as the pipe was closed, and a sweep that had succeeded
        ended with ``OSError: [Errno 9] Bad file descriptor`` (2 of 4 corridor sweeps)."""
        executor, self._executor = self._executor, None
        if executor is not None:
            executor.shutdown(wait=True)

    def _stop(self, futures: list[Future[Any]]) -> None:
        """After a stop request in this process: cancel the tasks not started, pass the request on
        to the workers (their jobs stop between ticks and are written, marked incomplete) and wait
        for them up to :data:`GRACE_S`; a second request, or the grace's end, ends them at once."""
        assert self._executor is not None
        workers = [p for p in multiprocessing.active_children() if p not in self._known]
        self._executor.shutdown(wait=False, cancel_futures=True)  # each worker ends after its task
        self._executor = None
        for process in workers:
            _signal(process, interrupts.requested() or signal.SIGINT)
        deadline = time.monotonic() + GRACE_S
        try:
            for process in workers:
                process.join(max(0.0, deadline - time.monotonic()))
        except KeyboardInterrupt:  # a second request: no more waiting
            pass
        for process in workers:
            if process.is_alive():
                _signal(process, signal.SIGKILL)


def warm_scenario(config: Any) -> str | None:
    """The scenario the fork server runs before forking, as JSON: the sweep's config without its
    ``hydra`` node (the command line's scenario with the swept keys at their defaults); None when it
    cannot be resolved outside a job (the fork server then only imports the engine)."""
    from omegaconf import OmegaConf, open_dict

    scenario = config.copy()
    with open_dict(scenario):
        scenario.pop("hydra", None)
    try:
        return json.dumps(OmegaConf.to_container(scenario, resolve=True))
    except Exception:  # a value read from a job's own HydraConfig (${hydra:job.num}) and the like
        return None


def start_fork_server(scenario: str | None) -> Any:
    """Start Python's fork server with :mod:`.warm` preloaded (it runs ``scenario``); returns the
    ``forkserver`` context the pool forks its workers from. The server starts at once and loads
    in the background; the first worker's start waits for it. A fork server already running in
    this process (a second sweep in the same process) is used as it is."""
    from multiprocessing import forkserver

    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["swarmscene.sweeps.warm"])
    before = os.environ.get(WARM_ENV)
    os.environ[WARM_ENV] = scenario or ""  # for the server only: it takes the variable out of its environment
    try:
        forkserver.ensure_running()
    finally:
        if before is None:
            os.environ.pop(WARM_ENV, None)
        else:
            os.environ[WARM_ENV] = before
    return context


def dumps(obj: Any) -> bytes:
    """``obj`` pickled for the workers, a class that Hydra re-imported pickled by its name.

    Hydra's plugin scan executes the modules of its plugins again (``Plugins.instance()``), so the
    config store can hold a structured config's class that is no longer the one its module names
    (the Optuna sweeper's ``OptunaSweeperConf``); ``pickle`` refuses such a class. It is the same
    class as the one a worker's own import gives, so it goes by its module and name."""
    buffer = io.BytesIO()
    _ByName(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
    return buffer.getvalue()


class _ByName(pickle.Pickler):
    def reducer_override(self, obj: Any) -> Any:
        if isinstance(obj, type) and _named(obj.__module__, obj.__qualname__) not in (None, obj):
            return _named, (obj.__module__, obj.__qualname__)
        return NotImplemented


def _named(module: str, qualname: str) -> Any:
    """The object ``module.qualname`` names (imported if need be), None when there is none."""
    import importlib

    try:
        found: Any = importlib.import_module(module)
        for part in qualname.split("."):
            found = getattr(found, part)
    except (ImportError, AttributeError):
        return None
    return found


def _signal(process: Any, signum: int) -> None:
    try:
        os.kill(process.pid, signum)
    except (ProcessLookupError, TypeError):  # ended already; or never started (pid None)
        pass


# -- in the worker processes ------------------------------------------------------------------------
_WORKER: dict[str, Any] = {}
"""What :func:`_start_worker` received: the sweep's Hydra context, config and task function."""


def _start_worker(sweep: bytes) -> None:
    """A worker's start (the pool's initializer), from :func:`dumps` of Hydra's singletons, the
    Hydra context, the sweep's config, the task function and the main process's compositions: the
    singletons as the main process has them (its config store, sources, version), the
    compositions in this process's cache (:func:`.compose.adopt`), OmegaConf's resolvers
    registered here as the main process registers them (they are local functions, which do not
    pickle), and stop signals recorded, not raised, so a job stops between ticks and writes what
    it has."""
    from hydra.core.utils import setup_globals

    from ..composition.hydra_internals import restore_hydra_singletons
    from ..composition.searchpath import register_search_path
    from .compose import adopt

    register_search_path()  # swarmscene's search path, sweeper, launcher and resolvers
    setup_globals()  # Hydra's resolvers (now, hydra, python_version)
    instances, hydra_context, config, task_function, composed = pickle.loads(sweep)
    restore_hydra_singletons(instances)
    adopt(composed)  # the compositions the grid's check made: the first job composes none again
    interrupts.install()
    _WORKER.update(hydra_context=hydra_context, config=config, task_function=task_function)


def _run_task(idx: int, overrides: list[str]) -> bytes:
    """One task in a worker, as Hydra's joblib launcher runs one: composed, numbered, run; its
    ``JobReturn`` pickled by :func:`dumps` (it holds the job's config, whose nodes name their
    structured config classes)."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.core.utils import run_job
    from omegaconf import open_dict

    hydra_context, config = _WORKER["hydra_context"], _WORKER["config"]
    sweep_config = hydra_context.config_loader.load_sweep_config(config, overrides)
    with open_dict(sweep_config):
        sweep_config.hydra.job.id = f"{sweep_config.hydra.job.name}_{idx}"
        sweep_config.hydra.job.num = idx
    HydraConfig.instance().set_config(sweep_config)
    return dumps(run_job(hydra_context=hydra_context, config=sweep_config, task_function=_WORKER["task_function"],
                         job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir"))
