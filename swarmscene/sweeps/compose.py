"""A job's config composed once per distinct set of config-group overrides (the workers' lever).

Hydra's launchers (basic, joblib, Ray, submitit) compose every job with
``hydra_context.config_loader.load_sweep_config(master, overrides)``: ~70 ms of defaults-list
resolution and YAML merging per job for this config tree, however small the job. Most of a grid's
jobs differ only in plain values (``seed=17``, ``avoidance.K=2``), which do not change the defaults
list. :class:`GroupCachingLoader` wraps Hydra's loader and composes each distinct set of
config-group overrides once per process; a job's plain values are then applied to a copy of that
composition the way Hydra applies them (``_apply_overrides_to_config``, the step of Hydra's own
composition that follows the defaults list), and the job's record in the ``hydra`` node
(``hydra.overrides.task``, ``hydra.job.override_dirname``) is written as Hydra writes it; both
through :mod:`swarmscene.composition.hydra_internals`, which holds the private Hydra functions they need. The
result equals Hydra's own composition (tests/test_sweep_compose.py compares them for every preset
and a sample of grids); a job costs a copy of the composed config and its few overrides (~4 ms).

The cache is per process (a launcher pickles the loader with every job; a worker keeps the
compositions of the earlier jobs it ran), bounded to :data:`CACHED` compositions, least recently
used first out.
"""

from __future__ import annotations

import copy
import json
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any, cast

from hydra.core.config_loader import ConfigLoader

CACHED = 32
"""Compositions kept per process (one per distinct set of config-group overrides)."""

_COMPOSED: OrderedDict[tuple[Any, ...], Any] = OrderedDict()
"""This process's compositions, by search path, config name, Hydra overrides and group overrides."""
_PARSED: dict[str, Any] = {}
PARSED = 100_000
"""Overrides kept parsed per process (a grid's distinct overrides: ~0.4 KiB each, 36 MiB at most)."""


def compositions() -> list[tuple[tuple[Any, ...], Any]]:
    """This process's compositions (key, composed config), least recently used first: what a pool's
    workers are handed at their start (:func:`adopt`), so that none composes them again (Hydra's
    composition of this config tree is ~0.2 s, each worker's first job's)."""
    return list(_COMPOSED.items())


def adopt(composed: Sequence[tuple[tuple[Any, ...], Any]]) -> None:
    """Take another process's compositions of the same sweep (:func:`compositions`) into this
    process's cache. A composition is a pure function of its key (the search path, the config
    name, the Hydra overrides and the group overrides) in a process holding the sweep's Hydra state,
    as a worker does once :func:`.pool._start_worker` restored it; the cache already serves every
    job of a process on that ground."""
    for key, cfg in composed:
        _keep(key, cfg)


def _keep(key: tuple[Any, ...], cfg: Any) -> None:
    """``cfg`` cached as the composition ``key``, the least recently used dropped beyond :data:`CACHED`."""
    _COMPOSED[key] = cfg
    while len(_COMPOSED) > CACHED:
        _COMPOSED.popitem(last=False)


