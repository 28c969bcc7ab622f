"""Compiled kernels of the ``quadrotor`` dynamics: one call per guidance tick, one per physics step.

:func:`latch_references` is ``Quadrotor.control`` (the references of a tick and their flatness
feed-forward) and :func:`step_swarm` is ``Quadrotor.step`` (all sub-steps of one physics step:
reference propagation, SE(3) control, allocation, rotor health, wind and RK4), for all agents in
one call. Each loops over agents with scalar arithmetic, 3-vectors as tuples, in the order of the
numpy formulas they replace (tests/oracles/quadrotor.py), so the two agree to round-off: only the
summation order inside numpy's small matrix products may differ.

Frames as in model.py: world z up, body front-left-up, thrust along +z_b, q = (w, x, y, z) body to
world. Lee, Leok and McClamroch (2010)'s symbols: e_x, e_v position and velocity errors, F the
desired force, f the collective thrust, R_d = [b_1d, b_2d, b_3d], e_R, e_Ω the attitude and rate
errors, M the moment, k_x, k_v, k_R, k_Ω the gains (se3_controller.py). Thesis (Karydes 2020)
equations 3.4-3.16 for the rigid body and mixer.

This module imports numba; the plugin imports it inside ``Quadrotor.__init__`` so that listing
plugins never pays for numba (start-up).
"""

from __future__ import annotations

import math

import numba
import numpy as np

GRAVITY = 9.81
"""g, m/s^2 (model.GRAVITY; repeated so that this module has no import chain to compile)."""

POSITION, VELOCITY, TRACK, HOLD = 0, 1, 2, 3
"""core.setpoint.Mode values."""


# --------------------------------------------------------------------------- 3-vector helpers


