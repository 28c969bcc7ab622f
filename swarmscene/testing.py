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
- dynamics: shapes of the state kept; HOLD keeps agents within 1 cm; a POSITION setpoint 1 m away
  is approached; a model with attitude keeps unit quaternions.

The built-in plugins pass these checks in the test suite (tests/test_contract.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import yaml

from .core.environment import Environment
from .core.plugin import Avoidance, BuildContext, Dynamics, Formation, PluginParams
from .core.sensing import Sensing
from .core.setpoint import Mode, Setpoints
from .core.state import WorldState

__all__ = ["check_avoidance", "check_dynamics", "check_formation", "check_params", "example_world"]

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


def check_params(cls: type, options: dict[str, Any] | None = None) -> PluginParams:
    """``name`` and ``Params`` as the engine needs them; returns the validated options."""
    assert isinstance(getattr(cls, "name", None), str) and cls.name, f"{cls.__name__}: set a `name`"
    assert issubclass(cls.Params, PluginParams), f"{cls.name}: Params must derive from PluginParams"
    assert cls.Params.model_config.get("extra") == "forbid", f"{cls.name}: Params must refuse unknown keys"
    for field, info in cls.Params.model_fields.items():
        assert info.description, f"{cls.name}: option {field!r} has no description"
    params = cls.Params.model_validate(options or {})
    text = yaml.safe_dump(params.model_dump(mode="json"))
    again = cls.Params.model_validate(yaml.safe_load(text))
    assert again == params, f"{cls.name}: Params do not round-trip through YAML ({text!r})"
    return params


def check_formation(cls: type[Formation], options: dict[str, Any] | None = None,
                    environment: Environment | None = None) -> None:
    """Run ``cls`` through the formation contract (see the module docstring)."""
    assert issubclass(cls, Formation), f"{cls.__name__} is not a Formation"
    params = check_params(cls, options)
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


def check_avoidance(cls: type[Avoidance], options: dict[str, Any] | None = None,
                    environment: Environment | None = None) -> None:
    """Run ``cls`` through the avoidance contract (see the module docstring)."""
    assert issubclass(cls, Avoidance), f"{cls.__name__} is not an Avoidance"
    params = check_params(cls, options)
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


def check_dynamics(cls: type[Dynamics], options: dict[str, Any] | None = None) -> None:
    """Run ``cls`` through the dynamics contract (see the module docstring)."""
    assert issubclass(cls, Dynamics), f"{cls.__name__} is not a Dynamics"
    params = check_params(cls, options)
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


# -- helpers -------------------------------------------------------------------------------------
def _build(cls: type, params: PluginParams, environment: Environment | None,
           world: WorldState | None = None) -> Any:
    world = world or example_world()
    ctx = BuildContext(
        n=world.n, guidance_period=GUIDANCE_PERIOD, physics_step=PHYSICS_STEP, duration=10.0,
        separation_limit=0.5, clearance_limit=0.2, comm_range=10.0,
        environment=environment or Environment(), rng=np.random.default_rng(0),
        initial=WorldState.at_rest(world.pos, leader=world.leader),
    )
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
