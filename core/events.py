"""Events: failures, faults and communication losses applied by the kernel, scheduled or random.

In config (``events`` list)::

    events:
      - {at: 5.0, agents: [0], kind: hover}        # agent 0 stops where it is and stays (CEM paper)
      - {at: 9.0, agents: [3, 4], kind: comm_loss}  # agents 3 and 4 drop out of the comm graph
      - {at: 4.0, agents: [1], kind: stuck}         # agent 1 flies on at its last velocity
      - {at: 4.0, agents: [2], kind: drift, velocity: [0.2, 0.0, 0.0]}  # drifts at 0.2 m/s east
      - {at: 3.0, agents: [5], kind: motor_failure, rotor: 0, fraction: 0.0}  # rotor 0 dead
      - {at: {uniform: [2, 20]}, agents: {sample: 1}, kind: hover}  # a random agent, a random time

Each ``kind`` is a registered event kind (:class:`EventKindPlugin`, hook ``swarmscene_register_events``):
the five above are built in (their classes here, registered by ``plugins/event/``), a package may
add its own, with its own fields validated by its ``Params``.

The kernel applies an event at the first guidance tick whose time reaches ``at`` (the events phase),
changes the world state, then calls the ``swarmscene_event`` hook so plugins can react; after the
physics sub-steps it calls :meth:`EventQueue.hold`, which moves the vehicles whose fault dictates
their motion (``hover``, ``stuck``, ``drift``) by that rule, whatever the dynamics model did.

Random events: ``at`` may be a distribution (:mod:`swarmscene.core.distributions`) and ``agents``
may be ``{sample: k}`` (k distinct agents, uniformly, optionally ``among`` a list). Each event
draws from its own stream derived from the run's ``seed`` and the event's index, never from the run's
generator: a scenario without random events draws exactly what it drew before, and the same seed
draws the same events. The drawn values are reported as metrics ``events.<k>.at`` and
``events.<k>.agents`` so a run can be written back as fixed events.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum, IntEnum
from typing import Annotated, Any, ClassVar, cast

import numpy as np
from pydantic import (
    Field,
    PrivateAttr,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from .distributions import EVENTS_STREAM, Draw, number_adapter, parse_draw, stream
from .fields import MAX_DURATION, Point3, StrictModel, key_error
from .state import WorldState
from .vectors import rows_of

_EVENT_TIME = number_adapter(0.0, MAX_DURATION)
_AGENT_LIST = TypeAdapter(Annotated[list[int], Field(min_length=1)])


class AgentSample(StrictModel):
    """``agents: {sample: k}``: k distinct agents drawn uniformly (without replacement)."""

    sample: int = Field(ge=1, description="how many agents the event hits")
    among: list[int] | None = Field(
        None, min_length=1, description="the agents to draw from (null: every agent 0..N-1)"
    )

    @model_serializer(mode="wrap")
    def _without_null_pool(self, handler: Any) -> dict[str, Any]:
        return {k: v for k, v in handler(self).items() if v is not None}


_KIND_FIELDS = ("velocity", "rotor", "fraction")


class EventConfig(StrictModel):
    """One event, scheduled or random (see :mod:`swarmscene.core.events`)."""

    at: Draw | float = Field(
        description="time, s: a number, or a distribution drawn from the run's seed "
        "({uniform: [a, b]}, {normal: [mean, std]}, {exponential: mean}, {choice: [...]}...; "
        "a draw below 0 is 0)"
    )
    agents: AgentSample | list[int] = Field(
        description="indices of the agents hit, or {sample: k, among: [...]} (k drawn at random)"
    )
    kind: str = Field(
        description="a registered event kind: hover: failure, holds position | comm_loss: radio "
        "lost | stuck: failure, keeps its last velocity | drift: failure, drifts at `velocity` | "
        "motor_failure: one rotor's thrust cut to `fraction` (quadrotor dynamics) | a plugin's kind"
    )
    velocity: Point3 | None = Field(None, description="drift only: drift velocity [vx, vy, vz], m/s")
    rotor: int | None = Field(None, ge=0, description="motor_failure only: index of the failed rotor")
    fraction: float | None = Field(
        None, ge=0, le=1, description="motor_failure only: thrust the rotor keeps, 0..1 (null: 0)"
    )

    @field_validator("at", mode="wrap")
    @classmethod
    def _number_or_distribution(cls, value: Any, handler: Any) -> Any:
        return parse_draw(value, _EVENT_TIME)

    @field_validator("agents", mode="wrap")
    @classmethod
    def _list_or_sample(cls, value: Any, handler: Any) -> Any:
        if isinstance(value, dict):
            return AgentSample.model_validate(value)
        if isinstance(value, list) and any(isinstance(a, bool) for a in value):
            raise ValueError("must be agent indices, not true/false")
        return _AGENT_LIST.validate_python(value)

    _kind: Any = PrivateAttr(None)
    _params: Any = PrivateAttr(None)

    @model_validator(mode="wrap")
    @classmethod
    def _kind_own_fields(cls, data: Any, handler: Any, info: ValidationInfo) -> Any:
        """A plugin kind's own fields (beyond velocity, rotor, fraction) are taken out before the
        strict check and validated by the kind's ``Params`` (after it, in :meth:`_checked`)."""
        own: dict[str, Any] = {}
        if isinstance(data, dict):
            kind_cls = _kind_class(data.get("kind"), info.context)
            if kind_cls is not None:
                takes = kind_cls.Params.model_fields
                unknown = [k for k in data if k not in cls.model_fields and k not in takes]
                if unknown:  # this kind's keys, not the built-in kinds' (velocity, rotor, fraction)
                    valid = ["at", "agents", "kind", *(k for k in takes if k not in ("at", "agents", "kind"))]
                    raise key_error(unknown[0], f"unknown key of a {data.get('kind')} event (valid keys: "
                                    f"{', '.join(valid)})", data[unknown[0]])
                own = {k: v for k, v in data.items() if k in takes and k not in cls.model_fields}
                data = {k: v for k, v in data.items() if k not in own}
        model = handler(data)
        return model._checked(own, info.context) if isinstance(model, EventConfig) else model

    @model_serializer(mode="wrap")
    def _without_unused_keys(self, handler: Any) -> dict[str, Any]:
        """Recorded as written: a hover event has no ``velocity: null``; a plugin kind's own
        fields are recorded with every default."""
        data = handler(self)
        data = {k: v for k, v in data.items() if v is not None or k not in _KIND_FIELDS}
        if self._params is not None:
            extra = self._params.model_dump(mode="json")
            data.update({k: v for k, v in extra.items() if k not in data and k not in _KIND_FIELDS})
        return data

    def _checked(self, own: dict[str, Any], context: Any) -> EventConfig:
        """The kind's rules: only its own fields given, the ones it needs present; its Params built.
        An unknown kind is the registry's error (``validate_choice``) when a registry validates,
        else one line here (listing the built-in kinds)."""
        kinds = _kinds(context)
        kind_cls = kinds.get(self.kind)
        if kind_cls is None:
            if isinstance(context, dict) and context.get("registry") is not None:
                return self  # reported once, by validate_choice
            raise key_error("kind", f"unknown event kind {self.kind!r} (valid: {', '.join(sorted(kinds))})",
                            self.kind)
        takes = kind_cls.Params.model_fields
        for key in _KIND_FIELDS:
            value = getattr(self, key)
            if value is not None and key not in takes:
                users = " or ".join(sorted(n for n, c in kinds.items() if key in c.Params.model_fields))
                raise key_error(key, f"only a {users} event takes it (this event is {self.kind})", value)
        given = {k: getattr(self, k) for k in _KIND_FIELDS if k in takes and getattr(self, k) is not None}
        for key, info in takes.items():
            if info.is_required() and key not in given and key not in own:
                raise key_error(key, f"a {self.kind} event needs {info.description}", None)
        values = {**given, **own}
        try:
            self._params = kind_cls.Params.model_validate(values)
        except ValidationError as exc:  # its first problem, at its key (events.<k>.<key>)
            raise _at_key(exc, kind_cls.Params, values) from None
        self._kind = kind_cls
        return self

    @property
    def kind_class(self) -> type[EventKindPlugin]:
        """The event kind's class (a registered :class:`EventKindPlugin`)."""
        return self._kind if self._kind is not None else BUILTIN_EVENT_KINDS[self.kind]

    @property
    def params(self) -> EventParams:
        """The kind's validated Params (its own fields, defaults filled)."""
        return self._params

    @property
    def random(self) -> bool:
        """Whether its time or its agents are drawn."""
        return isinstance(self.at, Draw) or isinstance(self.agents, AgentSample)