@numba.njit(cache=True)
def _cross(a, b):
    """a × b, in cross_rows' order: (a_1 b_2 - a_2 b_1, a_2 b_0 - a_0 b_2, a_0 b_1 - a_1 b_0)."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@numba.njit(cache=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True)
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@numba.njit(cache=True)
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@numba.njit(cache=True)
def _scale(s, a):
    return (s * a[0], s * a[1], s * a[2])


@numba.njit(cache=True)
def _div(a, s):
    return (a[0] / s, a[1] / s, a[2] / s)


@numba.njit(cache=True)
def _columns(R):
    """The columns of a 3x3 matrix held as three row tuples."""
    return ((R[0][0], R[1][0], R[2][0]), (R[0][1], R[1][1], R[2][1]), (R[0][2], R[1][2], R[2][2]))


@numba.njit(cache=True)
def _row(m, i):
    return (m[i, 0], m[i, 1], m[i, 2])


# --------------------------------------------------------------------------- flatness (tick)


@numba.njit(cache=True)
def normalize_with_derivatives(n, n_dot, n_ddot):
    """u = n / ν, ν = |n|, and its derivatives: u̇ = (ṅ - ν̇ u) / ν, ü = (n̈ - ν̈ u - 2 ν̇ u̇) / ν
    with ν̇ = u·ṅ, ν̈ = u̇·ṅ + u·n̈."""
    nu = math.sqrt(_dot(n, n))
    u = _div(n, nu)
    nu_dot = _dot(u, n_dot)
    u_dot = _div(_sub(n_dot, _scale(nu_dot, u)), nu)
    nu_ddot = _dot(u_dot, n_dot) + _dot(u, n_ddot)
    u_ddot = _div(_sub(_sub(n_ddot, _scale(nu_ddot, u)), _scale(2.0 * nu_dot, u_dot)), nu)
    return u, u_dot, u_ddot


@numba.njit(cache=True)
def flat_rates(acc, jerk, snap, y_c, yaw_rate, yaw_acc):
    """Body rates ω and angular acceleration α (body frame) of flat outputs (Mellinger and Kumar
    2011, sec. III; VRB paper sec. III), for one agent.

    Args:
        acc: p̈ (world, 3-tuple).
        jerk: p⃛ (world, 3-tuple).
        snap: p⁗ (world, 3-tuple).
        y_c: (-sin ψ, cos ψ, 0), the heading vector (flatness.heading_vector).
        yaw_rate: ψ̇.
        yaw_acc: ψ̈.

    z_b = t / |t| with t = a + g e_3 (ṫ = j, ẗ = s); x_b = (y_c × z_b) / |y_c × z_b|,
    y_b = z_b × x_b; R^T Ṙ = [ω×] (eq. 3.6) gives ω = (z_b·ẏ_b, x_b·ż_b, y_b·ẋ_b) and α its
    derivative.
    """
    t = (acc[0] + 0.0, acc[1] + 0.0, acc[2] + GRAVITY)
    z, z_d, z_dd = normalize_with_derivatives(t, jerk, snap)
    s, c = -y_c[0], y_c[1]
    y_c_d = (yaw_rate * -c, yaw_rate * -s, yaw_rate * 0.0)
    r2 = yaw_rate * yaw_rate
    y_c_dd = (yaw_acc * -c + r2 * s, yaw_acc * -s + r2 * -c, yaw_acc * 0.0 + r2 * 0.0)
    m = _cross(y_c, z)
    m_d = _add(_cross(y_c_d, z), _cross(y_c, z_d))
    m_dd = _add(_add(_cross(y_c_dd, z), _scale(2.0, _cross(y_c_d, z_d))), _cross(y_c, z_dd))
    x, x_d, x_dd = normalize_with_derivatives(m, m_d, m_dd)
    y = _cross(z, x)
    y_d = _add(_cross(z_d, x), _cross(z, x_d))
    y_dd = _add(_add(_cross(z_dd, x), _scale(2.0, _cross(z_d, x_d))), _cross(z, x_dd))
    omega = (_dot(z, y_d), _dot(x, z_d), _dot(y, x_d))
    alpha = (_dot(z_d, y_d) + _dot(z, y_dd), _dot(x_d, z_d) + _dot(x, z_dd), _dot(y_d, x_d) + _dot(y, x_dd))
    return omega, alpha


@numba.njit(cache=True)
def latch_references(healthy, mode, sp_pos, sp_vel, sp_acc, sp_jerk, sp_snap, pos, heading,
                     propagate, feedforward,
                     p_ref, v_ref, a_ref, dv, da, dj, ds, position_mask, omega_d, alpha_d):
    """One guidance tick's references, written in place (``Quadrotor.control``).

    A failed agent holds where it is (HOLD at ``pos``). HOLD zeroes v_d, a_d and the flatness
    input; VELOCITY drops the position error (``position_mask`` False); on TRACK rows (when
    ``propagate``) the Taylor coefficients dv, da, dj, ds carry v, a, jerk, snap, zero elsewhere.
    With ``feedforward`` (the setpoints carry jerk or snap) Ω_d, Ω̇_d are the flat rates of
    (a_d, jerk, snap, ψ) with ψ̇ = ψ̈ = 0 (:func:`flat_rates`), else zero.
    """
    for i in range(pos.shape[0]):
        m = mode[i] if healthy[i] else HOLD
        hold = m == HOLD
        track = m == TRACK and propagate
        position_mask[i] = m != VELOCITY
        for k in range(3):
            p_ref[i, k] = sp_pos[i, k] if healthy[i] else pos[i, k]
            v_ref[i, k] = 0.0 if hold else sp_vel[i, k]
            a_ref[i, k] = 0.0 if hold else sp_acc[i, k]
            dv[i, k] = v_ref[i, k] if track else 0.0
            da[i, k] = a_ref[i, k] if track else 0.0
            dj[i, k] = sp_jerk[i, k] if track else 0.0
            ds[i, k] = sp_snap[i, k] if track else 0.0
        if feedforward:
            jerk = (0.0, 0.0, 0.0) if hold else _row(sp_jerk, i)
            snap = (0.0, 0.0, 0.0) if hold else _row(sp_snap, i)
            w, a = flat_rates(_row(a_ref, i), jerk, snap, _row(heading, i), 0.0, 0.0)
        else:
            w = a = (0.0, 0.0, 0.0)
        for k in range(3):
            omega_d[i, k] = w[k]
            alpha_d[i, k] = a[k]


# --------------------------------------------------------------------------- SE(3) control (step)


@numba.njit(cache=True)
def rotmat(q0, q1, q2, q3):
    """R_b^o of q = (w, x, y, z) as three row tuples; each entry summed in the order of the rows of
    model._R_BASIS (the oracle's quadratic form)."""
    ww, xx, yy, zz = q0 * q0, q1 * q1, q2 * q2, q3 * q3
    return ((ww + xx - yy - zz, -2.0 * (q0 * q3) + 2.0 * (q1 * q2), 2.0 * (q0 * q2) + 2.0 * (q1 * q3)),
            (2.0 * (q0 * q3) + 2.0 * (q1 * q2), ww - xx + yy - zz, -2.0 * (q0 * q1) + 2.0 * (q2 * q3)),
            (-2.0 * (q0 * q2) + 2.0 * (q1 * q3), 2.0 * (q0 * q1) + 2.0 * (q2 * q3), ww - xx - yy + zz))


@numba.njit(cache=True)
def desired_force(p, v, p_d, v_d, a_d, position, k_x, k_v, mass, tan_max_tilt, min_lift):
    """F = -k_x e_x - k_v e_v + m g e_3 + m a_d (Lee et al.'s desired force, z up), e_x dropped when
    not ``position``; F_z kept >= ``min_lift`` m g and the tilt of F capped (|F_xy| <= F_z tan)."""
    w = 1.0 if position else 0.0
    F0 = -k_x * ((p[0] - p_d[0]) * w) - k_v * (v[0] - v_d[0]) + mass * a_d[0]
    F1 = -k_x * ((p[1] - p_d[1]) * w) - k_v * (v[1] - v_d[1]) + mass * a_d[1]
    F2 = -k_x * ((p[2] - p_d[2]) * w) - k_v * (v[2] - v_d[2]) + mass * a_d[2]
    F2 = max(F2 + mass * GRAVITY, min_lift * mass * GRAVITY)
    shrink = min(1.0, F2 * tan_max_tilt / max(math.hypot(F0, F1), 1e-12))
    return (F0 * shrink, F1 * shrink, F2)


@numba.njit(cache=True)
def attitude_torque(R, omega, R_d, omega_d, alpha_d, feedforward, k_R, k_Omega, J):
    """Lee et al.'s moment (body FLU), A = R_d^T R:
    e_R = ½ (A - A^T)^∨, e_Ω = Ω - A^T Ω_d,
    M = -k_R e_R - k_Ω e_Ω + Ω × J Ω - J (Ω × A^T Ω_d - A^T Ω̇_d) (Ω_d = Ω̇_d = 0 without
    ``feedforward``)."""
    c0, c1, c2 = _columns(R)
    d0, d1, d2 = _columns(R_d)
    A = ((_dot(d0, c0), _dot(d0, c1), _dot(d0, c2)),   # A_ij = Σ_k (R_d)_ki R_kj, k in order
         (_dot(d1, c0), _dot(d1, c1), _dot(d1, c2)),
         (_dot(d2, c0), _dot(d2, c1), _dot(d2, c2)))
    e_R = (0.5 * (A[2][1] - A[1][2]), 0.5 * (A[0][2] - A[2][0]), 0.5 * (A[1][0] - A[0][1]))
    gyro = _cross(omega, (omega[0] * J[0], omega[1] * J[1], omega[2] * J[2]))
    M = (-k_R[0] * e_R[0] + gyro[0], -k_R[1] * e_R[1] + gyro[1], -k_R[2] * e_R[2] + gyro[2])
    if not feedforward:
        return (M[0] - k_Omega[0] * omega[0], M[1] - k_Omega[1] * omega[1], M[2] - k_Omega[2] * omega[2])
    w_d = (A[0][0] * omega_d[0] + A[1][0] * omega_d[1] + A[2][0] * omega_d[2],
           A[0][1] * omega_d[0] + A[1][1] * omega_d[1] + A[2][1] * omega_d[2],
           A[0][2] * omega_d[0] + A[1][2] * omega_d[1] + A[2][2] * omega_d[2])
    a_d = (A[0][0] * alpha_d[0] + A[1][0] * alpha_d[1] + A[2][0] * alpha_d[2],
           A[0][1] * alpha_d[0] + A[1][1] * alpha_d[1] + A[2][1] * alpha_d[2],
           A[0][2] * alpha_d[0] + A[1][2] * alpha_d[1] + A[2][2] * alpha_d[2])
    c = _cross(omega, w_d)
    return (M[0] - k_Omega[0] * (omega[0] - w_d[0]) - J[0] * (c[0] - a_d[0]),
            M[1] - k_Omega[1] * (omega[1] - w_d[1]) - J[1] * (c[1] - a_d[1]),
            M[2] - k_Omega[2] * (omega[2] - w_d[2]) - J[2] * (c[2] - a_d[2]))


@numba.njit(cache=True)
def se3_control(p, v, R, omega, p_d, v_d, a_d, y_c, omega_d, alpha_d, feedforward, position,
                k_x, k_v, k_R, k_Omega, mass, J, tan_max_tilt, min_lift):
    """Collective thrust f = max(F·R e_3, 0) and moment M of Lee et al.'s tracking law, with
    b_3d = F / |F| and the heading axes b_1d = (y_c × b_3d) / |y_c × b_3d|, b_2d = b_3d × b_1d
    (the heading convention of flatness.py)."""
    F = desired_force(p, v, p_d, v_d, a_d, position, k_x, k_v, mass, tan_max_tilt, min_lift)
    thrust = F[0] * R[0][2] + F[1] * R[1][2] + F[2] * R[2][2]
    b3 = _div(F, math.sqrt(_dot(F, F)))
    b1 = _cross(y_c, b3)
    b1 = _div(b1, math.sqrt(_dot(b1, b1)))
    b2 = _cross(b3, b1)
    R_d = ((b1[0], b2[0], b3[0]), (b1[1], b2[1], b3[1]), (b1[2], b2[2], b3[2]))
    M = attitude_torque(R, omega, R_d, omega_d, alpha_d, feedforward, k_R, k_Omega, J)
    return max(thrust, 0.0), M


# --------------------------------------------------------------------------- mixer (eq. 3.15-3.16)


@numba.njit(cache=True)
def allocate(thrust, M, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, out):
    """Rotor speeds ϖ (eq. 3.16) into ``out`` (4,), within [ϖ_min, ϖ_max], thrust first: f is
    clipped to [thrust_min, thrust_max] (four rotors' range), ϖ^2 = base + λ δ with base = T^-1 (f,
    0), δ = T^-1 (0, M) and λ the largest value in [0, 1] keeping every ϖ_r^2 in [w2_min, w2_max]."""
    f = min(max(thrust, thrust_min), thrust_max)
    room_min = np.inf
    for r in range(4):
        base = f * mixer_inverse[r, 0]
        delta = M[0] * mixer_inverse[r, 1] + M[1] * mixer_inverse[r, 2] + M[2] * mixer_inverse[r, 3]
        room = (w2_max - base if delta > 0.0 else base - w2_min) / max(abs(delta), 1e-300)
        room_min = min(room_min, room)
    lam = min(room_min, 1.0)
    for r in range(4):
        base = f * mixer_inverse[r, 0]
        delta = M[0] * mixer_inverse[r, 1] + M[1] * mixer_inverse[r, 2] + M[2] * mixer_inverse[r, 3]
        out[r] = math.sqrt(min(max(base + lam * delta, w2_min), w2_max))


@numba.njit(cache=True)
def wrench(rotor_speed, gain, mixer):
    """Thrust T and moment M (eq. 3.15) of rotors turning at ``gain`` ϖ: a rotor keeping a fraction
    φ of its thrust and drag torque turns at an effective sqrt(φ) ϖ."""
    w0, w1, w2, w3 = (rotor_speed[0] * gain[0], rotor_speed[1] * gain[1],
                      rotor_speed[2] * gain[2], rotor_speed[3] * gain[3])
    w0, w1, w2, w3 = w0 * w0, w1 * w1, w2 * w2, w3 * w3
    return (w0 * mixer[0, 0] + w1 * mixer[0, 1] + w2 * mixer[0, 2] + w3 * mixer[0, 3],
            (w0 * mixer[1, 0] + w1 * mixer[1, 1] + w2 * mixer[1, 2] + w3 * mixer[1, 3],
             w0 * mixer[2, 0] + w1 * mixer[2, 1] + w2 * mixer[2, 2] + w3 * mixer[2, 3],
             w0 * mixer[3, 0] + w1 * mixer[3, 1] + w2 * mixer[3, 2] + w3 * mixer[3, 3]))


@numba.njit(cache=True)
def wind_load(R, wind, drag, mass, arm):
    """The wind's acceleration a = R D R^T w (world) and moment (0, 0, h) × m D R^T w (body)."""
    f = ((R[0][0] * wind[0] + R[1][0] * wind[1] + R[2][0] * wind[2]) * drag[0],
         (R[0][1] * wind[0] + R[1][1] * wind[1] + R[2][1] * wind[2]) * drag[1],
         (R[0][2] * wind[0] + R[1][2] * wind[1] + R[2][2] * wind[2]) * drag[2])
    acc = (_dot(R[0], f), _dot(R[1], f), _dot(R[2], f))
    return acc, (-arm * mass * f[1], arm * mass * f[0], 0.0)


# --------------------------------------------------------------------------- rigid body (eq. 3.4-3.8)


@numba.njit(cache=True)
def rhs(x, c, a, gyro, ext, out):
    """ẋ of x = [p v q ω] into ``out`` (13,): ṗ = v; v̇ = c R e_3 - g e_3 + ext (c = T / m);
    q̇ = ½ q ⊗ (0, ω); ω̇ = a - (ω_j ω_k) γ_i (a = M / J, γ = model.Airframe.gyro)."""
    q0, q1, q2, q3 = x[6], x[7], x[8], x[9]
    w0, w1, w2 = x[10], x[11], x[12]
    out[0], out[1], out[2] = x[3], x[4], x[5]
    out[3] = (2.0 * (q0 * q2) + 2.0 * (q1 * q3)) * c + ext[0]
    out[4] = (-2.0 * (q0 * q1) + 2.0 * (q2 * q3)) * c + ext[1]
    out[5] = (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * c - GRAVITY + ext[2]
    out[6] = -0.5 * q1 * w0 + -0.5 * q2 * w1 + -0.5 * q3 * w2
    out[7] = 0.5 * q0 * w0 + -0.5 * q3 * w1 + 0.5 * q2 * w2
    out[8] = 0.5 * q3 * w0 + 0.5 * q0 * w1 + -0.5 * q1 * w2
    out[9] = -0.5 * q2 * w0 + 0.5 * q1 * w1 + 0.5 * q0 * w2
    out[10] = a[0] - w1 * w2 * gyro[0]
    out[11] = a[1] - w2 * w0 * gyro[1]
    out[12] = a[2] - w0 * w1 * gyro[2]


@numba.njit(cache=True)
def rk4(x, thrust, M, ext, mass, J, gyro, dt, work):
    """One classical RK4 step of x (13,) in place with T, M and ext held; q renormalised.
    ``work`` (5, 13) is scratch (k_1..k_4 and the stage state)."""
    c = thrust / mass
    a = (M[0] / J[0], M[1] / J[1], M[2] / J[2])
    h = 0.5 * dt
    k1, k2, k3, k4, xs = work[0], work[1], work[2], work[3], work[4]
    rhs(x, c, a, gyro, ext, k1)
    for j in range(13):
        xs[j] = x[j] + h * k1[j]
    rhs(xs, c, a, gyro, ext, k2)
    for j in range(13):
        xs[j] = x[j] + h * k2[j]
    rhs(xs, c, a, gyro, ext, k3)
    for j in range(13):
        xs[j] = x[j] + dt * k3[j]
    rhs(xs, c, a, gyro, ext, k4)
    sixth = dt / 6.0
    for j in range(13):
        x[j] = x[j] + sixth * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
    norm = math.sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9])
    for j in range(6, 10):
        x[j] = x[j] / norm


