"""Differential flatness and the SE(3) tracking controller on the rigid-body model, in their numpy
form (tests/oracles/quadrotor.py); tests/methods/quadrotor/test_kernels.py checks the compiled kernels against it."""

import numpy as np
import pytest
from oracles.quadrotor import (
    allocate,
    flat_inputs,
    flat_state,
    rk4_step,
    se3_control,
    step_rotors,
    taylor_propagate,
)

from swarmscene.methods.quadrotor.model import (
    CRAZYFLIE,
    GRAVITY,
    M330,
    euler_zyx,
    quat_to_rotmat,
    rotmat_to_quat,
    yaw_to_quat,
)
from swarmscene.methods.quadrotor.se3_controller import se3_gains

DT = 1.0 / 240.0


def lissajous(t):
    """A smooth 3-D trajectory with turning yaw: flat outputs p..p'''' and ψ, ψ̇, ψ̈ at times t (N,)."""
    w = np.array([0.9, 1.3, 0.7])
    amp = np.array([1.5, 1.0, 0.4])
    ph = w * t[:, None]
    derivs = [amp * np.cos(ph), -amp * w * np.sin(ph), -amp * w**2 * np.cos(ph),
              amp * w**3 * np.sin(ph), amp * w**4 * np.cos(ph)]
    yaw = 0.5 * np.sin(0.8 * t)
    return derivs, yaw, 0.4 * np.cos(0.8 * t), -0.32 * np.sin(0.8 * t)


def circle(t, radius=1.0, speed=1.0, z=1.0):
    w = speed / radius
    c, s, o = np.cos(w * t), np.sin(w * t), np.zeros_like(t)
    r = radius
    return [np.stack(x, axis=1) for x in (
        (r * c, r * s, o + z), (-r * w * s, r * w * c, o), (-r * w**2 * c, -r * w**2 * s, o),
        (r * w**3 * s, -r * w**3 * c, o), (r * w**4 * c, r * w**4 * s, o))]


def test_flat_state_of_hover_is_level_with_yaw():
    z3 = np.zeros((2, 3))
    ff = flat_state(z3, z3, z3, np.array([0.0, 2.0]))
    np.testing.assert_allclose(ff.thrust, GRAVITY)
    np.testing.assert_allclose(euler_zyx(ff.R), [[0, 0, 0], [0, 0, 2.0]], atol=1e-15)
    np.testing.assert_allclose(ff.omega, 0.0, atol=1e-15)


def test_flat_state_matches_finite_differences():
    """R is a rotation with thrust along a + g e_3 and ZYX yaw ψ; ω and α equal the numerical
    derivatives of R and ω (independent of the closed-form derivation)."""
    t = np.linspace(0.0, 6.0, 13)
    h = 1e-5

    def at(tt):
        (p, v, a, j, s), yaw, yr, ya = lissajous(tt)
        return flat_state(a, j, s, yaw, yr, ya), a, yaw

    ff, a, yaw = at(t)
    fp, _, _ = at(t + h)
    fm, _, _ = at(t - h)
    eye = np.broadcast_to(np.eye(3), ff.R.shape)
    np.testing.assert_allclose(np.einsum("nji,njk->nik", ff.R, ff.R), eye, atol=1e-12)
    np.testing.assert_allclose(ff.thrust[:, None] * ff.R[:, :, 2], a + [0, 0, GRAVITY], atol=1e-12)
    np.testing.assert_allclose(euler_zyx(ff.R)[:, 2], yaw, atol=1e-12)
    W = np.einsum("nji,njk->nik", ff.R, (fp.R - fm.R) / (2 * h))
    np.testing.assert_allclose(np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], 1), ff.omega, atol=1e-7)
    np.testing.assert_allclose((fp.omega - fm.omega) / (2 * h), ff.alpha, atol=1e-6)
    np.testing.assert_allclose((fp.thrust - fm.thrust) / (2 * h), ff.thrust_rate, atol=1e-7)


def test_flat_inputs_fly_the_trajectory_open_loop():
    """Feeding the flat thrust and torque to the rigid body, started on the trajectory, keeps it on
    the trajectory (1 s open loop, RK4): the endogenous transformation is the model's inverse."""
    af = M330
    t0 = np.array([0.3])
    (p, v, a, j, s), yaw, yr, ya = lissajous(t0)
    ff = flat_state(a, j, s, yaw, yr, ya)
    q, w = rotmat_to_quat(ff.R), ff.omega
    for k in range(240):
        (_, _, a, j, s), yaw, yr, ya = lissajous(t0 + (k + 0.5) * DT)  # midpoint inputs
        f, M = flat_inputs(flat_state(a, j, s, yaw, yr, ya), af.mass, af.J)
        p, v, q, w = rk4_step(p, v, q, w, f, M, af, DT)
    (p_ref, *_), yaw_ref, _, _ = lissajous(t0 + 1.0)
    assert np.linalg.norm(p - p_ref) < 1e-3
    assert euler_zyx(quat_to_rotmat(q))[0, 2] == pytest.approx(yaw_ref[0], abs=1e-3)


