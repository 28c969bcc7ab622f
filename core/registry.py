"""Plugin manager factory and the registry of plugin classes by kind and name.

Built in the style of tox: a factory (no module-level manager) that loads the built-in modules
first, then the entry points of the group ``swarmscene``, calls ``check_pending()`` so a misspelt
hook fails loudly, and collects every class registered through the ``swarmscene_register_*`` hooks.
The engine never names a plugin: the app layer passes the tuple of built-in module names.
"""

from __future__ import annotations

import importlib
import os
import warnings
from collections.abc import Callable, Iterable
from functools import lru_cache
from importlib.metadata import entry_points
from typing import Any

import pluggy

from . import hookspecs
from .errors import PluginError
from .plugin import PLUGIN_KINDS, Plugin, PluginParams

ENTRY_POINT_GROUP = "swarmscene"
"""Entry-point group through which third-party packages add plugin modules."""
DISABLE_ENV = "SWARMSCENE_DISABLE_PLUGINS"
"""Comma-separated entry-point names (or ``dist:name``) to skip, e.g. to bisect a broken plugin."""
CORE_OBSERVERS = ("swarmscene.core.monitors", "swarmscene.core.recorder")


class Registry:
    """Plugin classes by kind (``formation``, ``avoidance``, ``dynamics``) and name, and observers.

    ``sources`` names the plugin module that registered each class (``(kind, name)`` -> the
    manager's plugin name: a built-in module, or ``dist:entry-point`` for a third-party one), and
    ``distributions`` the distribution and version behind each third-party plugin name, so
    ``swarmscene plugins`` and the manifest can say which package provides what.
    """

    def __init__(self) -> None:
        self.classes: dict[str, dict[str, type[Plugin]]] = {kind: {} for kind in PLUGIN_KINDS}
        self.observers: list[type[Any]] = []
        self.sources: dict[tuple[str, str], str] = {}
        self.distributions: dict[str, tuple[str, str]] = {}

    def register(self, kind: str, cls: type[Plugin]) -> None:
        """Add ``cls`` under its declared ``name``; a second class with the same name is an error."""
        base = PLUGIN_KINDS[kind]
        if not (isinstance(cls, type) and issubclass(cls, base)):
            raise PluginError(f"{kind} plugins must subclass {base.__name__} (got {cls!r})")
        name = getattr(cls, "name", None)
        if not isinstance(name, str) or not name:
            raise PluginError(f"{cls.__module__}.{cls.__qualname__} declares no `name`")
        if not (isinstance(cls.Params, type) and issubclass(cls.Params, PluginParams)):
            raise PluginError(f"{kind} {name!r}: Params must subclass PluginParams")
        old = self.classes[kind].get(name)
        if old is not None and old is not cls:
            raise PluginError(
                f"{kind} {name!r} registered twice: by {old.__module__}.{old.__qualname__} "
                f"and by {cls.__module__}.{cls.__qualname__}"
            )
        self.classes[kind][name] = cls

    def names(self, kind: str) -> list[str]:
        """Registered names of ``kind``, sorted."""
        return sorted(self.classes[kind])

    def get(self, kind: str, name: str) -> type[Plugin]:
        """The class registered as ``name``; unknown names list the valid ones."""
        try:
            return self.classes[kind][name]
        except KeyError:
            raise PluginError(
                f"unknown {kind} {name!r} (valid: {', '.join(self.names(kind))})"
            ) from None