# --------------------------------------------------------------------------- one physics step


@numba.njit(cache=True)
def taylor_weights(tau, h, substeps):
    """(τ, τ²/2, τ³/6, τ⁴/24) at the start of each sub-step, τ accumulated step by step from
    ``tau`` (the same for every agent, so computed once per call)."""
    w = np.empty((substeps + 1, 4))
    for k in range(substeps + 1):
        w[k, 0], w[k, 1] = tau, tau * tau / 2.0
        w[k, 2], w[k, 3] = math.pow(tau, 3.0) / 6.0, math.pow(tau, 4.0) / 24.0
        tau += h
    return w


@numba.njit(cache=True)
def reference(p_ref, v_ref, a_ref, dv, da, dj, ds, i, weights):
    """(p_d, v_d, a_d) of agent i at τ s after the tick: the quartic Taylor polynomial
    p + τ v + τ²/2 a + τ³/6 j + τ⁴/24 s (and its derivatives) on TRACK rows (dv..ds zero
    elsewhere); ``weights`` = (τ, τ²/2, τ³/6, τ⁴/24)."""
    tau, t2, t3, t4 = weights[0], weights[1], weights[2], weights[3]
    if tau == 0.0:
        return _row(p_ref, i), _row(v_ref, i), _row(a_ref, i)
    p = (p_ref[i, 0] + tau * dv[i, 0] + t2 * da[i, 0] + t3 * dj[i, 0] + t4 * ds[i, 0],
         p_ref[i, 1] + tau * dv[i, 1] + t2 * da[i, 1] + t3 * dj[i, 1] + t4 * ds[i, 1],
         p_ref[i, 2] + tau * dv[i, 2] + t2 * da[i, 2] + t3 * dj[i, 2] + t4 * ds[i, 2])
    v = (v_ref[i, 0] + tau * da[i, 0] + t2 * dj[i, 0] + t3 * ds[i, 0],
         v_ref[i, 1] + tau * da[i, 1] + t2 * dj[i, 1] + t3 * ds[i, 1],
         v_ref[i, 2] + tau * da[i, 2] + t2 * dj[i, 2] + t3 * ds[i, 2])
    a = (a_ref[i, 0] + tau * dj[i, 0] + t2 * ds[i, 0],
         a_ref[i, 1] + tau * dj[i, 1] + t2 * ds[i, 1],
         a_ref[i, 2] + tau * dj[i, 2] + t2 * ds[i, 2])
    return p, v, a


