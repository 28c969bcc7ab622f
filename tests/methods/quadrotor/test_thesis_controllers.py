"""Thesis section 3.2 controllers: synthesised gains and the step responses of Fig. 3.5-3.15."""

import numpy as np
import pytest

from swarmscene.core.setpoint import Mode
from swarmscene.methods.quadrotor.thesis_controllers import (
    ThesisController,
    conjugate_poles,
    position_gains,
    position_gains_from_poles,
    sat,
    tracker_gains,
    velocity_gains,
    velocity_limiter,
)

T_S = 0.1
VG = velocity_gains(0.30, 0.80, T_S)
PG = position_gains(0.23, 0.71, T_S)
TG = tracker_gains(1.5, 0.71, T_S)


def simulate(mode, steps, u_sat, r0=0.0, r_ref=0.0, v_ref=0.0, v_lim=None, n=1):
    """Close the loop on the thesis' discrete double integrator (eq. 3.21-3.22), axis x only."""
    ctrl = ThesisController(n, VG, PG, TG, u_sat)
    r = np.zeros((n, 3))
    r[:, 0] = r0
    v = np.zeros((n, 3))
    modes = np.full(n, mode, dtype=np.int8)
    rr = np.zeros((n, 3))
    vr = np.zeros((n, 3))
    rr[:, 0] = r_ref
    vr[:, 0] = v_ref
    out = {"r": [], "v": [], "u": []}
    for k in range(steps):
        lim = None if v_lim is None else v_lim(k * T_S)
        u = ctrl.step(modes, r, v, rr, vr, np.zeros((n, 3)), lim)
        out["r"].append(r[0, 0])
        out["v"].append(v[0, 0])
        out["u"].append(u[0, 0])
        r = r + T_S * v + 0.5 * T_S**2 * u
        v = v + T_S * u
    return {k: np.array(a) for k, a in out.items()}


def settling_time(y, final, band=0.05, scale=None):
    """First time after which |y - final| stays within band * scale (5 % band)."""
    scale = abs(final) if scale is None else scale
    outside = np.flatnonzero(np.abs(y - final) > band * scale)
    return 0.0 if outside.size == 0 else (outside[-1] + 1) * T_S


def test_velocity_gains_reproduce_thesis():
    assert (round(VG.K_Pv, 1), round(VG.K_Iv, 1), round(VG.K_Fv, 1)) == (9.0, 1.4, 7.0)


def test_position_gains_reproduce_thesis():
    assert round(PG.K_Pr, 2) == 0.10
    assert round(PG.K_Ir, 5) == 0.00084
    assert round(PG.K_Dr, 2) == 0.48
    assert round(PG.K_Fr, 3) == 0.052


def test_tracker_gains_reproduce_thesis():
    assert (round(TG.K_Pt, 1), round(TG.K_It, 2), round(TG.K_Dt, 1)) == (4.1, 0.20, 2.9)


def test_synthesised_gains_place_the_poles():
    """Characteristic polynomial of eq. 3.33-3.35 has the requested roots."""
    p = conjugate_poles(0.23, 0.71, T_S)
    g = position_gains_from_poles(*p, T_S)
    a2 = T_S**2 / 2 * g.K_Pr + T_S * g.K_Dr - 3
    a1 = T_S**2 / 2 * g.K_Ir - 2 * T_S * g.K_Dr + 3
    a0 = T_S**2 / 2 * (g.K_Ir - g.K_Pr) + T_S * g.K_Dr - 1
    roots = np.sort_complex(np.roots([1, a2, a1, a0]))
    np.testing.assert_allclose(roots, np.sort_complex(np.array(p, dtype=complex)), atol=1e-9)
    # and the zero b_0 = 1 - K_I / K_F cancels the real pole (eq. 3.37)
    assert 1 - g.K_Ir / g.K_Fr == pytest.approx(p[2])
    with pytest.raises(ValueError):
        velocity_gains(0.8, 0.3, T_S)


