"""Every use of Hydra's private API, in one place: what each uses, why, and the version checked.

pyproject.toml pins ``hydra-core>=1.3,<1.4``; each function below was read against hydra-core 1.3.8
(the version docs/sweeps.md reports tested). A new Hydra minor release means reading this module,
not the application: ``tests/test_layout.py`` (``test_only_hydra_internals_touches_hydras_private_api``)
fails when another module of the package imports ``hydra._internal`` or ``hydra.core.singleton``,
names either in a string, or assigns an attribute of something imported from Hydra.

Where the line is drawn. Private here, used only through this module:

- anything under ``hydra._internal`` (the config loader, the search path, the config sources, the
  basic sweeper's import path);
- ``hydra.core.singleton.Singleton``'s state, which Hydra's own launchers carry to their workers
  but no public function does;
- replacing or setting anything of Hydra's: the ``.hydra/`` writer (``hydra.core.utils._save_config``),
  the config sources' ``load_config``, ``HydraConfig``'s ``cfg`` set without ``set_config``.

Public, used where it is needed: ``hydra.core.hydra_config.HydraConfig`` read through ``get()``,
``initialized()`` and ``set_config()``; ``hydra.core.plugins.Plugins``, the ``hydra.plugins.*``
base classes (``Sweeper``, ``Launcher``, ``SearchPathPlugin``, ``ConfigSource``) and
``hydra.core.config_loader.ConfigLoader``; the override parser ``hydra.core.override_parser``
(documented for sweeper plugins); ``hydra.core.utils``' launcher helpers (``run_job``,
``setup_globals``, ``configure_log``, ``filter_overrides``, used by Hydra's own launcher plugins);
``ConfigStore``, ``GlobalHydra``, ``hydra.experimental.callback.Callback``, ``hydra.errors``,
``hydra.types``, ``compose``/``initialize_config_module``.

Hydra is imported inside each function, never at this module's import: importing the command line
or the API loads no more of Hydra than it did before.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from pathlib import Path

BASIC_SWEEPER = "hydra._internal.core_plugins.basic_sweeper.BasicSweeper"
"""The ``_target_`` of Hydra's basic sweeper (``hydra/sweeper=basic``, every multirun's default):
the multirun callback (:mod:`swarmscene.sweeps.callback`) recognises it in the composed config to
put swarmscene's sweeper in its place. Hydra's own config schema names the class by this private
path and there is no public one (hydra-core 1.3.8: ``BasicSweeperConf._target_`` in
``hydra/_internal/core_plugins/basic_sweeper.py``)."""

_CHECKED_MARK = "_swarmscene_checked"


# -- the .hydra/ writer -----------------------------------------------------------------------------
def save_config_loaded() -> bool:
    """Whether Hydra's job runner (``hydra.core.utils``, whose ``_save_config``
    :func:`replace_save_config` replaces) is imported in this process: a launcher's worker imports
    the command line with it already loaded, and must replace the writer before its first job."""
    return "hydra.core.utils" in sys.modules


def replace_save_config(writer: Callable[[Any, str, Path], None]) -> None:
    """Make Hydra write ``.hydra/config.yaml``, ``hydra.yaml`` and ``overrides.yaml`` with ``writer``
    (``writer(cfg, filename, output_dir)``; idempotent).

    Private: ``hydra.core.utils._save_config``, the module global ``run_job`` calls for each file
    (hydra-core 1.3.8). Why: Hydra's writer opens the path with a plain ``open(path, "w")``, which
    follows a link planted at that name, and no public option or hook changes how, or whether
    safely, those files are written (``hydra.output_subdir: null`` drops them altogether). The
    replacement (:func:`swarmscene.composition.hydra_files.save_config`) writes atomically, never through a link.
    """
    import hydra.core.utils as hydra_utils

    hydra_utils._save_config = writer  # type: ignore[assignment]  # its argument names aside: called positionally


# -- the config files Hydra reads -------------------------------------------------------------------
def check_before_config_files_are_read(check_file: Callable[[str], None],
                                       check_resource: Callable[[Any], None]) -> None:
    """Call ``check_file(path)`` before Hydra reads a config file from a folder (``file://``) and
    ``check_resource(resource)`` before it reads one from a package (``pkg://``): the real path, or
    the ``importlib.resources`` resource, Hydra is about to open (it may not exist: Hydra then
    reports it). A check raises to refuse the file. Idempotent.

    Private: ``hydra._internal.core_plugins.file_config_source.FileConfigSource`` and
    ``...importlib_resources_config_source.ImportlibResourcesConfigSource``, their ``load_config``
    wrapped, and the base class's ``_normalize_file_name`` and ``path`` to find the file as they do
    (hydra-core 1.3.8). Why: every file of a composition (primary config, groups, ``--config-dir``,
    a package's search-path entry) goes through these two sources, and Hydra has no hook between
    finding a file and parsing it; a ``SearchPathPlugin`` adds sources, it cannot inspect theirs.
    Call after ``Plugins.instance()``: its first scan imports the sources' modules again, which
    would drop the wrapping.
    """
    from hydra._internal.core_plugins.file_config_source import FileConfigSource
    from hydra._internal.core_plugins.importlib_resources_config_source import ImportlibResourcesConfigSource

    if getattr(FileConfigSource.load_config, _CHECKED_MARK, False):
        return
    file_load, package_load = FileConfigSource.load_config, ImportlibResourcesConfigSource.load_config

    def load_file(self: Any, config_path: str) -> Any:
        import os

        check_file(os.path.realpath(os.path.join(self.path, self._normalize_file_name(config_path))))
        return file_load(self, config_path)

    def load_package(self: Any, config_path: str) -> Any:
        from importlib import resources

        check_resource(resources.files(self.path).joinpath(self._normalize_file_name(config_path)))
        return package_load(self, config_path)

    setattr(load_file, _CHECKED_MARK, True)
    setattr(load_package, _CHECKED_MARK, True)
    FileConfigSource.load_config = load_file  # type: ignore[method-assign]
    ImportlibResourcesConfigSource.load_config = load_package  # type: ignore[method-assign]


# -- composing a sweep's jobs (swarmscene.sweeps.compose, .task) -----------------------------------
def config_search_path(entries: Iterable[tuple[str, str]]) -> Any:
    """A search path holding ``entries`` (``(provider, path)``, in order).

    Private: ``hydra._internal.config_search_path_impl.ConfigSearchPathImpl`` (hydra-core 1.3.8).
    Why: the public ``hydra.core.config_search_path.ConfigSearchPath`` is abstract; a launcher
    task's worker rebuilds the sweep's search path from its pickled entries to make a loader
    (:func:`config_loader`) without Hydra's start-up.
    """
    from hydra._internal.config_search_path_impl import ConfigSearchPathImpl

    search_path = ConfigSearchPathImpl()
    for provider, path in entries:
        search_path.append(provider, path)
    return search_path


def config_loader(search_path: Any) -> Any:
    """Hydra's config loader for ``search_path`` (a ``ConfigLoader``).

    Private: ``hydra._internal.config_loader_impl.ConfigLoaderImpl`` (hydra-core 1.3.8). Why: the
    public ``hydra.core.config_loader.ConfigLoader`` is abstract, and its one implementation is
    only built inside Hydra's start-up (``hydra_context.config_loader``); a worker rebuilds it from
    the search path rather than receiving it pickled (~30 KB with every job).
    """
    from hydra._internal.config_loader_impl import ConfigLoaderImpl

    return ConfigLoaderImpl(config_search_path=search_path)


def is_hydras_config_loader(loader: Any) -> bool:
    """Whether ``loader`` is exactly Hydra's own loader (:func:`config_loader` can rebuild it from its
    search path), not a subclass or another implementation.

    Private: ``ConfigLoaderImpl`` (hydra-core 1.3.8), as :func:`config_loader`.
    """
    from hydra._internal.config_loader_impl import ConfigLoaderImpl

    return type(loader) is ConfigLoaderImpl


def group_exists(loader: Any, name: str) -> bool | None:
    """Whether ``name`` is a config group on ``loader``'s search path; None when the loader holds no
    config repository (not Hydra's loader).

    Private: ``ConfigLoaderImpl.repository``, a ``hydra._internal.config_repository`` object, and
    its ``group_exists`` (hydra-core 1.3.8). Why: ``ConfigLoader.list_groups`` lists one level of
    groups; telling ``avoidance.K=2`` (a value) from ``avoidance/x=y`` needs the repository's own
    answer for a dotted name, as Hydra's composition asks it.
    """
    repository = getattr(loader, "repository", None)
    return None if repository is None else bool(repository.group_exists(name))


def apply_overrides_to_config(overrides: Sequence[Any], cfg: Any) -> None:
    """Apply value overrides (parsed ``Override`` objects) to a composed config, as Hydra's
    composition does once the defaults list is merged. OmegaConf's errors are raised as they are
    (``load_configuration`` wraps them in ``ConfigCompositionException``; the caller does too).

    Private: ``ConfigLoaderImpl._apply_overrides_to_config`` (hydra-core 1.3.8). Why: it is the one
    step of Hydra's composition that follows the defaults list, and no public API runs it alone;
    :class:`swarmscene.sweeps.compose.GroupCachingLoader` composes a set of group overrides once and
    applies each job's values with it, so a job's config equals Hydra's own composition
    (tests/test_sweep_compose.py).
    """
    from hydra._internal.config_loader_impl import ConfigLoaderImpl

    ConfigLoaderImpl._apply_overrides_to_config(list(overrides), cfg)


def overrides_dirname(overrides: Sequence[Any], kv_sep: str, item_sep: str, exclude_keys: Any) -> str:
    """``hydra.job.override_dirname`` for a job's parsed overrides, as Hydra writes it
    (``exclude_keys``: the keys left out, ``hydra.job.config.override_dirname.exclude_keys``).

    Private: ``hydra._internal.config_loader_impl.get_overrides_dirname`` (hydra-core 1.3.8). Why:
    a job composed by :class:`swarmscene.sweeps.compose.GroupCachingLoader` records its overrides
    in its ``hydra`` node itself, and must spell the directory name exactly as Hydra would.
    """
    from hydra._internal.config_loader_impl import get_overrides_dirname

    return get_overrides_dirname(overrides=list(overrides), kv_sep=kv_sep, item_sep=item_sep, exclude_keys=exclude_keys)


# -- HydraConfig and Hydra's process state (swarmscene.sweeps.task, .pool) -------------------------
def set_hydra_config_node(hydra_root: Any, task_cfg: Any) -> None:
    """Make ``hydra_root`` (a ``{"hydra": ...}`` config) ``HydraConfig``'s, its ``hydra`` node made
    read-only with ``task_cfg`` (the job's config without ``hydra``) as its parent: what
    ``HydraConfig.set_config`` leaves behind, without its copy of the whole config.

    Private: ``HydraConfig.instance().cfg`` assigned, and OmegaConf's ``_set_parent``, as
    ``set_config`` does them (hydra-core 1.3.8). Why: ``set_config`` takes the whole config and
    copies it (``OmegaConf.masked_copy``) every job; a launcher task's lean jobs reuse one ``hydra``
    node per composition (:meth:`swarmscene.sweeps.compose.GroupCachingLoader.load_task_job`), so
    ``${hydra:...}`` reads the job's own node without a copy per job.
    """
    from hydra.core.hydra_config import HydraConfig
    from omegaconf import OmegaConf

    node = hydra_root.hydra
    OmegaConf.set_readonly(node, True)
    node._set_parent(task_cfg)
    HydraConfig.instance().cfg = hydra_root


@contextmanager
def hydra_config_kept() -> Iterator[None]:
    """``HydraConfig`` as it is on entry, set back on exit (None included: not set).

    Private: ``HydraConfig.instance().cfg`` read and assigned (hydra-core 1.3.8). Why: ``get()``
    returns the ``hydra`` node only, and ``set_config`` takes a whole config and copies it; the
    first job of a launcher task is Hydra's own ``run_job``, whose ``HydraConfig`` must be the one
    left when the task's other jobs (:mod:`swarmscene.sweeps.task`) have run.
    """
    from hydra.core.hydra_config import HydraConfig

    before = HydraConfig.instance().cfg
    try:
        yield
    finally:
        HydraConfig.instance().cfg = before


def hydra_singletons() -> Any:
    """Hydra's singletons of this process (its ``ConfigStore``, ``HydraConfig``, ``GlobalHydra``...,
    copied; ``Plugins`` left out), to send to a worker process (:func:`restore_hydra_singletons`).

    Private: ``hydra.core.singleton.Singleton.get_state()["instances"]`` (hydra-core 1.3.8). Why: a
    launcher's workers need the main process's Hydra state and no public API transfers it; Hydra's
    own joblib and Ray launchers send ``Singleton.get_state()`` the same way.
    """
    from hydra.core.singleton import Singleton

    return Singleton.get_state()["instances"]


def restore_hydra_singletons(instances: Any) -> None:
    """Set Hydra's singletons to ``instances`` (from :func:`hydra_singletons`), keeping the
    OmegaConf resolvers this process registered (local functions do not pickle; the worker
    registers its own first).

    Private: ``hydra.core.singleton.Singleton.set_state`` (hydra-core 1.3.8), which also rescans
    ``Plugins``. Why: as :func:`hydra_singletons`; Hydra's joblib launcher's worker calls it too.
    """
    from hydra.core.singleton import Singleton

    Singleton.set_state({"instances": instances, "omegaconf_resolvers": Singleton.get_state()["omegaconf_resolvers"]})