def parse(overrides: Sequence[str]) -> list[Any]:
    """Hydra's parse of each override, each distinct text parsed once per process (the grammar's
    parser costs ~0.5 ms an override; a 10,000-job grid repeats most of them). The parsed
    ``Override`` objects are only read, never changed."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    missing = [o for o in dict.fromkeys(overrides) if o not in _PARSED]
    if missing:
        if len(_PARSED) + len(missing) > PARSED:
            _PARSED.clear()
        _PARSED.update(zip(missing, OverridesParser.create().parse_overrides(missing), strict=True))  # one each
    return [_PARSED[o] for o in overrides]


def extends_search_path(master_config: Any) -> bool:
    """Whether the sweep's config adds to Hydra's search path (``hydra.searchpath``, from the
    command line or the primary config): its folders may hold config groups that the loader's own
    repository does not know, so a group override would be taken for a value. Such a sweep's jobs
    are composed by Hydra whole."""
    try:
        return bool(master_config.hydra.searchpath)
    except Exception:  # no hydra node: nothing added
        return False


class GroupCachingLoader(ConfigLoader):
    """Hydra's config loader, with ``load_sweep_config`` composing once per set of group overrides.

    Every other method is the wrapped loader's. Picklable (the wrapped loader is; the cache is a
    module global of each process).
    """

    def __init__(self, inner: ConfigLoader | None, command: Sequence[str] | None = None,
                 search_path: Any = None) -> None:
        """``command``: the sweep's command as typed; given, each job's config is set up as a sweep
        job's (:func:`_as_sweep_job`), else it is exactly Hydra's composition. ``inner`` None: Hydra's
        loader for ``search_path``, made on first use (an unpickled copy: Hydra's config sources are
        registered in a worker only once the launcher has restored Hydra's state)."""
        self._inner = inner
        self._search_path_given = search_path
        self.command = None if command is None else list(command)
        self._groups: dict[str, bool] = {}
        self._where: tuple[tuple[str, str], ...] | None = None
        self._templates: OrderedDict[tuple[Any, ...], Any] = OrderedDict()

    @property
    def inner(self) -> ConfigLoader:
        """Hydra's loader this one wraps (built on first use after unpickling)."""
        if self._inner is None:
            self._inner = _loader_for(self._search_path_given)
        return self._inner

    def __reduce__(self) -> Any:
        """Pickled as its search path and command (~2 KB instead of Hydra's loader with its
        repository, ~30 KB): a launcher pickles the loader with every job it sends, in the main
        process, one job after another. The worker rebuilds Hydra's loader once per process."""
        from ..composition.hydra_internals import is_hydras_config_loader

        if self._inner is not None and not is_hydras_config_loader(self._inner):
            return (GroupCachingLoader, (self._inner, self.command))
        search_path = self._search_path_given if self._inner is None else self._inner.get_search_path()
        return (GroupCachingLoader, (None, self.command, search_path))

    def __getattr__(self, name: str) -> Any:
        # Attributes of Hydra's implementation that callers reach past the interface (``repository``).
        if name.startswith("_") or name in ("inner", "command"):
            raise AttributeError(name)
        return getattr(self.inner, name)

    def load_sweep_config(self, master_config: Any, sweep_overrides: list[str]) -> Any:
        """A sweep job's config (the first job's, for a launcher task of several)."""
        from . import chunks

        task = chunks.split(sweep_overrides)  # a launcher task of several jobs (sweeps.chunks)
        if task is None:
            return self._load_job(master_config, sweep_overrides)
        (first, overrides), rest = task[0], task[1:]
        cfg = self._load_job(master_config, overrides)
        chunks.set_first(cfg, first, rest, master_config, self._search_path())
        return cfg

    def _load_job(self, master_config: Any, sweep_overrides: list[str]) -> Any:
        from omegaconf import OmegaConf

        parsed = parse(list(sweep_overrides))
        values = [o for o in parsed if self._is_value(o)]
        if extends_search_path(master_config) or any(o.key_or_group == "hydra.searchpath" for o in parsed):
            cfg = self.inner.load_sweep_config(master_config, list(sweep_overrides))
        else:  # (group overrides alone too: the grid's check composes them, and a pool's workers adopt it)
            groups = [o.input_line for o in parsed if not self._is_value(o)]
            cfg = copy.deepcopy(self._composed(master_config, groups))
            _apply_values(values, cfg)
            _record_overrides(cfg, parsed)
            OmegaConf.copy_cache(from_config=master_config, to_config=cfg)  # as Hydra's own
        if self.command is not None:
            _as_sweep_job(cfg, self.command)
        return cfg

    def load_task_job(self, master_config: Any, sweep_overrides: list[str]) -> tuple[Any, Any] | None:
        """A job of a launcher task (:mod:`.chunks`) without the copies of the ``hydra`` node:
        ``(task config, hydra root)``, the first the job's config without its ``hydra`` node (what
        ``run_job`` hands the task function), the second a ``{"hydra": ...}`` config, one per
        composition and reused job after job, with this job's overrides recorded in it (its number
        and run directory are the caller's). None where a job must be composed whole
        (:meth:`load_sweep_config`): a group-only job, an added search path, a ``${hydra:...}``
        read in the task's config or overrides (the hydra root's parent is the task config, not a
        whole config), or a ``hydra.sweep.subdir`` other than ``${hydra.job.num}``."""
        from omegaconf import OmegaConf, read_write

        parsed = parse(list(sweep_overrides))  # a value's ${ is escaped in its override: \$\{hydra\:
        values = [o for o in parsed if self._is_value(o)]
        reads_hydra = any("${hydra:" in o.input_line.replace("\\", "") for o in parsed)
        if (not values or reads_hydra or extends_search_path(master_config)
                or any(o.key_or_group == "hydra.searchpath" for o in parsed)):
            return None
        groups = [o.input_line for o in parsed if not self._is_value(o)]
        template = self._task_template(master_config, groups)
        if template is None:
            return None
        task_base, hydra_root = template
        task = copy.deepcopy(task_base)
        _apply_values(values, task)
        OmegaConf.copy_cache(from_config=master_config, to_config=task)
        with read_write(hydra_root.hydra):
            _record_overrides(hydra_root, parsed)
        return task, hydra_root

    def _task_template(self, master_config: Any, groups: list[str]) -> tuple[Any, Any] | None:
        """(the composition without its ``hydra`` node, its ``hydra`` node set up as a sweep job's),
        once per composition; None where :meth:`load_task_job` cannot use them."""
        from omegaconf import OmegaConf, open_dict, read_write

        key = (master_config.hydra.job.config_name, tuple(master_config.hydra.overrides.hydra), tuple(groups))
        if key not in self._templates:
            composed = self._composed(master_config, groups)
            sweep = cast("dict[str, Any]", OmegaConf.to_container(composed.hydra.sweep, resolve=False))
            subdir = sweep.get("subdir")
            task = copy.deepcopy(composed)
            with read_write(task), open_dict(task):
                del task["hydra"]
            reads_hydra = "${hydra:" in OmegaConf.to_yaml(task)  # unresolved: the interpolations as written
            hydra_root = None  # set where the template is usable
            if self.command is not None and subdir == "${hydra.job.num}" and not reads_hydra:
                hydra_root = OmegaConf.masked_copy(composed, "hydra")
                _as_sweep_job(hydra_root, self.command)
            self._templates[key] = (task, hydra_root) if hydra_root is not None else None
            while len(self._templates) > CACHED:
                self._templates.popitem(last=False)
        return self._templates[key]

    def _composed(self, master_config: Any, groups: list[str]) -> Any:
        from omegaconf import OmegaConf

        hydra_overrides = cast("list[str]", OmegaConf.to_container(master_config.hydra.overrides.hydra))
        key = (self._search_path(), master_config.hydra.job.config_name, tuple(hydra_overrides), tuple(groups))
        if key in _COMPOSED:
            _COMPOSED.move_to_end(key)
            return _COMPOSED[key]
        cfg = self.inner.load_sweep_config(master_config, groups)
        _keep(key, cfg)
        return cfg

    def _search_path(self) -> tuple[tuple[str, str], ...]:
        """Where the wrapped loader finds configs: with the config name and the overrides, what
        tells one composition from another across the loader's pickled copies."""
        if self._where is None:
            self._where = tuple((str(p.provider), str(p.path)) for p in self.inner.get_search_path().get_path())
        return self._where

    def _is_value(self, override: Any) -> bool:
        """A plain value override: not Hydra's own, not a config group, not a package override
        (the overrides Hydra applies after the defaults list, ``Overrides.config_overrides``)."""
        if override.is_hydra_override() or override.package is not None or override.is_sweep_override():
            return False
        name = override.key_or_group
        if name not in self._groups:
            from ..composition.hydra_internals import group_exists

            exists = group_exists(self.inner, name)
            self._groups[name] = True if exists is None else exists  # no repository to ask: Hydra composes
        return not self._groups[name]

    # -- the rest of ConfigLoader: the wrapped loader's ------------------------------------------
    def load_configuration(self, *args: Any, **kwargs: Any) -> Any:
        """A run's whole configuration (the wrapped loader's)."""
        return self.inner.load_configuration(*args, **kwargs)

    def get_search_path(self) -> Any:
        """Where configs are found (the wrapped loader's)."""
        return self.inner.get_search_path()

    def get_sources(self) -> Any:
        """The config sources on the search path (the wrapped loader's)."""
        return self.inner.get_sources()

    def list_groups(self, parent_name: str) -> Any:
        """The config groups under ``parent_name`` (the wrapped loader's)."""
        return self.inner.list_groups(parent_name)

    def get_group_options(self, *args: Any, **kwargs: Any) -> Any:
        """A config group's options (the wrapped loader's)."""
        return self.inner.get_group_options(*args, **kwargs)

    def compute_defaults_list(self, *args: Any, **kwargs: Any) -> Any:
        """A config's defaults list (the wrapped loader's)."""
        return self.inner.compute_defaults_list(*args, **kwargs)


_LOADERS: dict[tuple[tuple[str, str], ...], Any] = {}


def _loader_for(search_path: Any) -> Any:
    """Hydra's loader for this search path, made once per process (it holds only the search path
    and a repository built from it)."""
    from ..composition.hydra_internals import config_loader

    key = tuple((str(p.provider), str(p.path)) for p in search_path.get_path())
    if key not in _LOADERS:
        _LOADERS[key] = config_loader(search_path)
    return _LOADERS[key]


def _as_sweep_job(cfg: Any, command: Sequence[str]) -> None:
    """What a sweep's job records, set in its config (the one place a launcher carries to it).

    - ``hydra.job.env_set``: the command as typed, which Hydra sets in the job's process for the
      manifest (``swarmscene.runs.outputs.run_command``), wherever the job runs;
    - ``hydra.output_subdir: null``: Hydra does not write ``.hydra/config.yaml`` and ``hydra.yaml``
      for each job (three YAML dumps, ~15 ms a job); the job writes ``.hydra/overrides.yaml``
      itself (:func:`.job.run_job`), its ``config.yaml`` is the effective configuration, and the sweep
      directory's ``multirun.yaml`` holds Hydra's own settings (docs/outputs.md).
    """
    from omegaconf import open_dict

    from ..runs.outputs import COMMAND_ENV
    from .chunks import literal

    with open_dict(cfg.hydra.job.env_set):
        cfg.hydra.job.env_set[COMMAND_ENV] = literal(json.dumps(list(command)))
    cfg.hydra.output_subdir = None


def _apply_values(values: Sequence[Any], cfg: Any) -> None:
    """Hydra's own step (no public API holds it;
    :func:`~swarmscene.composition.hydra_internals.apply_overrides_to_config`): the value
    overrides applied to the composed config, errors wrapped as ``load_configuration`` wraps them."""
    from hydra.errors import ConfigCompositionException
    from omegaconf.errors import OmegaConfBaseException

    from ..composition.hydra_internals import apply_overrides_to_config

    try:
        apply_overrides_to_config(values, cfg)
    except OmegaConfBaseException as exc:
        raise ConfigCompositionException().with_traceback(exc.__traceback__) from exc


def _record_overrides(cfg: Any, parsed: Sequence[Any]) -> None:
    """``hydra.overrides.task`` (every non-Hydra override, in order) and ``hydra.job.override_dirname``
    of the job, as ``_load_configuration_impl`` writes them."""
    from ..composition.hydra_internals import overrides_dirname

    task = [o for o in parsed if not o.is_hydra_override()]
    cfg.hydra.overrides.task = [o.input_line for o in task]
    dirname = cfg.hydra.job.config.override_dirname
    cfg.hydra.job.override_dirname = overrides_dirname(
        task, kv_sep=dirname.kv_sep, item_sep=dirname.item_sep, exclude_keys=dirname.exclude_keys,
    )
