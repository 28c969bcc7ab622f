"""A launcher task's jobs in the process that runs them (:mod:`.chunks` encodes a task of several
jobs; this module runs its first job's number and then the rest, each composed by
:class:`~.compose.GroupCachingLoader` and run by the command line's per-job function).

In the task's process, the first job is run by Hydra's ``run_job`` as ever; :func:`renumber_first`
gives it its own number, and :func:`run_rest` composes and runs the task's other jobs, each with
its run directory and ``HydraConfig`` set as ``run_job`` sets them.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from typing import Any

from .chunks import CHUNK_ENV


def renumber_first() -> None:
    """In the task's process, before its first job runs: the job's own number in ``HydraConfig``
    (the launcher gave the task's), so ``${hydra:job.num}`` and the records read the job's. The
    task is taken from the environment (emptied: a job's own subprocesses do not inherit it; Hydra
    removes the variable after the task)."""
    raw = os.environ.get(CHUNK_ENV)
    _CURRENT[0] = json.loads(raw) if raw else None
    if raw:
        os.environ[CHUNK_ENV] = ""
    task = _CURRENT[0]
    if task is not None:
        from hydra.core.hydra_config import HydraConfig

        job = HydraConfig.get().job
        _number(job, task["first"], _id_prefix(job))


def run_rest(run_one: Callable[[Any, Any], Any], first_cfg: Any) -> None:
    """Run the rest of this process's task (nothing for a job launched alone), each job as
    ``run_one(config without hydra, run directory)`` with its ``HydraConfig`` set as ``run_job``
    sets it. ``first_cfg``: the first job's config (its resolver cache: ``${now:}`` as Hydra's)."""
    task, _CURRENT[0] = _CURRENT[0], None  # read by renumber_first
    if task is None:
        return
    from hydra.core.hydra_config import HydraConfig

    from ..composition.hydra_internals import hydra_config_kept

    loader, master = _loader_and_master(task, first_cfg)
    prefix = _id_prefix(HydraConfig.get().job)  # the first job's, numbered by renumber_first
    with hydra_config_kept():
        for idx, overrides in task["rest"]:
            lean = loader.load_task_job(master, list(overrides))
            if lean is not None:
                task_cfg, hydra_root = lean
                run_one(*_as_lean_job(task_cfg, hydra_root, idx, task["sweep_dir"], prefix))
            else:
                cfg = loader.load_sweep_config(master, list(overrides))
                run_one(*_as_job(cfg, idx, task["sweep_dir"], prefix))


_CURRENT: list[dict[str, Any] | None] = [None]
"""The task this process runs now (:func:`renumber_first` takes it, :func:`run_rest` runs it)."""


def _id_prefix(job: Any) -> str | None:
    """What the launcher wrote before the number in ``hydra.job.id`` (basic: ``n``, joblib:
    ``<name>_n``, Ray: ``job_id_for_n``); None when the id does not end with the number."""
    number, ident = job.get("num"), str(job.get("id"))
    if number is None or not ident.endswith(str(number)):
        return None
    return ident[: len(ident) - len(str(number))]


def _number(job: Any, idx: int, id_prefix: str | None) -> None:
    """``hydra.job.num`` the job's, and ``hydra.job.id`` the launcher's prefix and the number."""
    from omegaconf import open_dict, read_write

    with read_write(job), open_dict(job):
        job.num = idx
        job.id = f"{id_prefix or ''}{idx}"


_LOADERS: dict[tuple[str, str | None], Any] = {}


def _loader_and_master(task: dict[str, Any], first_cfg: Any) -> tuple[Any, Any]:
    """This process's group-caching loader for the sweep's search path, and the little of the
    sweep's config that composing a job reads (its config name, Hydra overrides, resolver cache)."""
    from omegaconf import OmegaConf

    from ..composition.hydra_internals import config_search_path
    from ..runs.outputs import COMMAND_ENV
    from .compose import GroupCachingLoader

    raw_command = os.environ.get(COMMAND_ENV)
    key = (json.dumps(task["search_path"]), raw_command)
    if key not in _LOADERS:  # one per process: its compositions and job templates serve every task
        search_path = config_search_path((provider, path) for provider, path in task["search_path"])
        _LOADERS.clear()
        _LOADERS[key] = GroupCachingLoader(None, json.loads(raw_command) if raw_command else None, search_path)
    loader = _LOADERS[key]
    master = OmegaConf.create({"hydra": {"overrides": {"hydra": task["hydra_overrides"]},
                                         "job": {"config_name": task["config_name"]},
                                         "searchpath": task["searchpath"]}})
    OmegaConf.copy_cache(from_config=first_cfg, to_config=master)
    return loader, master


def _as_job(cfg: Any, idx: int, sweep_dir: str, id_prefix: str | None) -> tuple[Any, Any]:
    """What ``run_job`` does before the task function, for one job of a task: its number, its run
    directory (made), ``HydraConfig`` set; the config handed on without its ``hydra`` node."""
    from pathlib import Path

    from hydra.core.hydra_config import HydraConfig
    from omegaconf import OmegaConf, open_dict, read_write

    _number(cfg.hydra.job, idx, id_prefix)
    run_dir = Path(os.path.abspath(os.path.join(sweep_dir, str(OmegaConf.select(cfg, "hydra.sweep.subdir")))))
    with read_write(cfg.hydra.runtime), open_dict(cfg.hydra.runtime):
        cfg.hydra.runtime.output_dir = str(run_dir)
    HydraConfig.instance().set_config(cfg)
    run_dir.mkdir(parents=True, exist_ok=True)
    with read_write(cfg), open_dict(cfg):
        del cfg["hydra"]
    return cfg, run_dir


def _as_lean_job(task_cfg: Any, hydra_root: Any, idx: int, sweep_dir: str, id_prefix: str | None) -> tuple[Any, Any]:
    """:func:`_as_job` for a job from :meth:`~.compose.GroupCachingLoader.load_task_job`: the
    composition's one ``hydra`` node numbered for this job and set as ``HydraConfig`` (its parent the
    job's config, as ``set_config`` makes it; no copy:
    :func:`~swarmscene.composition.hydra_internals.set_hydra_config_node`), the run directory ``sweep_dir/<n>``."""
    from omegaconf import read_write

    from ..composition.hydra_internals import set_hydra_config_node

    run_dir = _as_lean_run_dir(sweep_dir, idx)
    node = hydra_root.hydra
    with read_write(node):
        _number(node.job, idx, id_prefix)
        node.runtime.output_dir = str(run_dir)
    set_hydra_config_node(hydra_root, task_cfg)
    return task_cfg, run_dir


def _as_lean_run_dir(sweep_dir: str, idx: int) -> Any:
    """A lean job's run directory, ``sweep_dir/<n>`` (its ``hydra.sweep.subdir`` is
    ``${hydra.job.num}``), made: :func:`_as_lean_job`'s, and a batch's twin of a lean job's
    (:class:`.batch._Twin`), which sets no ``HydraConfig`` of its own."""
    from pathlib import Path

    run_dir = Path(os.path.abspath(os.path.join(sweep_dir, str(idx))))
    run_dir.mkdir(parents=True, exist_ok=True)
    return run_dir