@numba.njit(cache=True)
def step_swarm(pos, vel, quat, omega, rotor_speed,
               p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
               feedforward, tau, h, substeps,
               mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
               mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
               wind, has_wind, arm, drag, force, has_force):
    """``substeps`` internal steps of length h for every agent, state written in place
    (``Quadrotor.step``); returns τ after them (time since the tick, accumulated step by step).

    Per sub-step and agent: the reference at τ (:func:`reference`), the SE(3) law
    (:func:`se3_control`), allocation with limits (eq. 3.16, :func:`allocate`), the rotors' real
    wrench (eq. 3.15) at ``rotor_gain`` = sqrt(health) times the commanded speeds, the wind's force
    and moment when ``has_wind`` (:func:`wind_load`), the force per mass ``force`` when
    ``has_force`` (the disturbances' force phase, held over the step), then RK4 (:func:`rk4`).
    ``rotor_speed`` receives the last commanded speeds.
    """
    x = np.empty(13)
    work = np.empty((5, 13))
    weights = taylor_weights(tau, h, substeps)
    for i in range(pos.shape[0]):
        _step_agent(i, x, work, weights, pos, vel, quat, omega, rotor_speed,
                    p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                    feedforward, h, substeps,
                    mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                    mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                    wind, has_wind, arm, drag, force, has_force)
    return weights[substeps, 0]


