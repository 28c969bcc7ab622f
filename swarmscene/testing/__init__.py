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
  as well); a model with attitude keeps unit quaternions; ``step_batch`` and ``control_batch``
  over three worlds give each world the bits of its own ``step`` and ``control``;
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

Each rule is a named check (:func:`list_checks`; :mod:`swarmscene.testing.contract` runs them): a failure
names every check that failed, and ``check_*`` returns each check's outcome. A class that knowingly
breaks a rule declares it, with the reason, in ``xfail_checks = {"<kind>.<check>": "why"}``.

The built-in plugins pass these checks in the test suite (tests/test_contract.py).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError

from ..core.batch import left_places, written_for
from ..core.environment import Environment
from ..core.errors import format_validation_error
from ..core.plugin import PLUGIN_KINDS, Avoidance, Dynamics, Formation, PluginParams
from ..core.sensing import Sensing
from ..core.setpoint import Mode, SetpointBatch, Setpoints
from ..core.state import WorldBatch, WorldState
from ..plugin import build_context
from .contract import ContractError, Outcome, Subject, checks_of, promise, run
from .kinds import (  # the kinds beside the three algorithms, rules listed above
    _assert_class_untouched,
    _class_state,
    check_disturbance,
    check_event_kind,
    check_generator,
    check_observer,
    check_policy,
)

__all__ = ["ContractError", "Outcome", "check_avoidance", "check_disturbance", "check_dynamics", "check_event_kind",
           "check_formation", "check_generator", "check_observer", "check_params", "check_policy", "example_world",
           "list_checks"]

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
    from ..runs.build import plugins

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


def _subject(kind: str, cls: type[Any], base: type, options: dict[str, Any] | None,
             refused: dict[str, dict[str, Any]] | None, environment: Environment | None = None) -> Subject:
    """The gate ``<kind>.params`` (a ``base`` subclass with ``name`` and ``Params`` as the engine needs
    them), then the subject every other check of the kind reads."""
    assert isinstance(cls, type) and issubclass(cls, base), f"{getattr(cls, '__name__', cls)} is not a {base.__name__}"
    params = check_params(cls, options, refused)
    return Subject(cls, params, environment, _class_state(cls, base))


def check_formation(cls: type[Formation], options: dict[str, Any] | None = None,
                    environment: Environment | None = None,
                    refused: dict[str, dict[str, Any]] | None = None) -> list[Outcome]:
    """Run ``cls`` through the formation checks (:func:`list_checks`); return each check's outcome.

    Raises:
        AssertionError: a promise broken (:class:`~swarmscene.testing.contract.ContractError`, naming each
            failed check), unless the class declares it in ``xfail_checks`` with a reason.
    """
    return run("formation", _subject("formation", cls, Formation, options, refused, environment))


def check_avoidance(cls: type[Avoidance], options: dict[str, Any] | None = None,
                    environment: Environment | None = None,
                    refused: dict[str, dict[str, Any]] | None = None) -> list[Outcome]:
    """Run ``cls`` through the avoidance checks (:func:`list_checks`); return each check's outcome.

    Raises:
        AssertionError: as :func:`check_formation`.
    """
    return run("avoidance", _subject("avoidance", cls, Avoidance, options, refused, environment))


def check_dynamics(cls: type[Dynamics], options: dict[str, Any] | None = None,
                   refused: dict[str, dict[str, Any]] | None = None) -> list[Outcome]:
    """Run ``cls`` through the dynamics checks (:func:`list_checks`); return each check's outcome.

    Raises:
        AssertionError: as :func:`check_formation`.
    """
    return run("dynamics", _subject("dynamics", cls, Dynamics, options, refused))


def list_checks(kind: str) -> list[tuple[str, str]]:
    """Every named check of ``kind`` (formation, avoidance, dynamics, disturbance, event, generator,
    policy, observer) as (name, promise), in the order they run: the names ``xfail_checks`` takes."""
    return [(c.name, c.promise) for c in checks_of(kind)]


