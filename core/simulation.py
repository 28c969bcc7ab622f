"""The kernel: clock, the one random generator, and the phases of a guidance tick.

Each guidance tick (period T_s = ``clock.guidance_period``)::

    events -> sense -> communicate -> formation -> avoidance -> dynamics.control
        -> physics sub-steps (wind, forces -> dynamics.step) -> hold failed -> raised events
        -> landed vehicles at rest -> floor -> wrap (periodic space) -> finite check -> observers

With a take-off or a landing (``swarm.takeoff``, ``swarm.land``, :mod:`swarmscene.core.phases`)
the clock starts at -T_to, and during those flights their vertical profile replaces formation and
avoidance.

sense and communicate (the ``disturbances`` group, :mod:`swarmscene.core.disturbances`) turn the
true state into what the plugins read: formation and avoidance get the swarm's picture (each agent's
estimate of itself as the others received it), the controller the agent's own estimate; the wind
acts on the plant each physics step, with the other forces (downwash, ground effect, drag, a
battery's limit). Without declared disturbances these phases pass the truth through and draw
nothing. Events a model raises (a battery run down) and the floor's (``environment.floor``,
:mod:`swarmscene.core.floor`: a landing or a crash) are applied after the hold, like scheduled
ones. Events, hold, the floor, the finite check and every observer read the truth.

The physics step divides T_s; the dynamics model's controller runs once per tick (zero-order hold)
and its plant ``T_s / physics_step`` times. Observers (monitors, metrics, recorders, and any chosen
plugin implementing lifecycle hooks) run through the plugin manager this simulation owns.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any, cast

import numpy as np
import pluggy

from . import interrupts, raised
from .config import Scenario
from .disturbances import Disturbances, Perceived
from .environment import Environment
from .errors import ConfigError
from .events import EventQueue
from .floor import Floor
from .metric_keys import RunMetrics, is_engine_code
from .monitors import SafetyMonitor
from .phases import Phases
from .plugin import Avoidance, BuildContext, Dynamics, Formation
from .raised import PluginRaised
from .recorder import TrajectoryRecorder
from .result import RunResult
from .run_view import RunView
from .sensing import Sensing
from .setpoint import Setpoints
from .state import WorldState
from .vectors import wrap

SHOWN_AGENTS = 10
"""How many agents an error names before it says how many more: a message stays one line."""


class Simulation:
    """One run of a validated scenario.

    Args:
        scenario: the validated scenario (:func:`swarmscene.core.validation.validate`).
        plugin_manager: the manager built by :func:`~swarmscene.core.registry.make_plugin_manager`
            with the same registry that validated ``scenario``; this simulation owns it and
            registers its observers and chosen plugins on it.
        observers: observer classes to instantiate for this run (``registry.observers``).
    """

    def __init__(
        self, scenario: Scenario, plugin_manager: pluggy.PluginManager, observers: list[type[Any]]
    ) -> None:
        cfg = scenario.config
        self.scenario = scenario
        self.config = cfg
        self.pm = plugin_manager
        self.hook = plugin_manager.hook
        self._step_end_impls: list[Any] | None = None
        self._step_end_calls: list[tuple[Any, bool]] | None = None
        # The start was drawn from default_rng(seed) during validation; the run continues that stream.
        self.rng = np.random.default_rng(cfg.seed)
        self.rng.bit_generator.state = scenario.rng_state
        self.guidance_period = cfg.clock.guidance_period
        self.physics_step = cfg.physics_step
        self.substeps = cfg.substeps
        self.total_steps = int(round(cfg.clock.duration / self.guidance_period))
        self.step_count = 0
        self.stop_reason: str | None = None
        self.error: str | None = None

        self.environment = Environment(scenario.obstacles, name=cfg.environment.name)
        floor = cfg.environment.floor
        self.floor = None if floor is None else Floor(floor, cfg.environment.touchdown_speed, self.guidance_period)
        self._refuse_start_below_floor(scenario.initial_positions)
        self.phases = self._phases(scenario.initial_positions)
        start = scenario.initial_positions if self.phases is None else self.phases.start()
        self.world = WorldState.at_rest(start, leader=cfg.swarm.leader)
        self.takeoff_ticks = 0 if self.phases is None else self.phases.takeoff_ticks
        if self.phases is not None:  # the mission's clock starts at 0, after the take-off
            self.world.t = -self.takeoff_ticks * self.guidance_period
            self.total_steps += self.phases.takeoff_ticks + 2 * self.phases.land_ticks  # the most it may fly
        self.events = EventQueue.from_scenario(cfg)  # random parts drawn from their own streams
        self.disturbances = Disturbances(
            scenario.disturbances, cfg.seed, cfg.swarm.n, self.guidance_period, self.physics_step,
            cfg.comm.range,
            lambda world, previous: Sensing(world, self.environment, cfg.comm.range, previous),
            floor,
        )
        ctx = BuildContext(
            n=cfg.swarm.n,
            guidance_period=self.guidance_period,
            physics_step=self.physics_step,
            duration=cfg.clock.duration,
            separation_limit=cfg.safety.separation_limit,
            clearance_limit=cfg.safety.clearance_limit,
            comm_range=cfg.comm.range,
            environment=self.environment,
            rng=self.rng,
            initial=WorldState.at_rest(scenario.initial_positions, leader=cfg.swarm.leader),
            link_delay=self.disturbances.link_delay(),
            link_loss=self.disturbances.link_loss(),
            floor=floor,
        )
        self.formation: Formation = self._build("formation", ctx)
        self.avoidance: Avoidance = self._build("avoidance", ctx)
        self.dynamics: Dynamics = self._build("dynamics", ctx)
        self.dynamics.initialize(self.world)
        self._periodic = self.formation.periodic_box()
        self._refuse_start_outside_periodic_box()
        self._wrap_periodic()
        self.sensing = Sensing(self.world, self.environment, cfg.comm.range)
        self.sensing.periodic = self._periodic  # connectivity by minimum image on a torus (kept each tick)
        self.disturbances.attach(self.formation, self.dynamics)
        if self.disturbances.active:
            self.pm.register(self.disturbances, name="disturbances")
        if self.floor is not None:
            self.pm.register(self.floor, name="floor")
        self.step_seconds = np.zeros(self.total_steps)
        self.view = RunView(self)  # what hooks and observers see of the run
        self.observers = [cls(self.view) for cls in observers]
        for obj in self.observers:
            self.pm.register(obj)

    def _build(self, kind: str, ctx: BuildContext) -> Any:
        try:
            obj = self.scenario.plugin_classes[kind](self.scenario.plugin_params[kind], ctx)
        except ValueError as exc:
            # A plugin refusing the scenario (e.g. "needs a leader") is a config problem too; a
            # message that starts with one of its options ("space: ...") names it as kind.option.
            message = str(exc)
            option = message.split(": ", 1)[0]
            sep = "." if option in type(self.scenario.plugin_params[kind]).model_fields else ": "
            raise ConfigError([f"{kind}{sep}{message}"]) from exc
        # A chosen plugin that implements lifecycle hooks takes part in them for this run.
        if any(callable(getattr(obj, name, None)) for name in _LIFECYCLE_HOOKS):
            self.pm.register(obj, name=f"{kind}:{obj.name}")
        return obj

    # -- the tick ---------------------------------------------------------------------------
    def step(self) -> None:
        """One guidance tick, phases in order."""
        self.guide()
        for j in range(self.substeps):
            self.blow(j)
            self.dynamics.step(self.world, self.physics_step)
            self.push()
        self.settle()

    # The tick's parts, apart so that a batch of worlds (core/batch.py) can latch the controllers
    # and step the physics of all its worlds in one call each between them.
    def guide(self) -> None:
        """Events, sense, communicate, formation, avoidance, the controller: up to the physics."""
        own, setpoints = self.guidance()
        self.dynamics.control(own, setpoints)

    def guidance(self) -> tuple[WorldState, Setpoints]:
        """Events, sense, communicate, formation, avoidance: what the controller reads this tick,
        the agents' own estimates and their setpoints (``guide`` without ``dynamics.control``)."""
        own, seen, setpoints = self.planned()
        if seen is not None:
            setpoints = self.avoidance.adjust(seen.world, seen.sensing, setpoints)
        return own, setpoints

    def planned(self) -> tuple[WorldState, Perceived | None, Setpoints]:
        """Events, sense, communicate, formation: the guidance up to the avoidance (a batch of
        worlds adjusts all of them in one call between the two, core/batch.py). Returns the agents'
        own estimates, what the avoidance perceives (None during a take-off or landing, whose
        setpoints the controller takes as they are) and the formation's setpoints."""
        own, seen, phase = self.perceived()
        if seen is None:
            return own, None, cast("Setpoints", phase)
        return own, seen, self.formation.setpoints(seen.formation_world, seen.formation_sensing)

    def perceived(self) -> tuple[WorldState, Perceived | None, Setpoints | None]:
        """Events, sense, communicate: :meth:`planned` up to the formation (a batch of worlds
        asks all their formations in one call after it, core/batch.py). Returns the agents' own
        estimates, what the formation and the avoidance perceive (None during a take-off or
        landing) and the take-off's or landing's setpoints (None otherwise)."""
        self._apply_due_events()
        seen = self.disturbances.perceive(self.world, self.sensing)  # sense, communicate
        if self.phases is not None and self.phases.flying(self.world.t):  # take-off, landing
            return seen.own, None, self.phases.setpoints(self.world.t)
        return seen.own, seen, None

    def blow(self, j: int, given: Sequence[np.ndarray] = ()) -> None:
        """The wind of physics sub-step ``j`` (before ``dynamics.step``); ``given``: the airs of
        the first wind models, asked by a batch of worlds at once (core/batch.py)."""
        self.disturbances.blow(self.world, self.wind_time(j), given)

    def wind_time(self, j: int) -> float:
        """The time at which physics sub-step ``j`` of this tick starts, s."""
        return self.world.t + j * self.physics_step

    def push(self) -> None:
        """The force phase of a physics sub-step (after ``dynamics.step``)."""
        self.disturbances.push(self.world, self.physics_step)

    def settle(self) -> None:
        """After the physics: hold failed agents, raised events, the floor, the wrap, the finite
        check, the clock, the new snapshot (:meth:`settle_world`), then the observers."""
        self.settle_world()
        self._step_end()

    def settle_world(self) -> None:
        """:meth:`settle` up to the observers (a batch of worlds answers their snapshots' first
        queries in one pass between the two, core/batch.py)."""
        self.events.hold(self.world)
        if self.disturbances.raisers:
            self._apply_raised(self.disturbances.raised(self.world, self.world.t + self.guidance_period))
        if self.phases is not None:
            self.phases.keep_down(self.world)  # landed vehicles stay down, motors stopped
        if self.floor is not None:
            self._apply_raised(self.floor.meet(self.world))
        if self.phases is not None:
            self.phases.touch(self.world)
        self._wrap_periodic()
        self._check_finite()
        self.step_count += 1
        # mission time, from whole ticks (no drift from summing dt); a take-off's ticks come before 0
        self.world.t = (self.step_count - self.takeoff_ticks) * self.guidance_period
        self.sensing = Sensing(self.world, self.environment, self.config.comm.range, self.sensing)

    def observe(self) -> None:
        """The tick's end for the observers: ``swarmscene_step_end`` (after :meth:`settle_world`)."""
        self._step_end()

    def _step_end(self) -> None:
        """``swarmscene_step_end`` to every observer, as pluggy calls them (last registered first)
        but without its dispatch (~2 us of a small swarm's tick): the implementations are read
        from pluggy each tick, so one registered meanwhile takes part; a wrapper among them, or an
        active hook monitor (``pm.trace``), leaves the call to pluggy."""
        caller = self.hook.swarmscene_step_end
        impls = caller.get_hookimpls()
        if impls != self._step_end_impls:
            self._step_end_impls = impls
            plain = not any(i.hookwrapper or i.wrapper for i in impls)
            self._step_end_calls = [(i.function, bool(i.argnames)) for i in reversed(impls)] if plain else None
        if self._step_end_calls is None or self.pm._inner_hookexec is not _PLAIN_HOOKEXEC:
            caller(sim=self.view)
            return
        for function, takes_sim in self._step_end_calls:
            if takes_sim:
                function(self.view)
            else:
                function()

    def _apply_due_events(self) -> None:
        for event in self.events.apply_due(self.world):
            self.sensing = Sensing(self.world, self.environment, self.config.comm.range, self.sensing)
            self.hook.swarmscene_event(sim=self.view, event=event)

    def _apply_raised(self, events: list[Any]) -> None:
        """Events raised by the tick's physics (a crash, a battery run down), applied like scheduled
        ones: the world changed, the motion recorded, the ``swarmscene_event`` hook called."""
        for event in events:
            self.events.apply_now(self.world, event)
            self.hook.swarmscene_event(sim=self.view, event=event)

    def _phases(self, targets: np.ndarray) -> Phases | None:
        """The take-off and landing flights, when the scenario has either (core/phases.py)."""
        swarm, floor = self.config.swarm, self.config.environment.floor
        if floor is None or (swarm.takeoff is None and swarm.land is None):
            return None
        return Phases(floor, swarm.takeoff, swarm.land, self.guidance_period, targets)

    def _refuse_start_below_floor(self, start: np.ndarray) -> None:
        if self.floor is not None and (below := self.floor.below_at_start(start)):
            raise ConfigError([f"swarm.start: agents {below} start below environment.floor = "
                               f"{self.floor.height:g} m"])

    def _check_finite(self) -> None:
        """Stop at the first non-finite position or velocity, naming the agent and the tick."""
        state = self.world.pos, self.world.vel
        # pos . vel is finite only when every entry of both is (a NaN or an infinity carries into
        # the sum; inf * 0 is NaN): one BLAS call at any N. An overflow (entries ~1e154) is settled
        # entry by entry below. (An infinity makes numpy warn here too, as where it arose.)
        if math.isfinite(state[0].ravel().dot(state[1].ravel())):
            return
        if all(np.isfinite(a).all() for a in state):
            return
        bad = ~(np.isfinite(state[0]).all(axis=1) & np.isfinite(state[1]).all(axis=1))
        agent = int(np.flatnonzero(bad)[0])
        raise NonFiniteState(
            f"non-finite state of agent {agent} at tick {self.step_count + 1} "
            f"(t = {(self.step_count + 1) * self.guidance_period:g} s; {int(bad.sum())} agents): "
            f"pos = {self.world.pos[agent].tolist()}, vel = {self.world.vel[agent].tolist()}"
        )

    def _refuse_start_outside_periodic_box(self) -> None:
        """The wrap phase folds positions into the formation's periodic box: at t = 0 it would
        silently move the agents that start outside it, so such a start is refused."""
        if self._periodic is None:
            return
        lo, size = self._periodic
        start = self.world.pos[:, : lo.size]
        outside = np.flatnonzero(np.any((start < lo) | (start >= lo + size), axis=1))
        if outside.size:
            named = outside[:SHOWN_AGENTS].tolist()
            more = f" and {outside.size - len(named)} more" if outside.size > len(named) else ""
            raise ConfigError([
                f"swarm.start: {outside.size} agents ({named}{more}) start outside the periodic box of "
                f"formation {self.formation.name!r}, {lo.tolist()} to {(lo + size).tolist()} m (its wrap "
                f"would move them at t = 0)"
            ])

    def _wrap_periodic(self) -> None:
        """Positions folded back into the formation's periodic box, if its space is one."""
        if self._periodic is not None:
            lo, size = self._periodic
            a = lo.size
            self.world.pos[:, :a] = wrap(self.world.pos[:, :a], lo, size)

    # -- the run ----------------------------------------------------------------------------
    def request_stop(self, reason: str) -> None:
        """End the run after the current tick (observers call this, e.g. on a collision)."""
        if self.stop_reason is None:
            self.stop_reason = reason

    def run(self, progress: Callable[[Simulation], None] | None = None) -> RunResult:
        """Run to the configured duration or an earlier termination; return the result.

        Args:
            progress: called after every tick (e.g. a progress line); must be cheap.
        A Ctrl-C or SIGTERM ends the run cleanly between two ticks: the result is marked
        incomplete (``stop_reason`` ``"interrupted"``) and holds everything recorded so far. The
        request is read from :mod:`~swarmscene.core.interrupts` (the command line's handler only
        records it, so nothing is raised inside compiled code); a ``KeyboardInterrupt`` raised
        in a tick (Python's own SIGINT handler) ends the run the same way. A position or velocity that
        becomes NaN or infinite stops the run before that tick is observed: ``stop_reason``
        ``"non_finite"``, ``error`` names the first such agent and the tick, ``success`` is False.
        An exception raised by a plugin (or an observer's hook) stops the run the same way
        (``stop_reason`` ``"plugin_error"``, ``error`` naming its kind, name, method and the
        simulated time) and is raised as :class:`~swarmscene.core.raised.PluginRaised`, which
        carries this result (what was recorded before the tick that failed) and has the plugin's
        exception as its cause.
        """
        wall_start = time.perf_counter()
        failure: Exception | None = None
        try:
            self.hook.swarmscene_run_start(sim=self.view)
            while self.going():
                if interrupts.requested() is not None:  # between ticks: nothing half-stepped
                    self.stop_reason = "interrupted"
                    break
                tick_start = time.perf_counter()
                self.step()
                self.ticked(time.perf_counter() - tick_start, progress)
        except BaseException as exc:
            failure = self.stopped_by(exc)
        result, failure = self.finish(time.perf_counter() - wall_start, failure)
        if failure is not None:
            raise PluginRaised(self.error or "", result) from failure
        return result

    def going(self) -> bool:
        """True while the run has ticks left and nothing asked it to stop."""
        return self.step_count < self.total_steps and self.stop_reason is None

    def ticked(self, seconds: float, progress: Callable[[Simulation], None] | None = None) -> None:
        """After a tick: its wall time recorded, the mission's completion, the progress callback."""
        self.step_seconds[self.step_count - 1] = seconds
        if self.phases is not None and self.phases.land is not None:
            self._land_when_done()
        elif self.world.t >= 0.0 and self.config.termination.on_complete and self.formation.complete(self.world):
            self.request_stop("complete")
        if progress is not None:
            progress(self)

    def _land_when_done(self) -> None:
        """Start the landing when the mission ends (its duration, or its completion under
        ``termination.on_complete``); end the run when the landing's time is up."""
        phases = self.phases
        assert phases is not None
        if phases.land_start is None:
            if self.world.t < 0.0:
                return
            done = self.formation.complete(self.world)
            finished = self.config.termination.on_complete and done
            if finished or self.world.t >= self.config.clock.duration - 0.5 * self.guidance_period:
                phases.begin_landing(self.world, done, completed=bool(finished))
        elif phases.over(self.world):
            self.request_stop("complete" if phases.completed else "duration")

    def stopped_by(self, exc: BaseException) -> Exception | None:
        """How an exception raised in a tick ends the run: a Ctrl-C is an interruption, a
        non-finite state a stop named by its agent (the tick is not recorded: observers keep
        finite data), anything else a plugin's error (returned, to be raised with the result)."""
        if isinstance(exc, KeyboardInterrupt):
            self.stop_reason = "interrupted"
        elif isinstance(exc, NonFiniteState):
            self.stop_reason = "non_finite"
            self.error = str(exc)
        elif isinstance(exc, Exception):  # a plugin raised: the run stops there, named, its records kept
            return self._plugin_raised(exc)
        else:
            raise exc
        return None

    def finish(self, wall: float, failure: Exception | None = None) -> tuple[RunResult, Exception | None]:
        """The run's end: its metrics, the ``swarmscene_run_end`` hook, its result; with the
        plugin exception that stopped it (or the run-end hook's), if any."""
        metrics = self._engine_metrics(wall)
        if self.phases is not None:
            metrics.update(self.phases.metrics(self.world))
        metrics.update(self.events.metrics())  # the drawn times and agents of random events
        guarded = RunMetrics(metrics, self._metric_prefixes())  # each plugin writes its own keys only
        try:
            self.hook.swarmscene_run_end(sim=self.view, metrics=guarded)
        except Exception as exc:
            failure = failure or self._plugin_raised(exc)
        metrics = dict(guarded)
        metrics["stop_reason"] = self.stop_reason or "duration"
        if self.error is not None:
            metrics["success"] = False
        else:
            metrics.setdefault("success", self.default_success(metrics))
        result = RunResult(
            metrics=metrics,
            stop_reason=self.stop_reason or "duration",
            complete=self.stop_reason != "interrupted",
            error=self.error,
            recorder=self._observer_of(TrajectoryRecorder),
            monitor=self._observer_of(SafetyMonitor),
            observers=self.observers,
        )
        return result, failure

    def _plugin_raised(self, exc: Exception) -> Exception:
        """Record a plugin's exception as the run's error: kind, name, method, simulated time."""
        modules = {plugin.__name__: name for name, plugin in self.pm.list_name_plugin()
                   if isinstance(plugin, ModuleType)}
        where = raised.origin(exc, self.observers, modules)
        self.stop_reason = "plugin_error"
        self.error = raised.describe(exc, where, self.world.t)
        return exc

    def _metric_prefixes(self) -> dict[Any, str | None]:
        """Who writes which metrics (:mod:`~swarmscene.core.metric_keys`): each chosen plugin its
        ``metric_prefix``, every other observer or hook module a prefix of its own."""
        prefixes: dict[Any, str | None] = {
            id(obj): obj.metric_prefix or obj.name for obj in (self.formation, self.avoidance, self.dynamics)}
        for obj in self.observers:
            if not is_engine_code(obj):
                prefixes.setdefault(id(obj), getattr(type(obj), "metric_prefix", None))
        for _, plugin in self.pm.list_name_plugin():
            if isinstance(plugin, ModuleType) and not is_engine_code(plugin):
                prefixes[plugin.__name__] = None
        return prefixes

    def _observer_of(self, cls: type) -> Any:
        """This run's observer of class ``cls`` (or a subclass), if one was registered."""
        return next((obs for obs in self.observers if isinstance(obs, cls)), None)

    def _engine_metrics(self, wall: float) -> dict[str, Any]:
        steps = self.step_count
        times = self.step_seconds[:steps]
        flown = steps * self.guidance_period  # world.t without a take-off (the clock sets it so)
        return {
            "duration": float(flown),
            "steps": steps,
            "agents": self.world.n,
            "wall_time": wall,
            "realtime_factor": float(flown / wall) if wall > 0 else None,
            "step_ms_median": float(np.median(times) * 1e3) if steps else None,
            "stop_reason": self.stop_reason or "duration",
            "healthy_at_end": int(self.world.healthy.sum()),
        }

    def default_success(self, metrics: dict[str, Any]) -> bool:
        """Safe throughout, and the mission complete where the formation defines one. Safe: no
        collision, no clearance violation, no crash on the floor and, when ``safety.keep_out`` is
        set, no pair inside the keep-out ellipsoid; after a landing, no healthy vehicle left in the air."""
        safe = (metrics.get("collisions", 0) == 0 and metrics.get("clearance_violations", 0) == 0
                and metrics.get("floor.crashes", 0) == 0 and not metrics.get("keep_out_conflicts")
                and not metrics.get("phases.airborne", 0))
        done = self.mission_complete()
        return bool(safe and done is not False and self.stop_reason != "interrupted")

    def mission_complete(self) -> bool | None:
        """The formation's verdict on its mission (None: it sets none): now, or after a landing, when
        the mission ended (the descent moved the vehicles off their goals)."""
        if self.phases is not None and self.phases.land_start is not None:
            return self.phases.mission_complete
        return self.formation.complete(self.world)


class NonFiniteState(ArithmeticError):
    """A position or velocity became NaN or infinite: the run cannot go on."""


_PLAIN_HOOKEXEC = pluggy.PluginManager("swarmscene")._inner_hookexec
"""pluggy's own call of a hook's implementations (a monitor, ``pm.trace``, replaces it)."""

_LIFECYCLE_HOOKS = (
    "swarmscene_run_start",
    "swarmscene_event",
    "swarmscene_step_end",
    "swarmscene_run_end",
)
