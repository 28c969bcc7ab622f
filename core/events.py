"""Events: failures, faults and communication losses applied by the kernel, scheduled or random.

In config (``events`` list)::

    events:
      - {at: 5.0, agents: [0], name: hover}        # agent 0 stops where it is and stays (CEM paper)
      - {at: 9.0, agents: [3, 4], name: comm_loss}  # agents 3 and 4 drop out of the comm graph
      - {at: 4.0, agents: [1], name: stuck}         # agent 1 flies on at its last velocity
      - {at: 4.0, agents: [2], name: drift, velocity: [0.2, 0.0, 0.0]}  # drifts at 0.2 m/s east
      - {at: 3.0, agents: [5], name: motor_failure, rotor: 0, fraction: 0.0}  # rotor 0 dead
      - {at: {uniform: [2, 20]}, agents: {sample: 1}, name: hover}  # a random agent, a random time

Each ``name`` is a registered event kind (:class:`EventKindPlugin`, hook ``swarmscene_register_events``),
chosen from the registry a validation is given (``context={"registry": ...}``); the engine lists
none. The five above are built-in plugins (``plugins/event/``), registered like a package's own;
each kind's fields beside ``at``, ``agents`` and ``name`` are validated by its ``Params``. The
spelling ``kind`` of ``name`` is read until 0.9.0, with a deprecation warning (:mod:`.spelling`).

The kernel applies an event at the first guidance tick whose time reaches ``at`` (the events phase),
changes the world state, then calls the ``swarmscene_event`` hook so plugins can react; after the
physics sub-steps it calls :meth:`EventQueue.hold`, which moves the vehicles whose fault dictates
their motion by the rule its kind declares (``motion``: HOLD, COAST), whatever the dynamics model did.

Random events: ``at`` may be a distribution (:mod:`swarmscene.core.distributions`) and ``agents``
may be ``{sample: k}`` (k distinct agents, uniformly, optionally ``among`` a list). Each event
draws from its own stream derived from the run's ``seed`` and the event's index, never from the run's
generator: a scenario without random events draws exactly what it drew before, and the same seed
draws the same events. The drawn values are reported as metrics ``events.<k>.at`` and
``events.<k>.agents`` so a run can be written back as fixed events.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from enum import IntEnum
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
from .errors import SwarmsceneDeprecationWarning
from .fields import MAX_DURATION, StrictModel, key_error
from .spelling import KIND, renamed_kind
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


class EventConfig(StrictModel):
    """One event, scheduled or random (its kind's own keys beside these: "Event kinds" below).

    When, whom, which kind (:mod:`swarmscene.core.events`); the kind's own fields (a drift's
    ``velocity``) sit beside these and are validated by its ``Params``."""

    at: Draw | float = Field(
        description="time, s: a number, or a distribution drawn from the run's seed "
        "({uniform: [a, b]}, {normal: [mean, std]}, {exponential: mean}, {choice: [...]}...; "
        "a draw below 0 is 0)"
    )
    agents: AgentSample | list[int] = Field(
        description="indices of the agents hit, or {sample: k, among: [...]} (k drawn at random)"
    )
    name: str = Field(
        description="a registered event kind: hover, comm_loss, stuck, drift, motor_failure (the "
        "built-in plugins) or a package's; each kind's own keys are listed under \"Event kinds\" "
        "(kind, its spelling until 0.6.0, is read until 0.9.0 with a warning)"
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
        """The kind's own fields are taken out before the strict check of ``at``, ``agents``,
        ``name`` and validated by the kind's ``Params`` after it (:meth:`_checked`). The old
        spelling ``kind`` is read as ``name`` (:func:`~.spelling.renamed_kind`)."""
        if not isinstance(data, dict):
            return handler(data)
        try:
            data = renamed_kind(data, "events[]")
        except ValueError as exc:
            raise key_error(KIND, str(exc), data[KIND]) from None
        kinds = _kinds(data.get("name"), info.context)
        kind_cls = kinds.get(data["name"]) if isinstance(data.get("name"), str) else None
        own = {k: v for k, v in data.items() if k not in cls.model_fields}
        if kind_cls is not None:
            _check_keys(data, own, kind_cls, kinds)
        model = handler({k: v for k, v in data.items() if k not in own})
        # an unknown kind is the registry's error (validate_choice), reported once: its keys unread
        return model._checked(own, kind_cls) if kind_cls is not None else model

    @model_serializer(mode="wrap")
    def _with_own_fields(self, handler: Any) -> dict[str, Any]:
        """Recorded with the kind's own fields, every default filled (a record validates again to
        the same event whatever the kind's defaults become)."""
        data = handler(self)
        if self._params is not None:
            extra = self._params.model_dump(mode="json")
            data.update({k: v for k, v in extra.items() if k not in data})
        return data

    def _checked(self, own: dict[str, Any], kind_cls: type[EventKindPlugin]) -> EventConfig:
        """The kind's Params built from its own fields (a required one missing: one line)."""
        for key, info in kind_cls.Params.model_fields.items():
            if info.is_required() and key not in own:
                raise key_error(key, f"a {self.name} event needs {info.description}", None)
        try:
            self._params = kind_cls.Params.model_validate(own)
        except ValidationError as exc:  # its first problem, at its key (events.<k>.<key>)
            raise _at_key(exc, kind_cls.Params, own) from None
        self._kind = kind_cls
        return self

    @property
    def kind_class(self) -> type[EventKindPlugin]:
        """The event kind's class (a registered :class:`EventKindPlugin`)."""
        if self._kind is None:
            raise ValueError(f"event kind {self.name!r}: not validated against a registry "
                             "(validate with context={'registry': ...})")
        return self._kind

    @property
    def params(self) -> EventParams:
        """The kind's validated Params (its own fields, defaults filled)."""
        return self._params

    @property
    def kind(self) -> str:
        """Deprecated name of :attr:`name` (read until 0.9.0)."""
        warnings.warn("EventConfig.kind is deprecated: read EventConfig.name", SwarmsceneDeprecationWarning,
                      stacklevel=2)
        return self.name

    @property
    def random(self) -> bool:
        """Whether its time or its agents are drawn."""
        return isinstance(self.at, Draw) or isinstance(self.agents, AgentSample)