# -- formation -----------------------------------------------------------------------------------
@dataclass
class _Tick:
    """One guidance tick of a formation or avoidance rollout: what went in and what came out."""

    world_before: dict[str, np.ndarray]
    world_after: dict[str, np.ndarray]
    out: Any  # the first instance's setpoints
    again: Any  # a second instance's, from the same inputs
    given: Setpoints | None = None  # avoidance: the setpoints handed in, as they were
    given_after: Setpoints | None = None  # avoidance: the same record after the call
    complete: Any = None  # formation: complete() after the tick


def _formation_rollout(s: Subject) -> list[_Tick]:
    """TICKS ticks of two instances on the example world, flown on the first one's setpoints."""
    first, second = (_build(s.cls, s.params, s.environment) for _ in range(2))
    world = example_world()
    ticks = []
    for _ in range(TICKS):
        before = _world_copy(world)
        out = first.setpoints(world, _sensing(world, s.environment))
        after = _world_copy(world)
        again = second.setpoints(world, _sensing(world, s.environment))
        ticks.append(_Tick(before, after, out, again, complete=first.complete(world)))
        if not _valid_setpoints(out, world.n):
            break  # nothing to fly: setpoints_valid names the problem
        _fly(world, out)
    return ticks


def _formation_ticks(s: Subject) -> list[_Tick]:
    return s.memo("rollout", lambda: _formation_rollout(s))


@promise("formation", "params")
def _formation_params(s: Subject) -> None:
    """``name`` set; ``Params`` derive from ``PluginParams``, refuse unknown keys, describe every option,
    round-trip through YAML; options given in ``refused`` are refused naming ``formation.<key>``."""


@promise("formation", "setpoints_valid")
def _formation_setpoints_valid(s: Subject) -> None:
    """``setpoints`` returns a ``Setpoints`` record: one finite row per agent, a valid mode each."""
    for tick in _formation_ticks(s):
        _assert_setpoints(s.name, tick.out, N_AGENTS)


@promise("formation", "reads_only")
def _formation_reads_only(s: Subject) -> None:
    """The world state it is handed is not modified (plugins read the state)."""
    for tick in _formation_ticks(s):
        _assert_world_untouched(s.name, tick.world_before, tick.world_after)


@promise("formation", "deterministic")
def _formation_deterministic(s: Subject) -> None:
    """Two instances built from the same seed give the same setpoints from the same inputs."""
    for tick in _formation_ticks(s):
        _assert_same(s.name, tick.out, tick.again)


@promise("formation", "complete_is_tristate")
def _formation_complete(s: Subject) -> None:
    """``complete`` returns True, False or None (no mission defined)."""
    for tick in _formation_ticks(s):
        done = tick.complete
        assert done is None or isinstance(done, (bool, np.bool_)), f"{s.name}: complete() returned {done!r}"


@promise("formation", "setpoints_batch_equals_worlds")
def _formation_setpoints_batch_equals_worlds(s: Subject) -> None:
    """``setpoints_batch`` over three worlds apart (two with a failed agent, one losing another
    mid-way) gives each world's own ``setpoints``, tick after tick, and the instances answer
    ``complete`` as theirs, bit for bit (the default returns ``NotImplemented``: the engine asks
    world by world)."""
    _check_formation_setpoints_batch_equals_worlds(s)


@promise("formation", "no_shared_state")
def _formation_no_shared_state(s: Subject) -> None:
    """Running an instance changes no class attribute (two instances share no state)."""
    _formation_ticks(s)
    _assert_class_untouched(s.name, s.cls, Formation, s.class_state)


# -- avoidance -----------------------------------------------------------------------------------
def _avoidance_rollout(s: Subject) -> list[_Tick]:
    """TICKS ticks of two instances adjusting setpoints that converge on the swarm's centre."""
    first, second = (_build(s.cls, s.params, s.environment) for _ in range(2))
    world = example_world()
    ticks = []
    for _ in range(TICKS):
        sp = _converging_setpoints(world)
        given, before = sp.copy(), _world_copy(world)
        out = first.adjust(world, _sensing(world, s.environment), sp)
        tick = _Tick(before, _world_copy(world), out, None, given=given, given_after=sp.copy())
        tick.again = second.adjust(world, _sensing(world, s.environment), given.copy())
        ticks.append(tick)
        if not _valid_setpoints(out, world.n):
            break
        _fly(world, out)
    return ticks


