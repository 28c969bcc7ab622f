"""The ``quadrotor`` Dynamics plugin driven as the kernel drives it: control() per tick, step() per
physics step."""

import numpy as np
import pydantic
import pytest

from swarmscene.core.plugin import BuildContext, Dynamics
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.methods.quadrotor.model import AIRFRAMES, euler_zyx, quat_to_rotmat
from swarmscene.plugins.dynamics import quadrotor as quadrotor_module
from swarmscene.plugins.dynamics.quadrotor import Quadrotor

T_S = 0.1
PHYSICS = 1.0 / 240.0


def build(pos, physics=PHYSICS, **params):
    world = WorldState.at_rest(np.asarray(pos, dtype=float))
    ctx = BuildContext(n=world.n, guidance_period=T_S, physics_step=physics, duration=10.0,
                       separation_limit=0.3, clearance_limit=0.3, comm_range=10.0, environment=None,
                       rng=np.random.default_rng(0), initial=world)
    dyn = Quadrotor(Quadrotor.Params(**params), ctx)
    dyn.initialize(world)
    return dyn, world


def run(dyn, world, setpoints_fn, seconds, physics=PHYSICS, record=None):
    substeps = int(round(T_S / physics))
    for k in range(int(round(seconds / T_S))):
        dyn.control(world, setpoints_fn(world.t))
        for _ in range(substeps):
            dyn.step(world, physics)
        world.t = (k + 1) * T_S
        if record is not None:
            record(world)


def test_plugin_contract_and_registration():
    assert issubclass(Quadrotor, Dynamics) and Quadrotor.name == "quadrotor"
    assert Quadrotor.has_attitude
    found = []
    quadrotor_module.swarmscene_register_dynamics(register=found.append)
    assert found == [Quadrotor]
    for key, field in Quadrotor.Params.model_fields.items():
        assert field.description, key
    with pytest.raises(pydantic.ValidationError):
        Quadrotor.Params(airframe="f450")
    with pytest.raises(pydantic.ValidationError):
        Quadrotor.Params(gain=1.0)
    with pytest.raises(pydantic.ValidationError, match="attitude_omega"):
        Quadrotor.Params(attitude_omega=300.0)


@pytest.mark.parametrize("airframe", sorted(AIRFRAMES))
def test_initialize_and_hold_hover(airframe):
    pos = np.array([[0.0, 0.0, 1.0], [3.0, -2.0, 5.0]])
    dyn, world = build(pos, airframe=airframe)
    assert world.quat.shape == (2, 4) and world.omega.shape == (2, 3)
    np.testing.assert_allclose(world.quat, [[1, 0, 0, 0]] * 2)
    np.testing.assert_allclose(world.rotor_speed, AIRFRAMES[airframe].hover_rotor_speed)
    run(dyn, world, lambda t: Setpoints.hold(pos), 2.0)
    np.testing.assert_allclose(world.pos, pos, atol=1e-9)
    np.testing.assert_allclose(world.rotor_speed, AIRFRAMES[airframe].hover_rotor_speed, rtol=1e-6)


def circle_setpoints(t, n=1, radius=1.0, speed=1.0, z=1.0):
    w = speed / radius
    c, s = np.cos(w * t), np.sin(w * t)
    row = lambda x, y, zz: np.tile([x, y, zz], (n, 1))  # noqa: E731
    return Setpoints(
        mode=np.full(n, Mode.TRACK, dtype=np.int8),
        pos=row(radius * c, radius * s, z),
        vel=row(-radius * w * s, radius * w * c, 0.0),
        acc=row(-radius * w**2 * c, -radius * w**2 * s, 0.0),
        yaw=np.zeros(n),
        jerk=row(radius * w**3 * s, -radius * w**3 * c, 0.0),
        snap=row(radius * w**4 * c, radius * w**4 * s, 0.0),
    )


