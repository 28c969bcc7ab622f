"""The namespaces of a run's metrics, enforced where a plugin writes them.

``swarmscene_run_end(sim, metrics)`` hands every observer and chosen plugin one dict. The rule
(core/hookspecs.py, docs/plugins.md "Reserved metric names"): the engine's keys are unprefixed
(``min_separation``, ``wall_time``) or under ``violations.``, ``events.``, ``disturbances.`` and
``phases.``; a chosen plugin writes ``<metric_prefix>.<key>`` (its ``name`` by default) and may set ``success``;
another observer writes dotted keys under a prefix of its own (its class's ``metric_prefix`` when
it declares one) and may set ``success``. A plain dict let a plugin replace an engine key
(``wall_time``) or lose its own under one the safety monitor writes later (``min_clearance``),
silently; :class:`RunMetrics` refuses such a write at once, naming the key and the rule, and the
run reports the plugin that tried it (:mod:`swarmscene.core.raised`).

The writer is told from the calling frame: a method of one of the run's plugin objects, or a hook
function of a plugin module. The engine's own observers (``swarmscene.core``, the application's
live view) write freely.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from types import FrameType
from typing import Any

ENGINE_KEYS = (
    "duration", "steps", "agents", "wall_time", "realtime_factor", "step_ms_median", "stop_reason",
    "healthy_at_end", "min_separation", "min_clearance", "collisions", "clearance_violations", "connected",
    "min_keep_out", "keep_out_conflicts", "success",
)
"""The engine's unprefixed keys (docs/outputs.md, metrics.json); any other unprefixed key is reserved too."""
ENGINE_PREFIXES = ("violations", "events", "disturbances", "phases")
"""Dotted namespaces that belong to the engine."""
SHARED_KEYS = ("success",)
"""Engine keys a plugin may set (its own definition of a successful run)."""
SEARCH_DEPTH = 8
"""Frames searched above a write for its writer (a plugin's helper function writing for it)."""


class MetricKeyError(KeyError):
    """A plugin wrote a metric outside its namespace."""

    def __str__(self) -> str:  # KeyError's str() is the repr of its argument
        return str(self.args[0])


class RunMetrics(dict[str, Any]):
    """The ``metrics`` dict of ``swarmscene_run_end`` that refuses a key outside its writer's namespace.

    Args:
        engine: the metrics the engine has when the hooks start (the duration, the timing, the
            events' draws).
        prefixes: id of each restricted writer (a chosen plugin, an observer that is not the
            engine's) or the module name of a hook module -> its prefix (None: any prefix that is
            not another plugin's or the engine's).
    """

    def __init__(self, engine: Mapping[str, Any], prefixes: dict[Any, str | None]) -> None:
        super().__init__(engine)
        self._prefixes = prefixes
        self._engine = set(engine) | set(ENGINE_KEYS)
        self._taken = {p for p in prefixes.values() if p is not None}

    def __setitem__(self, key: str, value: Any) -> None:
        self._check(key, sys._getframe(1))
        super().__setitem__(key, value)

    def update(self, *args: Any, **kwargs: Any) -> None:
        """``dict.update``, each key checked as :meth:`__setitem__` checks it."""
        items = dict(*args, **kwargs)
        frame = sys._getframe(1)
        for key in items:
            self._check(key, frame)
        super().update(items)

    def setdefault(self, key: str, default: Any = None) -> Any:
        """``dict.setdefault``, a new key checked as :meth:`__setitem__` checks it."""
        if key not in self:
            self._check(key, sys._getframe(1))
        return super().setdefault(key, default)

    def _writer(self, frame: FrameType | None) -> tuple[bool, str | None, str]:
        """(restricted, prefix, who) of the plugin writing from ``frame`` or a frame above it: a
        plugin object's method first (a chosen plugin's helper function writes for it), else a
        hook module's function."""
        module: str | None = None
        for _ in range(SEARCH_DEPTH):
            if frame is None or str(frame.f_globals.get("__name__")).startswith("pluggy"):
                break  # the hook caller: no plugin's frame below it wrote this
            owner = frame.f_locals.get("self")
            if owner is not None and id(owner) in self._prefixes:
                return True, self._prefixes[id(owner)], type(owner).__name__
            name = frame.f_globals.get("__name__")
            if module is None and owner is None and name in self._prefixes:
                module = name
            frame = frame.f_back
        if module is not None:
            return True, self._prefixes[module], module
        return False, None, "the engine"

    def _check(self, key: Any, frame: FrameType | None) -> None:
        restricted, prefix, who = self._writer(frame)
        if not restricted or key in SHARED_KEYS:
            return
        if not isinstance(key, str):
            raise MetricKeyError(f"metrics[{key!r}]: metric keys are strings ({who})")
        head = key.split(".", 1)[0] if "." in key else None
        if prefix is not None:
            if head != prefix:
                raise MetricKeyError(f"metrics[{key!r}]: {who} writes its metrics under {prefix!r} "
                                     f"({prefix}.<key>; docs/plugins.md, reserved metric names)")
            return
        if key in self._engine or head is None or head in ENGINE_PREFIXES or head in self._taken:
            owner = "the engine's" if head is None or key in self._engine or head in ENGINE_PREFIXES else \
                f"the namespace of plugin prefix {head!r}"
            raise MetricKeyError(f"metrics[{key!r}]: {owner}; {who} writes dotted keys under a prefix of "
                                 "its own (docs/plugins.md, reserved metric names)")


def is_engine_code(obj: Any) -> bool:
    """Whether ``obj`` (an observer, a hook module) is the engine's or the application's own, which
    write engine keys, rather than a plugin's (built-in plugins in ``swarmscene.plugins`` included)."""
    module = obj.__name__ if isinstance(obj, type(sys)) else type(obj).__module__
    return module.startswith("swarmscene.") and not module.startswith("swarmscene.plugins.")