def test_velocity_step_fig_3_5():
    """0.5 m/s step, u_sat = 3.4: settles in ~0.3 s (5 % band), no overshoot."""
    out = simulate(Mode.VELOCITY, 30, 3.4, v_ref=0.5)
    assert settling_time(out["v"], 0.5) == pytest.approx(0.3, abs=0.05)
    assert out["v"].max() <= 0.5 + 1e-9


def test_velocity_excessive_step_fig_3_6_no_windup():
    """A step ten times larger saturates; the anti-windup K_Wv = 0.5 keeps overshoot small."""
    out = simulate(Mode.VELOCITY, 60, 3.4, v_ref=5.0)
    assert np.abs(out["u"]).max() == pytest.approx(3.4)
    assert out["v"].max() < 5.0 * 1.02


def test_position_step_fig_3_8():
    """50 m step with u_sat = 2.6: settles in ~13 s, overshoot below 5 %, input just at u_sat."""
    out = simulate(Mode.POSITION, 400, 2.6, r_ref=50.0)
    assert settling_time(out["r"], 50.0) == pytest.approx(13.0, abs=1.0)
    assert 0.0 < out["r"].max() / 50.0 - 1.0 < 0.05
    assert np.abs(out["u"]).max() <= 2.6 + 1e-12
    assert out["r"][-1] == pytest.approx(50.0, rel=0.01)


def test_position_excessive_step_fig_3_9():
    """Ten times the step: saturated, K_Wr = 50 keeps the overshoot modest and it converges."""
    out = simulate(Mode.POSITION, 1500, 2.6, r_ref=500.0)
    assert out["r"].max() < 500.0 * 1.05
    assert out["r"][-1] == pytest.approx(500.0, abs=0.5)


def test_tracker_initial_error_fig_3_11_and_3_13():
    """2.5 m initial error: without saturation ~30 % undershoot, settling ~5 s (Fig. 3.11);
    with u_sat = 3.4 ~3 s and no undershoot (Fig. 3.13)."""
    free = simulate(Mode.TRACK, 100, 1e9, r0=2.5)
    assert -free["r"].min() / 2.5 == pytest.approx(0.30, abs=0.06)
    assert settling_time(free["r"], 0.0, scale=2.5, band=0.02) == pytest.approx(5.0, abs=0.5)
    sat_ = simulate(Mode.TRACK, 100, 3.4, r0=2.5)
    assert settling_time(sat_["r"], 0.0, scale=2.5) == pytest.approx(3.0, abs=0.4)
    assert -sat_["r"].min() / 2.5 < 0.01


def test_velocity_limiter_fig_3_15():
    """100 m step, limit 3 m/s for 10 s then 2 m/s, released at 30 s: |v| never exceeds the
    limit in force (after a step down it decays monotonically onto the new one), then r -> 100."""
    limit = lambda t: 3.0 if t < 10.0 - 1e-9 else (2.0 if t < 30.0 - 1e-9 else 1e3)  # noqa: E731
    out = simulate(Mode.POSITION, 800, 2.6, r_ref=100.0, v_lim=limit)
    t = np.arange(800) * T_S
    v = np.abs(out["v"])
    assert np.all(v[t <= 10.0] <= 3.0 + 1e-9)
    assert v[t <= 10.0].max() == pytest.approx(3.0, abs=1e-3)
    down = (t > 10.0) & (t < 12.0)
    assert np.all(np.diff(v[down]) <= 1e-12) and np.all(v[down] <= 3.0)
    assert np.all(v[(t >= 12.0) & (t <= 30.0)] <= 2.0 + 0.01)
    assert np.abs(out["u"]).max() <= 2.6 + 1e-12
    assert out["r"][-1] == pytest.approx(100.0, abs=0.1)


def test_velocity_limiter_law_eq_3_45():
    u_inf = np.array([[5.0, -5.0, 5.0]])
    v = np.array([[1.0, -1.0, 0.3]])
    # v > 0: min(u_inf, -K(v - lim)); v <= 0: max(u_inf, -K(v + lim))
    np.testing.assert_allclose(velocity_limiter(u_inf, v, 2.0, 2.5, 0.0), [[2.5, -2.5, 4.25]])
    np.testing.assert_allclose(velocity_limiter(u_inf, v, np.array([3.0]), 2.5, 0.0),
                               [[5.0, -5.0, 5.0]])
    # a limit below the anti-chattering threshold brakes smoothly: u = -K_lim v
    np.testing.assert_allclose(velocity_limiter(u_inf, v, 0.2, 2.5, 0.3), -2.5 * v)
    np.testing.assert_allclose(sat(np.array([-3.0, 1.0, 4.0]), 2.6), [-2.6, 1.0, 2.6])


