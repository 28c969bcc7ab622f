"""The ``quadrotor`` plugin's compiled kernels against the numpy step they replaced
(tests/oracles/quadrotor.py, issue #20): per step to round-off over random states, every setpoint
mode, failed agents, feed-forward on and off, wind with a moment arm, motor failures and rotor
saturation; and over 10 s flights."""

from __future__ import annotations

import platform
import re
from types import SimpleNamespace

import numpy as np
import pytest
from oracles.quadrotor import QuadrotorOracle, desired_force, flat_state

from swarmscene.core.plugin import BuildContext
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.methods.quadrotor.flatness import heading_vector
from swarmscene.methods.quadrotor.model import AIRFRAMES
from swarmscene.plugins.dynamics.quadrotor import Quadrotor
from swarmscene.plugins.event.motor_failure import MotorFailure

T_S = 0.1
PHYSICS = 1.0 / 240.0
STATE = ("pos", "vel", "quat", "omega", "rotor_speed")
REFERENCES = ("_p", "_v", "_a", "_dv", "_da", "_dj", "_ds", "_position_mask", "_omega_d", "_alpha_d")
RTOL = 1e-12
"""Per step, relative to each array's largest entry: the kernel sums a few products in another
order than numpy's small matrix products (measured over the cases below: 2e-16 on p, 2e-14 on ω,
1.4e-13 on ϖ^2)."""


def pair(pos, **params):
    """The kernel plugin and the oracle, each with its own copy of the same world."""
    out = []
    for cls in (Quadrotor, QuadrotorOracle):
        world = WorldState.at_rest(np.array(pos, dtype=float))
        ctx = BuildContext(n=world.n, guidance_period=T_S, physics_step=PHYSICS, duration=10.0,
                           separation_limit=0.3, clearance_limit=0.3, comm_range=10.0, environment=None,
                           rng=np.random.default_rng(0), initial=world)
        dyn = cls(Quadrotor.Params(**params), ctx)
        dyn.initialize(world)
        out.append((dyn, world))
    return out


def random_state(rng, world, tumbling):
    """Positions, velocities, attitudes and body rates; ``tumbling``: any attitude, fast rates."""
    n = world.n
    world.pos[...] = rng.uniform(-5.0, 5.0, (n, 3))
    world.vel[...] = rng.normal(0.0, 2.0, (n, 3))
    q = rng.normal(size=(n, 4))
    if not tumbling:
        q[:, 1:] *= 0.2  # within ~25 deg of level
    world.quat[...] = q / np.linalg.norm(q, axis=1, keepdims=True)
    world.omega[...] = rng.normal(0.0, 8.0 if tumbling else 1.0, (n, 3))


def random_setpoints(rng, n, feedforward):
    sp = Setpoints(
        mode=rng.integers(0, 4, n).astype(np.int8),
        pos=rng.uniform(-8.0, 8.0, (n, 3)), vel=rng.normal(0.0, 2.0, (n, 3)),
        acc=rng.normal(0.0, 3.0, (n, 3)), yaw=rng.uniform(-np.pi, np.pi, n))
    if feedforward:
        sp.jerk = rng.normal(0.0, 5.0, (n, 3))
        sp.snap = None if feedforward == "jerk" else rng.normal(0.0, 20.0, (n, 3))
    return sp


def assert_same(kernel, oracle, names, what):
    for name in names:
        k, o = getattr(kernel, name), getattr(oracle, name)
        if name == "rotor_speed":
            # compare ϖ^2 (what thrust and torque see): a rotor the allocation drives to its
            # lower limit 0 ends at ϖ^2 = 0 ± ~1e-10 of round-off, and sqrt turns that into 1e-5
            k, o = k * k, o * o
        scale = max(1.0, float(np.abs(o).max()))
        assert np.abs(k - o).max() <= RTOL * scale, f"{what}: {name} differs by {np.abs(k - o).max():.3g}"


