"""Contract checks of the kinds beside the three algorithms: disturbance models, event kinds, map
generators, policies and observers (re-exported by :mod:`swarmscene.testing`, where the rules of
every kind are listed).

Each check builds what the engine would (the kernel's own ``Disturbances``, ``EventConfig`` and
``EventQueue``, the observation of :mod:`swarmscene.env`, a short run) and raises ``AssertionError``
naming the rule that was broken.
"""

from __future__ import annotations

import copy
import json
import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import yaml
from pydantic import BaseModel, ValidationError

from .core import hookspecs
from .core.disturbances import Disturbances
from .core.disturbances.base import PHASES, Disturbance, DisturbanceParams
from .core.disturbances.comm import CommDelay, PacketLoss
from .core.environment import Environment
from .core.errors import format_validation_error
from .core.events import EventConfig, EventKindPlugin, EventParams, EventQueue, Motion, draw_event
from .core.fields import MAX_LENGTH
from .core.generators import MapGenerator
from .core.plugin import PluginParams, Policy
from .core.sensing import Sensing
from .core.state import WorldState

__all__ = ["check_disturbance", "check_event_kind", "check_generator", "check_observer", "check_policy"]

N_AGENTS = 6
GUIDANCE_PERIOD = 0.1  # s
PHYSICS_STEP = 0.01  # s
TICKS = 10
PHASE_METHOD = {"sense": "sense", "communicate": "communicate", "wind": "air"}
"""The method the kernel calls on a model of each phase (:class:`~swarmscene.core.disturbances.base.Disturbance`)."""
ENVIRONMENT_KEYS = ("name", "generator", "obstacles")
LIFECYCLE_HOOKS = ("swarmscene_run_start", "swarmscene_event", "swarmscene_step_end", "swarmscene_run_end")