def test_anti_chattering_threshold_reduces_switching():
    """Fig. 3.16-3.17: 100 m step, the limit drops to ~0 at t = 1 s with sigma_n = 0.1 m/s noise on
    v and r. Without threshold u_lim keeps switching between u_inf and u_+/-; eps_lim = 3 sigma_n
    brakes with u_~ = -K_lim v instead, leaving only the noise times K_lim."""

    def mean_jump(eps):
        rng = np.random.default_rng(1)
        ctrl = ThesisController(1, VG, PG, TG, 2.6, eps_lim=eps)
        r, v, us = np.zeros((1, 3)), np.zeros((1, 3)), []
        for k in range(130):
            lim = 1e3 if k < 10 else 0.01
            noise = np.zeros((2, 3))
            noise[:, 0] = rng.normal(0.0, 0.1, 2)
            u = ctrl.step(np.array([Mode.POSITION]), r + noise[0], v + noise[1],
                          np.array([[100.0, 0, 0]]), np.zeros((1, 3)), np.zeros((1, 3)), lim)
            us.append(u[0, 0])
            r, v = r + T_S * v + 0.5 * T_S**2 * u, v + T_S * u
        return float(np.abs(np.diff(us[40:])).mean())

    assert mean_jump(0.0) > 2.0 * mean_jump(0.3)


def test_per_agent_modes_match_single_agent_runs():
    """Agents with different modes in one controller behave as each alone, and the position law
    is shift-invariant thanks to the bumpless start (a step from r = 1000 m looks like from 0)."""
    ctrl = ThesisController(3, VG, PG, TG, 2.6)
    modes = np.array([Mode.POSITION, Mode.VELOCITY, Mode.TRACK], dtype=np.int8)
    r = np.array([[1000.0, 0, 0], [0, 0, 0], [2.5, 0, 0]])
    v = np.zeros((3, 3))
    r_ref = np.array([[1050.0, 0, 0], [0, 0, 0], [0, 0, 0]])
    v_ref = np.array([[0, 0, 0], [0.5, 0, 0], [0, 0, 0]])
    xs = []
    for _ in range(200):
        u = ctrl.step(modes, r, v, r_ref, v_ref, np.zeros((3, 3)))
        xs.append(r[:, 0].copy())
        r, v = r + T_S * v + 0.5 * T_S**2 * u, v + T_S * u
    xs = np.array(xs)
    pos = simulate(Mode.POSITION, 200, 2.6, r_ref=50.0)["r"]
    trk = simulate(Mode.TRACK, 200, 2.6, r0=2.5)["r"]
    vel = simulate(Mode.VELOCITY, 200, 2.6, v_ref=0.5)["r"]
    np.testing.assert_allclose(xs[:, 0] - 1000.0, pos, atol=1e-9)
    np.testing.assert_allclose(xs[:, 1], vel, atol=1e-9)
    np.testing.assert_allclose(xs[:, 2], trk, atol=1e-9)


def test_mode_switch_to_hold_is_bumpless():
    """An agent cruising in VELOCITY mode that switches to HOLD at its current position brakes
    with the derivative term only (no kick from the absolute position)."""
    ctrl = ThesisController(1, VG, PG, TG, 2.6)
    r, v = np.array([[500.0, -300.0, 20.0]]), np.array([[1.0, 0.0, 0.0]])
    z = np.zeros((1, 3))
    ctrl.step(np.array([Mode.VELOCITY]), r, v, z, v, z)
    u = ctrl.step(np.array([Mode.HOLD]), r, v, r.copy(), z, z)
    np.testing.assert_allclose(u, -PG.K_Dr * v, atol=1e-9)
