"""The ``disturbances`` config group: models the kernel applies in named phases (issue #18).

Every formation, avoidance and dynamics plugin, built-in or third-party, meets them without knowing
they exist; the safety monitors, the events' hold and the recorder keep reading the true state.

Where in the tick (``Simulation.step``)::

    events
    -> sense        each agent's estimate of its own position and velocity (truth + noise):
                    sensing_noise
    -> communicate  the swarm's picture of every agent: the last estimate of it the others received
                    (delay, loss): comm_delay, packet_loss
    -> formation, avoidance      read the picture (``world`` and a ``Sensing`` over it)
    -> dynamics.control          reads the agent's own estimate (its controller's feedback)
    -> per physics step: wind    the air's velocity at each agent (constant_wind, gust, dryden),
                    summed, acts as a force on the plant: dynamics.step integrates it
                    force   any other force per mass (downwash, ground_effect, drag, battery),
                    summed into ``world.force``, integrated with the step
    -> hold, raised events (a battery run down), floor, wrap, finite check, observers   on the truth

Models are registered plugins (hook ``swarmscene_register_disturbances``): the built-in ones are
plugins like a package's (``plugins/disturbance/``, their numerics in
:mod:`swarmscene.methods.disturbances` and :mod:`swarmscene.methods.physics`), and validation
reads the registry. The engine keeps the contract (:mod:`.base`), the phases (:class:`Disturbances`)
and the broadcast channel (:mod:`.channel`), and names no model: what it needs of one is a method
or an option the model declares (the channel's ``delays``/``lost``, ``channel_ticks``, a wind
model's ``moment_arm``).

Composition: ``swarmscene disturbances=[dryden,gps]`` (Hydra's list selection of one group);
options ``disturbances.dryden.speed=8``. With none declared the kernel takes none of these phases'
paths (:class:`Disturbances` is inactive) and draws nothing: results are bit-identical to a run
of the engine before disturbances existed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, cast

import numpy as np

from ..errors import ConfigError
from ..markers import hookimpl  # not ..hookspecs: it names this package's base (an import circle)
from ..state import WorldState
from .base import PHASES, Disturbance, DisturbanceContext, DisturbanceParams, model_rng
from .channel import ChannelModels, DelayModel, LossModel

__all__ = ["Disturbance", "DisturbanceParams", "Disturbances", "Perceived", "PHASES"]


# The phase methods (Disturbance's docstring): a model declares the one of its phase, which the
# base class cannot name, so the phases' lists are typed by these.
class _SenseModel(Protocol):
    def sense(self, world: WorldState, pos: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each agent's estimate of its own position and velocity, from the truth and the estimate so far."""