def fail_rotors(rng, dyns, worlds):
    """Two motor failures through the plugin's event hook: one rotor dead, one at 40 % thrust."""
    n = worlds[0].n
    for agents, rotor, fraction in ((rng.choice(n, 3, replace=False), 0, 0.0),
                                    (rng.choice(n, 3, replace=False), 2, 0.4)):
        event = MotorFailure.event(0.0, tuple(int(a) for a in agents), rotor=rotor, fraction=fraction)
        for dyn, world in zip(dyns, worlds, strict=True):
            dyn.swarmscene_event(sim=SimpleNamespace(world=world), event=event)


CASES = [
    # airframe, feed-forward, propagate, wind, motor failure, physics step (sub-steps), tumbling
    ("crazyflie", "snap", True, False, False, PHYSICS, False),
    ("crazyflie", "jerk", True, True, False, PHYSICS, False),
    ("crazyflie", None, True, True, True, T_S, True),
    ("m330", "snap", False, True, True, PHYSICS, True),
    ("m330", None, True, False, False, 0.01, False),
    ("m330", "snap", True, True, True, T_S, False),
]


@pytest.mark.parametrize("airframe, feedforward, propagate, wind, failure, physics, tumbling", CASES)
def test_kernel_step_matches_the_numpy_step(airframe, feedforward, propagate, wind, failure, physics,
                                            tumbling):
    """Random states and setpoints (all four modes, a fifth of the agents failed): the latched
    references agree exactly, and each physics step's state and rotor speeds agree to 1e-12."""
    rng = np.random.default_rng(len(airframe) + 7 * int(tumbling) + 13 * int(wind) + int(physics * 1e3))
    n = 150  # more than two of the kernel's blocks of lanes (kernels.BLOCK = 64), the last one partial
    (dk, wk), (do, wo) = pair(np.zeros((n, 3)), airframe=airframe, propagate_reference=propagate)
    if failure:
        fail_rotors(rng, (dk, do), (wk, wo))
    for _ in range(3):  # three ticks of random states: the reference moves (τ > 0) in each
        random_state(rng, wk, tumbling)
        healthy = rng.random(n) > 0.2
        sp = random_setpoints(rng, n, feedforward)
        for name in ("pos", "vel", "quat", "omega"):
            getattr(wo, name)[...] = getattr(wk, name)
        wk.healthy[...] = wo.healthy[...] = healthy
        gust = rng.normal(0.0, 6.0, (n, 3)) if wind else None
        wk.wind, wo.wind = gust, None if gust is None else gust.copy()
        wk.wind_moment_arm = wo.wind_moment_arm = 0.05 if wind else 0.0
        dk.control(wk, sp)
        do.control(wo, sp)
        for name in REFERENCES:  # same arithmetic, same order: bit for bit
            expected = getattr(do, name)
            expected = np.zeros((n, 3)) if expected is None else expected  # no feed-forward
            np.testing.assert_array_equal(getattr(dk, name), expected, err_msg=name)
        assert (dk._omega_d != 0).any() == (feedforward is not None)
        for _ in range(int(round(T_S / physics))):
            dk.step(wk, physics)
            do.step(wo, physics)
            assert_same(wk, wo, STATE, "state")


def test_random_cases_reach_every_safeguard():
    """The random cases above are not all gentle: the desired force hits the tilt cap and the
    minimum lift, and the allocation saturates rotors at both limits."""
    rng = np.random.default_rng(0)
    af = AIRFRAMES["crazyflie"]
    (dk, wk), _ = pair(np.zeros((60, 3)))
    random_state(rng, wk, tumbling=True)
    sp = random_setpoints(rng, 60, "snap")
    dk.control(wk, sp)
    F = desired_force(wk.pos, wk.vel, dk._p, dk._v, dk._a, dk.gains, af.mass, dk._position_mask, dk.max_tilt)
    capped = np.isclose(np.hypot(F[:, 0], F[:, 1]), F[:, 2] * np.tan(dk.max_tilt), rtol=1e-12)
    assert capped.any() and not capped.all()
    assert np.isclose(F[:, 2], 0.2 * af.mass * 9.81, rtol=1e-12).any()
    dk.step(wk, PHYSICS)
    assert (wk.rotor_speed == af.rotor_speed_max).any() and (wk.rotor_speed == 0.0).any()


