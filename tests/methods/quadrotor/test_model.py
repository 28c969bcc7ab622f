"""Rigid-body quadrotor (thesis eq. 3.4-3.16): mixer, limits and physics with independent answers.

The allocation, wrench and RK4 are checked in their numpy form (tests/oracles/quadrotor.py);
tests/methods/quadrotor/test_kernels.py checks the compiled kernels against it."""

import numpy as np
import pytest
from oracles.quadrotor import allocate, rk4_step, step_rotors, wrench

from swarmscene.methods.quadrotor.model import (
    AIRFRAMES,
    CRAZYFLIE,
    GRAVITY,
    M330,
    THESIS_TO_FLU_WRENCH,
    euler_zyx,
    quat_to_rotmat,
    rotmat_to_quat,
    thesis_mixer_matrix,
    yaw_to_quat,
)

DT = 1.0 / 240.0


def rest(n, z=1.0, yaw=None):
    p = np.zeros((n, 3))
    p[:, 2] = z
    yaw = np.zeros(n) if yaw is None else yaw
    return p, np.zeros((n, 3)), yaw_to_quat(yaw), np.zeros((n, 3))


@pytest.mark.parametrize("af", [CRAZYFLIE, M330], ids=lambda a: a.name)
def test_mixer_and_inverse_are_inverses(af):
    np.testing.assert_allclose(af.mixer @ af.mixer_inverse, np.eye(4), atol=1e-9)
    rng = np.random.default_rng(0)
    speeds = rng.uniform(0.3, 0.9, (50, 4)) * af.rotor_speed_max
    thrust, torque = wrench(speeds, af)
    np.testing.assert_allclose(allocate(thrust, torque, af), speeds, rtol=1e-9)
    # the thesis' inverse has orthogonal columns: T^-1 = T^T diag(1 / (4 row_i . row_i))
    T = thesis_mixer_matrix(af.arm, af.k_T, af.k_D)
    np.testing.assert_allclose(np.linalg.inv(T), T.T / (T * T).sum(axis=1), rtol=1e-12)


def test_mixer_is_the_thesis_matrix_in_engine_frames():
    """Eq. 3.13-3.15 (NED, FRD body) converted to z-up FLU: T -> -F_z, M_y -> -M_y, M_z -> -M_z."""
    for af in AIRFRAMES.values():
        T = thesis_mixer_matrix(af.arm, af.k_T, af.k_D)
        np.testing.assert_allclose(af.mixer, THESIS_TO_FLU_WRENCH @ T, rtol=1e-12)
    # the front-right rotor (1) alone lifts the right side: negative roll, nose up (negative pitch)
    _, torque = wrench(np.array([[1000.0, 0, 0, 0]]), M330)
    assert torque[0, 0] < 0 and torque[0, 1] < 0


@pytest.mark.parametrize("af", [CRAZYFLIE, M330], ids=lambda a: a.name)
def test_hover_needs_mg_and_stays_put(af):
    speeds = allocate(np.full(3, af.mass * GRAVITY), np.zeros((3, 3)), af)
    np.testing.assert_allclose(speeds, af.hover_rotor_speed, rtol=1e-12)
    thrust, torque = wrench(speeds, af)
    np.testing.assert_allclose(thrust, af.mass * GRAVITY, rtol=1e-12)
    p0, v, q, w = rest(3, yaw=np.array([0.0, 1.0, -2.0]))
    p = p0
    for _ in range(int(2.0 / DT)):
        p, v, q, w = step_rotors(p, v, q, w, speeds, af, DT)
    np.testing.assert_allclose(p, p0, atol=1e-9)
    np.testing.assert_allclose(w, 0.0, atol=1e-12)


@pytest.mark.parametrize("af", [CRAZYFLIE, M330], ids=lambda a: a.name)
def test_free_fall_with_motors_off_follows_g_t2_over_2(af):
    p, v, q, w = rest(2, z=100.0)
    steps = int(3.0 / DT)
    for _ in range(steps):
        p, v, q, w = step_rotors(p, v, q, w, np.zeros((2, 4)), af, DT)
    t = steps * DT
    np.testing.assert_allclose(p[:, 2], 100.0 - 0.5 * GRAVITY * t**2, rtol=1e-12)
    np.testing.assert_allclose(v[:, 2], -GRAVITY * t, rtol=1e-12)
    np.testing.assert_allclose(p[:, :2], 0.0, atol=1e-12)