class _RelayModel(Protocol):
    def communicate(self, world: WorldState, pos: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The swarm's picture of every agent, from the agents' own estimates."""


class _WindModel(Protocol):
    def air(self, world: WorldState, t: float) -> np.ndarray:
        """The air's velocity at each agent at time ``t`` (N, 3), m/s."""


class _ForceModel(Protocol):
    def force(self, world: WorldState, t: float) -> np.ndarray:
        """A force per unit mass on each vehicle (N, 3), m/s^2, for the physics step starting at ``t``."""


def _has(model: Any, method: str) -> bool:
    """Whether ``model`` offers ``method`` (the channel's protocol, Disturbance's docstring)."""
    return callable(getattr(model, method, None))


def effective(models: dict[str, tuple[type[Disturbance], DisturbanceParams]]) -> dict[str, Any]:
    """The declared models with every option resolved, as plain data (the run record): each with its
    ``name`` (recorded as ``kind`` until 0.6.0, :func:`~swarmscene.core.spelling.recorded_name`)."""
    return {key: {"name": cls.name, **params.model_dump(mode="json")} for key, (cls, params) in models.items()}


class Perceived:
    """What the plugins read this tick.

    Attributes:
        world: the swarm's picture (formation and avoidance): every agent's row is what the others
            received of it; masks, roles and attitude are the truth's.
        sensing: a :class:`~swarmscene.core.sensing.Sensing` over ``world``.
        own: each agent's own estimate (the controller's feedback, ``dynamics.control``).
        formation_world, formation_sensing: what the formation reads: the picture, or the agents'
            own estimates when the formation models communication itself
            (``Formation.models_communication``, e.g. the thesis' swarm map).
    """

    __slots__ = ("world", "sensing", "own", "formation_world", "formation_sensing")

    def __init__(self, world: WorldState, sensing: Any, own: WorldState,
                 formation_world: WorldState | None = None, formation_sensing: Any = None) -> None:
        self.world, self.sensing, self.own = world, sensing, own
        self.formation_world = world if formation_world is None else formation_world
        self.formation_sensing = sensing if formation_sensing is None else formation_sensing


class Disturbances:
    """The declared models of one run, by phase, and the kernel's calls into them.

    Args:
        models: from :func:`swarmscene.core.validation.validate_disturbances`.
        seed: the run's seed (each model draws from its own stream, :func:`~.base.model_rng`).
        n, guidance_period, physics_step, comm_range: the scenario's.
        make_sensing: builds a Sensing over a world, given the previous one (the kernel's).
    """

    def __init__(self, models: dict[str, tuple[type[Disturbance], DisturbanceParams]], seed: int, n: int,
                 guidance_period: float, physics_step: float, comm_range: float,
                 make_sensing: Any, floor: float | None = None) -> None:
        self.models: dict[str, Disturbance] = {}
        for key, (cls, params) in models.items():
            ctx = DisturbanceContext(key, n, guidance_period, physics_step, comm_range, model_rng(seed, key),
                                     floor)
            try:
                self.models[key] = cls(params, ctx)
            except ValueError as exc:  # a model refusing the scenario: its key (and option) named
                raise ConfigError([_refusal(key, params, str(exc))]) from exc
        self.by_phase = {phase: [m for m in self.models.values() if m.phase == phase] for phase in PHASES}
        self.sensors = cast(list[_SenseModel], self.by_phase["sense"])  # the same lists, typed by phase
        self.winds = cast(list[_WindModel], self.by_phase["wind"])
        self.forces = cast(list[_ForceModel], self.by_phase["force"])
        self.active = bool(self.models)
        self.has_wind = bool(self.by_phase["wind"])
        self.has_force = bool(self.forces)
        self.blows = self.has_wind or self.has_force  # the wind phase (blow) has something to do
        # models that may raise events (a battery run down): those overriding Disturbance.raised
        self.raisers = [m for m in self.models.values() if type(m).raised is not Disturbance.raised]
        self.perceives = bool(self.by_phase["sense"] or self.by_phase["communicate"])
        self.dynamics: Any = None
        self.shared_picture = True
        self.make_sensing = make_sensing
        self._sensing = self._own_sensing = None
        # one vehicle property declared on each wind model: the one of largest magnitude holds
        # (a plugin's wind model without the option has none: 0 m)
        arms = [getattr(m.params, "moment_arm", 0.0) for m in self.by_phase["wind"]]
        self.moment_arm = max(arms, key=abs, default=0.0)
        comm = self.by_phase["communicate"]
        # The channel's models by what they offer (Disturbance's docstring), built-in or a plugin's.
        self.channel = ChannelModels(cast(list[DelayModel], [m for m in comm if _has(m, "delays")]),
                                     cast(list[LossModel], [m for m in comm if _has(m, "lost")]))
        # A communicate model that is no channel model acts after the channel.
        self.relays = cast(list[_RelayModel], [m for m in comm if not (_has(m, "delays") or _has(m, "lost"))])
        self._acc: np.ndarray | None = None
        self.wind_peak = 0.0
        self.wind_sum = 0.0
        self.wind_steps = 0
        self.sense_sq = 0.0
        self.sense_count = 0
        self.link_sent = self.link_lost = 0

    def attach(self, formation: Any, dynamics: Any) -> None:
        """The run's chosen plugins: the dynamics' ``wind_coupling`` and drag
        (:class:`~swarmscene.core.plugin.Dynamics`), and whether the formation models its links."""
        self.dynamics = dynamics
        self.shared_picture = not getattr(formation, "models_communication", False)

    def link_delay(self) -> Any:
        """``hops (N, N) -> ticks (N, N)``: the declared delay models per link, summed (-1 where
        unreachable); ``None`` when no model offers ``link_delay`` (``BuildContext.link_delay``)."""
        models: list[Any] = [m for m in self.by_phase["communicate"] if _has(m, "link_delay")]
        if not models:
            return None

        def delay(hops: np.ndarray) -> np.ndarray:
            ticks = [m.link_delay(hops) for m in models]
            total = np.sum(ticks, axis=0)
            return np.where(np.isfinite(hops), total, -1).astype(np.int64)

        return delay

    def link_loss(self) -> Any:
        """``(world, sensing) -> lost (N, N) bool``: the declared loss models per link and tick
        (a message lost by any is lost); ``None`` when no model offers ``link_lost``
        (``BuildContext.link_loss``)."""
        models: list[Any] = [m for m in self.by_phase["communicate"] if _has(m, "link_lost")]
        if not models:
            return None

        def lost(world: WorldState, sensing: Any) -> np.ndarray:
            out = models[0].link_lost(world)
            for model in models[1:]:
                out = out | model.link_lost(world)
            self.link_sent += out.size - world.n
            self.link_lost += int(out.sum() - np.trace(out))
            return out

        return lost

    # -- sense and communicate ------------------------------------------------------------
    def perceive(self, world: WorldState, sensing: Any) -> Perceived:
        """The sense and communicate phases: the views of this tick (the truth when inactive)."""
        if not self.perceives:
            return Perceived(world, sensing, world)
        pos, vel = world.pos, world.vel
        for sensor in self.sensors:
            pos, vel = sensor.sense(world, pos, vel)
        if self.sensors:
            err = pos - world.pos
            self.sense_sq += float(np.einsum("ij,ij->", err, err))
            self.sense_count += world.n
        own = _view(world, pos, vel)
        if len(self.relays) < len(self.by_phase["communicate"]):
            pos, vel = self.channel.communicate(world, sensing, pos, vel)
        for relay in self.relays:
            pos, vel = relay.communicate(world, pos, vel)
        picture = own if pos is own.pos else _view(world, pos, vel)
        self._sensing = self.make_sensing(picture, self._sensing)
        if self.shared_picture or picture is own:
            return Perceived(picture, self._sensing, own)
        self._own_sensing = self.make_sensing(own, self._own_sensing)
        return Perceived(picture, self._sensing, own, own, self._own_sensing)

    # -- wind -----------------------------------------------------------------------------
    def blow(self, world: WorldState, t: float, given: Sequence[np.ndarray] = ()) -> None:
        """The wind and force phases, before a physics step starting at ``t``: ``world.wind``, the
        air's velocity at each agent (N, 3) m/s, summed over the wind models; ``world.force``, the
        other forces per mass (N, 3) m/s^2, summed over the force models. ``given``: the airs of
        the first wind models, already asked by a batch of worlds (core/batch.py); the others are
        asked here."""
        if self.has_force:
            self._exert(world, t)
        if not self.has_wind:
            return
        airs = [*given, *(model.air(world, t) for model in self.winds[len(given):])]
        air = airs[0]
        for other in airs[1:]:
            air = air + other
        world.wind = np.array(air, dtype=float)
        world.wind_moment_arm = self.moment_arm
        speed = np.sqrt(np.einsum("ij,ij->i", world.wind, world.wind))
        # the reductions' ufuncs, not the methods' Python wrappers (the same sums: mean = sum / n)
        self.wind_peak = max(self.wind_peak, float(np.maximum.reduce(speed, initial=0.0)))
        self.wind_sum += float(np.add.reduce(speed) / speed.size) if speed.size else 0.0
        self.wind_steps += 1
        if self.dynamics.wind_coupling == "force":
            self._acc = self.dynamics.wind_acceleration(world)

    def _exert(self, world: WorldState, t: float) -> None:
        """The force phase: ``world.force`` for the step starting at ``t``."""
        acc = self.forces[0].force(world, t)
        for model in self.forces[1:]:
            acc = acc + model.force(world, t)
        world.force = np.array(acc, dtype=float)

    def raised(self, world: WorldState, t: float) -> list[Any]:
        """The events the models raise at the end of the tick ending at ``t`` (Disturbance.raised)."""
        out: list[Any] = []
        for model in self.raisers:
            out += model.raised(world, t)
        return out

    def push(self, world: WorldState, dt: float) -> None:
        """After a physics step: the forces' and the wind's effect where the model does not integrate them.

        The force phase's ``world.force`` a: v += a dt, p += a dt^2 / 2 unless the dynamics
        integrates it (``Dynamics.force_coupling``). The wind, by ``wind_coupling``:

        force:   v += a dt, p += a dt^2 / 2 with a = D w (held over the step; exact for a point mass
                 whose own input is held too, by superposition);
        carried: p += w dt, v += w (a kinematic model flies relative to the air);
        integrated: nothing (the model read ``world.wind`` in its step).
        """
        if self.has_force and getattr(self.dynamics, "force_coupling", "added") == "added":
            a = cast(np.ndarray, world.force)  # _exert() set it before this step
            world.pos += 0.5 * dt * dt * a
            world.vel += dt * a
        if not self.has_wind:
            return
        coupling = self.dynamics.wind_coupling
        if coupling == "force":
            a = cast(np.ndarray, self._acc)  # blow() set it before this step (force coupling)
            world.pos += 0.5 * dt * dt * a
            world.vel += dt * a
        elif coupling == "carried":
            wind = cast(np.ndarray, world.wind)  # blow() set it before this step
            world.pos += dt * wind
            world.vel += wind

    # -- records ----------------------------------------------------------------------------
    def metrics(self) -> dict[str, Any]:
        """``disturbances.*`` metrics: what was applied (flat keys, SI units)."""
        out: dict[str, Any] = {"disturbances.models": sorted(self.models)}
        if self.by_phase["wind"]:
            out["disturbances.wind.peak_speed"] = self.wind_peak
            out["disturbances.wind.mean_speed"] = self.wind_sum / self.wind_steps if self.wind_steps else 0.0
        if self.sense_count:
            out["disturbances.sense.pos_error_rms"] = float(np.sqrt(self.sense_sq / self.sense_count))
        out.update(self.channel.metrics())
        if self.link_sent:
            out["disturbances.comm.link_loss_rate"] = self.link_lost / self.link_sent
        for key, model in self.models.items():
            out.update({f"disturbances.{key}.{k}": v for k, v in model.metrics().items()})
        return out

    @hookimpl
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """Add each model's ``disturbances.<key>.*`` metrics to the run's."""
        metrics.update(self.metrics())


def _refusal(key: str, params: DisturbanceParams, message: str) -> str:
    """``disturbances.<key>.<option>: ...`` when the message starts with one of the model's options,
    else ``disturbances.<key>: ...`` (as the kernel names a plugin refusing the scenario)."""
    option = message.split(": ", 1)[0]
    sep = "." if option in type(params).model_fields else ": "
    return f"disturbances.{key}{sep}{message}"


def _view(world: WorldState, pos: np.ndarray, vel: np.ndarray) -> WorldState:
    """A world with estimated ``pos``/``vel`` and the truth's other fields (shared, not copied)."""
    return WorldState(t=world.t, pos=pos, vel=vel, healthy=world.healthy, comm_ok=world.comm_ok,
                      role=world.role, quat=world.quat, omega=world.omega,
                      rotor_speed=world.rotor_speed, acc=world.acc)


_MOVED = {"ConstantWind": "swarmscene.plugins.disturbance.constant_wind", "Gust": "swarmscene.plugins.disturbance.gust",
          "Dryden": "swarmscene.plugins.disturbance.dryden",
          "SensingNoise": "swarmscene.plugins.disturbance.sensing_noise",
          "CommDelay": "swarmscene.plugins.disturbance.comm_delay",
          "PacketLoss": "swarmscene.plugins.disturbance.packet_loss"}
"""The built-in models' classes, moved to their plugin modules in 0.6.0 (the engine imports no plugin)."""


def __getattr__(name: str) -> Any:
    """One line naming where a name that left this package went (0.6.0)."""
    if name in _MOVED:
        raise ImportError(f"swarmscene.core.disturbances.{name} moved to {_MOVED[name]} (a plugin; the engine "
                          "holds no built-in disturbance model)")
    if name == "BUILTIN_MODELS":
        raise ImportError("swarmscene.core.disturbances.BUILTIN_MODELS was removed in 0.6.0: the models are the "
                          "registry's (registry.classes['disturbance'], swarmscene.core.registry.installed_registry())")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