def _avoidance_ticks(s: Subject) -> list[_Tick]:
    return s.memo("rollout", lambda: _avoidance_rollout(s))


@promise("avoidance", "params")
def _avoidance_params(s: Subject) -> None:
    """``name`` set; ``Params`` derive from ``PluginParams``, refuse unknown keys, describe every option,
    round-trip through YAML; options given in ``refused`` are refused naming ``avoidance.<key>``."""


@promise("avoidance", "rows_valid")
def _avoidance_rows_valid(s: Subject) -> None:
    """``adjust`` returns a ``Setpoints`` record: one finite row per agent, a valid mode each."""
    for tick in _avoidance_ticks(s):
        _assert_setpoints(s.name, tick.out, N_AGENTS)


@promise("avoidance", "reads_only")
def _avoidance_reads_only(s: Subject) -> None:
    """The world state it is handed is not modified (plugins read the state)."""
    for tick in _avoidance_ticks(s):
        _assert_world_untouched(s.name, tick.world_before, tick.world_after)


@promise("avoidance", "input_untouched")
def _avoidance_input_untouched(s: Subject) -> None:
    """The setpoints it is handed are not modified in place (it returns a copy)."""
    for tick in _avoidance_ticks(s):
        for key in ("mode", "pos", "vel", "acc", "yaw"):
            assert np.array_equal(getattr(tick.given_after, key), getattr(tick.given, key)), (
                f"{s.name}: adjust() modified its input setpoints ({key}); return a copy"
            )


@promise("avoidance", "failed_rows_kept")
def _avoidance_failed_rows_kept(s: Subject) -> None:
    """A failed agent's setpoint comes back exactly as it went in (failed vehicles are the kernel's)."""
    failed = ~example_world().healthy
    for tick in _avoidance_ticks(s):
        if not isinstance(tick.out, Setpoints):
            return  # rows_valid names it
        for key in ("mode", "pos", "vel", "acc", "yaw"):
            assert np.array_equal(getattr(tick.out, key)[failed], getattr(tick.given, key)[failed]), (
                f"{s.name}: adjust() changed a failed agent's setpoint ({key})"
            )


@promise("avoidance", "deterministic")
def _avoidance_deterministic(s: Subject) -> None:
    """Two instances built from the same seed give the same setpoints from the same inputs."""
    for tick in _avoidance_ticks(s):
        _assert_same(s.name, tick.out, tick.again)


@promise("avoidance", "adjust_batch_equals_worlds")
def _avoidance_adjust_batch_equals_worlds(s: Subject) -> None:
    """``adjust_batch`` over three worlds apart (one with a failed agent) gives each world's own
    ``adjust`` setpoints, tick after tick, and leaves the instances' counts as theirs, bit for bit
    (the default returns ``NotImplemented``: the engine adjusts world by world), given the
    setpoints as a list of records and as one ``SetpointBatch`` (as a batched formation hands them)."""
    _check_avoidance_adjust_batch_equals_worlds(s, one_batch=False)
    _check_avoidance_adjust_batch_equals_worlds(s, one_batch=True)


@promise("avoidance", "no_shared_state")
def _avoidance_no_shared_state(s: Subject) -> None:
    """Running an instance changes no class attribute (two instances share no state)."""
    _avoidance_ticks(s)
    _assert_class_untouched(s.name, s.cls, Avoidance, s.class_state)


# -- dynamics ------------------------------------------------------------------------------------
@dataclass
class _Hold:
    """Two seconds of HOLD from the example world: the state after, and the setpoints as handed in."""

    start: np.ndarray
    world: WorldState
    hold: Setpoints
    kept: Setpoints


