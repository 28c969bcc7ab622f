"""Plugin manager factory and the one registry of every kind of component chosen by name.

Built in the style of tox: a factory (no module-level manager) that loads the built-in modules
first, then the entry points of the group ``swarmscene``, calls ``check_pending()`` so a misspelt
hook fails loudly, and collects every class registered through the ``swarmscene_register_<kind>s``
hooks (:data:`KINDS`: formation, avoidance, dynamics, observer, disturbance, event, generator,
policy). A name a user writes is checked by one function, :func:`validate_choice`, for every kind.
The engine never names a plugin: the app layer passes the tuple of built-in module names.
"""

from __future__ import annotations

import importlib
import os
import types
import warnings
import weakref
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import lru_cache
from importlib.metadata import entry_points
from typing import Any

import pluggy
from pydantic import BaseModel

from . import hookspecs
from .disturbances.base import Disturbance, DisturbanceParams
from .errors import PluginError
from .events import EventKindPlugin, EventParams
from .generators import MapGenerator
from .plugin import Avoidance, Dynamics, Formation, PluginParams, Policy

ENTRY_POINT_GROUP = "swarmscene"
"""Entry-point group through which third-party packages add plugin modules."""
DISABLE_ENV = "SWARMSCENE_DISABLE_PLUGINS"
"""Comma-separated entry-point names (or ``dist:name``) to skip, e.g. to bisect a broken plugin; it
skips a package's config folder (group ``swarmscene.conf``) the same way."""
CONF_ENTRY_POINT_GROUP = "swarmscene.conf"
"""Entry-point group through which third-party packages add YAML options to Hydra's search path."""
CORE_OBSERVERS = ("swarmscene.core.monitors", "swarmscene.core.recorder")
BUILTINS_MODULE = "swarmscene.builtins"
"""The module whose ``BUILTIN_PLUGINS`` names the built-in plugin modules (the application's list:
the engine reads it by name at run time, as it loads an entry point, and imports no plugin)."""


@dataclass(frozen=True)
class Kind:
    """One kind of component chosen by name.

    Attributes:
        hook: its registration hook (``swarmscene_register_<kind>s``).
        base: the class every registered class derives from (None: any class, the observers).
        params: the base of its ``Params`` model (None: no ``Params``, the observers).
        label: how errors name it (``unknown disturbance model 'x'``).
        where: what a user writes to choose one (``swarmscene plugins`` and ``--help``).
    """

    hook: str
    base: type | None
    params: type[BaseModel] | None
    label: str
    where: str


KINDS: dict[str, Kind] = {
    "formation": Kind("swarmscene_register_formations", Formation, PluginParams, "formation",
                      "formation=<name>"),
    "avoidance": Kind("swarmscene_register_avoidances", Avoidance, PluginParams, "avoidance",
                      "avoidance=<name>"),
    "dynamics": Kind("swarmscene_register_dynamics", Dynamics, PluginParams, "dynamics",
                     "dynamics=<name>"),
    "observer": Kind("swarmscene_register_observers", None, None, "observer",
                     "every run (not chosen)"),
    "disturbance": Kind("swarmscene_register_disturbances", Disturbance, DisturbanceParams,
                        "disturbance model", "disturbances.<key>.name=<name>"),
    "event": Kind("swarmscene_register_events", EventKindPlugin, EventParams, "event kind",
                  "events.<k>.name=<name>"),
    "generator": Kind("swarmscene_register_generators", MapGenerator, BaseModel, "map generator",
                      "environment.generator=<name>"),
    "policy": Kind("swarmscene_register_policies", Policy, PluginParams, "policy",
                   "avoidance.policy=<name>"),
}
"""Every kind of component registered by name, in the order ``swarmscene plugins`` lists them."""