def _at_key(exc: ValidationError, model: type, values: dict[str, Any]) -> Exception:
    """The first problem of a kind's Params, in the schema's words, as an error at its key."""
    from .errors import format_validation_error

    err = exc.errors(include_url=False)[0]
    line = format_validation_error(exc, model, values)[0]
    key, _, message = line.partition(": ")
    got = f" (got {err['input']!r})"
    return key_error(key.split(".")[0], message.removesuffix(got), err["input"])


def check_events(events: list[EventConfig], n: int) -> list[str]:
    """One error line per event naming an agent outside 0..n-1 or sampling more agents than it may
    draw from (checks across config sections)."""
    errors = []
    for k, event in enumerate(events):
        key, listed = f"events.{k}.agents", event.agents
        if isinstance(listed, AgentSample):
            key, listed = f"{key}.among", listed.among or []
        bad = [a for a in listed if not 0 <= a < n]
        if bad:
            errors.append(f"{key}: agents are 0..{n - 1} (got {bad})")
        elif isinstance(event.agents, AgentSample):
            pool = len(set(event.agents.among)) if event.agents.among else n
            if event.agents.sample > pool:
                errors.append(f"events.{k}.agents.sample: at most {pool} distinct agents to draw "
                              f"from (got {event.agents.sample})")
    return errors


