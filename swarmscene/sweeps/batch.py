"""The batch launcher (``hydra/launcher=batch``): the jobs of a sweep that differ only in their seed
(or, with ``group: physics``, any jobs whose worlds can share a physics step) flown as batches of
worlds, on this machine's cores.

It is the pool launcher (:mod:`.pool`: workers forked from a warm fork server, the same stop
requests, the same one line for a worker that dies) with another unit of work. In the main process
:func:`plan` groups a launch's jobs by their overrides without the seed (``avoidance.K=2 seed=0``
and ``avoidance.K=2 seed=1`` share a group; with ``group: physics`` every job whose overrides
parse is in one group) and cuts each group of two or more jobs into batches of
at most ``batch_size`` jobs, small enough that every worker gets about :data:`TASKS_PER_WORKER`
tasks; a job alone in its group is a task of its own, run as the pool runs it (Hydra's
``run_job``). A worker runs a batch in :func:`run_batch_task`:

1. each job composed (:class:`~.compose.GroupCachingLoader`, the cached composition of its config
   groups) and set up as Hydra's ``run_job`` sets a job up, one after another, as a launcher task
   of several jobs does (:mod:`.task`): its number, its run directory, ``HydraConfig``, its
   ``.hydra/overrides.yaml``; then validated, and its run directory checked for a complete run of
   the same config (resume). A job that differs from the batch's first composed job in its seed
   alone (``seed=17``, an integer) is not composed: it is that job's twin (:class:`_Twin`), whose
   config is the first's with the seed set by Hydra's own step for a value override;
2. a job that cannot join a batch runs there and then through the per-job path
   (:func:`.job.job_from`, exactly as under the basic launcher): a config that does not resolve or
   validate (its failure recorded as ever), a job already complete (skipped, with its line), an
   output a batch does not write (``output.plots``, ``animation``, ``rerun``, ``mcap``, ``live``:
   :func:`swarmscene.views.writers.unbatched_output`), an environment (``hydra.job.env_set``) of its own;
3. the other jobs are grouped by their resolved config without ``seed`` (a job whose config
   differs in anything else, through an interpolation of the seed say, is a group of its own;
   with ``group: physics``, by what the worlds of a batch must share: the dynamics model, the
   number of agents, the guidance period and the physics step; options, methods and disturbances
   may differ from world to world, and each world's phases take the batched forms where the
   worlds' plugins and options agree, core/batch.py),
   each group built (one plugin manager per world, as each job has) and flown as one
   :class:`~swarmscene.core.batch.BatchSimulation`; a world that cannot be built runs alone (its
   failure recorded by the per-job path);
4. each world landed in its job's run directory by the per-job path's own step
   (:func:`swarmscene.runpath.land`, through :func:`.job.recorded_job`): ``config.yaml``, the
   trajectory, ``metrics.json``, the observers' files and the manifest, and for a world that
   failed (a plugin's exception, a non-finite state) ``error.json`` and the failed manifest, with
   the same line on stderr. A stop request stops every world between two ticks; all of them are
   written, marked incomplete, and the sweep stops.

Each world of a batch equals its single run bit for bit (core/batch.py), so every job's run
directory is the basic launcher's except the timing metrics (``wall_time``, ``realtime_factor``,
``step_ms_median``: the batch's, shared among its worlds) and the manifest's start time (the
batch's). The sweep's progress line counts a batch's jobs when they are written, all at once at the
batch's end.

Options (``hydra.launcher.*``): the pool's ``n_jobs`` and ``warm``, ``batch_size`` (the most
jobs one batch flies, default :data:`BATCH_SIZE`) and ``group`` (:data:`GROUPS`: ``seed``, the
default, or ``physics``: a falsifier's trials, or a grid's points, flown as batches).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core import interrupts
from . import pool
from .chunks import config_refusal
from .pool import PoolLauncher

log = logging.getLogger(__name__)

BATCH_SIZE = 64
"""The default ``batch_size``: the most jobs (worlds) one batch flies."""
TASKS_PER_WORKER = 4
"""A group is cut into batches small enough that each worker gets about this many tasks (a batch
ends when its slowest world ends: one batch per worker would leave cores idle at the sweep's end)..."""
MIN_BATCH = 16
"""...unless that makes batches smaller than this: then one batch per worker, at most this size."""
GROUPS = ("seed", "physics")
"""``hydra.launcher.group``: which jobs may share a batch. ``seed``: those whose overrides differ
only in the seed (one composition); ``physics``: any whose worlds can share a physics step."""
ALONE = "::alone"
"""The group key of a job that shares a group with no other (:func:`group_key`)."""


class BatchLauncher(PoolLauncher):
    """Hydra launcher: the pool launcher's workers, flying the jobs that differ only in their seed
    as batches of worlds (module docstring)."""

    def __init__(self, n_jobs: int | None = None, warm: bool = True, batch_size: int = BATCH_SIZE,
                 group: str = "seed") -> None:
        if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
            raise ValueError(f"hydra.launcher.batch_size: must be an integer >= 1 (got {batch_size!r})")
        if group not in GROUPS:
            raise ValueError(f"hydra.launcher.group: must be one of {', '.join(GROUPS)} (got {group!r})")
        super().__init__(n_jobs=n_jobs, warm=warm)
        self.batch_size = batch_size
        self.group = group

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[Any]:
        """Run a launch's jobs, batched where they may be; their ``JobReturn`` in the jobs' order."""
        from hydra.core.utils import configure_log, filter_overrides, setup_globals

        setup_globals()
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        sweep_dir.mkdir(parents=True, exist_ok=True)
        why = config_refusal(self.config)
        tasks = plan(job_overrides, initial_job_idx, 1 if why else self.batch_size, self.workers(), self.group)
        batched = sum(len(task) for task in tasks if len(task) > 1)
        log.info(f"Batch launcher: {self.workers()} workers, {len(job_overrides)} jobs, {batched} of them in "
                 f"{sum(len(task) > 1 for task in tasks)} batches{f' (none batched: {why})' if why else ''}"
                 f"{' (grouped by physics)' if self.group == 'physics' else ''}; "
                 f"sweep output dir: {sweep_dir}")
        others = " (and their seeds)" if self.group == "seed" else " (and the others' overrides)"
        for task in tasks:
            log.info(f"\t#{', '.join(str(idx) for idx, _ in task)} : {' '.join(filter_overrides(task[0][1]))}"
                     f"{others if len(task) > 1 else ''}")
        calls = [(run_batch_task, (task, str(sweep_dir), self.group)) if len(task) > 1 else (pool._run_task, task[0])
                 for task in tasks]
        returns: dict[int, Any] = {}
        for task, returned in zip(tasks, self._run_on_pool(calls, sweep_dir), strict=True):
            returns.update(zip((idx for idx, _ in task), returned if len(task) > 1 else [returned], strict=True))
        return [returns[initial_job_idx + offset] for offset in range(len(job_overrides))]


def group_key(overrides: Sequence[str], group: str = "seed") -> tuple[str, ...] | None:
    """A job's overrides without its seed (``seed=3``, ``++seed=3``): jobs with the same key share a
    composition but for the seed; with ``group="physics"`` one key for every job (the workers group
    them by their physics, :meth:`_World.key`). None for what cannot be grouped: a launcher task of
    several jobs (:mod:`.chunks`), overrides that do not parse (the job reports it)."""
    from .chunks import split
    from .compose import parse

    if split(overrides) is not None:
        return None
    try:
        parsed = parse(list(overrides))
    except Exception:  # the job's own composition says what is wrong
        return None
    if group == "physics":
        return ("::physics",)
    return tuple(text for text, o in zip(overrides, parsed, strict=True) if o.key_or_group != "seed")


def plan(jobs: Sequence[Sequence[str]], start: int, batch_size: int, workers: int,
         group: str = "seed") -> list[list[tuple[int, list[str]]]]:
    """The launch's tasks, in the order of their first job: ``[(job number, overrides), ...]`` each,
    a batch (two jobs or more of one group, :func:`group_key`) or one job. A group is cut into
    batches of equal size (within one) of at most ``batch_size`` jobs, and at most the batched jobs
    / (:data:`TASKS_PER_WORKER` x ``workers``), or / ``workers`` up to :data:`MIN_BATCH`, so that
    every worker gets tasks."""
    groups: dict[tuple[str, ...], list[tuple[int, list[str]]]] = {}
    for offset, overrides in enumerate(jobs):
        idx = start + offset
        key = group_key(overrides, group) if batch_size > 1 else None
        groups.setdefault(key if key is not None else (ALONE, str(idx)), []).append((idx, list(overrides)))
    batchable = sum(len(members) for members in groups.values() if len(members) > 1)
    workers = max(workers, 1)
    size = max(1, min(batch_size, max(math.ceil(batchable / (TASKS_PER_WORKER * workers)),
                                      min(MIN_BATCH, math.ceil(batchable / workers)))))
    tasks: list[list[tuple[int, list[str]]]] = []
    for members in groups.values():
        count = math.ceil(len(members) / size)
        tasks += [members[k * len(members) // count:(k + 1) * len(members) // count] for k in range(count)]
    tasks.sort(key=lambda task: task[0][0])
    return tasks


# -- in the worker processes ------------------------------------------------------------------------
@dataclass
class _World:
    """A job that joins a batch: what its per-job path had made of it before building."""

    idx: int
    overrides: list[str]
    data: dict[str, Any]
    scenario: Any
    plugin_set: Any
    run_dir: Path
    env: dict[str, str]

    def key(self, group: str = "seed") -> str:
        """What the worlds of one batch share, as text: the config without the seed (``group``
        ``seed``), or the physics step's terms (``physics``: the dynamics model, the number of
        agents, the guidance period and the physics step)."""
        if group == "physics":
            config = self.scenario.config  # the physics step as the engine resolves it (null: T_s)
            return json.dumps([self.data["dynamics"]["name"], config.swarm.n,
                               config.clock.guidance_period, config.physics_step], default=repr)
        return json.dumps({k: v for k, v in self.data.items() if k != "seed"}, sort_keys=True, default=repr)


def run_batch_task(items: list[tuple[int, list[str]]], sweep_dir: str, group: str = "seed") -> bytes:
    """A batch in a worker (module docstring): every job's ``JobReturn``, in the task's order,
    pickled by :func:`.pool.dumps`."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.core.utils import configure_log, env_override

    from ..composition.hydra_internals import hydra_config_kept

    hydra_context, config = pool._WORKER["hydra_context"], pool._WORKER["config"]
    loader = hydra_context.config_loader
    prefix = f"{config.hydra.job.name}_"  # the pool's hydra.job.id: <name>_<n>
    name = str(config.hydra.job.name)
    returns: dict[int, Any] = {}
    worlds: list[_World] = []
    twin: _Twin | None = None  # a joined job whose config its seed's twins reuse (group "seed")
    with hydra_config_kept():
        for idx, overrides in items:
            if twin is not None and (world := twin.joining(idx, overrides, sweep_dir)) is not None:
                worlds.append(world)
                continue
            cfg, run_dir, lean = _composed(loader, config, idx, overrides, sweep_dir, prefix)
            hydra: Any = HydraConfig.get()
            if idx == items[0][0]:
                configure_log(hydra.job_logging, hydra.verbose)  # as run_job does
            env = {str(k): str(v) for k, v in hydra.job.env_set.items()}
            task_overrides = [str(o) for o in hydra.overrides.task]
            with env_override(env):
                world = _joining(idx, task_overrides, cfg, run_dir, env, worlds[0].env if worlds else env)
                if world is None:  # its per-job path, now, as under the basic launcher
                    returns[idx] = _alone(cfg, task_overrides, name)
                else:
                    worlds.append(world)
                    if twin is None and lean and group == "seed":
                        twin = _Twin.of(cfg, list(overrides), world)
    groups: dict[str, list[_World]] = {}
    for world in worlds:
        groups.setdefault(world.key(group), []).append(world)
    if worlds:
        with env_override(worlds[0].env):
            for together in groups.values():
                overrides_of = {world.idx: world.overrides for world in together}
                for idx, value in fly(together).items():
                    returns[idx] = _job_return(overrides_of[idx], name, value)
    return pool.dumps([returns[idx] for idx, _ in items])


def _alone(cfg: Any, overrides: list[str], name: str) -> Any:
    """A job run through the per-job path (:func:`.job.job_from`) in the run directory
    ``HydraConfig`` names, and its ``JobReturn``: its value, or the exception that ended it, as
    Hydra's ``run_job`` keeps it (a stop request goes on up)."""
    from .job import job_from

    try:
        return _job_return(overrides, name, job_from(cfg))
    except Exception as exc:
        return _job_return(overrides, name, exc, failed=True)


def _composed(loader: Any, config: Any, idx: int, overrides: list[str], sweep_dir: str,
              prefix: str) -> tuple[Any, Path, bool]:
    """Job ``idx`` composed and set up as ``run_job`` sets it up (its number, run directory and
    ``HydraConfig``), as a launcher task's later jobs are (:func:`.task.run_rest`), and whether by
    the lean path (a task config without its ``hydra`` node, run directory ``sweep_dir/idx``). The
    loader is the sweeper's: swarmscene's group-caching one, or Hydra's own under another sweeper
    (Optuna's, the falsifier's), which composes each job whole."""
    from .task import _as_job, _as_lean_job

    lean = loader.load_task_job(config, list(overrides)) if hasattr(loader, "load_task_job") else None
    if lean is not None:
        task_cfg, hydra_root = lean
        cfg, run_dir = _as_lean_job(task_cfg, hydra_root, idx, sweep_dir, prefix)
    else:
        cfg, run_dir = _as_job(loader.load_sweep_config(config, list(overrides)), idx, sweep_dir, prefix)
    return cfg, Path(run_dir), lean is not None


SEED_OVERRIDE = re.compile(r"(\+\+)?seed=(0|-?[1-9][0-9]*)")
"""A seed override whose value Hydra reads as that integer (``seed=17``, ``++seed=17``)."""


@dataclass
class _Twin:
    """A job of a ``seed`` batch that joined it from a lean composition, whose config the batch's
    later jobs reuse with only their seed set: a job that differs from it in its seed's value alone
    (the same override texts elsewhere, the same ``seed=`` or ``++seed=`` spelling, an integer)
    is made from that config by Hydra's own step for a value override, with the seed's parsed
    override copied with the job's value, instead of a copy of the composition and Hydra's parse
    of its seed (~2 ms a job). What the job's per-job path would then do, it does
    (:func:`_joining`: its overrides file, its config resolved, validated, its run directory
    checked), and a job that cannot join is composed as ever and runs alone. The same config as
    its own composition: Hydra applies the same override to the same composed config. That config
    is the first job's own copy, its seed set in place for each twin in turn (each world's data is
    resolved from it before the next twin's seed is set)."""

    cfg: Any
    overrides: list[str]
    task_overrides: list[str]
    at: int
    seed: Any
    env: dict[str, str]

    @classmethod
    def of(cls, cfg: Any, overrides: list[str], world: _World) -> _Twin | None:
        """From a joined job's task config and overrides; None without exactly one plain seed override."""
        from .compose import parse

        at = [k for k, text in enumerate(overrides) if SEED_OVERRIDE.fullmatch(text)]
        if len(at) != 1 or world.overrides.count(overrides[at[0]]) != 1:
            return None
        return cls(cfg, overrides, world.overrides, at[0], parse([overrides[at[0]]])[0], world.env)

    def joining(self, idx: int, overrides: list[str], sweep_dir: str) -> _World | None:
        """Job ``idx`` as a world of the batch (:func:`_joining`), or None: it is not this job's
        twin, or it cannot join (then it is composed and runs alone, from the beginning)."""
        from hydra.core.utils import env_override

        from .compose import _apply_values
        from .task import _as_lean_run_dir

        seed = self._seed_of(overrides)
        if seed is None:
            return None
        text = overrides[self.at]
        _apply_values([dataclasses.replace(self.seed, _value=seed, input_line=text)], self.cfg)
        task_overrides = [text if o == self.overrides[self.at] else o for o in self.task_overrides]
        with env_override(self.env):
            return _joining(idx, task_overrides, self.cfg, _as_lean_run_dir(sweep_dir, idx), self.env, self.env)

    def _seed_of(self, overrides: list[str]) -> int | None:
        """The job's seed where its overrides are this job's but the seed's value, spelt the same
        way (``seed=`` or ``++seed=``); else None."""
        mine = self.overrides
        if len(overrides) != len(mine) or any(
                a != b for k, (a, b) in enumerate(zip(overrides, mine, strict=True)) if k != self.at):
            return None
        match = SEED_OVERRIDE.fullmatch(overrides[self.at])
        if match is None or overrides[self.at].startswith("++") != mine[self.at].startswith("++"):
            return None
        return int(match.group(2))


def _joining(idx: int, overrides: list[str], cfg: Any, run_dir: Path, env: dict[str, str],
             batch_env: dict[str, str]) -> _World | None:
    """The job as a world of a batch: the start of its per-job path (:func:`.job.run_job`: its
    ``.hydra/overrides.yaml``, its scenario validated, a complete run of the same config looked
    for); None when it must run alone (the module docstring's list), which then does all of it
    again and reports what went wrong."""
    from omegaconf import OmegaConf

    from ..runs.build import load, plugins
    from ..views.writers import unbatched_output
    from .records import completed_metrics, write_overrides

    if env != batch_env:
        return None
    try:
        data = OmegaConf.to_container(cfg, resolve=True)
        assert isinstance(data, dict)
        write_overrides(run_dir, overrides)  # the job's record of what it is, before anything can fail
        plugin_set = plugins()
        scenario = load({str(k): v for k, v in data.items()}, plugin_set[1])
        if unbatched_output(scenario.config.output) is not None:
            return None
        if completed_metrics(run_dir, scenario.data) is not None:
            return None
    except Exception:  # its per-job path records it
        return None
    return _World(idx, overrides, {str(k): v for k, v in data.items()}, scenario, plugin_set, run_dir, env)


def _job_return(overrides: list[str], name: str, value: Any, failed: bool = False) -> Any:
    """A ``JobReturn`` as Hydra's ``run_job`` makes it (the job's config left out: no sweeper reads it)."""
    from hydra.core.utils import JobReturn, JobStatus

    ret = JobReturn(overrides=overrides, working_dir=os.getcwd(), task_name=name)
    ret.return_value = value
    ret.status = JobStatus.FAILED if failed else JobStatus.COMPLETED
    return ret


def fly(group: list[_World]) -> dict[int, Any]:
    """Build, fly and land one group of worlds (module docstring, 3-4); each job's value as its
    per-job path returns it. A stop request, or a world interrupted, raises KeyboardInterrupt once
    every world is written."""
    from ..core.batch import BatchSimulation
    from ..runpath import utc_now
    from ..runs.build import build
    from ..views.summary import RunWarnings
    from .job import recorded_job

    values: dict[int, Any] = {}
    if interrupts.requested() is not None:  # came while the jobs were set up: stop before building
        raise KeyboardInterrupt
    built = []
    for world in group:
        try:
            built.append((world, build(world.scenario, world.plugin_set)))
        except Exception:  # its per-job path builds it again and records why it cannot be built
            values[world.idx] = recorded_job(world.data, world.run_dir)
    if not built:
        return values
    try:
        batch = BatchSimulation([sim for _, sim in built])
    except ValueError:  # worlds that cannot share a physics step: one by one
        for world, _ in built:
            values[world.idx] = recorded_job(world.data, world.run_dir)
        return values
    started_at = utc_now()
    with RunWarnings() as seen:
        outcomes = batch.run()
    seen.show(failed=any(outcome.result.error is not None for outcome in outcomes))
    for (world, sim), outcome in zip(built, outcomes, strict=True):
        values[world.idx] = recorded_job(world.data, world.run_dir, run=_lander(sim, outcome, started_at))
    if interrupts.requested() is not None or not all(outcome.result.complete for outcome in outcomes):
        raise KeyboardInterrupt  # every world is written (marked incomplete if cut); stop the sweep
    return values


def _lander(sim: Any, outcome: Any, started_at: str) -> Callable[[dict[str, Any], Path], Any]:
    """A world's landing, with :func:`.job.run_job`'s contract (for :func:`.job.recorded_job`): its run
    directory written as :func:`swarmscene.runpath.run_and_write` writes a sweep job's, its failure
    raised, else its objective returned."""
    from ..runpath import Flight, land
    from .job import objective_from

    def land_world(data: dict[str, Any], run_dir: Path) -> Any:
        failed = land(sim, Flight(outcome.result, started_at, cause=outcome.failure), run_dir)
        if failed is not None:
            raise failed  # recorded as a failed job (error.json, manifest), outputs kept
        return objective_from(sim.config.output.objective, outcome.result.metrics)

    return land_world