def _hold_flight(s: Subject) -> _Hold:
    world = example_world(failed=False)
    start = world.pos.copy()
    model = _build(s.cls, s.params, None, world)
    model.initialize(world)
    hold = Setpoints.hold(start)
    kept = hold.copy()
    _flight(model, world, hold, seconds=2.0)
    return _Hold(start, world, hold, kept)


def _held(s: Subject) -> _Hold:
    return s.memo("hold", lambda: _hold_flight(s))


def _position_flights(s: Subject) -> tuple[Setpoints, list[np.ndarray]]:
    """A POSITION setpoint 1 m along x, flown twice from the same start for 30 s (the thesis'
    position loop is slow, 0.23 rad/s): the target and each flight's end positions."""
    start = example_world(failed=False).pos
    target = Setpoints.hold(start + [1.0, 0.0, 0.0])
    target.mode[:] = Mode.POSITION
    positions = []
    for _ in range(2):
        world = example_world(failed=False)
        model = _build(s.cls, s.params, None, world)
        model.initialize(world)
        _flight(model, world, target, seconds=30.0)
        assert np.isfinite(world.pos).all() and np.isfinite(world.vel).all(), f"{s.name}: non-finite state"
        positions.append(world.pos.copy())
    return target, positions


def _positions(s: Subject) -> tuple[Setpoints, list[np.ndarray]]:
    return s.memo("position", lambda: _position_flights(s))


@promise("dynamics", "params")
def _dynamics_params(s: Subject) -> None:
    """``name`` set; ``Params`` derive from ``PluginParams``, refuse unknown keys, describe every option,
    round-trip through YAML; options given in ``refused`` are refused naming ``dynamics.<key>``."""


@promise("dynamics", "setpoints_untouched")
def _dynamics_setpoints_untouched(s: Subject) -> None:
    """``control`` does not modify the setpoints it is handed."""
    flight = _held(s)
    for key in ("mode", "pos", "vel", "acc", "yaw"):
        assert np.array_equal(getattr(flight.hold, key), getattr(flight.kept, key)), (
            f"{s.name}: control() modified its setpoints ({key})"
        )


@promise("dynamics", "state_shapes")
def _dynamics_state_shapes(s: Subject) -> None:
    """The state keeps its shapes: ``pos`` and ``vel`` (N, 3), ``quat`` (N, 4) with attitude."""
    flight = _held(s)
    world = flight.world
    assert world.pos.shape == flight.start.shape and world.vel.shape == flight.start.shape, (
        f"{s.name}: state shape changed")
    if s.cls.has_attitude:
        assert world.quat is not None and world.quat.shape == (world.n, 4), f"{s.name}: quat must be (N, 4)"


@promise("dynamics", "hold")
def _dynamics_hold(s: Subject) -> None:
    """HOLD keeps agents within 1 cm of where they were for 2 s."""
    flight = _held(s)
    assert np.abs(flight.world.pos - flight.start).max() < 1e-2, f"{s.name}: HOLD let agents drift more than 1 cm"


@promise("dynamics", "unit_quaternions")
def _dynamics_unit_quaternions(s: Subject) -> None:
    """A model with attitude keeps unit quaternions (nothing to check without attitude)."""
    if s.cls.has_attitude:
        quat = _held(s).world.quat
        assert quat is not None and np.allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-9), (
            f"{s.name}: quaternions not unit")


@promise("dynamics", "deterministic")
def _dynamics_deterministic(s: Subject) -> None:
    """Two flights from the same start under the same seed end in the same state."""
    _, positions = _positions(s)
    assert np.array_equal(positions[0], positions[1]), f"{s.name}: not deterministic under a seed"


@promise("dynamics", "position_approached")
def _dynamics_position_approached(s: Subject) -> None:
    """A POSITION setpoint 1 m away is approached within 0.5 m in 30 s."""
    target, positions = _positions(s)
    gap = np.linalg.norm(positions[0] - target.pos, axis=1)
    assert np.all(gap < 0.5), f"{s.name}: a POSITION setpoint 1 m away was not approached (gap {gap.max():.2f} m)"


