"""Contract checks any plugin author can run, in the style of scikit-learn's ``check_estimator``.

    from swarmscene.testing import check_avoidance

    def test_my_avoidance_honours_the_contract():
        check_avoidance(MyAvoidance)                      # Params() defaults
        check_avoidance(MyAvoidance, {"radius": 2.0})     # or chosen options

Each check builds a small world of its own (six agents 3 m apart at 2 m altitude, agent 0 leading,
the last one failed), runs the class through the contract of its kind for a few ticks and raises
``AssertionError`` naming the rule that was broken. The rules (docs/plugins.md):

- every kind: ``name`` is set; ``Params`` derives from ``PluginParams``, refuses unknown keys,
  documents every option and round-trips through YAML; the same seed gives the same output;
  nothing it is handed (world state, setpoints) is modified in place;
- formation: ``setpoints`` returns one finite row per agent with a valid mode; ``complete``
  returns True, False or None;
- avoidance: ``adjust`` returns one finite row per agent, and a failed agent's row exactly as it
  came in (failed vehicles are the kernel's business);
- every kind: two instances do not share state (one flown beside another with other inputs
  gives what it gives alone); options that must be refused (``refused={"key": {...}}``) are refused
  with a one-line error naming ``<kind>.key`` (a cross-field check raises ``ValueError("key: ...")``);
- dynamics: shapes of the state kept; HOLD keeps agents within 1 cm; a POSITION setpoint 1 m away
  is approached; a VELOCITY setpoint is flown (0.5 m/s held within 20 %, ``pos`` ignored); TRACK
  uses its feed-forward (a moving target is followed more closely with ``vel``/``acc`` than from
  ``pos`` alone); the declared ``wind_coupling`` is honoured (``integrated``: ``step`` reacts to
  ``world.wind``; ``force``/``carried``: the kernel applies the wind, so ``step`` must not read it
  as well); a model with attitude keeps unit quaternions;
- disturbance model (:func:`check_disturbance`): a ``phase`` and its method; run through the
  kernel's phases, it never modifies the truth, gives finite (N, 3) outputs, draws only from its own
  stream, shares no state between instances, and reports unprefixed, finite JSON metrics;
- event kind (:func:`check_event_kind`): ``Params`` from ``EventParams``, ``failure`` and ``motion``
  declared; an event of the kind validates and its record validates to itself; ``apply`` changes
  only its agents' flags and velocities (never a position);
- map generator (:func:`check_generator`): parameters that do not clash with the environment's
  keys; ``build`` returns valid, finite, non-empty polygons, the same for the same parameters;
- policy (:func:`check_policy`): finite actions (N, 3) in [-1, 1] for velocity and acceleration
  actions, observations left as they were, deterministic, no state shared between instances;
- observer (:func:`check_observer`): only lifecycle hooks, each marked ``hookimpl``; it changes
  nothing of a run, adds finite JSON metrics, and gives the same metrics in a second run.

The built-in plugins pass these checks in the test suite (tests/test_contract.py).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError

from .core.environment import Environment
from .core.errors import format_validation_error
from .core.plugin import PLUGIN_KINDS, Avoidance, Dynamics, Formation, PluginParams
from .core.sensing import Sensing
from .core.setpoint import Mode, Setpoints
from .core.state import WorldState
from .plugin import build_context
from .testing_kinds import (  # the kinds beside the three algorithms, rules listed above
    _assert_class_untouched,
    _class_state,
    check_disturbance,
    check_event_kind,
    check_generator,
    check_observer,
    check_policy,
)

__all__ = ["check_avoidance", "check_disturbance", "check_dynamics", "check_event_kind", "check_formation",
           "check_generator", "check_observer", "check_params", "check_policy", "example_world"]

N_AGENTS = 6
GUIDANCE_PERIOD = 0.1  # s
PHYSICS_STEP = 0.01  # s
TICKS = 5


def example_world(n: int = N_AGENTS, failed: bool = True) -> WorldState:
    """``n`` agents on a 2-row grid 3 m apart at 2 m altitude, agent 0 leading, the last failed."""
    k = np.arange(n)
    pos = np.column_stack([3.0 * (k // 2), 3.0 * (k % 2), np.full(n, 2.0)])
    world = WorldState.at_rest(pos, leader=0)
    if failed:
        world.healthy[-1] = False
    return world


@functools.cache
def installed_registry() -> Any:
    """The registry of this installation (built-ins and installed packages), built once: the checks
    validate options against it as a scenario would, so an option naming another kind's component
    (``avoidance.policy``) is resolved."""
    from .api import plugins

    return plugins()[1]


def check_params(cls: type[Any], options: dict[str, Any] | None = None,
                 refused: dict[str, dict[str, Any]] | None = None) -> PluginParams:
    """``name`` and ``Params`` as the engine needs them; returns the validated options.

    Args:
        cls: the plugin class (any kind with a ``name`` and a ``Params`` model).
        options: the options to validate (the defaults when None).
        refused: option name -> options that ``Params`` must refuse with a line naming that option
            (for cross-field checks: a model validator names its key, ``ValueError("vision: ...")``).
    """
    assert isinstance(getattr(cls, "name", None), str) and cls.name, f"{cls.__name__}: set a `name`"
    assert issubclass(cls.Params, PluginParams), f"{cls.name}: Params must derive from PluginParams"
    assert cls.Params.model_config.get("extra") == "forbid", f"{cls.name}: Params must refuse unknown keys"
    for field, info in cls.Params.model_fields.items():
        assert info.description, f"{cls.name}: option {field!r} has no description"
    context = {"registry": installed_registry()}  # as a scenario validates them (core.plugin.choose)
    params = cls.Params.model_validate(options or {}, context=context)
    text = yaml.safe_dump(params.model_dump(mode="json"))
    again = cls.Params.model_validate(yaml.safe_load(text), context=context)
    assert again == params, f"{cls.name}: Params do not round-trip through YAML ({text!r})"
    for key, bad in (refused or {}).items():
        _assert_refused(cls, key, bad)
    return params


def _assert_refused(cls: type[Any], key: str, options: dict[str, Any]) -> None:
    kind = next((k for k, base in PLUGIN_KINDS.items() if issubclass(cls, base)), "plugin")
    try:
        cls.Params.model_validate(options, context={"registry": installed_registry()})
    except ValidationError as exc:
        lines = format_validation_error(exc, cls.Params, options, prefix=kind)
    else:
        raise AssertionError(f"{cls.name}: Params accepted {options!r}, which must be refused naming {key!r}")
    assert any(line.startswith(f"{kind}.{key}: ") for line in lines), (
        f"{cls.name}: refusing {options!r} must name {kind}.{key} (got {lines}); a cross-field check "
        f"raises ValueError(\"{key}: ...\")"
    )


def check_formation(cls: type[Formation], options: dict[str, Any] | None = None,
                    environment: Environment | None = None,
                    refused: dict[str, dict[str, Any]] | None = None) -> None:
    """Run ``cls`` through the formation contract (see the module docstring)."""
    assert issubclass(cls, Formation), f"{cls.__name__} is not a Formation"
    params = check_params(cls, options, refused)
    state = _class_state(cls, Formation)
    first, second = (_build(cls, params, environment) for _ in range(2))
    world = example_world()
    for _ in range(TICKS):
        before = _world_copy(world)
        sp = first.setpoints(world, _sensing(world, environment))
        _assert_world_untouched(cls.name, before, world)
        _assert_setpoints(cls.name, sp, world.n)
        _assert_same(cls.name, sp, second.setpoints(world, _sensing(world, environment)))
        done = first.complete(world)
        assert done is None or isinstance(done, (bool, np.bool_)), f"{cls.name}: complete() returned {done!r}"
        _fly(world, sp)
    _assert_class_untouched(cls.name, cls, Formation, state)


def check_avoidance(cls: type[Avoidance], options: dict[str, Any] | None = None,
                    environment: Environment | None = None,
                    refused: dict[str, dict[str, Any]] | None = None) -> None:
    """Run ``cls`` through the avoidance contract (see the module docstring)."""
    assert issubclass(cls, Avoidance), f"{cls.__name__} is not an Avoidance"
    params = check_params(cls, options, refused)
    state = _class_state(cls, Avoidance)
    first, second = (_build(cls, params, environment) for _ in range(2))
    world = example_world()
    failed = ~world.healthy
    for _ in range(TICKS):
        sp = _converging_setpoints(world)
        before, world_before = sp.copy(), _world_copy(world)
        out = first.adjust(world, _sensing(world, environment), sp)
        _assert_world_untouched(cls.name, world_before, world)
        _assert_setpoints(cls.name, out, world.n)
        for key in ("mode", "pos", "vel", "acc", "yaw"):
            assert np.array_equal(getattr(sp, key), getattr(before, key)), (
                f"{cls.name}: adjust() modified its input setpoints ({key}); return a copy"
            )
            assert np.array_equal(getattr(out, key)[failed], getattr(before, key)[failed]), (
                f"{cls.name}: adjust() changed a failed agent's setpoint ({key})"
            )
        _assert_same(cls.name, out, second.adjust(world, _sensing(world, environment), sp.copy()))
        _fly(world, out)
    _assert_class_untouched(cls.name, cls, Avoidance, state)


def check_dynamics(cls: type[Dynamics], options: dict[str, Any] | None = None,
                   refused: dict[str, dict[str, Any]] | None = None) -> None:
    """Run ``cls`` through the dynamics contract (see the module docstring)."""
    assert issubclass(cls, Dynamics), f"{cls.__name__} is not a Dynamics"
    params = check_params(cls, options, refused)
    state = _class_state(cls, Dynamics)
    world = example_world(failed=False)
    start = world.pos.copy()
    model = _build(cls, params, None, world)
    model.initialize(world)
    hold = Setpoints.hold(start)
    kept = hold.copy()
    _flight(model, world, hold, seconds=2.0)
    for key in ("mode", "pos", "vel", "acc", "yaw"):
        assert np.array_equal(getattr(hold, key), getattr(kept, key)), (
            f"{cls.name}: control() modified its setpoints ({key})"
        )
    assert world.pos.shape == start.shape and world.vel.shape == start.shape, f"{cls.name}: state shape changed"
    assert np.abs(world.pos - start).max() < 1e-2, f"{cls.name}: HOLD let agents drift more than 1 cm"
    if cls.has_attitude:
        assert world.quat is not None and world.quat.shape == (world.n, 4), f"{cls.name}: quat must be (N, 4)"
        assert np.allclose(np.linalg.norm(world.quat, axis=1), 1.0, atol=1e-9), f"{cls.name}: quaternions not unit"
    target = Setpoints.hold(start + [1.0, 0.0, 0.0])
    target.mode[:] = Mode.POSITION
    positions = []
    for _ in range(2):  # twice from the same start: the same seed gives the same motion
        world = example_world(failed=False)
        model = _build(cls, params, None, world)
        model.initialize(world)
        _flight(model, world, target, seconds=30.0)  # the thesis' position loop is slow (0.23 rad/s)
        assert np.isfinite(world.pos).all() and np.isfinite(world.vel).all(), f"{cls.name}: non-finite state"
        positions.append(world.pos.copy())
    assert np.array_equal(positions[0], positions[1]), f"{cls.name}: not deterministic under a seed"
    gap = np.linalg.norm(positions[0] - target.pos, axis=1)
    assert np.all(gap < 0.5), f"{cls.name}: a POSITION setpoint 1 m away was not approached (gap {gap.max():.2f} m)"
    _check_velocity_mode(cls, params)
    _check_track_feed_forward(cls, params)
    _check_wind_coupling(cls, params)
    _check_dynamics_instances_apart(cls, params)
    _assert_class_untouched(cls.name, cls, Dynamics, state)


VELOCITY_COMMAND = 0.5
"""m/s along +x: the VELOCITY check's command."""