def test_pure_yaw_torque_changes_only_yaw():
    af = M330
    Mz = 0.02
    speeds = allocate(np.array([af.mass * GRAVITY]), np.array([[0.0, 0.0, Mz]]), af)
    thrust, torque = wrench(speeds, af)
    np.testing.assert_allclose(torque, [[0.0, 0.0, Mz]], atol=1e-15)
    p0, v, q, w = rest(1, yaw=np.array([0.3]))
    p = p0
    t = 1.5
    for _ in range(int(round(t / DT))):
        p, v, q, w = step_rotors(p, v, q, w, speeds, af, DT)
    roll, pitch, yaw = euler_zyx(quat_to_rotmat(q))[0]
    assert abs(roll) < 1e-12 and abs(pitch) < 1e-12
    assert yaw == pytest.approx(0.3 + 0.5 * Mz / af.inertia[2] * t**2, rel=1e-9)
    np.testing.assert_allclose(w[0, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(p, p0, atol=1e-9)


@pytest.mark.parametrize("af", [CRAZYFLIE, M330], ids=lambda a: a.name)
def test_energy_and_angular_momentum_conserved_without_input(af):
    """Motors off, tumbling in free fall: E = ½ m v² + m g z + ½ ωᵀJω and the world angular
    momentum R J ω are constants of the motion (asymmetric spin about all three axes)."""
    p, v, q, _ = rest(1, z=50.0)
    v = np.array([[1.0, -0.5, 2.0]])
    w = np.array([[3.0, -2.0, 5.0]])
    J = af.J

    def invariants(p, v, q, w):
        energy = 0.5 * af.mass * (v**2).sum() + af.mass * GRAVITY * p[0, 2] + 0.5 * (J * w**2).sum()
        return energy, quat_to_rotmat(q)[0] @ (J * w[0])

    e0, L0 = invariants(p, v, q, w)
    zero = np.zeros(1), np.zeros((1, 3))
    for _ in range(int(2.0 / DT)):
        p, v, q, w = rk4_step(p, v, q, w, *zero, af, DT)
    e1, L1 = invariants(p, v, q, w)
    assert e1 == pytest.approx(e0, rel=1e-8)
    np.testing.assert_allclose(L1, L0, rtol=1e-7, atol=1e-9 * np.abs(L0).max())
    assert np.abs(w).max() > 1.0  # still tumbling: the test exercised the gyroscopic term


def test_rotor_limits_keep_thrust_and_torque_direction():
    af = CRAZYFLIE
    # an impossible roll torque: thrust is kept, torque shrinks along its own direction
    want = np.array([[1e-2, 5e-3, 0.0]])
    speeds = allocate(np.array([af.mass * GRAVITY]), want, af)
    assert np.all(speeds <= af.rotor_speed_max + 1e-9) and np.all(speeds >= af.rotor_speed_min)
    thrust, torque = wrench(speeds, af)
    assert thrust[0] == pytest.approx(af.mass * GRAVITY)
    cos = torque[0] @ want[0] / np.linalg.norm(torque[0]) / np.linalg.norm(want[0])
    assert cos == pytest.approx(1.0) and np.linalg.norm(torque) < np.linalg.norm(want)
    # too much thrust is clipped to four rotors at full speed
    speeds = allocate(np.array([10.0]), np.zeros((1, 3)), af)
    np.testing.assert_allclose(speeds, af.rotor_speed_max)
    # and step_rotors clips commands outside the range
    p, v, q, w = rest(1)
    p1, v1, *_ = step_rotors(p, v, q, w, np.full((1, 4), 1e6), af, DT)
    assert v1[0, 2] == pytest.approx((af.max_thrust / af.mass - GRAVITY) * DT)


def test_quaternion_helpers_round_trip():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.sign(q[:, :1])
    R = quat_to_rotmat(q)
    np.testing.assert_allclose(np.einsum("nji,njk->nik", R, R), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)
    np.testing.assert_allclose(rotmat_to_quat(R), q, atol=1e-12)
    np.testing.assert_allclose(euler_zyx(quat_to_rotmat(yaw_to_quat(np.array([0.7]))))[0],
                               [0, 0, 0.7], atol=1e-15)