def _check_keys(data: dict[str, Any], own: dict[str, Any], kind_cls: type[EventKindPlugin],
                kinds: dict[str, type[EventKindPlugin]]) -> None:
    """A key that is neither an event's nor the kind's own: one line, naming the kinds that take it
    when some registered kind does (``velocity`` on a hover event), else the valid keys."""
    takes = kind_cls.Params.model_fields
    unknown = [k for k in own if k not in takes]
    if not unknown:
        return
    key = unknown[0]
    users = sorted(n for n, c in kinds.items() if key in c.Params.model_fields)
    if not users:
        valid = ", ".join(["at", "agents", "name", *takes])
        raise key_error(key, f"unknown key of a {data['name']} event (valid keys: {valid})", data[key])
    message = f"only a {' or '.join(users)} event takes it (this event is {data['name']})"
    raise key_error(key, message, _as_read(kinds[users[0]].Params.model_fields[key], data[key]))


def _as_read(info: Any, value: Any) -> Any:
    """``value`` as the field ``info`` reads it (``[1, 0, 0]`` -> ``(1.0, 0.0, 0.0)``), else as given."""
    try:
        return TypeAdapter(info.annotation).validate_python(value)
    except (ValidationError, TypeError):
        return value


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


class Motion(IntEnum):
    """How :meth:`EventQueue.hold` moves an agent after the dynamics (the last event decides)."""

    DYNAMICS = 0  # the dynamics model moves it (healthy, a lost radio, a failed rotor)
    HOLD = 1  # stays where it failed, at rest (a hover failure)
    COAST = 2  # constant velocity from where it failed (a stuck or drifting vehicle)