@pytest.mark.parametrize("airframe", sorted(AIRFRAMES))
def test_circle_at_1_m_s_through_guidance_ticks(airframe):
    """TRACK setpoints at 10 Hz, physics at 240 Hz: RMS position error < 5 cm over one lap."""
    dyn, world = build([[1.0, 0.0, 1.0]], airframe=airframe)
    world.vel[0] = [0.0, 1.0, 0.0]  # enter the circle at speed (from rest adds a start transient)
    errors = []
    run(dyn, world, circle_setpoints, 2 * np.pi,
        record=lambda w: errors.append(np.linalg.norm(w.pos[0] - circle_setpoints(w.t).pos[0])))
    rms = np.sqrt(np.mean(np.square(errors)))
    assert rms < 0.05
    assert rms < 0.01  # with the Taylor-propagated reference it is millimetres


def test_reference_propagation_matters():
    """Holding the 10 Hz TRACK reference as a staircase is visibly worse (the option is real)."""
    errs = {}
    for flag in (True, False):
        dyn, world = build([[1.0, 0.0, 1.0]], propagate_reference=flag)
        world.vel[0] = [0.0, 1.0, 0.0]
        e = []
        run(dyn, world, circle_setpoints, 3.0,
            record=lambda w: e.append(np.linalg.norm(w.pos[0] - circle_setpoints(w.t).pos[0])))  # noqa: B023 (run now)
        errs[flag] = np.sqrt(np.mean(np.square(e)))
    assert errs[False] > 3 * errs[True]


def test_modes_per_agent_in_one_swarm():
    """POSITION goes to its point, VELOCITY cruises at its velocity holding altitude, HOLD stays."""
    pos = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 2.0], [20.0, 0.0, 3.0]])
    dyn, world = build(pos, airframe="m330")
    sp = Setpoints.hold(pos)
    sp.mode[:] = [Mode.POSITION, Mode.VELOCITY, Mode.HOLD]
    sp.pos[0] = [2.0, 1.0, 1.5]
    sp.vel[1] = [0.5, -0.5, 0.0]
    run(dyn, world, lambda t: sp, 6.0)
    np.testing.assert_allclose(world.pos[0], [2.0, 1.0, 1.5], atol=1e-3)
    np.testing.assert_allclose(world.vel[1], [0.5, -0.5, 0.0], atol=1e-3)
    assert world.pos[1, 2] == pytest.approx(2.0, abs=0.05)
    np.testing.assert_allclose(world.pos[2], pos[2], atol=1e-9)


def test_coarse_physics_step_is_sub_stepped():
    """With physics_step = T_s (the engine default) the plugin integrates internally at max_step,
    so `dynamics=quadrotor` alone works and gives the same motion as an explicit 240 Hz clock."""
    target = Setpoints.hold(np.array([[1.0, 1.0, 2.0]]))
    target.mode[:] = Mode.POSITION
    dyn_a, wa = build([[0.0, 0.0, 1.0]])
    dyn_b, wb = build([[0.0, 0.0, 1.0]], physics=T_S)
    run(dyn_a, wa, lambda t: target, 3.0)
    run(dyn_b, wb, lambda t: target, 3.0, physics=T_S)
    np.testing.assert_allclose(wb.pos, wa.pos, atol=1e-9)
    np.testing.assert_allclose(wb.pos, target.pos, atol=1e-2)


def test_failed_agent_holds_level_where_it_is():
    pos = np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0]])
    dyn, world = build(pos)
    world.healthy[1] = False
    sp = Setpoints.hold(pos + [5.0, 0.0, 0.0])
    sp.mode[:] = Mode.POSITION
    run(dyn, world, lambda t: sp, 1.0)
    np.testing.assert_allclose(world.pos[1], pos[1], atol=1e-9)
    assert world.pos[0, 0] > 1.0


