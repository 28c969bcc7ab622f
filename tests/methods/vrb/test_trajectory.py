"""VRB body trajectory (Zhou and Schwager, section II-III): keyframes, C^4, R_v and its derivatives."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene.methods.vrb.airshow import (
    CIRCLE_HEIGHT,
    CIRCLE_RADIUS,
    DURATION,
    airshow_keyframes,
)
from swarmscene.methods.vrb.trajectory import (
    ORDER,
    Keyframes,
    VRBTrajectory,
    minimum_snap,
    rotation_derivatives,
)


@pytest.fixture(scope="module")
def random_trajectory() -> tuple[Keyframes, VRBTrajectory]:
    rng = np.random.default_rng(7)
    t = np.cumsum(np.r_[0.0, rng.uniform(0.8, 3.0, 7)])
    derivs = np.full((t.size, ORDER, 6), np.nan)
    derivs[3, 0, :3] = [0.4, -0.2, 0.3]  # a velocity fixed in the middle (Fig. 4, K3)
    derivs[4, 1, 2] = -0.5  # an acceleration
    derivs[5, 0, 3] = 0.7  # a roll rate
    kf = Keyframes(t, rng.normal(size=(t.size, 3)), rng.normal(scale=0.8, size=(t.size, 3)), derivs)
    return kf, VRBTrajectory(kf)


@pytest.fixture(scope="module")
def airshow_trajectory() -> VRBTrajectory:
    return VRBTrajectory(airshow_keyframes())


def test_passes_through_keyframes_and_fixed_derivatives(random_trajectory):
    kf, traj = random_trajectory
    ch = traj.channels(kf.t)
    np.testing.assert_allclose(ch[0, :, :3], kf.pos, atol=1e-10)
    np.testing.assert_allclose(ch[0, :, 3:], kf.euler, atol=1e-10)
    np.testing.assert_allclose(ch[1, 3, :3], [0.4, -0.2, 0.3], atol=1e-10)
    assert ch[2, 4, 2] == pytest.approx(-0.5, abs=1e-10)
    assert ch[1, 5, 3] == pytest.approx(0.7, abs=1e-10)
    # ends at rest by default (take-off and landing), up to jerk
    np.testing.assert_allclose(ch[1:4, [0, -1]], 0.0, atol=1e-10)


def test_c4_at_every_knot(random_trajectory):
    _, traj = random_trajectory
    jumps = traj.knot_jumps()  # (5, K-2, 6)
    scale = np.abs(traj.channels(traj.keyframes.t)).max(axis=1)  # (5, 6)
    assert np.all(np.abs(jumps) <= 1e-8 * (1.0 + scale[:, None, :]))


def test_minimum_snap_optimality_gives_c6_at_free_knots():
    """Natural conditions of the snap functional: where a keyframe fixes no derivative, the optimum
    is also continuous in derivatives 5 and 6 (only 1..4 are imposed); where it fixes the velocity,
    the variation of p' vanishes there, so derivative 6 may jump (and does)."""
    t = np.array([0.0, 1.0, 2.5, 4.0])
    vals = np.array([0.0, 1.0, -0.5, 2.0])
    fixed = np.full((4, ORDER), np.nan)
    fixed[[0, -1], :3] = 0.0
    fixed[2, 0] = 3.0
    c = minimum_snap(t, vals, fixed)  # (3, 8) in normalised time
    h = np.diff(t)
    k = np.arange(8)

    def deriv_at(piece: int, s: float, n: int) -> float:
        fall = np.array([np.prod(np.arange(j - n + 1, j + 1)) if j >= n else 0.0 for j in k])
        return float(np.sum(c[piece] * fall * s ** np.maximum(k - n, 0)) / h[piece] ** n)

    for n in (5, 6):  # free knot 1: continuous
        assert deriv_at(0, 1.0, n) == pytest.approx(deriv_at(1, 0.0, n), rel=1e-7, abs=1e-7)
    assert deriv_at(1, 1.0, 5) == pytest.approx(deriv_at(2, 0.0, 5), rel=1e-7)
    assert abs(deriv_at(1, 1.0, 6) - deriv_at(2, 0.0, 6)) > 1.0  # fixed velocity: d^6 jumps


def test_single_rest_to_rest_piece_is_the_degree7_smoothstep():
    c = minimum_snap(np.array([0.0, 2.0]), np.array([0.0, 1.0]), np.r_[[[0.0, 0, 0, np.nan]] * 2])
    np.testing.assert_allclose(c[0], [0, 0, 0, 0, 35, -84, 70, -20], atol=1e-9)


