"""Launcher tasks of several jobs: one task runs K of a sweep's jobs back to back in one process.

A job launched alone pays Hydra's per-job bookkeeping (``hydra.core.utils.run_job``: two masked
copies of the ``hydra`` node and two deep copies of the whole config, ~40 % of a small job) and, on
joblib, one pickled config and one task round trip. The sweeper hands a launcher tasks of K jobs
instead (``hydra.sweeper.jobs_per_task``); a task is the jobs' override lists one after another, each
closed by its index marker (``::job=<n>``, which no override can be), so it travels through any
launcher unchanged. In the process that composes the task (:class:`~.compose.GroupCachingLoader`):

- the task's first job is composed as a job of its own, its run directory fixed as the job's
  (``hydra.sweep.subdir`` resolved with its own number: the launcher numbers tasks, not jobs), and
  the rest of the task set in its environment (:data:`CHUNK_ENV`, through ``hydra.job.env_set``);
- Hydra's ``run_job`` runs the first job as ever; the task function (:func:`.job.launcher_task`) then runs the
  rest (:func:`.task.run_rest`): each composed from the cached composition of its groups, numbered, given
  its own run directory and ``HydraConfig``, and run by the same per-job function, which writes the
  same run directory (``.hydra/overrides.yaml``, config, manifest, metrics; resume and failure
  records per job). A job that only changes values takes the lean path
  (:meth:`~.compose.GroupCachingLoader.load_task_job`): a copy of its composition without the
  ``hydra`` node, and one ``hydra`` node per composition renumbered job after job (Hydra copies
  that node twice a job); a config that reads ``${hydra:...}`` is composed whole.

What a task does not do per job: Hydra's job callbacks (``on_job_start``/``on_job_end``; a sweep with
callbacks other than the summary, MLflow's say, is launched job by job), a working-directory change
(``hydra.job.chdir: true``: job by job), and Hydra's ``#n : overrides`` log line (one per task, listing
its jobs). A stop request ends the task between jobs, as it ends a launch.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Sequence
from typing import Any, cast

JOB_MARK = "::job="
"""Closes each job's overrides in a task (not an override Hydra's grammar accepts: never a user's)."""
CHUNK_ENV = "SWARMSCENE_SWEEP_TASK"
"""The environment variable that carries the rest of a task to its first job's process."""
MAX_PER_TASK = 64
"""The most jobs one task runs (a task is the launcher's unit of load balancing and of its log)."""
TASKS_PER_WORKER = 4
"""``auto``: tasks per worker in a batch (K = jobs / (4 workers)): a slow task cannot hold the last
quarter of a sweep on one core."""
CHUNKING_LAUNCHERS = ("BasicLauncher", "JoblibLauncher", "PoolLauncher", "RayLauncher")
"""Launchers whose tasks are composed and run as the module docstring says (submitit's jobs keep
their own SLURM ids: job by job)."""


def jobs_per_task(setting: Any, launcher: Any, config: Any, jobs: int, cores: int | None = None) -> int:
    """K for a batch of ``jobs``: 1 where a task cannot run several jobs (:func:`refusal`), whatever
    the setting; else ``setting`` when an integer; for ``auto`` the whole batch (at most
    :data:`MAX_PER_TASK`) in this process's basic launcher, else ``jobs / (TASKS_PER_WORKER x
    workers)``."""
    if refusal(launcher, config) is not None:
        return 1
    if setting != "auto":
        return max(1, min(int(setting), jobs))
    workers = 1 if type(launcher).__name__ == "BasicLauncher" else _workers(config, cores)
    per_worker = 1 if workers == 1 else TASKS_PER_WORKER
    return max(1, min(MAX_PER_TASK, math.ceil(jobs / (per_worker * workers))))


def refusal(launcher: Any, config: Any) -> str | None:
    """Why this sweep's jobs must be launched one by one (None: they may share tasks): a launcher
    that does not run tasks (:data:`CHUNKING_LAUNCHERS`), or :func:`config_refusal`."""
    if type(launcher).__name__ not in CHUNKING_LAUNCHERS:
        return f"launcher {type(launcher).__name__}"
    return config_refusal(config)


