"""swarmscene's grid sweeper (the default of every multirun): Hydra's basic sweeper without its
per-job composition, with the sweep checked before its jobs run.

Hydra's basic sweeper composes every job in the main process before launching any
(``validate_batch_is_legal``, hydra#1324: ~70 ms a job here, half an hour for 10,000 jobs). This one
does no per-job composition in the main process:

1. the directory: the sweep takes its lock (one sweep at a time), and a directory that belongs to
   another grid is refused with one line (:mod:`swarmscene.sweeps.records`); ``sweep.json`` records
   the jobs;
2. the check: each distinct set of group overrides composed once, each distinct value validated
   once (:mod:`swarmscene.sweeps.grid`), whole before the first job for a grid of up to
   ``upfront`` distinct overrides (1,000), else batch by batch;
3. the launch: the launcher gets tasks of several jobs each (``jobs_per_task``, below), and a
   :class:`~swarmscene.sweeps.compose.GroupCachingLoader`, so its workers compose once per set of
   group overrides too; and the command as typed
   (``SWARMSCENE_COMMAND`` in ``hydra.job.env_set``) for the jobs' manifests, wherever they run.
   A grid checked whole is launched in batches of ``max_batch_size`` (all at once by default); a
   grid checked batch by batch in batches of :data:`FIRST_BATCH` jobs, doubling up to
   :data:`LAST_BATCH`, so the first job starts at once.
4. the tables: the sweep's summary (``summary.csv``/``.md``,
   :class:`~swarmscene.sweeps.callback.SweepSummary`) is written before the lock is released, so a
   second sweep let into the directory never changes its jobs under tables being written.

Options (``hydra.sweeper.*``), besides ``params`` and ``max_batch_size``:

- ``validate``: ``each_value`` (above) or ``all`` (every job composed and validated first);
- ``on_invalid``: ``stop`` (the default) or ``record``: a job the schema rejects is launched anyway
  and recorded as failed with its error (``error.json``), for comparisons in which some
  combinations are known not to apply (``+sweep=methods``); a composition error (an unknown option
  or key) still stops the sweep;
- ``upfront``: the most distinct overrides a grid may hold to be checked whole before its first
  job (default 1,000: about a second); a larger grid is checked batch by batch;
- ``jobs_per_task``: ``auto`` (the default) or K >= 1: jobs one launcher task runs back to back in
  one process (:mod:`swarmscene.sweeps.chunks`: Hydra's per-job bookkeeping and the launcher's
  round trip paid once per task). ``auto``: a batch's jobs / (4 x the launcher's workers), at most
  64; the basic launcher's whole batch (at most 64). Whatever the setting, 1 (job by job) where a
  task cannot run several (launchers other than basic, pool, joblib and Ray, job callbacks such as
  MLflow's, ``hydra.job.chdir``);
- ``cases``: a list of override lists taken together rather than crossed (Hydra's grid is a
  product only): the jobs are every case times the product of ``params``. A key given on the
  command line that a case also sets replaces the cases (the command line picks the grid).

It uses Hydra's launcher plugins unchanged (basic, joblib, Ray, submitit) and swarmscene's pool
launcher (:mod:`.pool`). Hydra finds it as
``hydra_plugins.swarmscene_sweeper.SwarmsceneSweeper`` (a thin adapter: Hydra takes sweepers
from the ``hydra_plugins`` package only).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hydra.plugins.sweeper import Sweeper

from ..core import interrupts
from .grid import ON_INVALID, UPFRONT, VALIDATE, GridCheck, JobCheck, expand

FIRST_BATCH = 16
"""Jobs of the first batch of a grid checked batch by batch (the next ones double)."""
LAST_BATCH = 1024
"""The largest batch of a grid checked batch by batch."""


class SwarmsceneSweeper(Sweeper):
    """Hydra's grid sweeper with the checks and launch of the module docstring."""

    def __init__(
        self,
        max_batch_size: int | None,
        params: dict[str, str] | None = None,
        validate: str = "each_value",
        on_invalid: str = "stop",
        cases: Sequence[Sequence[str]] | None = None,
        upfront: int = UPFRONT,
        jobs_per_task: int | str = "auto",
    ) -> None:
        if validate not in VALIDATE:
            raise ValueError(f"hydra.sweeper.validate: must be one of {VALIDATE} (got {validate!r})")
        if on_invalid not in ON_INVALID:
            raise ValueError(f"hydra.sweeper.on_invalid: must be one of {ON_INVALID} (got {on_invalid!r})")
        if isinstance(upfront, bool) or not isinstance(upfront, int) or upfront < 0:
            raise ValueError(f"hydra.sweeper.upfront: must be an integer >= 0 (got {upfront!r})")
        if jobs_per_task != "auto" and (isinstance(jobs_per_task, bool) or not isinstance(jobs_per_task, int)
                                        or jobs_per_task < 1):
            raise ValueError(f"hydra.sweeper.jobs_per_task: must be auto or an integer >= 1 (got {jobs_per_task!r})")
        if max_batch_size is not None and max_batch_size != -1 and max_batch_size < 1:
            raise ValueError(f"hydra.sweeper.max_batch_size: must be >= 1, -1 or null (got {max_batch_size})")
        self.max_batch_size = None if max_batch_size == -1 else max_batch_size
        self.params = dict(params or {})
        self.validate = validate
        self.on_invalid = on_invalid
        self.cases = [list(case) for case in (cases or [])]
        self.upfront = upfront
        self.jobs_per_task = jobs_per_task
        self.config: Any = None
        self.hydra_context: Any = None
        self.launcher: Any = None

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        """Hydra's call before :meth:`sweep`: the config, a group-caching config loader, the launcher."""
        from hydra.core.plugins import Plugins
        from hydra.types import HydraContext

        from .compose import GroupCachingLoader

        self.config = config
        self.hydra_context = HydraContext(
            config_loader=GroupCachingLoader(hydra_context.config_loader, command=command_as_typed()),
            callbacks=hydra_context.callbacks,
        )
        self.launcher = Plugins.instance().instantiate_launcher(
            hydra_context=self.hydra_context, task_function=task_function, config=config
        )

    def _stoppable(self) -> Any:
        """While other processes run the jobs (joblib, Ray, submitit) this one only waits: a stop
        signal may raise at once, which stops the launch; jobs in this process stop between ticks."""
        import contextlib

        if type(self.launcher).__name__ in IN_PROCESS_LAUNCHERS:
            return contextlib.nullcontext()
        return interrupts.raising()

    def sweep(self, arguments: list[str]) -> Any:
        """Run the grid of ``params`` and ``arguments`` under the sweep directory's lock: expand it,
        refuse a directory holding another grid, validate, record the grid, then launch the jobs
        batch by batch (tasks of ``jobs_per_task`` jobs) and write the summary tables."""
        from hydra.core.override_parser.overrides_parser import OverridesParser
        from omegaconf import OmegaConf

        from ..runs.outputs import atomic_write_bytes
        from .callback import summary_wanted, write_under_lock
        from .chunks import jobs_per_task, tasks
        from .records import SweepLock, check_grid_owner, record_grid
        from .tables import load_table_libraries

        loader = self.hydra_context.config_loader
        grid, jobs = expand(self.params, arguments, OverridesParser.create(config_loader=loader), self.cases)
        sweep_dir = Path(self.config.hydra.sweep.dir)
        lock = SweepLock(sweep_dir).acquire()
        try:
            check_grid_owner(sweep_dir, grid, jobs)
            checker = GridCheck(JobCheck(loader, self.config), jobs, self.validate, self.on_invalid)
            whole = self.validate == "all" or checker.distinct() <= self.upfront
            if whole:
                checker.check(0, len(jobs))
            record_grid(sweep_dir, grid, jobs)
            # Hydra's basic sweeper writes it with OmegaConf.save, which follows a planted link
            atomic_write_bytes(sweep_dir / "multirun.yaml", OmegaConf.to_yaml(self.config).encode("utf-8"))
            returns = []
            if summary_wanted(self.config):
                load_table_libraries()
            for start, stop in batches(len(jobs), self.max_batch_size, whole):
                if not whole:
                    checker.check(start, stop)
                if interrupts.requested() is not None:  # a stop request between batches
                    raise KeyboardInterrupt
                per_task = jobs_per_task(self.jobs_per_task, self.launcher, self.config, stop - start)
                with self._stoppable():
                    results = self.launcher.launch(tasks(jobs, start, stop, per_task), initial_job_idx=start)
                for result in results:
                    _ = result.return_value  # re-raises what ended a job (a Ctrl-C)
                returns.append(results)
            if summary_wanted(self.config):  # the tables, before another sweep may take the directory
                write_under_lock(sweep_dir)
            return returns
        finally:
            close = getattr(self.launcher, "close", None)  # a launcher that keeps workers (pool) ends them
            if callable(close):
                close()
            lock.release()


