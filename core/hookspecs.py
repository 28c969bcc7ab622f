"""Every hook of swarmscene, in one module (the pluggy project name is ``swarmscene``).

Two kinds of hook only:

* registration hooks, called once when a plugin manager is built, each receiving a typed
  ``register`` callback that takes a plugin class (keyed by the ``name`` it declares);
* lifecycle hooks, called by the simulation on every registered observer (monitors, metrics,
  recorders, and the chosen formation/avoidance/dynamics instances when they implement them).

The kernel calls the chosen formation, avoidance and dynamics objects directly; hooks are never on
the per-agent hot path. None of the hooks is ``firstresult``: every implementation runs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

# the markers live in .markers (so that an implementation need not import what the specs name)
from .markers import PROJECT as PROJECT
from .markers import hookimpl as hookimpl
from .markers import hookspec as hookspec

if TYPE_CHECKING:  # pragma: no cover
    from .disturbances.base import Disturbance
    from .events import Event, EventKindPlugin
    from .generators import MapGenerator
    from .plugin import Avoidance, Dynamics, Formation, Policy
    from .run_view import RunView


FormationRegister = Callable[[type["Formation"]], None]
AvoidanceRegister = Callable[[type["Avoidance"]], None]
DynamicsRegister = Callable[[type["Dynamics"]], None]
ObserverRegister = Callable[[type[Any]], None]
DisturbanceRegister = Callable[[type["Disturbance"]], None]
EventKindRegister = Callable[[type["EventKindPlugin"]], None]
GeneratorRegister = Callable[[type["MapGenerator"]], None]
PolicyRegister = Callable[[type["Policy"]], None]


@hookspec
def swarmscene_register_formations(register: FormationRegister) -> None:
    """Register formation classes: call ``register(cls)`` once per class.

    When: once, while the plugin manager is built (before any run).

    Args:
        register: takes a subclass of :class:`~swarmscene.core.plugin.Formation` declaring
            ``name`` and ``Params``; a name registered twice is an error naming both sources.
    """


@hookspec
def swarmscene_register_avoidances(register: AvoidanceRegister) -> None:
    """Register avoidance classes: call ``register(cls)`` once per class.

    When: once, while the plugin manager is built.

    Args:
        register: takes a subclass of :class:`~swarmscene.core.plugin.Avoidance`.
    """


@hookspec
def swarmscene_register_dynamics(register: DynamicsRegister) -> None:
    """Register dynamics classes: call ``register(cls)`` once per class.

    When: once, while the plugin manager is built.

    Args:
        register: takes a subclass of :class:`~swarmscene.core.plugin.Dynamics`.
    """


@hookspec
def swarmscene_register_observers(register: ObserverRegister) -> None:
    """Register observer classes (monitors, metrics, recorders) built once per run.

    When: once, while the plugin manager is built. Each class is instantiated as
    ``cls(sim)`` when a :class:`~swarmscene.core.simulation.Simulation` is built (``sim`` the run's
    read-only :class:`~swarmscene.core.run_view.RunView`) and the instance is registered with that
    simulation's plugin manager, so its lifecycle hooks fire for that run only (state never leaks
    between runs).

    Args:
        register: takes a class whose instances implement lifecycle hooks.
    """


@hookspec
def swarmscene_register_disturbances(register: DisturbanceRegister) -> None:
    """Register disturbance models: call ``register(cls)`` once per class.

    When: once, while the plugin manager is built. A scenario chooses one under
    ``disturbances.<key>`` (``name: <name>``, or the key itself).

    Args:
        register: takes a subclass of :class:`~swarmscene.core.disturbances.base.Disturbance`
            declaring ``name``, ``phase`` and a ``Params`` subclassing ``DisturbanceParams``.
    """


@hookspec
def swarmscene_register_events(register: EventKindRegister) -> None:
    """Register event kinds: call ``register(cls)`` once per class.

    When: once, while the plugin manager is built. A scenario names one as an event's ``name``.

    Args:
        register: takes a subclass of :class:`~swarmscene.core.events.EventKindPlugin` declaring
            ``name``, ``Params`` (subclassing ``EventParams``), ``failure`` and ``motion``.
    """


@hookspec
def swarmscene_register_generators(register: GeneratorRegister) -> None:
    """Register map generators: call ``register(cls)`` once per class.

    When: once, while the plugin manager is built. A scenario chooses one with
    ``environment.generator``.

    Args:
        register: takes a subclass of :class:`~swarmscene.core.generators.MapGenerator`
            declaring ``name``, ``Params`` and ``build``.
    """


@hookspec
def swarmscene_register_policies(register: PolicyRegister) -> None:
    """Register policies (observation rows to actions): call ``register(cls)`` once per class.

    When: once, while the plugin manager is built. A scenario chooses one with
    ``avoidance.policy`` (the ``policy`` avoidance) and :mod:`swarmscene.env` with ``policy=``.

    Args:
        register: takes a subclass of :class:`~swarmscene.core.plugin.Policy` declaring ``name``
            and ``Params``.
    """


@hookspec
def swarmscene_run_start(sim: RunView) -> None:
    """The run is about to take its first step.

    When: once per run, after every component is built and before the first tick; ``sim.world``
    holds the initial state.

    Args:
        sim: the run's read-only view (:class:`~swarmscene.core.run_view.RunView`: world,
            sensing, environment, config, t, step counters, has_attitude, request_stop).
    """


@hookspec
def swarmscene_event(sim: RunView, event: Event) -> None:
    """A scheduled event (failure, communication loss) has just been applied to the world.

    When: during the events phase of the guidance tick at which ``event.at`` is reached, after the
    kernel changed ``sim.world`` (e.g. ``healthy`` mask) and before sensing and formation run.
    A dynamics model may react here to what only it can apply (the quadrotor cuts the thrust of
    the rotor an event of a ``rotor_fault`` kind names, ``motor_failure``'s). React to what the
    kind declares (``event.behaviour``), not to its name: a package's kind then works too.

    Args:
        sim: the run's read-only view (:class:`~swarmscene.core.run_view.RunView`).
        event: the event applied (``at``, ``agents``, ``name`` its kind's, ``params`` its own fields,
            ``behaviour`` its :class:`~swarmscene.core.events.EventKindPlugin`).
    """


@hookspec
def swarmscene_step_end(sim: RunView) -> None:
    """A guidance tick has finished: dynamics have moved the agents and sensing is rebuilt.

    When: once per guidance tick, after the physics sub-steps; ``sim.world.t`` is the new time and
    ``sim.sensing`` reflects the new positions (the k-d tree is shared, do not rebuild it).

    Args:
        sim: the run's read-only view (:class:`~swarmscene.core.run_view.RunView`).
    """


@hookspec
def swarmscene_run_end(sim: RunView, metrics: dict[str, Any]) -> None:
    """The run is over: add entries to ``metrics``.

    When: once per run, after the last tick (or an early termination). Implementations add flat,
    dotted keys in SI units. A plugin's keys start with its class's ``metric_prefix`` and a dot
    (``cem.max_speed``, ``indoor.success``; the prefix defaults to the plugin's ``name``); the
    engine's own keys are unprefixed (``min_separation``) or under ``violations.``, ``events.``,
    ``disturbances.`` and ``phases.``; a plugin may also set the engine's ``success``. A key outside the writer's
    namespace raises at once (:mod:`swarmscene.core.metric_keys`). Values must be JSON-serialisable.

    Args:
        sim: the run's read-only view (:class:`~swarmscene.core.run_view.RunView`).
        metrics: the run's metrics, to be written to ``metrics.json``.
    """
