"""What a hook sees of a run: a narrow, read-only view of the simulation (issue #27).

The lifecycle hooks (``swarmscene_run_start``, ``swarmscene_event``, ``swarmscene_step_end``,
``swarmscene_run_end``) and each observer's constructor receive a :class:`RunView` as their
``sim`` argument, not the :class:`~swarmscene.core.simulation.Simulation` itself: an observer
reads the run and may ask it to stop, and that is all. The kernel's parts (plugin objects, the
plugin manager, the event queue, the disturbances) are out of its reach, so an observer cannot
come to depend on them, and ``core/hookspecs.py`` needs no import of the kernel.

What it holds is what the built-in observers, the safety monitor and the recorder read (listed
by grep when it was introduced): ``world``, ``sensing``, ``environment``, ``config``, the step
counters, ``has_attitude`` and :meth:`RunView.request_stop`. Reading is free of copies: ``world``
is the live :class:`~swarmscene.core.state.WorldState`, read-only by contract (copying it every
tick would cost more than most observers; ``swarmscene.testing.check_observer`` refuses an
observer that moves an agent). Setting an attribute of the view raises, and so does reading any
other attribute of the simulation (``sim.formation``, ``sim.pm``): an AttributeError naming it and
what the view holds (0.4.0 and 0.5.0 read it through with a DeprecationWarning; 0.6.0 refuses it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NoReturn, Protocol

if TYPE_CHECKING:
    from .config import ScenarioConfig
    from .environment import Environment
    from .sensing import Sensing
    from .state import WorldState


class Run(Protocol):
    """What the view reads of a run (:class:`~swarmscene.core.simulation.Simulation` is one). A
    protocol, not the class: the kernel imports this module, so this module does not import the
    kernel (no import circle, tests/test_layout.py)."""

    world: WorldState
    environment: Environment
    config: ScenarioConfig
    sensing: Sensing
    step_count: int
    total_steps: int
    dynamics: Any

    def request_stop(self, reason: str) -> None:
        """End the run after the current tick."""


class RunView:
    """The run as a hook sees it (every attribute read through to the live simulation).

    Attributes:
        world: the true state (positions, velocities, health, time ``t``); read-only by contract.
        sensing: this tick's :class:`~swarmscene.core.sensing.Sensing` over the true state (the
            kernel makes a new one every tick, so read it through the view, not once).
        environment: the map (obstacle footprints and their queries).
        config: the validated scenario configuration (``config.safety``, ``config.output``, ...).
        t: the simulated time, s (``world.t``).
        step_count: guidance ticks done so far.
        total_steps: guidance ticks the run lasts at most (``clock.duration / clock.guidance_period``,
            plus a take-off's ticks and twice a landing's: core/phases.py).
        has_attitude: whether the dynamics model flies attitude (the recorder records ``quat``).
    """

    __slots__ = ("_sim", "world", "environment", "config")

    world: WorldState
    environment: Environment
    config: ScenarioConfig

    def __init__(self, sim: Run) -> None:
        # The simulation sets these three once, before the view exists: plain slots read faster
        # than properties, and observers read them every tick.
        for name, value in (("_sim", sim), ("world", sim.world), ("environment", sim.environment),
                            ("config", sim.config)):
            object.__setattr__(self, name, value)

    @property
    def sensing(self) -> Sensing:
        """This tick's sensing over the true state (new every tick)."""
        return self._sim.sensing

    @property
    def t(self) -> float:
        """The simulated time, s."""
        return self.world.t

    @property
    def step_count(self) -> int:
        """Guidance ticks done so far."""
        return self._sim.step_count

    @property
    def total_steps(self) -> int:
        """Guidance ticks the run lasts."""
        return self._sim.total_steps

    @property
    def has_attitude(self) -> bool:
        """Whether the dynamics model flies attitude (quaternions to record)."""
        return bool(self._sim.dynamics.has_attitude)

    def request_stop(self, reason: str) -> None:
        """End the run after the current tick (e.g. the safety monitor on a collision)."""
        self._sim.request_stop(reason)

    def __getattr__(self, name: str) -> NoReturn:
        """Another attribute of the simulation: refused, in one line naming what the view holds."""
        if name.startswith("__"):
            raise AttributeError(name)
        raise AttributeError(
            f"swarmscene: a hook read sim.{name}, which is not part of the run's view (world, sensing, "
            "environment, config, t, step_count, total_steps, has_attitude, request_stop); refused since "
            "0.6.0: read what you need from the view, or take it at construction (a formation or an "
            "avoidance method has its ctx)")

    def __setattr__(self, name: str, value: Any) -> NoReturn:
        raise AttributeError(f"a hook's view of the run is read-only (cannot set {name!r})")

    def __repr__(self) -> str:
        return f"RunView(t={self.t:g}, step {self.step_count} of {self.total_steps})"
