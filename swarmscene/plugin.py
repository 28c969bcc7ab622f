"""Everything a plugin author imports, in one public module, for every kind: formation,
avoidance, dynamics (``Formation``...), observer (any class with lifecycle hooks), disturbance model
(``Disturbance``), event kind (``EventKindPlugin``), map generator (``MapGenerator``, its ``Params``
with ``MAX_LENGTH``, ``Point2``, ``Draw``) and policy (``Policy``); docs/plugins.md has a section and
a worked example for each.

    from swarmscene.plugin import Avoidance, PluginParams, Setpoints, hookimpl

    class Slowdown(Avoidance):
        name = "slowdown"

        class Params(PluginParams):
            factor: float = Field(0.5, gt=0, le=1, description="fraction of velocity kept")

        def adjust(self, world, sensing, sp):
            ...

    @hookimpl
    def swarmscene_register_avoidances(register):
        register(Slowdown)

The names here are the plugin interface: they keep their meaning across releases (a change is
announced in CHANGELOG.md and the old name kept for one release with a warning). The engine's
internal modules (``swarmscene.core.*``) may move. In a unit test, :func:`build_context` gives the
``BuildContext`` a plugin is constructed with, without composing a scenario:

    ctx = build_context(n=4)
    plugin = Slowdown(Slowdown.Params(), ctx)

and :mod:`swarmscene.testing` holds the contract checks every built-in passes.
"""

from __future__ import annotations

from enum import Enum
from typing import Any

import numpy as np

from .core.distributions import Draw, number_adapter, parse_draw
from .core.disturbances.base import PHASES, Disturbance, DisturbanceContext, DisturbanceParams
from .core.environment import Environment
from .core.errors import SwarmsceneDeprecationWarning, format_validation_error, validate_renamed
from .core.events import Event, EventKindPlugin, EventParams, Motion
from .core.fields import MAX_DURATION, MAX_LENGTH, Point2, Point3, StrictModel, key_error
from .core.generators import MapGenerator
from .core.hookspecs import hookimpl
from .core.plugin import (
    SHARED,
    Avoidance,
    BuildContext,
    Dynamics,
    Formation,
    Plugin,
    PluginParams,
    Policy,
    choose,
)
from .core.run_view import RunView
from .core.sensing import Sensing
from .core.setpoint import Mode, SetpointBatch, Setpoints
from .core.state import Role, WorldBatch, WorldState
from .core.vectors import clip_norm, every, min_distance_between, min_pair_distance, rows_of, wrap

__all__ = [
    "Avoidance", "BuildContext", "Disturbance", "DisturbanceContext", "DisturbanceParams", "Dynamics",
    "Environment", "Event", "EventKindPlugin", "EventParams", "Formation", "MapGenerator", "Mode",
    "Motion", "PHASES", "Plugin", "PluginParams", "Policy", "Role", "RunView", "SHARED", "Sensing", "SetpointBatch",
    "Setpoints",
    "StrictModel", "SwarmsceneDeprecationWarning", "WorldBatch", "WorldState", "build_context", "choose",
    "disturbance_context",
    "hookimpl", "validate_renamed",
    # what a Params declares (core/fields.py, core/distributions.py): lengths bounded by MAX_LENGTH,
    # times by MAX_DURATION, points, a cross-field error at the key it names, a number or a distribution
    "Draw", "MAX_DURATION", "MAX_LENGTH", "Point2", "Point3", "key_error", "number_adapter", "parse_draw",
    # helpers the built-ins use (core/vectors.py, core/errors.py), as stable as the names above
    "clip_norm", "every", "format_validation_error", "min_distance_between", "min_pair_distance", "rows_of", "wrap",
]


def build_context(
    n: int = 6,
    *,
    positions: np.ndarray | None = None,
    leader: int | None = 0,
    guidance_period: float = 0.1,
    physics_step: float = 0.01,
    seed: int = 0,
    environment: Environment | None = None,
    **fields: Any,
) -> BuildContext:
    """A :class:`BuildContext` for unit tests of a plugin, as the engine would build it.

    Args:
        n: number of agents (ignored when ``positions`` is given).
        positions: (N, 3) m, the agents at t = 0; default ``n`` agents on a 2-row grid 3 m apart at
            2 m altitude (:func:`swarmscene.testing.example_world`).
        leader: the leading agent, or None.
        guidance_period: T_s, s.
        physics_step: the plant's integration step, s.
        seed: seed of the run's random generator (``ctx.rng``).
        environment: the obstacle map; default an open one.
        **fields: any other ``BuildContext`` field (``duration``, ``separation_limit``,
            ``clearance_limit``, ``comm_range``, ``link_delay``, ``link_loss``).
    """
    if positions is None:
        k = np.arange(n)
        positions = np.column_stack([3.0 * (k // 2), 3.0 * (k % 2), np.full(n, 2.0)])
    positions = np.asarray(positions, dtype=float)
    values: dict[str, Any] = {
        "duration": 10.0, "separation_limit": 0.5, "clearance_limit": 0.2, "comm_range": 10.0,
        **fields,
    }
    return BuildContext(
        n=len(positions), guidance_period=guidance_period, physics_step=physics_step,
        environment=environment or Environment(), rng=np.random.default_rng(seed),
        initial=WorldState.at_rest(positions, leader=leader), **values,
    )


def disturbance_context(key: str = "model", n: int = 6, *, guidance_period: float = 0.1,
                        physics_step: float = 0.01, comm_range: float = 10.0,
                        seed: int = 0) -> DisturbanceContext:
    """A :class:`DisturbanceContext` for unit tests of a disturbance model, as the engine builds it
    (the model's own random stream: seed ``seed``, key ``key``)."""
    from .core.disturbances.base import model_rng

    return DisturbanceContext(key, n, guidance_period, physics_step, comm_range, model_rng(seed, key))


_EventKind = Enum("EventKind", {"HOVER": "hover", "COMM_LOSS": "comm_loss", "STUCK": "stuck",  # type: ignore[misc]
                                 "DRIFT": "drift", "MOTOR_FAILURE": "motor_failure"}, type=str)
"""``EventKind`` as it was, kept for one release (0.6.0 removed it: the engine lists no kind)."""


def __getattr__(name: str) -> Any:
    """``EventKind``, deprecated: the built-in kinds' names as an enum, for one more release.

    An event's kind is its registered name, a plain ``str`` (``event.name == "hover"``; ``event.kind``
    is its deprecated alias, read until 0.9.0); what a plugin needs to know of a kind is a property
    the kind declares (``event.behaviour.failure``, ``.motion``, ``.stays_where_failed``, ``.rotor_fault``)."""
    if name != "EventKind":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import warnings

    warnings.warn("swarmscene.plugin.EventKind is deprecated: an event's kind is its registered name, a str "
                  "(event.name == 'hover'); read what a kind does from event.behaviour (failure, motion, "
                  "stays_where_failed, rotor_fault)", SwarmsceneDeprecationWarning, stacklevel=2)
    return _EventKind