def config_refusal(config: Any) -> str | None:
    """Why this sweep's config keeps each job to Hydra's ``run_job`` (None: jobs may share a task or
    a batch, :mod:`.batch`): callbacks other than the summary with job hooks of their own
    (``on_job_start``/``on_job_end`` are ``run_job``'s), ``hydra.job.chdir``, a
    ``hydra.sweep.subdir`` read through ``${hydra:...}`` (resolved against HydraConfig: not the
    task's own job)."""
    from omegaconf import OmegaConf

    from .callback import SUMMARY_TARGET

    hydra = config.hydra
    if hydra.job.chdir:
        return "hydra.job.chdir"
    callbacks = hydra.callbacks or {}
    if any(_has_job_hooks((c or {}).get("_target_")) for c in callbacks.values() if (c or {}).get("_target_")
           != SUMMARY_TARGET):
        return "job callbacks"
    sweep = cast("dict[str, Any]", OmegaConf.to_container(hydra.sweep, resolve=False))
    if "${hydra:" in str(sweep.get("subdir")):
        return "hydra.sweep.subdir"
    return None


def _has_job_hooks(target: Any) -> bool:
    """Whether the callback class ``target`` names has its own ``on_job_start`` or ``on_job_end``
    (Hydra's ``run_job`` calls them, so its jobs must run one by one); True when it cannot be
    imported here (its job then reports what is wrong). A callback with only the sweep's hooks
    (the falsifier's ``WorstCase``) lets jobs share a task or a batch."""
    from hydra.experimental.callback import Callback
    from hydra.utils import get_class

    try:
        cls = get_class(str(target))
    except Exception:
        return True
    return any(getattr(cls, hook, None) is not getattr(Callback, hook) for hook in ("on_job_start", "on_job_end"))


def _workers(config: Any, cores: int | None) -> int:
    n_jobs = config.hydra.launcher.get("n_jobs") if "launcher" in config.hydra else None
    return workers_for(n_jobs if isinstance(n_jobs, int) and n_jobs != 0 else None, cores)


def workers_for(n_jobs: int | None, cores: int | None = None) -> int:
    """A launcher's ``n_jobs`` as a count of workers, as joblib counts it (the pool launcher's and
    joblib's): None every core, -1 all of them, -2 all but one; ``cores`` by default those this
    process may use."""
    if cores is None:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if n_jobs is None:
        return cores
    if n_jobs < 0:
        return max(1, cores + 1 + n_jobs)
    return n_jobs


def tasks(jobs: Sequence[Sequence[str]], start: int, stop: int, per_task: int) -> list[list[str]]:
    """The launcher's override lists for jobs ``start:stop``: ``per_task`` jobs each, each job's
    overrides closed by its marker; with ``per_task`` 1, the jobs' own lists (Hydra's launch)."""
    if per_task <= 1:
        return [list(job) for job in jobs[start:stop]]
    out = []
    for first in range(start, stop, per_task):
        task: list[str] = []
        for idx in range(first, min(first + per_task, stop)):
            task += [*jobs[idx], f"{JOB_MARK}{idx}"]
        out.append(task)
    return out


def split(overrides: Sequence[str]) -> list[tuple[int, list[str]]] | None:
    """``[(job number, its overrides), ...]`` of a task; None for one job's plain overrides."""
    if not overrides or not str(overrides[-1]).startswith(JOB_MARK):
        return None
    out: list[tuple[int, list[str]]] = []
    current: list[str] = []
    for item in overrides:
        if item.startswith(JOB_MARK):
            out.append((int(item[len(JOB_MARK):]), current))
            current = []
        else:
            current.append(item)
    return out


def set_first(cfg: Any, first: int, rest: list[tuple[int, list[str]]], master_config: Any,
              search_path: Sequence[tuple[str, str]]) -> None:
    """The task's first job, composed: numbered, its run directory fixed (the launcher will number
    the task), and the rest of the task in its environment for :func:`.task.run_rest`."""
    from omegaconf import OmegaConf, open_dict

    with open_dict(cfg):
        cfg.hydra.job.num = first
        cfg.hydra.sweep.subdir = str(OmegaConf.select(cfg, "hydra.sweep.subdir"))
        cfg.hydra.job.env_set[CHUNK_ENV] = literal(json.dumps({
            "first": first,
            "rest": rest,
            "sweep_dir": str(OmegaConf.select(cfg, "hydra.sweep.dir")),
            "config_name": master_config.hydra.job.config_name,
            "hydra_overrides": OmegaConf.to_container(master_config.hydra.overrides.hydra),
            "searchpath": OmegaConf.to_container(master_config.hydra.searchpath),  # compose.extends_search_path
            "search_path": [list(p) for p in search_path],
        }))


def literal(text: str) -> str:
    """``text`` as a config value that OmegaConf reads back unchanged: every ``${`` escaped (with
    the backslashes before it doubled). Hydra resolves ``hydra.job.env_set`` when it sets the job's
    environment: the command as typed ``description='${hydra:job.num}'`` must reach the manifest as
    typed, not as the first job's value."""
    return re.sub(r"(\\*)\$\{", lambda m: m.group(1) * 2 + "\\${", text)