def circle(n, t, centres):
    a = t + np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    c, s, z = np.cos(a), np.sin(a), np.zeros(n)
    vec = lambda x, y, zz: np.stack([x, y, zz], axis=1)  # noqa: E731
    return Setpoints(mode=np.full(n, Mode.TRACK, dtype=np.int8), pos=centres + vec(c, s, z),
                     vel=vec(-s, c, z), acc=vec(-c, -s, z), yaw=0.3 * np.ones(n), jerk=vec(s, -c, z),
                     snap=vec(c, s, z))


def test_ten_second_flights_agree():
    """30 quadrotors on circles for 10 s at 10 Hz guidance and 240 Hz physics under a gusty wind,
    two of them losing a rotor at 4 s (they fall and tumble): the kernel's trajectories stay on
    the oracle's. Measured: max |Δp| 4e-15 m for the flying ones, 4e-13 m for the falling,
    spinning ones (their motion amplifies round-off)."""
    n = 30
    centres = np.column_stack([np.arange(n) * 3.0, np.zeros(n), np.full(n, 20.0)])
    (dk, wk), (do, wo) = pair(centres + [1.0, 0.0, 0.0])
    rng = np.random.default_rng(5)
    worst = np.zeros(n)
    for k in range(100):
        if k == 40:
            event = MotorFailure.event(4.0, (3, 17), rotor=1, fraction=0.0)
            for dyn, world in ((dk, wk), (do, wo)):
                world.healthy[[3, 17]] = False
                dyn.swarmscene_event(sim=SimpleNamespace(world=world), event=event)
        sp = circle(n, wk.t, centres)
        dk.control(wk, sp)
        do.control(wo, sp)
        for _ in range(24):
            gust = rng.normal(0.0, 2.0, (n, 3)) + [4.0, 0.0, 0.0]
            wk.wind, wo.wind = gust, gust.copy()
            wk.wind_moment_arm = wo.wind_moment_arm = 0.03
            dk.step(wk, PHYSICS)
            do.step(wo, PHYSICS)
            worst = np.maximum(worst, np.linalg.norm(wk.pos - wo.pos, axis=1))
        wk.t = wo.t = (k + 1) * T_S
    failed = np.zeros(n, dtype=bool)
    failed[[3, 17]] = True
    assert worst[~failed].max() < 1e-12
    assert worst[failed].max() < 1e-9
    assert wk.pos[failed, 2].max() < 15.0  # they did fall