class EventParams(StrictModel):
    """Base of an event kind's own fields (``velocity`` of a drift, ``rotor`` of a motor failure).

    A field without a default is required; its ``description`` completes the error line
    ``events.<k>.<field>: a <kind> event needs <description>``. The validated fields are
    ``event.params`` (and read as the event's attributes: ``event.velocity``)."""


class EventKindPlugin:
    """An event kind: what an event does to its agents, and how the kernel moves them afterwards.

    Subclasses declare ``name`` (what a scenario's event writes as ``name``), ``Params`` (its own fields),
    ``failure`` and ``motion``, and may extend :meth:`apply`. The kernel applies an event in the
    events phase of a tick (:meth:`apply`, then the ``swarmscene_event`` hook, through which a
    dynamics model applies what only it can, e.g. a rotor's thrust), and after the physics
    sub-steps moves each agent by the motion of the last failure event that hit it. What other
    plugins need to know of a kind is a property it declares (``stays_where_failed``,
    ``rotor_fault``), never its name.
    """

    name: ClassVar[str]
    Params: ClassVar[type[EventParams]] = EventParams
    failure: ClassVar[bool] = True
    """True: the agents fail (``healthy`` False: formations and avoidance treat them as failed);
    False: they lose their radio (``comm_ok`` False) and keep flying on their last information."""
    motion: ClassVar[Motion] = Motion.DYNAMICS
    """After the dynamics, each tick: HOLD (stays where it failed, at rest), COAST (constant velocity
    from where it failed: the velocity :meth:`apply` left), DYNAMICS (the dynamics model moves it)."""
    stays_where_failed: ClassVar[bool] = False
    """True: a failed vehicle stays about the point where it failed (a hovering one; one that lost
    a rotor falls or spins down about it), so an avoidance may take it for a fixed obstacle (CEM's
    Assumption 3). False: it moves on (a fly-away), or the kind says nothing of where it goes."""
    rotor_fault: ClassVar[bool] = False
    """True: the kind's ``Params`` have ``rotor`` (int, the rotor's index) and ``fraction`` (0..1,
    the thrust it keeps): a dynamics model with rotors applies it through the ``swarmscene_event``
    hook, and validation refuses it with a dynamics model without rotors, or a rotor it lacks."""

    @classmethod
    def apply(cls, event: Event, world: WorldState, idx: np.ndarray) -> None:
        """Change ``world`` for the agents ``idx`` (their flags, and velocities where the kind sets
        them: a COAST kind coasts at the velocity left here)."""
        if cls.failure:
            world.healthy[idx] = False
        else:
            world.comm_ok[idx] = False

    @classmethod
    def event(cls, at: float, agents: tuple[int, ...] | list[int], **fields: Any) -> Event:
        """An :class:`Event` of this kind at ``at`` s hitting ``agents``, its own ``fields``
        validated by ``Params`` (as a scenario's would be): ``Drift.event(1.0, (2,), velocity=v)``."""
        return Event(float(at), tuple(int(a) for a in agents), cls.name,
                     params=cls.Params.model_validate(fields), kind_class=cls)


def _kinds(name: Any, context: Any) -> dict[str, type[EventKindPlugin]]:
    """The event kinds known to a validation: its registry's (``context={"registry": ...}``, as
    :mod:`.validation` passes it). The engine holds no list of built-ins: an event validated without
    a registry is refused in one line, naming the way."""
    registry = context.get("registry") if isinstance(context, dict) else None
    if registry is None:
        raise key_error("name", "an event kind is chosen from a plugin registry: validate with "
                        "context={'registry': ...} (swarmscene.api.load does)", name)
    return registry.classes["event"]