@promise("dynamics", "velocity_mode")
def _dynamics_velocity_mode(s: Subject) -> None:
    """A VELOCITY setpoint (0.5 m/s) is flown within 20 %, its ``pos`` ignored."""
    _check_velocity_mode(s.cls, s.params)


@promise("dynamics", "track_feed_forward")
def _dynamics_track_feed_forward(s: Subject) -> None:
    """TRACK uses its feed-forward: a moving target is followed more closely with ``vel`` and ``acc``."""
    _check_track_feed_forward(s.cls, s.params)


@promise("dynamics", "wind_coupling")
def _dynamics_wind_coupling(s: Subject) -> None:
    """The declared ``wind_coupling`` is honoured (``integrated``: ``step`` reacts to ``world.wind``;
    ``force``, ``carried``: the kernel applies it, so ``step`` must not read it as well)."""
    _check_wind_coupling(s.cls, s.params)


@promise("dynamics", "instances_apart")
def _dynamics_instances_apart(s: Subject) -> None:
    """A model flown beside a second instance flying elsewhere moves as it does alone."""
    _check_dynamics_instances_apart(s.cls, s.params)


@promise("dynamics", "batch_equals_worlds")
def _dynamics_batch_equals_worlds(s: Subject) -> None:
    """``step_batch`` over three worlds flying apart equals each world's own ``step``, bit for bit
    (the default steps world by world; a batched form must give the same numbers)."""
    _check_dynamics_batch_equals_worlds(s.cls, s.params)


@promise("dynamics", "control_batch_equals_worlds")
def _dynamics_control_batch_equals_worlds(s: Subject) -> None:
    """``control_batch`` over five worlds with setpoints of their own (modes, targets, headings,
    an agent failed) flies them as each world's own ``control`` does, bit for bit (the default
    controls world by world; a batched form must latch the same commands), given the setpoints
    as a list of records and as one ``SetpointBatch`` (as the engine hands on the ``policy``
    avoidance's)."""
    _check_dynamics_control_batch_equals_worlds(s.cls, s.params, one_batch=False)
    _check_dynamics_control_batch_equals_worlds(s.cls, s.params, one_batch=True)


@promise("dynamics", "no_shared_state")
def _dynamics_no_shared_state(s: Subject) -> None:
    """Flying an instance changes no class attribute (two instances share no state)."""
    _held(s)
    _positions(s)
    _assert_class_untouched(s.name, s.cls, Dynamics, s.class_state)


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


def _check_dynamics_batch_equals_worlds(cls: type[Dynamics], params: PluginParams) -> None:
    """Three worlds (agents shifted apart, each with its own target: a move, a climb, a hold)
    flown 2 s alone, then together as a :class:`~swarmscene.core.state.WorldBatch`."""
    shifts = ([0.0, 0.0, 0.0], [5.0, -2.0, 1.0], [-3.0, 4.0, 0.5])
    moves = ([1.0, 0.0, 0.0], [0.0, 0.5, 1.0], [0.0, 0.0, 0.0])

    def worlds() -> list[tuple[WorldState, Dynamics, Setpoints]]:
        out = []
        for shift, move in zip(shifts, moves, strict=True):
            world = example_world(failed=False)
            world.pos += shift
            model = _build(cls, params, None, world)
            model.initialize(world)
            target = Setpoints.hold(world.pos + move)
            target.mode[:] = Mode.POSITION
            out.append((world, model, target))
        return out

    alone = worlds()
    for world, model, target in alone:
        _flight(model, world, target, seconds=2.0)
    together = worlds()
    batch = WorldBatch([world for world, _, _ in together])
    models = [model for _, model, _ in together]
    for _ in range(int(round(2.0 / GUIDANCE_PERIOD))):
        for world, model, target in together:
            model.control(world, target)
        batch.controlled()
        for _ in range(int(round(GUIDANCE_PERIOD / PHYSICS_STEP))):
            if _batched(cls, "step", models, batch, PHYSICS_STEP) is NotImplemented:
                for world, model, _ in together:
                    model.step(world, PHYSICS_STEP)
        for world, _, _ in together:
            world.t += GUIDANCE_PERIOD
    _assert_worlds_equal([one for one, _, _ in alone], [batched for batched, _, _ in together],
                         lambda b, field: f"{cls.name}: step_batch gave world {b} another {field} than its own "
                         "step()", "must repeat the per-world arithmetic")