def _check_velocity_mode(cls: type[Dynamics], params: PluginParams) -> None:
    """A VELOCITY setpoint is flown: over the last 5 s of 20 s the mean velocity is the command
    within 20 % (and ``sp.pos``, left at the start, is ignored)."""
    world, model = _fresh(cls, params)
    sp = Setpoints.hold(world.pos)
    sp.mode[:] = Mode.VELOCITY
    sp.vel[:] = [VELOCITY_COMMAND, 0.0, 0.0]
    _flight(model, world, sp, seconds=15.0)
    before = world.pos.copy()
    _flight(model, world, sp, seconds=5.0)
    mean = (world.pos - before) / 5.0
    error = np.linalg.norm(mean - sp.vel, axis=1).max()
    assert error < 0.2 * VELOCITY_COMMAND, (
        f"{cls.name}: a VELOCITY setpoint of {VELOCITY_COMMAND} m/s along x was not flown (mean velocity "
        f"{mean[np.argmax(np.linalg.norm(mean - sp.vel, axis=1))].round(3).tolist()} m/s): honour Mode.VELOCITY"
    )


def _moving_target(start: np.ndarray, t: float, feed_forward: bool) -> Setpoints:
    """TRACK setpoints on x(t) = start + A sin(w t) e_x (A = 1 m, w = 0.5 rad/s), with the target's
    velocity and acceleration as feed-forward, or without them (zeros)."""
    amplitude, omega = 1.0, 0.5
    sp = Setpoints.hold(start + [amplitude * np.sin(omega * t), 0.0, 0.0])
    sp.mode[:] = Mode.TRACK
    if feed_forward:
        sp.vel[:] = [amplitude * omega * np.cos(omega * t), 0.0, 0.0]
        sp.acc[:] = [-amplitude * omega**2 * np.sin(omega * t), 0.0, 0.0]
    return sp