class EventKind(str, Enum):  # noqa: UP042  # not StrEnum: str() and f-strings of a member keep "EventKind.HOVER"
    """The built-in kinds' names (a plugin's kind is its registered name, a plain string; the
    behaviour of each is its :class:`EventKindPlugin` below).

    What happens to the event's agents. Every kind but ``comm_loss`` is a failure: the agent's
    ``healthy`` flag drops, so formations and avoidance treat it as failed from that tick on.

    HOVER: abrupt failure; the vehicle stops where it is (velocity zero) and stays there for the
        rest of the run. It remains a physical obstacle (the CEM paper's failure model).
    COMM_LOSS: the agent's radio fails (``comm_ok`` False): it leaves the communication graph but
        keeps flying on its last information.
    STUCK: the vehicle no longer responds to commands and keeps the velocity it had at the event:
        p(t) = p(t_f) + v(t_f) (t - t_f), a fly-away (the "stuck-at" / lock-in-place fault of the
        fault-tolerant-control taxonomy applied to the velocity command).
    DRIFT: the vehicle no longer responds and moves at the event's constant ``velocity`` v_d:
        p(t) = p(t_f) + v_d (t - t_f). Source: the drift fault of the sensor-fault taxonomy, an
        additive error growing linearly in time, y(t) = x(t) + r (t - t_f) (Balaban et al., IEEE
        Sensors Journal 9(12), 2009; Sharma et al., ACM TOSN 6(3), 2010): a position estimate
        drifting at rate r makes a vehicle that holds its estimate move physically at v_d = -r.
    MOTOR_FAILURE: one rotor (``rotor``) keeps ``fraction`` of its thrust. The engine only marks
        the vehicle failed; the dynamics model applies the loss through the ``swarmscene_event``
        hook and the vehicle then moves as its physics says (it is not held).
    """

    HOVER = "hover"
    COMM_LOSS = "comm_loss"
    STUCK = "stuck"
    DRIFT = "drift"
    MOTOR_FAILURE = "motor_failure"


class Motion(IntEnum):
    """How :meth:`EventQueue.hold` moves an agent after the dynamics (the last event decides)."""

    DYNAMICS = 0  # the dynamics model moves it (healthy, comm_loss, motor_failure)
    HOLD = 1  # hover: stays where it failed, at rest
    COAST = 2  # stuck, drift: constant velocity from where it failed


class EventParams(StrictModel):
    """Base of an event kind's own fields (``velocity`` of a drift, ``rotor`` of a motor failure).

    A field without a default is required; its ``description`` completes the error line
    ``events.<k>.<field>: a <kind> event needs <description>``. The fields ``velocity``,
    ``rotor`` and ``fraction`` are the event's own attributes (:class:`Event`); any other field
    is read from ``event.params``."""