def _batched(cls: type, single: str, *args: Any) -> object:
    """``cls.<single>_batch(*args)``, or ``NotImplemented`` where the engine flies the worlds by
    their own ``single`` instead (a subclass that overrides it alone: :func:`~swarmscene.core.batch.written_for`)."""
    if not written_for(cls, f"{single}_batch", single):
        return NotImplemented
    return getattr(cls, f"{single}_batch")(*args)


def _assert_worlds_equal(alone: list[WorldState], together: list[WorldState], differs: Callable[[int, str], str],
                         must: str) -> None:
    """Each batched world's state equals its world flown alone bit for bit; else ``differs(b, field)``,
    the largest difference, and what ``a batched form`` ``must`` do."""
    for b, (one, batched) in enumerate(zip(alone, together, strict=True)):
        for field in ("pos", "vel", "quat", "omega", "rotor_speed"):
            a, c = getattr(one, field), getattr(batched, field)
            assert (a is None) == (c is None) and (a is None or np.array_equal(a, c)), (
                f"{differs(b, field)} (largest difference {np.abs(np.asarray(a) - np.asarray(c)).max():.3g}): "
                f"a batched form {must} (docs/batched.md)")


def _check_dynamics_control_batch_equals_worlds(cls: type[Dynamics], params: PluginParams, one_batch: bool) -> None:
    """Five worlds flown 2 s alone (``control`` and ``step``), then together (``control_batch``
    and ``step_batch``): each tick every world gets setpoints of its own (worlds 0 and 3 a
    POSITION move each, worlds 1 and 4 a TRACK along a moving target with vel, acc and a turning
    heading, world 2 a VELOCITY command with one agent failed and the rest held), so that a
    batched form that groups worlds by their controller's mode has groups to take. With
    ``one_batch`` the worlds' records are handed together as one
    :class:`~swarmscene.core.setpoint.SetpointBatch` (one record has one set of fields: every
    world's carries jerk and snap, zero where the TRACK's do not, on both sides)."""
    shifts = ([0.0, 0.0, 0.0], [5.0, -2.0, 1.0], [-3.0, 4.0, 0.5], [2.0, 6.0, -1.0], [-6.0, -5.0, 2.0])

    def worlds() -> list[tuple[WorldState, Dynamics]]:
        out = []
        for b, shift in enumerate(shifts):
            world = example_world(failed=b == 2)
            world.pos += shift
            model = _build(cls, params, None, world)
            model.initialize(world)
            out.append((world, model))
        return out

    def setpoints(b: int, world: WorldState, t: float) -> Setpoints:
        sp = Setpoints.hold(world.pos)
        if b in (0, 3):
            sp.mode[:] = Mode.POSITION
            sp.pos[:] = world.pos + [1.0, 0.0, 0.0] if b == 0 else world.pos + [-0.5, 2.0, 0.3]
        elif b in (1, 4):
            sp = _moving_target(world.pos, t + b, feed_forward=True)
            sp.yaw[:] = 0.3 * t + 0.1 * np.arange(world.n)
        else:
            sp.mode[:] = Mode.VELOCITY
            sp.vel[:] = [0.0, VELOCITY_COMMAND, 0.0]
            sp.mode[1] = Mode.HOLD
        if one_batch:
            sp.jerk = np.zeros((world.n, 3)) if sp.jerk is None else sp.jerk
            sp.snap = np.zeros((world.n, 3)) if sp.snap is None else sp.snap
        return sp

    ticks, substeps = int(round(2.0 / GUIDANCE_PERIOD)), int(round(GUIDANCE_PERIOD / PHYSICS_STEP))
    alone = worlds()
    for b, (world, model) in enumerate(alone):
        for _ in range(ticks):
            model.control(world, setpoints(b, world, world.t))
            for _ in range(substeps):
                model.step(world, PHYSICS_STEP)
            world.t += GUIDANCE_PERIOD
    together = worlds()
    batch = WorldBatch([world for world, _ in together])
    models = [model for _, model in together]
    for _ in range(ticks):
        records = [setpoints(b, world, world.t) for b, (world, _) in enumerate(together)]
        sps: list[Setpoints] | SetpointBatch = records
        if one_batch:
            sps = SetpointBatch.stack(records)
        done = _batched(cls, "control", models, batch, batch.worlds, sps)
        left = range(len(models)) if done is NotImplemented else left_places(done, len(models), cls)
        for b in left:  # the worlds it left to their own control, as the engine reads them
            (world, model), sp = together[b], sps[b]
            model.control(world, sp)
        batch.controlled()
        for _ in range(substeps):
            if _batched(cls, "step", models, batch, PHYSICS_STEP) is NotImplemented:
                for world, model in together:
                    model.step(world, PHYSICS_STEP)
        for world, _ in together:
            world.t += GUIDANCE_PERIOD
    _assert_worlds_equal([one for one, _ in alone], [batched for batched, _ in together],
                         lambda b, field: f"{cls.name}: control_batch flew world {b} to another {field} than its "
                         f"own control(){' (setpoints given as one SetpointBatch)' if one_batch else ''}",
                         "must latch each world's commands with the per-world arithmetic")


