"""Base classes of the three interchangeable algorithm kinds: formation, avoidance, dynamics.

A plugin class declares its registered ``name`` and a pydantic ``Params`` model (the single source
of truth for its YAML options, ``extra="forbid"``). The kernel builds one instance per run with the
validated params and a :class:`BuildContext`, then calls it directly every guidance tick:

    sp = formation.setpoints(world, sensing)      # where each agent should be or go
    sp = avoidance.adjust(world, sensing, sp)     # made safe
    dynamics.control(world, sp)                   # once per guidance tick (controller)
    dynamics.step(world, dt)                      # once per physics step (plant)

An instance may also implement any lifecycle hook of :mod:`swarmscene.core.hookspecs`
(``swarmscene_run_start``, ``swarmscene_event``, ``swarmscene_step_end``, ``swarmscene_run_end``):
the simulation registers the chosen instances with its plugin manager, so e.g. an avoidance method
learns of failures and contributes metrics through the same hooks as the monitors.
"""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Self

import numpy as np
from pydantic import BaseModel, ConfigDict, field_validator

from .errors import SwarmsceneDeprecationWarning
from .setpoint import Setpoints
from .state import WorldBatch, WorldState

if TYPE_CHECKING:  # pragma: no cover
    from .environment import Environment
    from .sensing import Sensing


def _admits_bool(annotation: Any) -> bool:
    """Whether a field's type accepts a boolean anywhere (``bool``, ``bool | None``, ``Any``...)."""
    if annotation is bool or annotation is Any:
        return True
    return any(_admits_bool(arg) for arg in getattr(annotation, "__args__", ()) or ())


def _holds_bool(value: Any) -> bool:
    if isinstance(value, bool):
        return True
    return isinstance(value, (list, tuple)) and any(_holds_bool(v) for v in value)


def reject_bool_as_number(model: type[BaseModel], value: Any, info: Any) -> Any:
    """A ``before`` field validator: ``true``/``false`` given where the field's type has no
    boolean is an error (pydantic's lax mode would read 1 or 0: ``swarm.n=true`` would run one
    agent). Lists are searched too (``center: [true, 0, 1]``)."""
    field = model.model_fields.get(info.field_name) if info.field_name else None
    if field is None or not _holds_bool(value) or _admits_bool(field.annotation):
        return value
    raise ValueError("must be a number, not true/false")