class EventKindPlugin:
    """An event kind: what an event does to its agents, and how the kernel moves them afterwards.

    Subclasses declare ``name`` (what a scenario writes as ``kind``), ``Params`` (its own fields),
    ``failure`` and ``motion``, and may extend :meth:`apply`. The kernel applies an event in the
    events phase of a tick (:meth:`apply`, then the ``swarmscene_event`` hook, through which a
    dynamics model applies what only it can, e.g. a rotor's thrust), and after the physics
    sub-steps moves each agent by the motion of the last failure event that hit it.
    """

    name: ClassVar[str]
    Params: ClassVar[type[EventParams]] = EventParams
    failure: ClassVar[bool] = True
    """True: the agents fail (``healthy`` False: formations and avoidance treat them as failed);
    False: they lose their radio (``comm_ok`` False) and keep flying on their last information."""
    motion: ClassVar[Motion] = Motion.DYNAMICS
    """After the dynamics, each tick: HOLD (stays where it failed, at rest), COAST (constant velocity
    from where it failed: the velocity :meth:`apply` left), DYNAMICS (the dynamics model moves it)."""

    @classmethod
    def apply(cls, event: Event, world: WorldState, idx: np.ndarray) -> None:
        """Change ``world`` for the agents ``idx`` (their flags, and velocities where the kind sets
        them: a COAST kind coasts at the velocity left here)."""
        if cls.failure:
            world.healthy[idx] = False
        else:
            world.comm_ok[idx] = False


class Hover(EventKindPlugin):
    """Abrupt failure: stops where it is and stays (the CEM paper's failure model)."""

    name = "hover"
    motion = Motion.HOLD

    @classmethod
    def apply(cls, event: Event, world: WorldState, idx: np.ndarray) -> None:
        """Hover: the agent fails and stops where it is (velocity zero, held by the queue)."""
        super().apply(event, world, idx)
        world.vel[idx] = 0.0


class CommLoss(EventKindPlugin):
    """Radio lost: leaves the communication graph, keeps flying on its last information."""

    name = "comm_loss"
    failure = False


class Stuck(EventKindPlugin):
    """No longer responds: keeps the velocity it had at the event (a fly-away)."""

    name = "stuck"
    motion = Motion.COAST


class Drift(EventKindPlugin):
    """No longer responds: moves at the event's constant ``velocity`` (a drifting estimate)."""

    name = "drift"
    motion = Motion.COAST

    class Params(EventParams):
        velocity: Point3 = Field(description="its drift velocity [vx, vy, vz], m/s")

    @classmethod
    def apply(cls, event: Event, world: WorldState, idx: np.ndarray) -> None:
        """Drift: the agent fails and coasts at the event's ``velocity`` from now on."""
        super().apply(event, world, idx)
        world.vel[idx] = event.velocity


class MotorFailure(EventKindPlugin):
    """One rotor keeps ``fraction`` of its thrust; the dynamics model applies it (not held)."""

    name = "motor_failure"

    class Params(EventParams):
        rotor: int = Field(ge=0, description="the index of the failed rotor")
        fraction: float = Field(0.0, ge=0, le=1, description="thrust the rotor keeps, 0..1 (0: dead)")


BUILTIN_EVENT_KINDS: dict[str, type[EventKindPlugin]] = {
    cls.name: cls for cls in (Hover, CommLoss, Stuck, Drift, MotorFailure)
}
"""The built-in kinds (:class:`EventKind`). The kernel's motions are theirs, so their classes live
here; ``plugins/event/`` registers each through ``swarmscene_register_events`` like a third-party
kind, and validation reads the registry. Without a registry (an ``EventConfig`` validated on its
own) these are the kinds known."""


def _kinds(context: Any) -> dict[str, type[EventKindPlugin]]:
    """The event kinds known to a validation: its registry's, else the built-ins."""
    registry = context.get("registry") if isinstance(context, dict) else None
    return registry.classes["event"] if registry is not None else BUILTIN_EVENT_KINDS


def _kind_class(kind: Any, context: Any) -> type[EventKindPlugin] | None:
    return _kinds(context).get(kind) if isinstance(kind, str) else None