def _track_error(cls: type[Dynamics], params: PluginParams, feed_forward: bool) -> float:
    """RMS distance to the moving target over 20 s of TRACK."""
    world, model = _fresh(cls, params)
    start = world.pos.copy()
    squares = []
    for _ in range(int(round(20.0 / GUIDANCE_PERIOD))):
        sp = _moving_target(start, world.t, feed_forward)
        _flight(model, world, sp, seconds=GUIDANCE_PERIOD)
        squares.append(np.sum((world.pos - _moving_target(start, world.t, False).pos) ** 2, axis=1).mean())
    return float(np.sqrt(np.mean(squares)))


def _check_track_feed_forward(cls: type[Dynamics], params: PluginParams) -> None:
    """TRACK uses ``sp.vel`` and ``sp.acc``: a moving target is followed more closely with them."""
    with_ff, without = _track_error(cls, params, True), _track_error(cls, params, False)
    assert with_ff < without, (
        f"{cls.name}: TRACK ignores its feed-forward (RMS error {with_ff:.4f} m with sp.vel/sp.acc, "
        f"{without:.4f} m without): a moving target's velocity and acceleration must be used"
    )


WIND = np.array([3.0, 0.0, 0.0])
"""m/s: the wind the coupling check blows."""


def _check_wind_coupling(cls: type[Dynamics], params: PluginParams) -> None:
    """``integrated``: the model's step reacts to ``world.wind``; ``force``/``carried``: the kernel
    applies the wind (Dynamics.wind_coupling), so a step that read it too would count it twice."""
    flights = []
    for wind in (None, WIND):
        world, model = _fresh(cls, params)
        hold = Setpoints.hold(world.pos)
        for _ in range(int(round(2.0 / GUIDANCE_PERIOD))):
            model.control(world, hold)
            for _ in range(int(round(GUIDANCE_PERIOD / PHYSICS_STEP))):
                world.wind = None if wind is None else np.tile(wind, (world.n, 1))
                model.step(world, PHYSICS_STEP)
            world.t += GUIDANCE_PERIOD
        flights.append(np.concatenate([world.pos, world.vel]))
    moved = not np.array_equal(flights[0], flights[1])
    if cls.wind_coupling == "integrated":
        assert moved, (f"{cls.name}: declares wind_coupling = 'integrated' but its step ignores world.wind "
                       f"({WIND.tolist()} m/s changed nothing)")
    else:
        assert not moved, (f"{cls.name}: declares wind_coupling = {cls.wind_coupling!r} (the kernel applies "
                           f"the wind) but its step reads world.wind too: the wind would count twice")