def make_plugin_manager(
    builtins: Iterable[str] = (), load_entry_points: bool = True
) -> tuple[pluggy.PluginManager, Registry]:
    """Build a plugin manager and collect the registered classes.

    Args:
        builtins: module names of the built-in plugins (registered like any other plugin).
        load_entry_points: also load third-party modules from the ``swarmscene`` entry points.
    Returns:
        The manager (owned by whoever asked: one per simulation) and the filled registry.
    """
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    for module_name in (*CORE_OBSERVERS, *builtins):
        pm.register(importlib.import_module(module_name), name=module_name)
    registry = Registry()
    if load_entry_points:
        registry.distributions = _load_entry_points(pm)
    pm.check_pending()
    trusted = {*CORE_OBSERVERS, *builtins}
    for hook_name, kind in (
        ("swarmscene_register_formations", "formation"),
        ("swarmscene_register_avoidances", "avoidance"),
        ("swarmscene_register_dynamics", "dynamics"),
        ("swarmscene_register_observers", None),
    ):
        _call_registration(getattr(pm.hook, hook_name), registry, kind, trusted)
    return pm, registry


def _call_registration(hook: Any, registry: Registry, kind: str | None, trusted: set[str]) -> None:
    """Call one registration hook plugin by plugin, so a failure names its plugin.

    A built-in that fails is a bug and raises; a third-party plugin that fails is skipped with a
    warning naming it. ``kind`` None is the observers' hook.
    """
    for impl in hook.get_hookimpls():
        def register(cls: Any, source: str = impl.plugin_name) -> None:
            if kind is None:
                registry.observers.append(cls)
                return
            registry.register(kind, cls)
            registry.sources[(kind, cls.name)] = source

        try:
            impl.function(register=register)
        except Exception as exc:
            if impl.plugin_name in trusted:
                raise
            warnings.warn(
                f"swarmscene: skipping plugin {impl.plugin_name!r}: {type(exc).__name__}: {exc}",
                RuntimeWarning,
                stacklevel=3,
            )


def installed_plugins() -> tuple[Any, ...]:
    """The installed ``swarmscene`` entry points (listed once per process)."""
    return _installed(entry_points)


def plugin_distributions() -> dict[str, str]:
    """Each distribution that provides a ``swarmscene`` entry point, with its version."""
    return {ep.dist.name: ep.dist.version for ep in installed_plugins() if ep.dist is not None}


@lru_cache(maxsize=4)
def _installed(lister: Callable[..., Any]) -> tuple[Any, ...]:
    """The ``swarmscene`` entry points, listed once per process (a scan of every installed
    distribution's metadata costs a few ms, paid by every plugin manager: every job of a sweep).
    Keyed by the lister, so a test that replaces ``entry_points`` gets its own list."""
    return tuple(lister(group=ENTRY_POINT_GROUP))


def _load_entry_points(pm: pluggy.PluginManager) -> dict[str, tuple[str, str]]:
    """Register every ``swarmscene`` entry point not blocked by :data:`DISABLE_ENV`; return the
    distribution and version behind each registered plugin name."""
    blocked = {b.strip() for b in os.environ.get(DISABLE_ENV, "").split(",") if b.strip()}
    provided: dict[str, tuple[str, str]] = {}
    seen: set[str] = set()
    for ep in _installed(entry_points):
        dist = ep.dist.name if ep.dist is not None else "unknown"
        # Named by distribution, so two packages using the same entry-point name cannot shadow.
        plugin_name = f"{dist}:{ep.name}"
        seen.update((ep.name, plugin_name))
        if ep.name in blocked or plugin_name in blocked or pm.has_plugin(plugin_name):
            continue
        try:
            pm.register(ep.load(), name=plugin_name)
            provided[plugin_name] = (dist, ep.dist.version if ep.dist is not None else "unknown")
        except Exception as exc:  # a broken third-party plugin must not take the engine down
            warnings.warn(
                f"swarmscene: skipping plugin {plugin_name!r} ({ep.value}): "
                f"{type(exc).__name__}: {exc}",
                RuntimeWarning,
                stacklevel=2,
            )
    for name in sorted(blocked - seen):  # a misspelt name would otherwise block nothing, silently
        warnings.warn(
            f"swarmscene: {DISABLE_ENV} names {name!r}, which no installed plugin is "
            f"(installed: {', '.join(sorted(n for n in seen if ':' in n)) or 'none'})",
            RuntimeWarning,
            stacklevel=2,
        )
    return provided
