"""A run from its configuration: the plugin manager, the validated scenario, the simulation.

``api.plugins``, ``api.load`` and ``api.build`` are these functions, composing first when given
overrides; the sweeps' jobs, the suite and the tools call them here, below the public API, with
composed data.
"""

from __future__ import annotations

from typing import Any

from ..builtins import BUILTIN_PLUGINS
from ..core.config import Scenario
from ..core.errors import ConfigError
from ..core.registry import Registry, make_plugin_manager
from ..core.simulation import Simulation
from ..core.validation import validate


def plugins() -> tuple[Any, Registry]:
    """A fresh plugin manager (built-ins, then entry points) and its registry."""
    return make_plugin_manager(BUILTIN_PLUGINS)


def load(data: dict[str, Any], registry: Registry | None = None) -> Scenario:
    """Validate composed data; raises ConfigError with one line per problem.

    A run directory's ``config.yaml`` (the effective configuration) loads back to the same scenario.
    """
    data = {k: v for k, v in data.items() if k != "hydra"}
    if registry is None:
        _, registry = plugins()
    return validate(data, registry)


def build(
    config: dict[str, Any] | Scenario,
    plugin_set: tuple[Any, Registry] | None = None,
) -> Simulation:
    """A ready-to-run :class:`Simulation` owning a plugin manager.

    Args:
        config: composed data, or a scenario validated by ``load``.
        plugin_set: the ``(plugin manager, registry)`` pair of :func:`plugins` that validated
            ``config`` (one manager per run); a fresh one when omitted.
    """
    pm, registry = plugin_set if plugin_set is not None else plugins()
    scenario = config if isinstance(config, Scenario) else load(config, registry)
    try:
        return Simulation(scenario, pm, registry.observers)
    except ConfigError:
        raise
    except Exception as exc:  # options valid one by one that no plugin can build (memory, overflow)
        raise ConfigError([build_error_line(scenario, exc)]) from exc


def build_error_line(scenario: Scenario, exc: BaseException) -> str:
    """One line for an exception raised while building a run: the plugin kind whose code raised
    it (the first plugin module in the traceback), its name, and the exception."""
    from ..core.raised import zero_options

    reason = f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}"
    modules = {cls.__module__: kind for kind, cls in scenario.plugin_classes.items()}
    tb = exc.__traceback__
    while tb is not None:
        kind = modules.get(tb.tb_frame.f_globals.get("__name__"))
        if kind is not None:
            name = scenario.plugin_classes[kind].name
            options = zero_options(exc, tb.tb_frame.f_locals.get("self"), kind) or zero_options(
                exc, _Holder(scenario.plugin_params.get(kind)), kind)
            return (f"{kind}: {name!r} cannot be built for this scenario (swarm.n = {scenario.config.swarm.n})"
                    f"{options}: {reason}")
        tb = tb.tb_next
    return f"scenario: cannot be built: {reason}"


class _Holder:
    """A plugin's ``params`` before the plugin exists (a constructor that raised)."""

    def __init__(self, params: Any) -> None:
        self.params = params


WARM_UP = 1.0
"""s of simulated time of a warm-up run (:func:`shortened`), after the last (moved) event."""


def shortened(data: dict[str, Any]) -> dict[str, Any]:
    """The scenario cut for a warm-up run (``swarmscene-compile``, a pool's fork server): its events
    at the first ticks and a duration just past the last one, no progress, summary or trajectory."""
    data = dict(data)
    events = [dict(e) for e in data.get("events") or []]
    step = float(data["clock"]["guidance_period"])
    for i, event in enumerate(events):
        if "at" in event:
            event["at"] = round((i + 2) * 5 * step, 9)
    last = max([e.get("at", 0.0) for e in events] + [0.0])
    data["events"] = events
    data["clock"] = {**data["clock"], "duration": min(float(data["clock"]["duration"]), last + WARM_UP)}
    data["output"] = {**data.get("output", {}), "progress": "off", "summary": False, "trajectory": False}
    return data