IN_PROCESS_LAUNCHERS = ("BasicLauncher",)
"""Launchers that run the jobs in this process: a stop request waits for the tick (see interrupts)."""


def command_as_typed() -> list[str]:
    """This process's command as typed: ``sys.argv[0]`` and the arguments before the command line
    rewrote them (``searchpath.plain_command_line``), from ``/proc/self/cmdline`` where it exists."""
    given = list(sys.argv[1:])
    try:
        with open("/proc/self/cmdline", "rb") as fh:
            original = [a.decode(errors="replace") for a in fh.read().split(b"\0")[:-1]]
    except OSError:
        original = []
    if given and len(original) >= len(given):
        given = original[len(original) - len(given):]
    return [sys.argv[0], *given]


def batches(count: int, max_batch_size: int | None, whole: bool) -> list[tuple[int, int]]:
    """``(start, stop)`` of each launch: ``max_batch_size`` jobs (all by default) for a grid checked
    whole; else :data:`FIRST_BATCH` jobs, doubling up to :data:`LAST_BATCH` (and at most
    ``max_batch_size``)."""
    out = []
    start = 0
    size = FIRST_BATCH if not whole else (max_batch_size or max(count, 1))
    while start < count:
        step = size if whole or max_batch_size is None else min(size, max_batch_size)
        out.append((start, min(start + step, count)))
        start += step
        if not whole:
            size = min(size * 2, LAST_BATCH)
    return out