@numba.njit(cache=True, parallel=True)
def step_swarm_parallel(pos, vel, quat, omega, rotor_speed,
                        p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                        feedforward, tau, h, substeps,
                        mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                        mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                        wind, has_wind, arm, drag, force, has_force, chunks):
    """:func:`step_swarm` with the agents dealt to ``chunks`` shares in turn (agent i to share
    i mod ``chunks``, so that agents that cost more, a region of the swarm that turns or
    saturates, are spread over the shares), stepped by numba's threads (``prange``; as many at
    once as ``numba.set_num_threads`` allows). The agents are independent and each is stepped by
    the same :func:`_step_agent`, so every agent gets the bits :func:`step_swarm` gives it
    (tests/plugins/dynamics/test_quadrotor_threads.py)."""
    weights = taylor_weights(tau, h, substeps)
    n = pos.shape[0]
    for c in numba.prange(chunks):
        x = np.empty(13)
        work = np.empty((5, 13))
        for i in range(c, n, chunks):
            _step_agent(i, x, work, weights, pos, vel, quat, omega, rotor_speed,
                        p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                        feedforward, h, substeps,
                        mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                        mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                        wind, has_wind, arm, drag, force, has_force)
    return weights[substeps, 0]


@numba.njit(cache=True)
def _step_agent(i, x, work, weights, pos, vel, quat, omega, rotor_speed,
                p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                feedforward, h, substeps,
                mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                wind, has_wind, arm, drag, force, has_force):
    """Agent i's ``substeps`` internal steps (:func:`step_swarm`'s loop body), with ``x`` (13,)
    and ``work`` (5, 13) as its scratch state."""
    no_wind = (0.0, 0.0, 0.0)
    for k in range(3):
        x[k], x[3 + k], x[10 + k] = pos[i, k], vel[i, k], omega[i, k]
    for k in range(4):
        x[6 + k] = quat[i, k]
    y_c, w_d, al_d = _row(heading, i), _row(omega_d, i), _row(alpha_d, i)
    for sub in range(substeps):
        p_d, v_d, a_d = reference(p_ref, v_ref, a_ref, dv, da, dj, ds, i, weights[sub])
        R = rotmat(x[6], x[7], x[8], x[9])
        f, M = se3_control((x[0], x[1], x[2]), (x[3], x[4], x[5]), R, (x[10], x[11], x[12]),
                           p_d, v_d, a_d, y_c, w_d, al_d, feedforward, position_mask[i],
                           k_x, k_v, k_R, k_Omega, mass, J, tan_max_tilt, min_lift)
        allocate(f, M, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_speed[i])
        thrust, torque = wrench(rotor_speed[i], rotor_gain[i], mixer)
        ext = no_wind
        if has_wind:
            ext, moment = wind_load(R, _row(wind, i), drag, mass, arm)
            torque = _add(torque, moment)
        if has_force:
            ext = _add(ext, _row(force, i))
        rk4(x, thrust, torque, ext, mass, J, gyro, h, work)
    for k in range(3):
        pos[i, k], vel[i, k], omega[i, k] = x[k], x[3 + k], x[10 + k]
    for k in range(4):
        quat[i, k] = x[6 + k]