def test_rotation_derivatives_match_finite_differences(random_trajectory):
    _, traj = random_trajectory
    t = np.linspace(0.2, traj.t_end - 0.2, 40)
    h = 1e-5
    mid, plus, minus = traj.evaluate(t), traj.evaluate(t + h), traj.evaluate(t - h)
    for n in range(1, ORDER + 1):
        fd = (plus.R[n - 1] - minus.R[n - 1]) / (2 * h)
        assert np.max(np.abs(fd - mid.R[n])) <= 1e-5 * (1.0 + np.max(np.abs(mid.R[n])))
    rtr = np.einsum("tji,tjk->tik", mid.R[0], mid.R[0])
    np.testing.assert_allclose(rtr, np.broadcast_to(np.eye(3), rtr.shape), atol=1e-12)


def test_angular_velocity_is_the_euler_rate_kinematics(random_trajectory):
    _, traj = random_trajectory
    st = traj.evaluate(np.linspace(0.0, traj.t_end, 30))
    (phi, theta, _), (dphi, dtheta, dpsi) = st.euler[0].T, st.euler[1].T
    expected = np.stack(
        [
            dphi - dpsi * np.sin(theta),
            dtheta * np.cos(phi) + dpsi * np.cos(theta) * np.sin(phi),
            -dtheta * np.sin(phi) + dpsi * np.cos(theta) * np.cos(phi),
        ],
        axis=1,
    )
    np.testing.assert_allclose(st.omega_body, expected, atol=1e-12)
    np.testing.assert_allclose(
        st.omega_world, np.einsum("tij,tj->ti", st.R[0], st.omega_body), atol=1e-12
    )


def test_zyx_convention_at_a_known_pose():
    e = np.zeros((ORDER + 1, 1, 3))
    e[0, 0] = [np.pi / 2, 0.0, np.pi / 2]  # roll 90 deg then yaw 90 deg
    R = rotation_derivatives(e)[0, 0]
    # body y (left wing) points up after the roll; body x points along world y after the yaw
    np.testing.assert_allclose(R @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_holds_end_pose_outside_the_keyframes(random_trajectory):
    kf, traj = random_trajectory
    ch = traj.channels([kf.t[0] - 1.0, kf.t[-1] + 5.0])
    np.testing.assert_allclose(ch[0, 0, :3], kf.pos[0], atol=1e-12)
    np.testing.assert_allclose(ch[0, 1, :3], kf.pos[-1], atol=1e-12)
    assert np.all(ch[1:] == 0.0)


def test_rejects_bad_keyframes():
    with pytest.raises(ValueError, match="strictly increasing"):
        Keyframes(np.array([0.0, 1.0, 1.0]), np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="shape"):
        Keyframes(np.array([0.0, 1.0]), np.zeros((3, 3)), np.zeros((2, 3)))


def test_airshow_keyframes_follow_section_iv(airshow_trajectory):
    kf = airshow_trajectory.keyframes
    assert kf.t.size == 30 and kf.t[0] == 0.0 and kf.t[-1] == DURATION == 71.0
    ch = airshow_trajectory.channels(kf.t)
    # K1 rest at the origin, K2 at 1.5 s above it, K3 at 6.5 s climbing (Fig. 4)
    np.testing.assert_allclose(ch[0, 0, :3], 0.0, atol=1e-12)
    assert kf.t[1] == 1.5 and ch[0, 1, 2] > 0.0 and np.allclose(ch[0, 1, :2], 0.0)
    assert kf.t[2] == 6.5 and ch[1, 2, 2] > 0.0
    # circle keyframes: on the circle, and a constant roll rate
    circle = slice(3, 28)
    np.testing.assert_allclose(np.hypot(ch[0, circle, 0], ch[0, circle, 1]), CIRCLE_RADIUS)
    np.testing.assert_allclose(ch[0, circle, 2], CIRCLE_HEIGHT)
    roll_rates = ch[1, circle, 3]
    assert np.ptp(roll_rates) < 1e-9 and roll_rates[0] > 0.0
    # lands level at rest at the origin
    np.testing.assert_allclose(ch[0, -1, :3], 0.0, atol=1e-12)
    assert np.cos(ch[0, -1, 3]) == pytest.approx(1.0)
    np.testing.assert_allclose(ch[1:4, -1], 0.0, atol=1e-12)


def test_airshow_body_stays_in_a_small_arena(airshow_trajectory):
    st = airshow_trajectory.evaluate(np.linspace(0.0, DURATION, 2001))
    assert np.max(np.linalg.norm(st.p[0, :, :2], axis=1)) < CIRCLE_RADIUS + 0.6
    assert st.p[0, :, 2].min() > -1e-9
    assert np.max(np.linalg.norm(st.p[1], axis=1)) < 1.5  # m/s, a tight indoor circle