class Registry:
    """Registered classes by kind (:data:`KINDS`) and name, and the observers in registration order.

    ``sources`` names the plugin module that registered each class (``(kind, name)`` -> the
    manager's plugin name: a built-in module, or ``dist:entry-point`` for a third-party one), and
    ``distributions`` the distribution and version behind each third-party plugin name, so
    ``swarmscene plugins`` and the manifest can say which package provides what. Observers carry no
    ``name``: they are keyed by their class name and all of them run in every run.
    """

    def __init__(self) -> None:
        self.classes: dict[str, dict[str, type[Any]]] = {kind: {} for kind in KINDS}
        self.observers: list[type[Any]] = []
        self.sources: dict[tuple[str, str], str] = {}
        self.distributions: dict[str, tuple[str, str]] = {}

    def register(self, kind: str, cls: type[Any]) -> str:
        """Add ``cls`` under its declared ``name``; return the name. A second class with the same
        name is an error naming both; so is a class that is not of its kind."""
        spec = KINDS[kind]
        if spec.base is None:
            if not isinstance(cls, type):
                raise PluginError(f"{kind}s must be classes (got {cls!r})")
            self.observers.append(cls)
            name = cls.__name__
        else:
            name = _checked_name(kind, spec, cls)
        old = self.classes[kind].get(name)
        if old is not None and old is not cls and spec.base is not None:
            raise PluginError(
                f"{kind} {name!r} registered twice: by {old.__module__}.{old.__qualname__} "
                f"and by {cls.__module__}.{cls.__qualname__}"
            )
        self.classes[kind].setdefault(name, cls)
        return name

    def names(self, kind: str) -> list[str]:
        """Registered names of ``kind``, sorted."""
        return sorted(self.classes[kind])

    def get(self, kind: str, name: str) -> type[Any]:
        """The class registered as ``name``; unknown names list the valid ones."""
        try:
            return self.classes[kind][name]
        except KeyError:
            raise PluginError(
                f"unknown {KINDS[kind].label} {name!r} (valid: {', '.join(self.names(kind))})"
            ) from None


def _checked_name(kind: str, spec: Kind, cls: Any) -> str:
    """The ``name`` ``cls`` declares, after checking it is a class of ``kind`` with a Params model."""
    assert spec.base is not None and spec.params is not None
    if not (isinstance(cls, type) and issubclass(cls, spec.base)):
        raise PluginError(f"{kind} plugins must subclass {spec.base.__name__} (got {cls!r})")
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name:
        raise PluginError(f"{cls.__module__}.{cls.__qualname__} declares no `name`")
    params = getattr(cls, "Params", None)
    if not (isinstance(params, type) and issubclass(params, spec.params)):
        raise PluginError(f"{kind} {name!r}: Params must subclass {spec.params.__name__}")
    return name


def validate_choice(registry: Registry, kind: str, name: Any, key: str, errors: list[str]) -> Any:
    """The class registered as ``name`` for the config key ``key``, or None with one error line.

    The one check of a chosen name for every kind (formation, disturbance model, event kind, map
    generator, policy...): ``<key>: unknown <kind> 'x' (valid: a, b, c)``.
    """
    if isinstance(name, str) and name in registry.classes[kind]:
        return registry.classes[kind][name]
    errors.append(f"{key}: unknown {KINDS[kind].label} {name!r} "
                  f"(valid: {', '.join(registry.names(kind))})")
    return None


_HOOKABLE = (types.FunctionType, types.MethodType, staticmethod, classmethod)
"""What pluggy takes as a hook implementation (a function, a bound method, a static or class method)."""