def _check_dynamics_instances_apart(cls: type[Dynamics], params: PluginParams) -> None:
    """A model flown beside another instance flying elsewhere moves as it does alone."""
    def fly(world, model, target, ticks, other=None):
        for _ in range(ticks):
            model.control(world, target)
            if other is not None:
                other[1].control(other[0], other[2])
            for _ in range(int(round(GUIDANCE_PERIOD / PHYSICS_STEP))):
                model.step(world, PHYSICS_STEP)
                if other is not None:
                    other[1].step(other[0], PHYSICS_STEP)
            world.t += GUIDANCE_PERIOD
            if other is not None:
                other[0].t += GUIDANCE_PERIOD

    world, model = _fresh(cls, params)
    target = Setpoints.hold(world.pos + [1.0, 0.0, 0.0])
    target.mode[:] = Mode.POSITION
    fly(world, model, target, 20)
    alone = world.pos.copy()
    world, model = _fresh(cls, params)
    other_world, other_model = _fresh(cls, params)
    other_target = Setpoints.hold(other_world.pos - [0.0, 2.0, 1.0])
    other_target.mode[:] = Mode.POSITION
    fly(world, model, target, 20, other=(other_world, other_model, other_target))
    assert np.array_equal(world.pos, alone), (
        f"{cls.name}: two instances share state (one flew differently beside another): keep state on the "
        f"instance, not the class or the module"
    )