@dataclass(frozen=True)
class Event:
    """One event, as applied (random parts drawn).

    Attributes:
        at: time at which it happens, s (applied at the first guidance tick with t >= at).
        agents: indices of the agents it hits.
        kind: :class:`EventKind` for a built-in kind, else the registered name (a ``str`` either way).
        velocity: drift velocity (3,), m/s, world frame (``drift`` only).
        rotor: index of the failed rotor (``motor_failure`` only).
        fraction: thrust the failed rotor keeps, 0..1 (``motor_failure`` only).
        params: the kind's validated Params (a plugin kind's own fields), or None.
        kind_class: the kind's :class:`EventKindPlugin` (None: the built-in of that name).
    """

    at: float
    agents: tuple[int, ...]
    kind: EventKind | str
    velocity: tuple[float, float, float] | None = None
    rotor: int | None = None
    fraction: float | None = None
    params: Any = field(default=None, compare=False)
    kind_class: Any = field(default=None, compare=False)

    @property
    def behaviour(self) -> type[EventKindPlugin]:
        """The class that says what this event does."""
        if self.kind_class is not None:
            return self.kind_class
        return BUILTIN_EVENT_KINDS[getattr(self.kind, "value", self.kind)]

    @property
    def failure(self) -> bool:
        """Whether it fails its agents (every built-in kind but ``comm_loss``)."""
        return self.behaviour.failure

    def apply(self, world: WorldState) -> None:
        """Change ``world`` as this event says (its flags and, for hover and drift, velocities)."""
        self.behaviour.apply(self, world, np.asarray(self.agents, dtype=int))


def draw_event(config: EventConfig, index: int, n: int, seed: int) -> Event:
    """The :class:`Event` of ``config`` (the ``index``-th of the scenario), its random parts drawn
    from stream ``(seed, EVENTS_STREAM, index)``: first the time, then the agents."""
    at, agents = config.at, config.agents
    if config.random:
        rng = stream(seed, EVENTS_STREAM, index)
        if isinstance(at, Draw):
            at = max(0.0, float(at.sample(rng)))
        if isinstance(agents, AgentSample):
            pool = np.unique(agents.among) if agents.among else np.arange(n)
            agents = np.sort(rng.choice(pool, size=agents.sample, replace=False)).tolist()
    kind_class, params = config.kind_class, config.params
    fraction = config.fraction
    if fraction is None and "fraction" in kind_class.Params.model_fields:
        # the kind's own Params have the field (checked just above); EventParams does not
        fraction = params.fraction if params is not None else 0.0  # type: ignore[attr-defined]
    kind = EventKind(config.kind) if config.kind in EventKind._value2member_map_ else config.kind
    # Whatever was random is drawn by now: a time in seconds, a list of indices.
    at, agents = cast(float, at), cast(list[int], agents)
    return Event(float(at), tuple(int(a) for a in agents), kind, velocity=config.velocity,
                 rotor=config.rotor, fraction=fraction, params=params, kind_class=kind_class)