def test_yaw_setpoint_is_followed():
    dyn, world = build([[0.0, 0.0, 1.0]])
    sp = Setpoints.hold(np.array([[0.0, 0.0, 1.0]]), yaw=np.array([1.2]))
    run(dyn, world, lambda t: sp, 3.0)
    assert euler_zyx(quat_to_rotmat(world.quat))[0, 2] == pytest.approx(1.2, abs=1e-3)
    np.testing.assert_allclose(world.pos, [[0.0, 0.0, 1.0]], atol=1e-6)


def _leaves(numba_type):
    """The scalar types inside a (nested) numba tuple type."""
    inner = getattr(numba_type, "types", None)
    return [numba_type] if inner is None else [leaf for t in inner for leaf in _leaves(t)]


def test_float32_lanes_compute_in_float32():
    """The physics step's pieces, given float32 state and constants (``dynamics.dtype=float32``),
    compute and return float32 throughout: no float64 literal promotes them (kernels.lit)."""
    import numba

    from swarmscene.methods.quadrotor import kernels

    f = np.float32
    dyn, _ = build([[0.0, 0.0, 1.0]], dtype="float32")
    c = dyn._constants
    assert {value.dtype for value in c.values()} == {np.dtype(np.float32)}
    v, q = (f(0.1), f(-0.2), f(0.3)), (f(0.9), f(0.1), f(-0.3), f(0.2))
    R = tuple(tuple(f(x) for x in row) for row in kernels.rotmat(*q))  # boxed as Python floats
    calls = {
        "rotmat": (kernels.rotmat, q),
        "desired_force": (kernels.desired_force, (v, v, v, v, v, True, c["k_x"], c["k_v"], c["mass"],
                                                  c["min_lift"])),
        "cap_tilt": (kernels.cap_tilt, ((f(3.0), f(-2.0), f(0.2)), c["tan_max_tilt"])),
        "se3_control": (kernels.se3_control, ((f(0.1), f(0.0), f(0.3)), R, v, (f(0.0), f(1.0), f(0.0)), v, v,
                                              True, c["k_R"], c["k_Omega"], c["J"])),
        "allocate": (kernels.allocate, (f(0.3), v, c["mixer_inverse"], c["thrust_min"], c["thrust_max"],
                                        c["w2_min"], c["w2_max"])),
        "wind_load": (kernels.wind_load, (R, v, c["drag"], c["mass"], f(0.05))),
        "rk4": (kernels.rk4, (v, v, q, v, f(0.3), v, v, c["mass"], c["J"], c["gyro"], f(1 / 240))),
    }
    for name, (function, args) in calls.items():
        function(*args)
        signature = next(s for s in function.nopython_signatures if s.args[0] == numba.typeof(args[0]))
        assert set(_leaves(signature.return_type)) == {numba.float32}, (name, signature)


def test_float32_flight_stays_within_its_rounding_of_float64():
    """A lap of the circle in float32 and in float64: the same flight to well under a millimetre,
    but not the same bits (the step did run in float32); both track to millimetres."""
    laps = {}
    for dtype in ("float64", "float32"):
        dyn, world = build([[1.0, 0.0, 1.0]], dtype=dtype)
        world.vel[0] = [0.0, 1.0, 0.0]
        track: list[np.ndarray] = []
        run(dyn, world, circle_setpoints, 2 * np.pi, record=lambda w: track.append(w.pos[0].copy()))  # noqa: B023
        laps[dtype] = np.array(track)
    apart = np.abs(laps["float32"] - laps["float64"]).max()
    assert 1e-8 < apart < 1e-4
    reference = np.array([circle_setpoints(T_S * (k + 1)).pos[0] for k in range(len(laps["float32"]))])
    assert np.sqrt(np.mean(np.sum((laps["float32"] - reference) ** 2, axis=1))) < 0.01


def test_dtype_is_checked():
    with pytest.raises(pydantic.ValidationError, match="float64"):
        Quadrotor.Params(dtype="float16")