def _fresh(cls: type[Dynamics], params: PluginParams) -> tuple[WorldState, Dynamics]:
    world = example_world(failed=False)
    model = _build(cls, params, None, world)
    model.initialize(world)
    return world, model


# -- helpers -------------------------------------------------------------------------------------
def _build(cls: type, params: PluginParams, environment: Environment | None,
           world: WorldState | None = None) -> Any:
    world = world or example_world()
    ctx = build_context(positions=world.pos, leader=world.leader, guidance_period=GUIDANCE_PERIOD,
                        physics_step=PHYSICS_STEP, environment=environment)
    return cls(params, ctx)


def _sensing(world: WorldState, environment: Environment | None) -> Sensing:
    return Sensing(world, environment or Environment(), 10.0)


def _converging_setpoints(world: WorldState) -> Setpoints:
    """Every healthy agent sent through the swarm's centre (so avoidance has work to do)."""
    sp = Setpoints.hold(world.pos)
    centre = world.pos.mean(axis=0)
    healthy = world.healthy
    sp.mode[healthy] = Mode.POSITION
    sp.pos[healthy] = 2 * centre - world.pos[healthy]
    sp.vel[healthy] = 1.0 * (centre - world.pos[healthy]) / np.maximum(
        np.linalg.norm(centre - world.pos[healthy], axis=1, keepdims=True), 1e-9
    )
    return sp


def _fly(world: WorldState, sp: Setpoints) -> None:
    """A kinematic point per healthy agent: VELOCITY integrates, other modes move 10 % of the way."""
    moving = world.healthy & (sp.mode != Mode.HOLD)
    velocity_mode = moving & (sp.mode == Mode.VELOCITY)
    world.pos[velocity_mode] += sp.vel[velocity_mode] * GUIDANCE_PERIOD
    toward = moving & ~velocity_mode
    world.pos[toward] += 0.1 * (sp.pos[toward] - world.pos[toward])
    world.t += GUIDANCE_PERIOD


def _flight(model: Dynamics, world: WorldState, sp: Setpoints, seconds: float) -> None:
    for _ in range(int(round(seconds / GUIDANCE_PERIOD))):
        model.control(world, sp)
        for _ in range(int(round(GUIDANCE_PERIOD / PHYSICS_STEP))):
            model.step(world, PHYSICS_STEP)
        world.t += GUIDANCE_PERIOD


def _world_copy(world: WorldState) -> dict[str, np.ndarray]:
    return {key: np.array(getattr(world, key), copy=True) for key in ("pos", "vel", "healthy", "comm_ok", "role")}


def _assert_world_untouched(name: str, before: dict[str, np.ndarray], world: WorldState) -> None:
    for key, value in before.items():
        assert np.array_equal(getattr(world, key), value), f"{name}: modified world.{key} (plugins read the state)"


def _assert_setpoints(name: str, sp: Any, n: int) -> None:
    assert isinstance(sp, Setpoints), f"{name}: must return a Setpoints record (got {type(sp).__name__})"
    shapes = {"mode": (n,), "pos": (n, 3), "vel": (n, 3), "acc": (n, 3), "yaw": (n,)}
    for key, shape in shapes.items():
        value = getattr(sp, key)
        assert value.shape == shape, f"{name}: setpoints.{key} has shape {value.shape}, expected {shape}"
        assert np.isfinite(value).all(), f"{name}: setpoints.{key} is not finite"
    assert set(np.unique(sp.mode).tolist()) <= {int(m) for m in Mode}, f"{name}: unknown setpoint mode"
    for key in ("jerk", "snap"):
        value = getattr(sp, key)
        assert value is None or (value.shape == (n, 3) and np.isfinite(value).all()), f"{name}: bad setpoints.{key}"


def _assert_same(name: str, a: Setpoints, b: Setpoints) -> None:
    for key in ("mode", "pos", "vel", "acc", "yaw"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), f"{name}: not deterministic under a seed ({key})"