class PluginParams(BaseModel):
    """Base of every plugin's ``Params``: unknown keys are errors, values are validated on
    assignment, non-finite numbers are refused and so are booleans where a number is expected."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_numbers(cls, value: Any, info: Any) -> Any:
        return reject_bool_as_number(cls, value, info)


@dataclass(frozen=True)
class BuildContext:
    """What a plugin may know about the scenario when it is built.

    Attributes:
        n: number of agents.
        guidance_period: T_s, s; formation, avoidance and controllers run at this period.
        physics_step: s; the plant integrates at this step (divides ``guidance_period``).
        duration: simulated duration, s.
        separation_limit: safety distance between agents, m (``safety.separation_limit``).
        clearance_limit: safety distance to obstacles, m (``safety.clearance_limit``).
        comm_range: communication range, m.
        environment: the obstacle map and its geometric queries.
        rng: the run's one random generator (draws from it are part of the seeded run).
        initial: the world state at t = 0 (read it, do not keep mutating it).
        link_delay: the declared per-link delay models (disturbances offering ``link_delay``,
            ``comm_delay``'s, ``radio``'s): ``link_delay(hops) -> ticks`` (N, N) int, -1 where
            unreachable; ``None`` when none is declared. For plugins that keep per-link maps
            (:attr:`Formation.models_communication`).
        link_loss: the declared per-link packet loss (disturbances offering ``link_lost``,
            ``packet_loss``'s, ``radio``'s): ``link_loss(world, sensing) -> lost`` (N, N) bool, the
            messages (receiver, sender) lost this tick (call it once per tick); ``None`` when none
            is declared.
        floor: the ground's height, m (``environment.floor``): a take-off starts from it and a
            landing ends on it; ``None``: the scenario has no ground (vehicles may fly at any z).
    """

    n: int
    guidance_period: float
    physics_step: float
    duration: float
    separation_limit: float
    clearance_limit: float
    comm_range: float
    environment: Environment
    rng: np.random.Generator
    initial: WorldState
    link_delay: Callable[[np.ndarray], np.ndarray] | None = None
    link_loss: Callable[[WorldState, Any], np.ndarray] | None = None
    floor: float | None = None

    @property
    def min_separation(self) -> float:
        """Deprecated name of :attr:`separation_limit` (kept for one release)."""
        warnings.warn("BuildContext.min_separation is deprecated: use separation_limit",
                      SwarmsceneDeprecationWarning, stacklevel=2)
        return self.separation_limit

    @property
    def min_clearance(self) -> float:
        """Deprecated name of :attr:`clearance_limit` (kept for one release)."""
        warnings.warn("BuildContext.min_clearance is deprecated: use clearance_limit",
                      SwarmsceneDeprecationWarning, stacklevel=2)
        return self.clearance_limit


class Plugin(ABC):
    """Common part of every plugin class (abstract: a kind's required methods must be defined)."""

    name: ClassVar[str]
    """Registered name, the value users write in ``formation=``, ``avoidance=``, ``dynamics=``."""
    Params: ClassVar[type[PluginParams]] = PluginParams
    """Pydantic model of the YAML options (one docstring-described field per option); a subclass
    declares ``params: Params`` under its own so that ``self.params`` is typed as that model."""
    metric_prefix: ClassVar[str | None] = None
    """Prefix of the metrics the plugin adds (``<prefix>.<key>``); ``None``: its ``name``."""

    def __init__(self, params: PluginParams, ctx: BuildContext) -> None:
        self.params = params
        self.ctx = ctx


class Formation(Plugin):
    """Produces each agent's setpoint for this tick (where it should be or go, and how)."""

    requires_leader: ClassVar[bool] = False
    """True when the method needs ``swarm.leader``: a scenario without one is refused at validation."""
    models_communication: ClassVar[bool] = False
    """True when the method keeps per-link maps with its own delays (the thesis' swarm map): it then
    reads the agents' own estimates, not the disturbances' shared broadcast picture, and builds its
    delays from ``BuildContext.link_delay`` when one is declared."""

    @abstractmethod
    def setpoints(self, world: WorldState, sensing: Sensing) -> Setpoints:
        """Return the setpoints of all N agents for this guidance tick."""

    @classmethod
    def setpoints_batch(cls, formations: Sequence[Self], worlds: Sequence[WorldState],
                        sensings: Sequence[Sensing]) -> Sequence[Setpoints] | object:
        """``setpoints`` of B worlds at once: ``[formations[b].setpoints(worlds[b], sensings[b])
        for each b]``, the worlds of a batch (core/batch.py) that fly their formation, in one call.

        This default returns ``NotImplemented``: the engine then asks each world's own instance,
        so every formation works in a batch (and a world whose ``setpoints`` raises stops alone,
        as its single run). A formation overrides it to make all worlds' setpoints in one pass
        (docs/batched.md), returning a list of B records or one
        :class:`~swarmscene.core.setpoint.SetpointBatch`, which the engine hands on to the
        avoidance's and the controllers' batched forms as it is. The records, and what the
        instances hold afterwards (what ``complete`` answers), must equal each world's own
        ``setpoints`` bit for bit (the contract check ``formation.setpoints_batch_equals_worlds``).
        An override may return ``NotImplemented`` for a batch it cannot take whole. An exception
        it raises stops every world of the batch. A subclass that overrides ``setpoints`` and not
        this is asked world by world.
        """
        return NotImplemented

    def periodic_box(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The formation's space when it is periodic (a torus), else ``None`` (the default).

        Returns ``(lo, size)``, arrays (A,) in m for the first A world axes: the kernel folds
        positions into ``[lo, lo + size)`` in its ``wrap`` phase, at the start of the run and
        after every physics update, before any observer reads them.
        """
        return None

    def complete(self, world: WorldState) -> bool | None:
        """Whether the formation's mission is complete; ``None`` when it defines no mission.

        A run with ``termination.on_complete`` ends at the first tick this returns True, and a
        run's default ``success`` requires it not to be False.
        """
        return None


class Avoidance(Plugin):
    """Takes the formation's setpoints and returns safe ones."""

    @abstractmethod
    def adjust(self, world: WorldState, sensing: Sensing, sp: Setpoints) -> Setpoints:
        """Return setpoints that keep agents apart and clear of obstacles (may return ``sp``)."""

    @classmethod
    def adjust_batch(cls, avoidances: Sequence[Self], worlds: Sequence[WorldState], sensings: Sequence[Sensing],
                     setpoints: Sequence[Setpoints]) -> list[Setpoints] | object:
        """``adjust`` of B worlds at once: ``[avoidances[b].adjust(worlds[b], sensings[b],
        setpoints[b]) for each b]``, the worlds of a batch (core/batch.py) in one call.

        This default returns ``NotImplemented``: the engine then adjusts each world with its own
        instance, so every method works in a batch (and a world whose ``adjust`` raises stops
        alone, as its single run). A method overrides it to take all worlds' agents in one pass of
        its numerics (docs/batched.md); the setpoints it returns, and what the instances hold
        afterwards, must equal each world's own ``adjust`` bit for bit (the contract check
        ``avoidance.adjust_batch_equals_worlds``). An override may return ``NotImplemented`` for a
        batch it cannot take whole (instances whose options differ). An exception it raises stops
        every world of the batch. A subclass that overrides ``adjust`` and not this is adjusted
        world by world (the engine uses a batched form only with the ``adjust`` it was written for).
        An override that makes every world's setpoints in one pass may return them as one
        :class:`~swarmscene.core.setpoint.SetpointBatch` (a sequence of the B records): the engine
        then hands it to the dynamics model's ``control_batch`` as it is, which may read it whole.
        """
        return NotImplemented


class Dynamics(Plugin):
    """A controller plus a plant: turns setpoints into motion, respecting saturation."""

    has_attitude: ClassVar[bool] = False
    """True when the model fills ``WorldState.quat`` and ``WorldState.omega``."""
    rotors: ClassVar[int] = 0
    """Number of rotors the model simulates (``motor_failure`` events need a model with rotors; it
    applies them through the ``swarmscene_event`` hook)."""
    wind_coupling: ClassVar[Literal["force", "carried", "integrated"]] = "force"
    """How a declared wind acts on the model (``disturbances``, wind phase):

    * ``force``: the kernel adds a = :meth:`wind_acceleration` after each ``step`` (v += a dt,
      p += a dt^2 / 2: exact for a point mass whose input is held over the step);
    * ``carried``: a kinematic model flies relative to the air: the kernel adds p += w dt, v += w;
    * ``integrated``: ``step`` reads ``world.wind`` and integrates the force itself.
    """
    force_coupling: ClassVar[Literal["added", "integrated"]] = "added"
    """How the ``disturbances`` force phase's ``world.force`` a (m/s^2) acts on the model: ``added``,
    the kernel adds v += a dt, p += a dt^2 / 2 after each ``step`` (exact for a point mass whose
    input is held over the step); ``integrated``, ``step`` reads ``world.force`` itself."""
    drag_coefficient: ClassVar[float] = 0.21
    """D, 1/s: linear drag per unit mass, a = D (w - v) (rotor drag, linear in airspeed: Martin and
    Salaun 2010). The models carry no still-air drag (their controllers' tuning absorbs it), so the
    wind adds the change the moving air makes, D (w - v) - D (0 - v) = D w: zero wind is exactly the
    model without wind. Default 0.21 1/s: the Crazyflie 2.0's identified K_aero (Foerster 2015,
    9.1785e-7 kg/rad x 4 rotors x 1516 rad/s at hover / 0.027 kg)."""

    def wind_acceleration(self, world: WorldState) -> np.ndarray:
        """The wind's acceleration on each agent, (N, 3) m/s^2: ``drag_coefficient * world.wind``."""
        assert world.wind is not None, "wind_acceleration: the kernel calls it only under a wind model"
        return self.drag_coefficient * world.wind

    def initialize(self, world: WorldState) -> None:
        """Add the model's own state (attitude, integrators) to ``world`` at t = 0."""

    @abstractmethod
    def control(self, world: WorldState, sp: Setpoints) -> None:
        """Compute the control input from ``sp``; called once per guidance tick (zero-order hold)."""

    @abstractmethod
    def step(self, world: WorldState, dt: float) -> None:
        """Advance ``world.pos``/``world.vel`` (and attitude) in place by one physics step ``dt``.

        Failed agents may be moved here; the kernel restores them afterwards (they hover in place).
        """

    @classmethod
    def control_batch(cls, models: Sequence[Self], batch: WorldBatch, worlds: Sequence[WorldState],
                      setpoints: Sequence[Setpoints]) -> object:
        """``control`` of B worlds at once: ``models[b].control(worlds[b], setpoints[b])`` for each b.

        ``worlds[b]`` is what world b's controller reads (the agents' own estimates, which are
        ``batch.worlds[b]`` itself when no sensing disturbance is declared) and ``setpoints[b]``
        its guidance's setpoints for this tick; ``batch`` holds the worlds' true state.
        ``setpoints`` is a list of the worlds' records, or, where the avoidance's batched form
        made them in one pass, a :class:`~swarmscene.core.setpoint.SetpointBatch`: the same
        records, whose ``whole()`` gives them stacked (B N agents) to read without stacking them
        again (the contract check hands an override both).

        This default controls each world with its own instance, so every model works in a batch
        (the engine then runs it itself, world by world, so that a world whose ``control`` raises
        stops alone, as its single run). A model overrides it to latch all worlds' commands at
        once (docs/batched.md); what the instances hold afterwards must equal their per-world
        ``control`` bit for bit (the contract check ``dynamics.control_batch_equals_worlds``). An
        override returns ``None`` when it controlled every world; ``NotImplemented`` for a batch
        it cannot take (instances whose options or setpoint fields differ): the worlds are then
        controlled one by one; or the places (indices into ``models``) of the worlds it left, which
        the engine then controls one by one (a world whose ``control`` raises stops alone). An
        exception it raises stops every world of the batch. A subclass that overrides ``control``
        and not this is controlled world by world (the engine uses a batched form only with the
        ``control`` it was written for).
        """
        for model, world, sp in zip(models, worlds, setpoints, strict=True):
            model.control(world, sp)
        return None

    @classmethod
    def step_batch(cls, models: Sequence[Self], batch: WorldBatch, dt: float) -> object:
        """Advance the B worlds of ``batch`` by one physics step ``dt``; ``models[b]`` is world b's
        instance (built with that world's options and controlled by that world's ``control``).

        This default steps each world with its own instance, so every model works in a batch.
        A model overrides it to update the batch's (B, N, k) arrays at once (the world axis,
        docs/batched.md); the result must equal the per-world steps bit for bit (the contract
        check ``dynamics.batch_equals_worlds``). An override may return ``NotImplemented`` for a
        batch it cannot take whole (instances whose options differ): the worlds are then
        stepped one by one. A subclass that overrides ``step`` and not this is stepped world by
        world (the engine uses a batched form only with the ``step`` it was written for).
        """
        for model, world in zip(models, batch.worlds, strict=True):
            model.step(world, dt)
        return None


class Policy(ABC):
    """A named policy: maps every agent's observation row to a normalised action in [-1, 1].

    Chosen by ``avoidance.policy=<name>`` (the ``policy`` avoidance, :mod:`swarmscene.env`); built
    once per run as ``cls(params, layout, spec)`` with its validated ``Params`` (the avoidance's
    ``policy_options``), the observation layout (which columns hold what,
    :class:`~swarmscene.methods.policy.observation.ObservationLayout`) and the action spec
    (velocity or acceleration actions and their scales,
    :class:`~swarmscene.methods.policy.actions.ActionSpec`); then called once per guidance tick.
    """

    name: ClassVar[str]
    """Registered name, the value users write in ``avoidance.policy``."""
    Params: ClassVar[type[PluginParams]] = PluginParams
    """Pydantic model of its options (``avoidance.policy_options``); ``params: Params`` under a
    subclass's own types ``self.params`` as that model."""

    def __init__(self, params: PluginParams, layout: Any, spec: Any) -> None:
        self.params, self.layout, self.spec = params, layout, spec

    @abstractmethod
    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Actions (N, 3) in [-1, 1] from observations (N, D): row i is agent i's."""


PLUGIN_KINDS: dict[str, type[Plugin]] = {
    "formation": Formation,
    "avoidance": Avoidance,
    "dynamics": Dynamics,
}
"""The config group of each kind and the base class its plugins derive from."""


def choose(info: Any, kind: str, name: str) -> type | None:
    """In a ``Params`` model validator: the registered class of ``kind`` that an option names (the
    ``policy`` avoidance's ``policy``), from the registry validating the scenario, which passes
    itself as the validation context. None when the Params are validated without one (a unit test).

    Raises:
        ValueError: ``<option>: unknown <kind> 'x' (valid: ...)`` is the caller's to raise from a
            model validator, so the line names ``<plugin kind>.<option>``; here the message
            without the option: ``unknown policy 'x' (valid: ...)``.
    """
    registry = info.context.get("registry") if isinstance(info.context, dict) else None
    if registry is None:
        return None
    found = registry.classes[kind].get(name)
    if found is None:
        raise ValueError(f"unknown {kind} {name!r} (valid: {', '.join(registry.names(kind))})")
    return found


SHARED = "shared"
"""Key of a Params field's ``json_schema_extra`` naming the per-tick quantity the option describes
(e.g. ``Field(1.0, json_schema_extra={SHARED: "thesis.indoor_snapshot"})``). Chosen plugins whose
options describe the same quantity must agree: it is built once per tick for all of them
(:meth:`~swarmscene.core.sensing.Sensing.shared`)."""


def shared_option_conflicts(params: dict[str, PluginParams]) -> list[str]:
    """One line per option that two chosen plugins declare for one shared quantity with two values.

    Args:
        params: each chosen plugin's validated Params, by kind (``formation``, ``avoidance``, ...).
    """
    first: dict[tuple[Any, str], tuple[str, Any]] = {}  # (quantity, option) -> (kind, value)
    lines = []
    for kind, model in params.items():
        for field, info in type(model).model_fields.items():
            extra = info.json_schema_extra
            quantity = extra.get(SHARED) if isinstance(extra, dict) else None
            if quantity is None:
                continue
            value = getattr(model, field)
            seen = first.setdefault((quantity, field), (kind, value))
            if seen[1] != value:
                lines.append(
                    f"{kind}.{field}: must equal {seen[0]}.{field} = {seen[1]!r} (got {value!r}): both "
                    f"describe {quantity}, built once per tick for every plugin"
                )
    return lines