class _PluginManager(pluggy.PluginManager):
    """pluggy's manager, with a cheaper look at a plugin's names.

    ``register`` asks :meth:`parse_hookimpl_opts` about every name in a plugin's ``dir()``; pluggy
    looks each one up with ``inspect.getattr_static``, which walks the type's MRO with checks for
    shadowed dictionaries and metaclasses. Every run, sweep job and world of a batch builds a
    manager: the built-in modules (~1,000 names: ~7 ms with pluggy's lookup) and the run's plugin
    instances and observers with lifecycle hooks (a few, ~100 names each: ~1.2 ms of a run's
    ~3.5 ms build). The answer is pluggy's own:

    * a module's name is found in its own ``__dict__`` (the module type's data descriptors,
      ``__dict__`` and ``__annotations__``, are never hook implementations), an instance's in its
      own ``__dict__`` or else in the first class of its type's MRO whose ``__dict__`` holds it
      (where ``getattr_static`` finds it for a class that does not shadow its own ``__dict__``,
      which no plugin class does);
    * a value that is not a function, method, ``staticmethod`` or ``classmethod`` is never a hook
      implementation: such a name (a dunder included) is answered None here, as pluggy would;
    * for a function or method, pluggy's answer depends on the value alone (its marker), wherever
      it was found: it is asked once per process and kept with the value (a weak key, so that a
      class or module that goes keeps nothing alive here).

    Every other name (a ``__slots__`` member, a name found nowhere, a class registered as a
    plugin, a ``staticmethod`` or ``classmethod``, which cannot be a weak key) goes to pluggy's own
    method."""

    _answers: weakref.WeakKeyDictionary[Any, dict[str, Any]] = weakref.WeakKeyDictionary()
    """pluggy's answer per function (or method) and project."""

    def parse_hookimpl_opts(self, plugin: Any, name: str) -> Any:
        found, value = _static_value(plugin, name)
        if not found:
            return super().parse_hookimpl_opts(plugin, name)
        if not isinstance(value, _HOOKABLE):
            return None
        if not isinstance(value, (types.FunctionType, types.MethodType)):
            return super().parse_hookimpl_opts(plugin, name)
        answers = self._answers.setdefault(value, {})
        if self.project_name not in answers:
            answers[self.project_name] = super().parse_hookimpl_opts(plugin, name)
        return answers[self.project_name]


def _static_value(plugin: Any, name: str) -> tuple[bool, Any]:
    """(True, the value) where pluggy's static lookup of ``name`` on ``plugin`` finds it (a module's
    or an instance's own ``__dict__``, else the first class of the type's MRO holding it), or
    (False, None) where only pluggy's own lookup can say (a slot, a class plugin, a name found
    nowhere)."""
    if isinstance(plugin, types.ModuleType):
        own = vars(plugin)
        return (True, own[name]) if name in own else (False, None)
    if isinstance(plugin, type):
        return False, None
    try:
        own = object.__getattribute__(plugin, "__dict__")
    except AttributeError:
        own = {}
    if name in own:
        return True, own[name]
    for klass in type(plugin).__mro__:
        if name in vars(klass):
            value = vars(klass)[name]
            return (False, None) if isinstance(value, types.MemberDescriptorType) else (True, value)
    return False, None


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
    pm = _PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    for module_name in (*CORE_OBSERVERS, *builtins):
        pm.register(importlib.import_module(module_name), name=module_name)
    registry = Registry()
    if load_entry_points:
        registry.distributions = _load_entry_points(pm)
    pm.check_pending()
    trusted = {*CORE_OBSERVERS, *builtins}
    for kind, spec in KINDS.items():
        _call_registration(getattr(pm.hook, spec.hook), registry, kind, trusted)
    return pm, registry


@lru_cache(maxsize=1)
def installed_registry() -> Registry:
    """The registry of the installed plugins (the built-in modules, then the entry points), built
    once per process: what a model validated without a registry (``context={"registry": ...}``)
    chooses from, the same classes ``swarmscene.api.plugins()`` registers."""
    builtins = importlib.import_module(BUILTINS_MODULE).BUILTIN_PLUGINS
    return make_plugin_manager(builtins)[1]


def _call_registration(hook: Any, registry: Registry, kind: str, trusted: set[str]) -> None:
    """Call one registration hook plugin by plugin, so a failure names its plugin.

    A built-in that fails is a bug and raises; a third-party plugin that fails is skipped with a
    warning naming it (what it registered before failing stays registered).
    """
    for impl in hook.get_hookimpls():
        def register(cls: Any, source: str = impl.plugin_name) -> None:
            name = registry.register(kind, cls)
            registry.sources.setdefault((kind, name), source)

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
    if not blocked:  # the scan of every distribution below (~7 ms) only checks the names blocked
        return provided
    for ep in entry_points(group=CONF_ENTRY_POINT_GROUP):  # config folders are named the same way
        seen.update((ep.name, f"{ep.dist.name if ep.dist is not None else 'unknown'}:{ep.name}"))
    for name in sorted(blocked - seen):  # a misspelt name would otherwise block nothing, silently
        warnings.warn(
            f"swarmscene: {DISABLE_ENV} names {name!r}, which no installed plugin is "
            f"(installed: {', '.join(sorted(n for n in seen if ':' in n)) or 'none'})",
            RuntimeWarning,
            stacklevel=2,
        )
    return provided