def _three_worlds() -> list[WorldState]:
    """The batched forms' checks' worlds: the example world shifted apart three times, world 1
    squeezed to half its spacing, world 2 without its failed agent."""
    out = []
    for b, shift in enumerate(([0.0, 0.0, 0.0], [40.0, -10.0, 0.0], [-30.0, 25.0, 0.0])):
        world = example_world(failed=b != 2)
        world.pos = (0.5 * world.pos if b == 1 else world.pos) + shift
        out.append(world)
    return out


def _check_formation_setpoints_batch_equals_worlds(s: Subject) -> None:
    """Three worlds (the example world shifted apart, world 1 squeezed to half its spacing, world
    2 without its failed agent until agent 1 fails at the middle tick) flown 2 TICKS ticks on
    their setpoints twice side by side: each world by its own instance's ``setpoints``, and all
    three by ``setpoints_batch``."""
    alone, together = _three_worlds(), _three_worlds()
    alone_formations = [_build(s.cls, s.params, s.environment, world) for world in alone]
    batch_formations = [_build(s.cls, s.params, s.environment, world) for world in together]
    for tick in range(2 * TICKS):
        if tick == TICKS:
            alone[2].healthy[1] = together[2].healthy[1] = False
        outs = _batched(s.cls, "setpoints", batch_formations, together,
                        [_sensing(w, s.environment) for w in together])
        if outs is NotImplemented:
            return
        assert isinstance(outs, (list, SetpointBatch)) and len(outs) == len(together), (
            f"{s.name}: setpoints_batch returned {type(outs).__name__}, not one Setpoints per world")
        for b, (world, formation, out) in enumerate(zip(alone, alone_formations, outs, strict=True)):
            own = formation.setpoints(world, _sensing(world, s.environment))
            for key in ("mode", "pos", "vel", "acc", "yaw", "jerk", "snap"):
                mine, theirs = getattr(own, key), getattr(out, key)
                assert (mine is None) == (theirs is None) and (mine is None or np.array_equal(mine, theirs)), (
                    f"{s.name}: setpoints_batch gave world {b} other setpoints ({key}) than its own setpoints() at "
                    f"tick {tick}: a batched form must give each world its own arithmetic (docs/batched.md)")
            differs = _held_differs(formation, batch_formations[b])
            assert differs is None, (
                f"{s.name}: after setpoints_batch world {b}'s instance holds another {differs} than after its "
                f"own setpoints() at tick {tick}")
            done, batched_done = formation.complete(world), batch_formations[b].complete(together[b])
            assert done == batched_done, (
                f"{s.name}: after setpoints_batch world {b}'s complete() is {batched_done!r}, after its own "
                f"setpoints() {done!r}")
            _fly(world, own)
            _fly(together[b], out)