def test_flat_rates_match_the_oracle_with_turning_yaw():
    """The kernel's flatness (ω, α) with ψ̇, ψ̈ != 0 (the plugin passes zero; the formula is
    general) equals the numpy flat state to round-off."""
    from swarmscene.methods.quadrotor.kernels import flat_rates

    rng = np.random.default_rng(2)
    n = 20
    acc, jerk, snap = rng.normal(0, 3, (n, 3)), rng.normal(0, 5, (n, 3)), rng.normal(0, 20, (n, 3))
    yaw, yaw_rate, yaw_acc = rng.uniform(-3, 3, n), rng.normal(0, 1, n), rng.normal(0, 2, n)
    ff = flat_state(acc, jerk, snap, yaw, yaw_rate, yaw_acc)
    y_c = heading_vector(yaw)
    for i in range(n):
        omega, alpha = flat_rates(tuple(acc[i]), tuple(jerk[i]), tuple(snap[i]), tuple(y_c[i]),
                                  yaw_rate[i], yaw_acc[i])
        np.testing.assert_allclose(omega, ff.omega[i], rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(alpha, ff.alpha[i], rtol=1e-13, atol=1e-12)


@pytest.mark.parametrize("airframe", sorted(AIRFRAMES))
def test_kernel_rk4_conserves_energy_and_angular_momentum(airframe):
    """Motors off, tumbling in free fall, 2 s at 240 Hz through the kernel's own RK4: the energy
    ½ m v² + m g z + ½ ωᵀJω and the world angular momentum R J ω stay constant (the numpy oracle's
    test_model.py checks the same of its RK4)."""
    from swarmscene.methods.quadrotor.kernels import rk4, rotmat

    af = AIRFRAMES[airframe]
    J, gyro = np.array(af.J), np.array(af.gyro)
    x = np.array([0, 0, 50.0, 1.0, -0.5, 2.0, 1, 0, 0, 0, 3.0, -2.0, 5.0])

    def invariants(x):
        w = x[10:13]
        energy = 0.5 * af.mass * (x[3:6] ** 2).sum() + af.mass * 9.81 * x[2] + 0.5 * (J * w**2).sum()
        return energy, np.array(rotmat(*x[6:10])) @ (J * w)

    e0, L0 = invariants(x)
    for _ in range(480):
        p, v, q, w = rk4(tuple(x[0:3]), tuple(x[3:6]), tuple(x[6:10]), tuple(x[10:13]), 0.0, (0.0, 0.0, 0.0),
                         (0.0, 0.0, 0.0), af.mass, J, gyro, PHYSICS)
        x = np.concatenate([p, v, q, w])
    e1, L1 = invariants(x)
    assert e1 == pytest.approx(e0, rel=1e-8)
    np.testing.assert_allclose(L1, L0, rtol=1e-7, atol=1e-9 * np.abs(L0).max())
    assert np.linalg.norm(x[6:10]) == pytest.approx(1.0, abs=1e-15)
    assert np.abs(x[10:13] - [3.0, -2.0, 5.0]).max() > 0.1  # the gyroscopic term acted


PACKED_MULTIPLY = {"x86_64": r"\bv?mulpd\b", "amd64": r"\bv?mulpd\b", "aarch64": r"\bfmul\s+v\d+\.2d",
                   "arm64": r"\bfmul\s+v\d+\.2d"}
"""A float64 SIMD multiply in each architecture's assembly (SSE/AVX on x86-64, NEON on ARM64)."""


@pytest.mark.skipif(platform.machine().lower() not in PACKED_MULTIPLY, reason="reads x86-64 or ARM64 machine code")
@pytest.mark.parametrize("name", ["_force_lanes", "_step_lanes"])
def test_the_sub_step_loops_vectorise(name):
    """The two loops over a block's lanes compile to packed (SIMD) multiplies: a call, a branch, a
    signed index or an array the loop might write, added to the law, would quietly make them
    scalar again (2-3x slower). Compiled afresh (the cached code has no assembly to read)."""
    import numba

    from swarmscene.methods.quadrotor import kernels

    fresh = numba.njit(error_model="numpy")(getattr(kernels, name).py_func)
    lanes, taylor = np.zeros(kernels.ROWS * kernels.STRIDE), np.array([0.01, 5e-5, 1.7e-7, 4e-10, 1 / 240])
    af = AIRFRAMES["crazyflie"]
    three, four = (1.0, 1.0, 1.0), ((1.0, 0.0, 0.0, 0.0),) * 4
    args = {"_force_lanes": (4, lanes, taylor, 1.0, 1.0, af.mass, 0.2),
            "_step_lanes": (4, lanes, taylor, True, af.mass, three, three, three, three, four, four,
                            0.0, 1.0, 0.0, 1.0, True, 0.0, three, True)}[name]
    fresh(*args)
    packed = PACKED_MULTIPLY[platform.machine().lower()]
    assert re.search(packed, fresh.inspect_asm(fresh.signatures[0])), f"{name} compiled to scalar code"