class EventQueue:
    """Events sorted by time; the kernel applies them (:meth:`apply_due`) in the events phase of
    a tick and moves the vehicles their faults dictate (:meth:`hold`) after the dynamics.

    Args:
        events: the events, random parts already drawn.
        guidance_period: T_s, s: :meth:`hold` runs once per tick before the clock advances, so a
            coasting vehicle is placed where it is at the end of the tick, t + T_s (needed only
            when a ``stuck`` or ``drift`` event is queued).
        drawn: ``(index in the config list, event)`` of the events whose parts were drawn.
    """

    def __init__(
        self, events: list[Event], guidance_period: float | None = None,
        drawn: list[tuple[int, Event]] | None = None,
    ) -> None:
        self._events = sorted(events, key=lambda e: e.at)
        self._next = 0
        self.guidance_period = guidance_period
        self.drawn = list(drawn or [])
        coasting = any(e.failure and e.behaviour.motion is Motion.COAST for e in events)
        if coasting and guidance_period is None:
            raise ValueError("EventQueue: stuck and drift events need the guidance period "
                             "(build the queue with EventQueue.from_scenario)")
        self._motion: np.ndarray | None = None  # (N,) Motion, allocated at the first failure
        # Sized with _motion at the first failure (empty until then: nothing reads them before).
        self._anchor = np.zeros((0, 3))  # (N, 3) m: where each vehicle failed
        self._anchor_t = np.zeros(0)  # (N,) s: when
        self._coast_vel = np.zeros((0, 3))  # (N, 3) m/s: its constant velocity

    @classmethod
    def from_config(cls, events: list[EventConfig], n: int | None = None, seed: int = 0,
                    guidance_period: float | None = None) -> EventQueue:
        """The queue of a scenario's ``events`` list; random parts drawn with ``seed`` for ``n``
        agents (both needed only when an event is random)."""
        if n is None and any(e.random for e in events):
            raise ValueError("EventQueue: random events need the number of agents and the seed "
                             "(build the queue with EventQueue.from_scenario)")
        built = [draw_event(e, k, n or 0, seed) for k, e in enumerate(events)]
        drawn = [(k, built[k]) for k, e in enumerate(events) if e.random]
        return cls(built, guidance_period, drawn)

    @classmethod
    def from_scenario(cls, config: Any) -> EventQueue:
        """The queue of a validated ``ScenarioConfig``: its events, random parts drawn for its
        ``swarm.n`` agents from its ``seed``, holding at its guidance period."""
        return cls.from_config(config.events, config.swarm.n, config.seed, config.clock.guidance_period)

    def metrics(self) -> dict[str, Any]:
        """The drawn events, ``events.<k>.at`` (s) and ``events.<k>.agents`` (k: index in the
        config list): writing them as fixed events reproduces the run. Empty without random events."""
        out: dict[str, Any] = {}
        for k, event in self.drawn:
            out[f"events.{k}.at"] = event.at
            out[f"events.{k}.agents"] = list(event.agents)
        return out

    def due(self, t: float, tol: float = 1e-9) -> list[Event]:
        """Events with ``at <= t`` (within ``tol``) not yet returned, in time order."""
        start = self._next
        while self._next < len(self._events) and self._events[self._next].at <= t + tol:
            self._next += 1
        return self._events[start : self._next]

    def apply_due(self, world: WorldState) -> list[Event]:
        """Apply the events due at ``world.t`` to ``world``; return them, in time order."""
        applied = self.due(world.t)
        for event in applied:
            event.apply(world)
            if event.failure:
                self._set_motion(world, event)
        return applied

    def apply_now(self, world: WorldState, event: Event) -> None:
        """Apply an event raised during the tick (a crash on the floor, a battery run down) to
        ``world`` as a due one is applied: its flags, and the motion :meth:`hold` gives its agents."""
        event.apply(world)
        if event.failure:
            self._set_motion(world, event)

    def _set_motion(self, world: WorldState, event: Event) -> None:
        """Record how :meth:`hold` moves the event's agents from now on (the last event decides)."""
        if self._motion is None:
            n = world.n
            self._motion = np.full(n, Motion.DYNAMICS, dtype=np.int8)
            self._anchor, self._anchor_t = np.zeros((n, 3)), np.zeros(n)
            self._coast_vel = np.zeros((n, 3))
        idx = np.asarray(event.agents, dtype=int)
        self._motion[idx] = event.behaviour.motion
        self._anchor[idx] = world.pos[idx]
        self._anchor_t[idx] = world.t
        self._coast_vel[idx] = world.vel[idx]  # stuck: the last velocity; drift and hover: set by apply
        # hold() runs every tick and the motions change only here: its agents, listed once.
        self._held = rows_of(np.flatnonzero(self._motion == int(Motion.HOLD)))
        self._held_at = self._anchor[self._held]
        self._coasting = np.flatnonzero(self._motion == int(Motion.COAST))

    def hold(self, world: WorldState) -> None:
        """After the physics sub-steps of the tick starting at ``world.t``: hovering vehicles stay
        where they failed, at rest; stuck and drifting ones are where their constant velocity has
        taken them at the tick's end, p_f + v (t + T_s - t_f). Others keep what the dynamics did."""
        if self._motion is None:
            return
        held = self._held
        if self._held_at.size:
            world.pos[held] = self._held_at
            world.vel[held] = 0.0
        coast = self._coasting
        if coast.size:
            T_s = cast(float, self.guidance_period)  # set whenever an event coasts (__init__ checks)
            elapsed = world.t + T_s - self._anchor_t[coast]
            world.pos[coast] = self._anchor[coast] + self._coast_vel[coast] * elapsed[:, None]
            world.vel[coast] = self._coast_vel[coast]