def test_taylor_propagation_is_exact_for_constant_snap():
    (p, v, a, j, s), *_ = lissajous(np.array([0.0]))
    tau = 0.1
    pp, vp, ap, jp = taylor_propagate(p, v, a, j, s, tau)
    np.testing.assert_allclose(vp, v + tau * a + tau**2 / 2 * j + tau**3 / 6 * s)
    np.testing.assert_allclose(jp, j + tau * s)
    np.testing.assert_allclose(pp, p + tau * v + tau**2 / 2 * a + tau**3 / 6 * j + tau**4 / 24 * s)


def fly(af, ref_fn, seconds, p0=None, yaw_fn=None, **gain_kw):
    gains = se3_gains(af, **gain_kw)
    p, v, a, j, s = ref_fn(np.array([0.0]))
    if p0 is not None:
        p = p0
    q, w = yaw_to_quat(np.zeros(1)), np.zeros((1, 3))
    errors, tilts = [], []
    for k in range(int(round(seconds / DT))):
        t = np.array([k * DT])
        pd, vd, ad, jd, sd = ref_fn(t)
        yaw, yr = (np.zeros(1), np.zeros(1)) if yaw_fn is None else yaw_fn(t)
        ff = flat_state(ad, jd, sd, yaw, yr)
        R = quat_to_rotmat(q)
        f, M, _ = se3_control(p, v, R, w, pd, vd, ad, yaw, ff.omega, ff.alpha, gains, af)
        p, v, q, w = step_rotors(p, v, q, w, allocate(f, M, af), af, DT)
        errors.append(np.linalg.norm(p - ref_fn(t + DT)[0]))
        tilts.append(np.arccos(np.clip(quat_to_rotmat(q)[0, 2, 2], -1, 1)))
    return np.array(errors), np.array(tilts), q


@pytest.mark.parametrize("af", [CRAZYFLIE, M330], ids=lambda a: a.name)
def test_circle_at_1_m_s_tracked_within_5_cm_rms(af):
    """One lap of a 1 m radius circle at 1 m/s with the nose turning along (ψ = t): RMS error is
    ~2 mm here (issue bound 5 cm), the heading follows."""
    errors, _, q = fly(af, circle, 2 * np.pi, yaw_fn=lambda t: (t * 1.0, np.ones(1)))
    assert np.sqrt(np.mean(errors**2)) < 0.05
    assert np.sqrt(np.mean(errors**2)) < 0.005  # what this controller actually achieves
    final_yaw = (np.round(2 * np.pi / DT) * DT + np.pi) % (2 * np.pi) - np.pi
    assert euler_zyx(quat_to_rotmat(q))[0, 2] == pytest.approx(final_yaw, abs=0.02)


def test_position_step_converges_with_tilt_capped():
    """A 5 m step: the tilt safeguard holds (<= 45 deg + overshoot of the attitude loop) and the
    vehicle settles on the target."""
    target = lambda t: [np.array([[5.0, 0.0, 1.0]])] + [np.zeros((1, 3))] * 4  # noqa: E731
    errors, tilts, _ = fly(M330, target, 4.0, p0=np.array([[0.0, 0.0, 1.0]]))
    assert tilts.max() < np.radians(50.0)
    assert errors[-1] < 1e-3


def test_attitude_recovers_from_large_tilt():
    af = CRAZYFLIE
    gains = se3_gains(af)
    p, v = np.zeros((1, 3)), np.zeros((1, 3))
    q = rotmat_to_quat(quat_to_rotmat(np.array([[np.cos(0.6), np.sin(0.6), 0.0, 0.0]])))  # 69 deg roll
    w = np.zeros((1, 3))
    z3 = np.zeros((1, 3))
    for _ in range(240):
        f, M, _ = se3_control(p, v, quat_to_rotmat(q), w, p, z3, z3, np.zeros(1), z3, z3, gains, af)
        p, v, q, w = step_rotors(p, v, q, w, allocate(f, M, af), af, DT)
    assert np.abs(euler_zyx(quat_to_rotmat(q))[0]).max() < 0.02