def _check_avoidance_adjust_batch_equals_worlds(s: Subject, one_batch: bool) -> None:
    """Three worlds (the example world shifted apart, world 1 squeezed to half its spacing, world 2
    without its failed agent) flown TICKS ticks towards their centres twice side by side: each
    world by its own instance's ``adjust``, and all three by ``adjust_batch`` (handed the
    setpoints as one :class:`~swarmscene.core.setpoint.SetpointBatch` with ``one_batch``)."""
    alone, together = _three_worlds(), _three_worlds()
    alone_methods = [_build(s.cls, s.params, s.environment, world) for world in alone]
    batch_methods = [_build(s.cls, s.params, s.environment, world) for world in together]
    for tick in range(TICKS):
        sps = [_converging_setpoints(world) for world in together]
        handed: list[Setpoints] | SetpointBatch = [sp.copy() for sp in sps]
        if one_batch:
            handed = SetpointBatch.stack(sps)
        outs = _batched(s.cls, "adjust", batch_methods, together, [_sensing(w, s.environment) for w in together],
                        handed)
        if outs is NotImplemented:
            return
        assert isinstance(outs, (list, SetpointBatch)) and len(outs) == len(together), (
            f"{s.name}: adjust_batch returned {type(outs).__name__}, not one Setpoints per world")
        for b, (world, method, out) in enumerate(zip(alone, alone_methods, outs, strict=True)):
            own = method.adjust(world, _sensing(world, s.environment), _converging_setpoints(world))
            for key in ("mode", "pos", "vel", "acc", "yaw"):
                assert np.array_equal(getattr(own, key), getattr(out, key)), (
                    f"{s.name}: adjust_batch gave world {b} other setpoints ({key}) than its own adjust() at "
                    f"tick {tick}{' (setpoints given as one SetpointBatch)' if one_batch else ''}: a batched form "
                    "must give each world its own arithmetic (docs/batched.md)")
            _fly(world, own)
            _fly(together[b], out)
    for b, (one, batched) in enumerate(zip(alone_methods, batch_methods, strict=True)):
        assert _counts(one) == _counts(batched), (
            f"{s.name}: after adjust_batch world {b}'s instance holds {_counts(batched)}, its own adjust() "
            f"{_counts(one)}")


def _counts(obj: Any) -> dict[str, Any]:
    """An instance's plain attributes (counters, flags, names): what its metrics are made of."""
    return {k: v for k, v in vars(obj).items() if isinstance(v, (bool, int, float, str))}


def _held_differs(one: Any, other: Any) -> str | None:
    """The first of two instances' plain attributes and arrays whose values differ (its name), or
    ``None``: what a batched form must leave each world's instance holding."""
    mine, theirs = vars(one), vars(other)
    for key, value in mine.items():
        if isinstance(value, np.ndarray):
            if not isinstance(theirs.get(key), np.ndarray) or not np.array_equal(
                    value, theirs[key], equal_nan=value.dtype.kind in "fc"):
                return key
        elif isinstance(value, (bool, int, float, str)) and theirs.get(key) != value:
            return key
    return None


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


def _assert_world_untouched(name: str, before: dict[str, np.ndarray], after: dict[str, np.ndarray]) -> None:
    for key, value in before.items():
        assert np.array_equal(after[key], value), f"{name}: modified world.{key} (plugins read the state)"


def _valid_setpoints(sp: Any, n: int) -> bool:
    """Whether ``sp`` can be flown (a record of the right shapes, finite): the rollouts stop otherwise."""
    try:
        _assert_setpoints("", sp, n)
    except AssertionError:
        return False
    return True


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