@dataclass(frozen=True)
class Event:
    """One event, as applied (random parts drawn).

    Attributes:
        at: time at which it happens, s (applied at the first guidance tick with t >= at).
        agents: indices of the agents it hits.
        name: the kind's registered name (``"hover"``); ``kind`` is its deprecated alias (read
            until 0.9.0).
        params: the kind's validated Params (its own fields: a drift's ``velocity``), read also as
            the event's attributes (``event.velocity``).
        kind_class: the kind's :class:`EventKindPlugin` (what the event does).
    """

    at: float
    agents: tuple[int, ...]
    name: str
    params: Any = field(default=None, hash=False)
    kind_class: Any = field(default=None, compare=False)

    @property
    def kind(self) -> str:
        """Deprecated name of :attr:`name` (read until 0.9.0)."""
        warnings.warn("Event.kind is deprecated: read Event.name (the kind's registered name; "
                      "Event.kind is read until 0.9.0)", SwarmsceneDeprecationWarning, stacklevel=2)
        return self.name

    def __getattr__(self, name: str) -> Any:
        """The kind's own fields as attributes (``event.velocity``, ``event.rotor``)."""
        params = self.__dict__.get("params")  # not getattr: unpickling asks before params is set
        if params is None or name.startswith("__") or name not in type(params).model_fields:
            raise AttributeError(f"{type(self).__name__} of kind {self.__dict__.get('name')!r} has no {name!r}")
        return getattr(params, name)

    @property
    def behaviour(self) -> type[EventKindPlugin]:
        """The class that says what this event does."""
        if self.kind_class is None:
            raise ValueError(f"event kind {self.name!r}: an Event needs its kind's class (kind_class=...; "
                             f"KindClass.event(at, agents, ...) builds one)")
        return self.kind_class

    @property
    def failure(self) -> bool:
        """Whether it fails its agents (``healthy`` drops) rather than their radio."""
        return self.behaviour.failure

    def apply(self, world: WorldState) -> None:
        """Change ``world`` as this event's kind says (its flags and, where it sets them, velocities)."""
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
    # Whatever was random is drawn by now: a time in seconds, a list of indices.
    at, agents = cast(float, at), cast(list[int], agents)
    return Event(float(at), tuple(int(a) for a in agents), config.name, params=config.params,
                 kind_class=config.kind_class)


class EventQueue:
    """Events sorted by time; the kernel applies them (:meth:`apply_due`) in the events phase of
    a tick and moves the vehicles their faults dictate (:meth:`hold`) after the dynamics.

    Args:
        events: the events, random parts already drawn.
        guidance_period: T_s, s: :meth:`hold` runs once per tick before the clock advances, so a
            coasting vehicle is placed where it is at the end of the tick, t + T_s (needed only
            when an event of a COAST kind is queued).
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
            raise ValueError("EventQueue: coasting events (stuck, drift) need the guidance period "
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
        self._coast_vel[idx] = world.vel[idx]  # its own, or the one its kind's apply set
        # hold() runs every tick and the motions change only here: its agents, listed once.
        self._held = rows_of(np.flatnonzero(self._motion == int(Motion.HOLD)))
        self._held_at = self._anchor[self._held]
        self._coasting = np.flatnonzero(self._motion == int(Motion.COAST))

    def hold(self, world: WorldState) -> None:
        """After the physics sub-steps of the tick starting at ``world.t``: hovering vehicles stay
        where they failed, at rest (HOLD); coasting ones are where their constant velocity has
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


_MOVED = {"Hover": "swarmscene.plugins.event.hover", "CommLoss": "swarmscene.plugins.event.comm_loss",
          "Stuck": "swarmscene.plugins.event.stuck", "Drift": "swarmscene.plugins.event.drift",
          "MotorFailure": "swarmscene.plugins.event.motor_failure"}
"""The built-in kinds' classes, moved to their plugin modules in 0.6.0 (the engine imports no plugin)."""


def __getattr__(name: str) -> Any:
    """One line naming where a name that left this module went (0.6.0)."""
    if name in _MOVED:
        raise ImportError(f"swarmscene.core.events.{name} moved to {_MOVED[name]} (a plugin; the engine holds "
                          f"no built-in event kind)")
    if name in ("BUILTIN_EVENT_KINDS", "EventKind"):
        raise ImportError(f"swarmscene.core.events.{name} was removed in 0.6.0: the event kinds are the "
                          "registry's (registry.classes['event'], swarmscene.core.registry.installed_registry()); "
                          "an event's kind is its registered name, a str (event.name)")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