def _world(n: int = N_AGENTS) -> WorldState:
    """``n`` agents on a 2-row grid 3 m apart at 2 m altitude, moving at 0.5 m/s east, agent 0 leading."""
    k = np.arange(n)
    world = WorldState.at_rest(np.column_stack([3.0 * (k // 2), 3.0 * (k % 2), np.full(n, 2.0)]), leader=0)
    world.vel[:, 0] = 0.5
    return world


def _check_declaration(cls: type, base: type, params_base: type[BaseModel], label: str,
                       options: dict[str, Any] | None, refused: dict[str, dict[str, Any]] | None,
                       prefix: str) -> Any:
    """``name``, ``Params`` as the engine needs them (refusing unknown keys, each option described,
    a YAML round trip), refused options named ``<prefix>.<key>``; returns the validated options."""
    assert isinstance(cls, type) and issubclass(cls, base), f"{getattr(cls, '__name__', cls)} is not a {base.__name__}"
    name = getattr(cls, "name", None)
    assert isinstance(name, str) and name, f"{cls.__name__}: set a `name` (the {label} a scenario writes)"
    params_cls = getattr(cls, "Params", None)
    assert isinstance(params_cls, type) and issubclass(params_cls, params_base), (
        f"{name}: Params must derive from {params_base.__name__}")
    assert params_cls.model_config.get("extra") == "forbid", f"{name}: Params must refuse unknown keys"
    for field, info in params_cls.model_fields.items():
        assert info.description, f"{name}: option {field!r} has no description"
    params = params_cls.model_validate(options or {})
    text = yaml.safe_dump(params.model_dump(mode="json"))
    again = params_cls.model_validate(yaml.safe_load(text))
    assert again.model_dump(mode="json") == params.model_dump(mode="json"), (
        f"{name}: Params do not round-trip through YAML ({text!r})")
    for key, bad in (refused or {}).items():
        try:
            params_cls.model_validate(bad)
        except ValidationError as exc:
            lines = format_validation_error(exc, params_cls, bad, prefix=prefix)
        else:
            raise AssertionError(f"{name}: Params accepted {bad!r}, which must be refused naming {key!r}")
        assert any(line.startswith(f"{prefix}.{key}: ") for line in lines), (
            f"{name}: refusing {bad!r} must name {prefix}.{key} (got {lines}); a cross-field check "
            f"raises ValueError(\"{key}: ...\")")
    return params


def _class_state(cls: type, stop: type) -> dict[str, Any]:
    """Copies of the plain data attributes of ``cls`` and its bases below ``stop`` (the kind's base;
    the engine's own classes end the walk too): one walk for every kind's check."""
    state = {}
    for klass in cls.__mro__:
        if klass is stop or klass is object or klass.__module__.startswith("swarmscene.core."):
            break
        for attr, value in vars(klass).items():
            if attr.startswith("__") or callable(value) or isinstance(value, (classmethod, staticmethod, property)):
                continue
            try:
                state[f"{klass.__qualname__}.{attr}"] = copy.deepcopy(value)
            except Exception:  # an attribute that cannot be copied is not data the check can compare
                continue
    return state


def _assert_class_untouched(name: str, cls: type, stop: type, before: dict[str, Any]) -> None:
    """Instances keep their state to themselves: running them changed no class attribute."""
    after = _class_state(cls, stop)
    for attr, value in before.items():
        new: Any = after.get(attr)  # None where the attribute is gone: then not equal
        same = (np.array_equal(value, new) if isinstance(value, np.ndarray) or isinstance(new, np.ndarray)
                else _equal(value, new))
        assert same, (f"{name}: running an instance changed the class attribute {attr}: two instances "
                      "share state (keep it on the instance, not the class or module)")


def _equal(a: Any, b: Any) -> bool:
    try:
        return bool(a == b)
    except Exception:  # containers of arrays compare element-wise: compare their reprs instead
        return repr(a) == repr(b)


def _assert_json_metrics(name: str, metrics: Any, where: str) -> None:
    assert isinstance(metrics, dict), f"{name}: {where} must return a dict (got {type(metrics).__name__})"
    for key, value in metrics.items():
        assert isinstance(key, str) and key, f"{name}: metric key {key!r} is not a string"
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError):
            raise AssertionError(f"{name}: metric {key!r} = {value!r} is not finite JSON") from None


# -- disturbance models --------------------------------------------------------------------------
class _IntegratedDynamics:
    """A stand-in dynamics for the wind phase: it integrates the wind itself (the kernel adds nothing)."""

    wind_coupling = "integrated"


def _disturbances(cls: type[Disturbance], params: DisturbanceParams, key: str, seed: int) -> Disturbances:
    """The kernel's own phase runner around one model, as a run seeded ``seed`` builds it."""
    env = Environment()
    runner = Disturbances({key: (cls, params)}, seed, N_AGENTS, GUIDANCE_PERIOD, PHYSICS_STEP, 10.0,
                          lambda world, previous: Sensing(world, env, 10.0, previous))
    runner.attach(SimpleNamespace(models_communication=False), _IntegratedDynamics())
    return runner


def _disturbed_ticks(runners: list[Disturbances], ticks: int = TICKS) -> list[list[np.ndarray]]:
    """Each runner's outputs over ``ticks`` guidance ticks (picture and own estimate, wind), the
    runners taking their turns tick by tick on worlds of their own."""
    worlds = [_world() for _ in runners]
    out: list[list[np.ndarray]] = [[] for _ in runners]
    env = Environment()
    for _ in range(ticks):
        for world, runner, record in zip(worlds, runners, out, strict=True):
            truth = {k: np.array(getattr(world, k), copy=True) for k in ("pos", "vel", "healthy", "comm_ok")}
            try:
                seen = runner.perceive(world, Sensing(world, env, 10.0))
            except (ValueError, TypeError, IndexError) as exc:  # e.g. outputs of the wrong shape
                raise AssertionError(
                    f"{runner_name(runner)}: the kernel's sense/communicate phase failed on its outputs "
                    f"(each must be (N, 3) m or m/s): {type(exc).__name__}: {exc}") from None
            for k, v in truth.items():
                assert np.array_equal(getattr(world, k), v), (
                    f"{runner_name(runner)}: modified world.{k} "
                    "(a model returns new arrays; the truth is the kernel's)")
            for label, arr in (("picture pos", seen.world.pos), ("picture vel", seen.world.vel),
                               ("own pos", seen.own.pos), ("own vel", seen.own.vel)):
                assert np.shape(arr) == (N_AGENTS, 3), (
                    f"{runner_name(runner)}: {label} has shape {np.shape(arr)}, expected (N, 3)")
                assert np.isfinite(arr).all(), f"{runner_name(runner)}: {label} is not finite"
            record += [np.array(seen.world.pos), np.array(seen.own.vel)]
            for j in range(int(round(GUIDANCE_PERIOD / PHYSICS_STEP))):
                runner.blow(world, world.t + j * PHYSICS_STEP)
                if runner.has_wind:
                    wind = np.asarray(world.wind)
                    assert wind.shape == (N_AGENTS, 3) and np.isfinite(wind).all(), (
                        f"{runner_name(runner)}: air() must return finite (N, 3) m/s (got shape {wind.shape})")
                    record.append(np.array(wind))
                world.pos += PHYSICS_STEP * world.vel
            world.t += GUIDANCE_PERIOD
    return out


def runner_name(runner: Disturbances) -> str:
    return ", ".join(type(m).name for m in runner.models.values())


def check_disturbance(cls: type[Disturbance], options: dict[str, Any] | None = None,
                      refused: dict[str, dict[str, Any]] | None = None) -> None:
    """Run a disturbance model through the kernel's phases (:class:`~swarmscene.core.disturbances.Disturbances`).

    Rules: ``name``, ``phase`` (one of sense, communicate, wind) and its method (``sense``,
    ``communicate`` or ``air``); Params as every kind's (refused options named
    ``disturbances.<name>.<key>``); the truth it is handed is never modified; its outputs are finite
    (N, 3); it draws only from its own stream (``ctx.rng``: the same seed gives the same outputs);
    two instances do not share state; ``metrics()`` is flat, finite JSON without the
    ``disturbances.<key>.`` prefix (the engine adds it).
    """
    params = _check_declaration(cls, Disturbance, DisturbanceParams, "disturbances.<key>.kind",
                                options, refused, f"disturbances.{getattr(cls, 'name', '?')}")
    name = cls.name
    phase = getattr(cls, "phase", None)
    assert phase in PHASES, f"{name}: phase must be one of {', '.join(PHASES)} (got {phase!r})"
    method = PHASE_METHOD[cls.phase]
    builtin_channel = issubclass(cls, (CommDelay, PacketLoss))
    assert builtin_channel or callable(getattr(cls, method, None)), (
        f"{name}: a {cls.phase}-phase model must define {method}() (the kernel calls it)")
    state = _class_state(cls, Disturbance)
    alone = _disturbed_ticks([_disturbances(cls, params, "a", 0)])[0]
    _assert_class_untouched(name, cls, Disturbance, state)
    again = _disturbed_ticks([_disturbances(cls, params, "a", 0)])[0]
    for x, y in zip(alone, again, strict=True):
        assert np.array_equal(x, y), f"{name}: not deterministic under a seed (draw only from ctx.rng)"
    beside = _disturbed_ticks([_disturbances(cls, params, "a", 0), _disturbances(cls, params, "b", 1)])[0]
    for x, y in zip(alone, beside, strict=True):
        assert np.array_equal(x, y), (
            f"{name}: two instances share state (one ran differently beside another): keep state on "
            "the instance, not the class or the module")
    model = next(iter(_disturbances(cls, params, "a", 0).models.values()))
    metrics = model.metrics()
    _assert_json_metrics(name, metrics, "metrics()")
    bad = [k for k in metrics if k.startswith("disturbances.")]
    assert not bad, f"{name}: metrics() keys are unprefixed (the engine adds disturbances.<key>.): {bad}"


# -- event kinds ---------------------------------------------------------------------------------
class _OneKind:
    """A registry holding the built-in event kinds and one more (what a scenario validates against)."""

    def __init__(self, cls: type[EventKindPlugin]) -> None:
        from .core.events import BUILTIN_EVENT_KINDS

        self.classes = {"event": {**BUILTIN_EVENT_KINDS, cls.name: cls}}

    def names(self, kind: str) -> list[str]:
        return sorted(self.classes[kind])


def check_event_kind(cls: type[EventKindPlugin], options: dict[str, Any] | None = None,
                     refused: dict[str, dict[str, Any]] | None = None) -> None:
    """Run an event kind through ``EventConfig`` (validation, the run record) and ``EventQueue``.

    Rules: ``name``; ``Params`` derive from ``EventParams`` (each field described: a required one's
    description completes ``a <kind> event needs <description>``), no field named like an event's
    own keys (``at``, ``agents``, ``kind``); ``failure`` a bool and ``motion`` a :class:`Motion`;
    an event of the kind validates, and its record validates again to the same record;
    :meth:`~EventKindPlugin.apply` changes only its agents, never a position (the kernel moves
    vehicles), drops ``healthy`` when it is a failure and ``comm_ok`` when it is not, leaves finite
    velocities; the queue then moves them by its ``motion`` (HOLD: held where they failed).
    """
    params = _check_declaration(cls, EventKindPlugin, EventParams, "event kind", options, refused,
                                "events.0")
    name = cls.name
    clash = sorted(set(cls.Params.model_fields) & {"at", "agents", "kind"})
    assert not clash, f"{name}: Params fields {clash} clash with every event's own keys"
    assert isinstance(cls.failure, bool), f"{name}: failure must be True or False (got {cls.failure!r})"
    assert isinstance(cls.motion, Motion), f"{name}: motion must be a Motion (got {cls.motion!r})"
    data = {"at": 0.3, "agents": [1, 2], "kind": name, **params.model_dump(mode="json", exclude_none=True)}
    context = {"registry": _OneKind(cls)}
    try:
        config = EventConfig.model_validate(data, context=context)
    except ValidationError as exc:
        problems = format_validation_error(exc, EventConfig, data, "events.0")
        raise AssertionError(f"{name}: an event of this kind is refused: {problems}") from None
    record = config.model_dump(mode="json")
    again = EventConfig.model_validate(record, context=context).model_dump(mode="json")
    assert again == record, f"{name}: an event's record does not validate to itself ({record} -> {again})"
    event = draw_event(config, 0, N_AGENTS, 0)
    _check_apply(name, cls, event)
    _check_motion(name, cls, event)


def _check_apply(name: str, cls: type[EventKindPlugin], event: Any) -> None:
    world = _world()
    before = {k: np.array(getattr(world, k), copy=True) for k in ("pos", "vel", "healthy", "comm_ok")}
    event.apply(world)
    hit = np.zeros(N_AGENTS, dtype=bool)
    hit[list(event.agents)] = True
    for k, value in before.items():
        assert np.array_equal(getattr(world, k)[~hit], value[~hit]), (
            f"{name}: apply() changed world.{k} of agents it does not hit")
    assert np.array_equal(world.pos, before["pos"]), (
        f"{name}: apply() moved agents (the kernel moves them: declare a motion)")
    assert np.isfinite(world.vel).all(), f"{name}: apply() left non-finite velocities"
    if cls.failure:
        assert not world.healthy[hit].any(), f"{name}: a failure must drop healthy of its agents"
        assert np.array_equal(world.comm_ok, before["comm_ok"]), (
            f"{name}: a failure keeps comm_ok (declare failure = False for a radio loss)")
    else:
        assert not world.comm_ok[hit].any(), f"{name}: a kind that is not a failure must drop comm_ok of its agents"
        assert np.array_equal(world.healthy, before["healthy"]), f"{name}: a kind that is not a failure keeps healthy"


def _check_motion(name: str, cls: type[EventKindPlugin], event: Any) -> None:
    """Five ticks of the queue after a kinematic 'dynamics' that moves everyone at its velocity."""
    world = _world()
    queue = EventQueue([event], GUIDANCE_PERIOD)
    for _ in range(5):
        queue.apply_due(world)
        world.pos += GUIDANCE_PERIOD * world.vel
        queue.hold(world)
        world.t += GUIDANCE_PERIOD
    assert np.isfinite(world.pos).all() and np.isfinite(world.vel).all(), f"{name}: the queue left non-finite states"
    if cls.failure and cls.motion is Motion.HOLD:
        idx = list(event.agents)
        assert np.allclose(world.vel[idx], 0.0), f"{name}: a HOLD kind's agents must be at rest"


# -- map generators ------------------------------------------------------------------------------
def check_generator(cls: type[MapGenerator], options: dict[str, Any] | None = None,
                    refused: dict[str, dict[str, Any]] | None = None) -> None:
    """Build a map generator's obstacles.

    Rules: ``name``; ``Params`` refuse unknown keys, describe each parameter and use none of the
    environment section's own keys (``name``, ``generator``, ``obstacles``: the parameters sit beside
    them); refused options named ``environment.<key>``; ``build`` returns a list of valid, non-empty
    shapely polygons with finite vertices within the engine's length limit, the same for the same
    parameters, leaving the parameters as they were.
    """
    import shapely

    params = _check_declaration(cls, MapGenerator, BaseModel, "environment.generator", options, refused,
                                "environment")
    name = cls.name
    clash = sorted(set(cls.Params.model_fields) & set(ENVIRONMENT_KEYS))
    assert not clash, f"{name}: parameters {clash} clash with the environment section's own keys"
    # build is a classmethod: mypy types the bound method without its __func__
    overridden = cls.build.__func__ is not MapGenerator.build.__func__  # type: ignore[attr-defined]
    assert overridden, f"{name}: define build(params)"
    dump = params.model_dump(mode="json")
    first, second = cls.build(params), cls.build(params)
    assert params.model_dump(mode="json") == dump, f"{name}: build() changed its parameters"
    assert isinstance(first, list) and first, f"{name}: build() must return a non-empty list of polygons"
    for k, poly in enumerate(first):
        assert isinstance(poly, shapely.Polygon), f"{name}: obstacle {k} is a {type(poly).__name__}, not a Polygon"
        assert poly.is_valid and not poly.is_empty and poly.area > 0, (
            f"{name}: obstacle {k} is not a valid, non-empty polygon")
        bounds = np.asarray(poly.bounds)
        assert np.isfinite(bounds).all() and np.abs(bounds).max() <= MAX_LENGTH, (
            f"{name}: obstacle {k} reaches beyond {MAX_LENGTH:g} m or is not finite")
    assert len(first) == len(second) and all(a.equals_exact(b, 0.0) for a, b in zip(first, second, strict=True)), (
        f"{name}: not deterministic (the same parameters must build the same map)")


# -- policies ------------------------------------------------------------------------------------
def _observations(layout: Any) -> np.ndarray:
    from .methods.policy.observation import observe

    world = _world()
    return observe(Sensing(world, Environment(), 10.0), None, layout, 10.0, 5.0)


def check_policy(cls: type[Policy], options: dict[str, Any] | None = None,
                 refused: dict[str, dict[str, Any]] | None = None) -> None:
    """Call a policy on the observations :mod:`swarmscene.env` would give it.

    Rules: ``name``; Params as every kind's (refused options named ``avoidance.policy_options.<key>``);
    for velocity and acceleration actions, ``policy(obs)`` returns finite (N, 3) actions in [-1, 1],
    leaves ``obs`` as it was, is the same for the same input, and two instances do not share state.
    """
    from .methods.policy.actions import ActionSpec
    from .methods.policy.observation import ObservationLayout

    params = _check_declaration(cls, Policy, PluginParams, "avoidance.policy", options, refused,
                                "avoidance.policy_options")
    name = cls.name
    layout = ObservationLayout(4)
    obs = _observations(layout)
    state = _class_state(cls, Policy)
    for kind in ("velocity", "acceleration"):
        spec = ActionSpec(kind, 2.0, 2.0, GUIDANCE_PERIOD)
        first, second = cls(params, layout, spec), cls(params, layout, spec)
        given = obs.copy()
        alone = [np.array(first(given)) for _ in range(3)]
        _assert_class_untouched(name, cls, Policy, state)
        assert np.array_equal(given, obs), f"{name}: modified the observations it was handed"
        for act in alone:
            assert act.shape == (N_AGENTS, 3), f"{name}: actions have shape {act.shape}, expected (N, 3)"
            assert np.isfinite(act).all() and np.abs(act).max() <= 1.0, f"{name}: actions must be finite, in [-1, 1]"
        other = obs * 0.5
        fresh = cls(params, layout, spec)
        beside = []
        for _ in range(3):
            beside.append(np.array(fresh(obs)))
            second(other)
        for a, b in zip(alone, beside, strict=True):
            assert np.array_equal(a, b), (
                f"{name}: not deterministic, or two instances share state (one acted differently beside "
                "another): keep state on the instance")
    _assert_class_untouched(name, cls, Policy, state)


# -- observers -----------------------------------------------------------------------------------
SHORT_RUN = ["swarm.n=4", "clock.duration=1"]
TIMING = ("wall_time", "realtime_factor", "step_ms_median")
"""Metrics that measure the machine, not the run."""


def _run(observers: list[type], overrides: list[str]) -> tuple[dict[str, Any], np.ndarray]:
    from .api import load, plugins
    from .core.simulation import Simulation

    pm, registry = plugins()
    sim = Simulation(load(overrides, registry), pm, observers)
    result = sim.run()
    return result.metrics, np.array(sim.world.pos)


def _run_checked(name: str, observers: list[type], overrides: list[str]) -> tuple[dict[str, Any], np.ndarray]:
    """:func:`_run`, an observer's exception turned into the check's failure: a metric written
    outside its namespace is the rule "changed the run's metrics" (the engine refuses the write)."""
    from .core.metric_keys import MetricKeyError
    from .core.raised import PluginRaised

    try:
        return _run(observers, overrides)
    except PluginRaised as exc:
        if isinstance(exc.__cause__, MetricKeyError):
            raise AssertionError(f"{name}: changed the run's metrics: {exc.__cause__} (add keys under your own "
                                 "prefix)") from exc
        raise AssertionError(f"{name}: raised during the run: {exc}") from exc


def check_observer(cls: type, overrides: list[str] | None = None) -> None:
    """Run a short scenario with and without an observer.

    Rules: a class whose every ``swarmscene_*`` method is a lifecycle hook (run start, event, step
    end, run end) marked with ``hookimpl``, at least one; built as ``cls(sim)``; it changes nothing
    of the run (the trajectory and every metric the run has without it); the metrics it adds are
    finite JSON; a fresh instance in a second run gives the same metrics (no state kept across runs).
    """
    assert isinstance(cls, type), f"{cls!r}: observers are classes"
    name = cls.__name__
    hooks = [a for a in dir(cls) if a.startswith("swarmscene_")]
    assert hooks, f"{name}: implements no lifecycle hook ({', '.join(LIFECYCLE_HOOKS)})"
    for attr in hooks:
        assert attr in LIFECYCLE_HOOKS, (
            f"{name}: {attr} is not a lifecycle hook (valid: {', '.join(LIFECYCLE_HOOKS)})")
        assert hasattr(getattr(cls, attr), f"{hookspecs.PROJECT}_impl"), f"{name}: {attr} is not marked @hookimpl"
    overrides = [*SHORT_RUN, "events=lead_fails", "events.0.at=0.5", *(overrides or [])]
    from .api import plugins

    base = [c for c in plugins()[1].observers if c is not cls]
    without, traj_without = _run(base, overrides)
    with_it, traj_with = _run_checked(name, [*base, cls], overrides)
    assert np.array_equal(traj_without, traj_with), f"{name}: the run moved differently with it (observers only read)"
    changed = sorted(k for k, v in without.items() if k not in TIMING and k in with_it and not _same(with_it[k], v))
    assert not changed, f"{name}: changed the run's metrics {changed} (add keys under your own prefix)"
    added = {k: v for k, v in with_it.items() if k not in without and k not in TIMING}
    _assert_json_metrics(name, added, "its swarmscene_run_end")
    again, _ = _run_checked(name, [*base, cls], overrides)
    second = {k: again.get(k) for k in added}
    assert all(_same(second[k], v) for k, v in added.items()), (
        f"{name}: a second run gave other metrics: keep state on the instance (built per run), not the class")


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(np.array_equal(a, b)) if isinstance(a, (list, np.ndarray)) else a == b
