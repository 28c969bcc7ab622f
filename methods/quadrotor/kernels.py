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
from numba.extending import overload

GRAVITY = 9.81
"""g, m/s^2 (model.GRAVITY; repeated so that this module has no import chain to compile)."""

POSITION, VELOCITY, TRACK, HOLD = 0, 1, 2, 3
"""core.setpoint.Mode values."""

_jit = numba.njit(cache=True, error_model="numpy")
"""Every kernel's compilation: cached beside the module, and a division by zero gives inf or nan
(numpy's rule) instead of a check and an exception per division (Python's), which would put a
branch and an exit in every loop. No formula here divides by zero: |F| >= min_lift m g, y_c is
horizontal while b_3d points up, |q| ~ 1, J > 0."""

_inline = numba.njit(cache=True, error_model="numpy", inline="always")
"""The helpers of the physics step: inlined into their caller in numba's own IR, so that the step's
loop over agents has no calls left and its arrays no reference counting (15-25 % faster a step,
bench_batch physics; its first compilation takes ~1.5 s more)."""


def lit(x, value):
    """``value`` in the precision of the float ``x``. numba types a Python float literal as float64,
    which would promote every float32 product it enters to float64; the physics step writes its
    constants through this so that with float32 lanes (``dynamics.dtype=float32``) it computes in
    float32, while in float64 the constant is the literal itself (the same machine code)."""
    return value


@overload(lit, inline="always")
def _lit(x, value):
    if x == numba.types.float32:
        return lambda x, value: np.float32(value)
    return lambda x, value: value


# --------------------------------------------------------------------------- 3-vector helpers


@_inline
def _cross(a, b):
    """a × b, in cross_rows' order: (a_1 b_2 - a_2 b_1, a_2 b_0 - a_0 b_2, a_0 b_1 - a_1 b_0)."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@_inline
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_inline
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@_inline
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_inline
def _scale(s, a):
    return (s * a[0], s * a[1], s * a[2])


@_inline
def _div(a, s):
    return (a[0] / s, a[1] / s, a[2] / s)


@_inline
def _columns(R):
    """The columns of a 3x3 matrix held as three row tuples."""
    return ((R[0][0], R[1][0], R[2][0]), (R[0][1], R[1][1], R[2][1]), (R[0][2], R[1][2], R[2][2]))


@_inline
def _row(m, i):
    return (m[i, 0], m[i, 1], m[i, 2])


# --------------------------------------------------------------------------- flatness (tick)


@_jit
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


@_jit
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


@_jit
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


@_inline
def rotmat(q0, q1, q2, q3):
    """R_b^o of q = (w, x, y, z) as three row tuples; each entry summed in the order of the rows of
    model._R_BASIS (the oracle's quadratic form)."""
    ww, xx, yy, zz = q0 * q0, q1 * q1, q2 * q2, q3 * q3
    two = lit(q0, 2.0)
    return ((ww + xx - yy - zz, -two * (q0 * q3) + two * (q1 * q2), two * (q0 * q2) + two * (q1 * q3)),
            (two * (q0 * q3) + two * (q1 * q2), ww - xx + yy - zz, -two * (q0 * q1) + two * (q2 * q3)),
            (-two * (q0 * q2) + two * (q1 * q3), two * (q0 * q1) + two * (q2 * q3), ww - xx - yy + zz))


@_inline
def desired_force(p, v, p_d, v_d, a_d, position, k_x, k_v, mass, tan_max_tilt, min_lift):
    """F = -k_x e_x - k_v e_v + m g e_3 + m a_d (Lee et al.'s desired force, z up), e_x dropped when
    not ``position``; F_z kept >= ``min_lift`` m g and the tilt of F capped (|F_xy| <= F_z tan)."""
    w = lit(mass, 1.0) if position else lit(mass, 0.0)
    F0 = -k_x * ((p[0] - p_d[0]) * w) - k_v * (v[0] - v_d[0]) + mass * a_d[0]
    F1 = -k_x * ((p[1] - p_d[1]) * w) - k_v * (v[1] - v_d[1]) + mass * a_d[1]
    F2 = -k_x * ((p[2] - p_d[2]) * w) - k_v * (v[2] - v_d[2]) + mass * a_d[2]
    g = lit(mass, GRAVITY)
    F2 = max(F2 + mass * g, min_lift * mass * g)
    shrink = min(lit(mass, 1.0), F2 * tan_max_tilt / max(math.hypot(F0, F1), lit(mass, 1e-12)))
    return (F0 * shrink, F1 * shrink, F2)


@_inline
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
    half = lit(J[0], 0.5)
    e_R = (half * (A[2][1] - A[1][2]), half * (A[0][2] - A[2][0]), half * (A[1][0] - A[0][1]))
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


@_inline
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
    return max(thrust, lit(thrust, 0.0)), M


# --------------------------------------------------------------------------- mixer (eq. 3.15-3.16)


@_inline
def allocate(thrust, M, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max):
    """Rotor speeds ϖ (eq. 3.16), within [ϖ_min, ϖ_max], thrust first: f is clipped to
    [thrust_min, thrust_max] (four rotors' range), ϖ^2 = base + λ δ with base = T^-1 (f, 0),
    δ = T^-1 (0, M) and λ the largest value in [0, 1] keeping every ϖ_r^2 in [w2_min, w2_max].
    Written out rotor by rotor (no loop, no array) so that it inlines into :func:`_step_lanes`."""
    f = min(max(thrust, thrust_min), thrust_max)
    b0, b1, b2, b3 = (f * mixer_inverse[0, 0], f * mixer_inverse[1, 0],
                      f * mixer_inverse[2, 0], f * mixer_inverse[3, 0])
    d0 = M[0] * mixer_inverse[0, 1] + M[1] * mixer_inverse[0, 2] + M[2] * mixer_inverse[0, 3]
    d1 = M[0] * mixer_inverse[1, 1] + M[1] * mixer_inverse[1, 2] + M[2] * mixer_inverse[1, 3]
    d2 = M[0] * mixer_inverse[2, 1] + M[1] * mixer_inverse[2, 2] + M[2] * mixer_inverse[2, 3]
    d3 = M[0] * mixer_inverse[3, 1] + M[1] * mixer_inverse[3, 2] + M[2] * mixer_inverse[3, 3]
    room = min(min(min(min(lit(f, np.inf), _room(b0, d0, w2_min, w2_max)), _room(b1, d1, w2_min, w2_max)),
                   _room(b2, d2, w2_min, w2_max)), _room(b3, d3, w2_min, w2_max))
    lam = min(room, lit(f, 1.0))
    return (math.sqrt(min(max(b0 + lam * d0, w2_min), w2_max)), math.sqrt(min(max(b1 + lam * d1, w2_min), w2_max)),
            math.sqrt(min(max(b2 + lam * d2, w2_min), w2_max)), math.sqrt(min(max(b3 + lam * d3, w2_min), w2_max)))


@_inline
def _room(base, delta, w2_min, w2_max):
    """The largest λ keeping base + λ δ in [w2_min, w2_max] (δ = 0: as good as unbounded; in float32
    the floor 1e-300 is 0, and λ = ±inf or nan, which the ``min`` over the rotors passes over)."""
    return (w2_max - base if delta > 0.0 else base - w2_min) / max(abs(delta), lit(delta, 1e-300))


@_inline
def wrench(w, gain, mixer):
    """Thrust T and moment M (eq. 3.15) of rotors turning at ``gain`` ϖ (4-tuples): a rotor
    keeping a fraction φ of its thrust and drag torque turns at an effective sqrt(φ) ϖ."""
    w0, w1, w2, w3 = w[0] * gain[0], w[1] * gain[1], w[2] * gain[2], w[3] * gain[3]
    w0, w1, w2, w3 = w0 * w0, w1 * w1, w2 * w2, w3 * w3
    return (w0 * mixer[0, 0] + w1 * mixer[0, 1] + w2 * mixer[0, 2] + w3 * mixer[0, 3],
            (w0 * mixer[1, 0] + w1 * mixer[1, 1] + w2 * mixer[1, 2] + w3 * mixer[1, 3],
             w0 * mixer[2, 0] + w1 * mixer[2, 1] + w2 * mixer[2, 2] + w3 * mixer[2, 3],
             w0 * mixer[3, 0] + w1 * mixer[3, 1] + w2 * mixer[3, 2] + w3 * mixer[3, 3]))


@_inline
def wind_load(R, wind, drag, mass, arm):
    """The wind's acceleration a = R D R^T w (world) and moment (0, 0, h) × m D R^T w (body)."""
    f = ((R[0][0] * wind[0] + R[1][0] * wind[1] + R[2][0] * wind[2]) * drag[0],
         (R[0][1] * wind[0] + R[1][1] * wind[1] + R[2][1] * wind[2]) * drag[1],
         (R[0][2] * wind[0] + R[1][2] * wind[1] + R[2][2] * wind[2]) * drag[2])
    acc = (_dot(R[0], f), _dot(R[1], f), _dot(R[2], f))
    return acc, (-arm * mass * f[1], arm * mass * f[0], lit(arm, 0.0))


# --------------------------------------------------------------------------- rigid body (eq. 3.4-3.8)


@_inline
def rhs(v, q, w, c, a, gyro, ext):
    """ẋ of x = (p, v, q, ω) as (ṗ, v̇, q̇, ω̇): ṗ = v; v̇ = c R e_3 - g e_3 + ext (c = T / m);
    q̇ = ½ q ⊗ (0, ω); ω̇ = a - (ω_j ω_k) γ_i (a = M / J, γ = model.Airframe.gyro)."""
    q0, q1, q2, q3 = q
    w0, w1, w2 = w
    two, half = lit(c, 2.0), lit(c, 0.5)
    v_dot = ((two * (q0 * q2) + two * (q1 * q3)) * c + ext[0],
             (-two * (q0 * q1) + two * (q2 * q3)) * c + ext[1],
             (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * c - lit(c, GRAVITY) + ext[2])
    q_dot = (-half * q1 * w0 + -half * q2 * w1 + -half * q3 * w2,
             half * q0 * w0 + -half * q3 * w1 + half * q2 * w2,
             half * q3 * w0 + half * q0 * w1 + -half * q1 * w2,
             -half * q2 * w0 + half * q1 * w1 + half * q0 * w2)
    w_dot = (a[0] - w1 * w2 * gyro[0], a[1] - w2 * w0 * gyro[1], a[2] - w0 * w1 * gyro[2])
    return v, v_dot, q_dot, w_dot


@_inline
def _stage3(x, h, k):
    return (x[0] + h * k[0], x[1] + h * k[1], x[2] + h * k[2])


@_inline
def _stage4(x, h, k):
    return (x[0] + h * k[0], x[1] + h * k[1], x[2] + h * k[2], x[3] + h * k[3])


@_inline
def _rk4_sum3(x, s, k1, k2, k3, k4):
    two = lit(s, 2.0)
    return (x[0] + s * (k1[0] + two * (k2[0] + k3[0]) + k4[0]),
            x[1] + s * (k1[1] + two * (k2[1] + k3[1]) + k4[1]),
            x[2] + s * (k1[2] + two * (k2[2] + k3[2]) + k4[2]))


@_inline
def _rk4_sum4(x, s, k1, k2, k3, k4):
    two = lit(s, 2.0)
    return (x[0] + s * (k1[0] + two * (k2[0] + k3[0]) + k4[0]),
            x[1] + s * (k1[1] + two * (k2[1] + k3[1]) + k4[1]),
            x[2] + s * (k1[2] + two * (k2[2] + k3[2]) + k4[2]),
            x[3] + s * (k1[3] + two * (k2[3] + k3[3]) + k4[3]))


@_inline
def rk4(p, v, q, w, thrust, M, ext, mass, J, gyro, dt):
    """One classical RK4 step of (p, v, q, ω) with T, M and ext held; returns the new state, q
    renormalised."""
    c = thrust / mass
    a = (M[0] / J[0], M[1] / J[1], M[2] / J[2])
    h = lit(dt, 0.5) * dt
    p1, v1, q1, w1 = rhs(v, q, w, c, a, gyro, ext)
    p2, v2, q2, w2 = rhs(_stage3(v, h, v1), _stage4(q, h, q1), _stage3(w, h, w1), c, a, gyro, ext)
    p3, v3, q3, w3 = rhs(_stage3(v, h, v2), _stage4(q, h, q2), _stage3(w, h, w2), c, a, gyro, ext)
    p4, v4, q4, w4 = rhs(_stage3(v, dt, v3), _stage4(q, dt, q3), _stage3(w, dt, w3), c, a, gyro, ext)
    sixth = dt / lit(dt, 6.0)
    q = _rk4_sum4(q, sixth, q1, q2, q3, q4)
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (_rk4_sum3(p, sixth, p1, p2, p3, p4), _rk4_sum3(v, sixth, v1, v2, v3, v4),
            (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm), _rk4_sum3(w, sixth, w1, w2, w3, w4))


# --------------------------------------------------------------------------- one physics step


@_jit
def taylor_weights(tau, h, substeps):
    """(τ, τ²/2, τ³/6, τ⁴/24) at the start of each sub-step, τ accumulated step by step from
    ``tau`` (the same for every agent, so computed once per call)."""
    w = np.empty((substeps + 1, 4))
    for k in range(substeps + 1):
        w[k, 0], w[k, 1] = tau, tau * tau / 2.0
        w[k, 2], w[k, 3] = math.pow(tau, 3.0) / 6.0, math.pow(tau, 4.0) / 24.0
        tau += h
    return w


# Rows of the lanes (structure of arrays, one column per agent; :func:`_to_lanes`). The state X:
P, V, Q, W = 0, 3, 6, 10
STATE_ROWS = 13
# the held inputs U: the tick's reference p, v, a and its Taylor coefficients v, a, jerk, snap
# (zero off TRACK rows), the heading y_c, Ω_d, Ω̇_d, the position mask (1 or 0), the rotor gains,
# the wind and the force per mass
P_REF, V_REF, A_REF, DV, DA, DJ, DS, HEADING, OMEGA_D, ALPHA_D = 0, 3, 6, 9, 12, 15, 18, 21, 24, 27
MASK, GAIN, WIND, FORCE = 30, 31, 35, 38
INPUT_ROWS = 41
BLOCK = 64
"""Agents stepped together as lanes: their state and inputs, ~30 kB, stay in the core's first-level
cache through the sub-steps."""
PAD = 8
"""Spare columns in each row of the lanes: with rows a power of two of bytes apart, the rows would
share a few cache sets and evict one another (measured: 1.6x slower at 256 columns)."""


@_jit
def step_swarm(pos, vel, quat, omega, rotor_speed,
               p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
               feedforward, tau, h, substeps,
               mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
               mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
               wind, has_wind, arm, drag, force, has_force):
    """``substeps`` internal steps of length h for every agent, state written in place
    (``Quadrotor.step``); returns τ after them (time since the tick, accumulated step by step).

    Per sub-step and agent: the reference at τ (the quartic Taylor polynomial on TRACK rows), the
    SE(3) law (:func:`se3_control`), allocation with limits (eq. 3.16, :func:`allocate`), the
    rotors' real wrench (eq. 3.15) at ``rotor_gain`` = sqrt(health) times the commanded speeds,
    the wind's force and moment when ``has_wind`` (:func:`wind_load`), the force per mass
    ``force`` when ``has_force`` (the disturbances' force phase, held over the step), then RK4
    (:func:`rk4`). ``rotor_speed`` receives the last commanded speeds.

    The agents are stepped as SIMD lanes (:func:`_step_lanes`): copied into a structure of
    arrays, one column per agent, so that the compiler runs one instruction over 4-8 agents at
    once (the branches of the law are per-agent selects, the same work in every lane); each
    agent's arithmetic is the same, in the same order, as when agents were stepped one by one.
    """
    weights = taylor_weights(tau, h, substeps)
    _step_range(0, pos.shape[0], weights, pos, vel, quat, omega, rotor_speed,
                p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                feedforward, h, substeps,
                mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                wind, has_wind, arm, drag, force, has_force)
    return weights[substeps, 0]


@numba.njit(cache=True, parallel=True, error_model="numpy")
def step_swarm_parallel(pos, vel, quat, omega, rotor_speed,
                        p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                        feedforward, tau, h, substeps,
                        mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                        mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                        wind, has_wind, arm, drag, force, has_force, chunks):
    """:func:`step_swarm` with the agents cut into ``chunks`` runs of consecutive agents, stepped
    by numba's threads (``prange``; as many at once as ``numba.set_num_threads`` allows). Every
    lane does the same work whatever its agent does, so equal runs are equal loads. The agents are
    independent and each is stepped by the same code, so every agent gets the bits
    :func:`step_swarm` gives it (tests/plugins/dynamics/test_quadrotor_threads.py)."""
    n = pos.shape[0]
    weights = taylor_weights(tau, h, substeps)
    for c in numba.prange(chunks):
        _step_range(c * n // chunks, (c + 1) * n // chunks, weights, pos, vel, quat, omega, rotor_speed,
                    p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                    feedforward, h, substeps,
                    mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                    mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                    wind, has_wind, arm, drag, force, has_force)
    return weights[substeps, 0]


@_jit
def _step_range(start, stop, weights, pos, vel, quat, omega, rotor_speed,
                p_ref, v_ref, a_ref, dv, da, dj, ds, heading, position_mask, omega_d, alpha_d,
                feedforward, h, substeps,
                mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max, rotor_gain,
                wind, has_wind, arm, drag, force, has_force):
    """Agents ``start:stop``, ``BLOCK`` at a time: into the lanes, ``substeps`` sub-steps, back into
    the (N, k) arrays. The lanes hold the precision of the model's constants (``J``): float64, or
    float32 with ``dynamics.dtype=float32`` (the engine's arrays stay float64; a float32 step rounds
    the state to float32 on the way in)."""
    lanes = J.dtype
    X, U = np.empty((STATE_ROWS, BLOCK + PAD), lanes), np.empty((INPUT_ROWS, BLOCK + PAD), lanes)
    Wr, taylor = np.empty((4, BLOCK + PAD), lanes), np.empty(5, lanes)
    for first in range(start, stop, BLOCK):
        last = min(first + BLOCK, stop)
        _to_lanes(first, last, X, U, pos, vel, quat, omega, p_ref, v_ref, a_ref, dv, da, dj, ds, heading,
                  position_mask, omega_d, alpha_d, rotor_gain, wind, has_wind, force, has_force)
        for sub in range(substeps):
            for k in range(4):
                taylor[k] = weights[sub, k]
            taylor[4] = h
            _step_lanes(last - first, X, U, Wr, taylor, feedforward,
                        mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                        mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max,
                        has_wind, arm, drag, has_force)
        for i in range(first, last):
            j = i - first
            for k in range(3):
                pos[i, k], vel[i, k], omega[i, k] = X[P + k, j], X[V + k, j], X[W + k, j]
            for k in range(4):
                quat[i, k], rotor_speed[i, k] = X[Q + k, j], Wr[k, j]


@_jit
def _to_lanes(start, stop, X, U, pos, vel, quat, omega, p_ref, v_ref, a_ref, dv, da, dj, ds, heading,
              position_mask, omega_d, alpha_d, rotor_gain, wind, has_wind, force, has_force):
    """Agents ``start:stop`` into columns 0, 1, ... of the state X and the held inputs U (the rows
    above), from the engine's (N, k) arrays."""
    for i in range(start, stop):
        j = i - start
        for k in range(3):
            X[P + k, j], X[V + k, j], X[W + k, j] = pos[i, k], vel[i, k], omega[i, k]
            U[P_REF + k, j], U[V_REF + k, j], U[A_REF + k, j] = p_ref[i, k], v_ref[i, k], a_ref[i, k]
            U[DV + k, j], U[DA + k, j], U[DJ + k, j], U[DS + k, j] = dv[i, k], da[i, k], dj[i, k], ds[i, k]
            U[HEADING + k, j], U[OMEGA_D + k, j], U[ALPHA_D + k, j] = heading[i, k], omega_d[i, k], alpha_d[i, k]
            U[WIND + k, j] = wind[i, k] if has_wind else 0.0
            U[FORCE + k, j] = force[i, k] if has_force else 0.0
        for k in range(4):
            X[Q + k, j], U[GAIN + k, j] = quat[i, k], rotor_gain[i, k]
        U[MASK, j] = 1.0 if position_mask[i] else 0.0


@_inline
def _column(A, row, i):
    """Rows row..row+2 of column i, a 3-tuple."""
    return (A[row, i], A[row + 1, i], A[row + 2, i])


@_jit
def _step_lanes(count, X, U, Wr, taylor, feedforward,
                mass, J, gyro, k_x, k_v, k_R, k_Omega, tan_max_tilt, min_lift,
                mixer, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max,
                has_wind, arm, drag, has_force):
    """One sub-step of length h of the agents in columns ``0:count`` of X, U, Wr, ``taylor`` =
    (τ, τ²/2, τ³/6, τ⁴/24) at its start and h, in the lanes' precision. The loop body has no call
    that stays a call and no exit, so the compiler vectorises it across agents."""
    tau, t2, t3, t4, h = taylor[0], taylor[1], taylor[2], taylor[3], taylor[4]
    no_wind = (lit(h, 0.0), lit(h, 0.0), lit(h, 0.0))
    for i in range(count):
        p, v, w = _column(X, P, i), _column(X, V, i), _column(X, W, i)
        q = (X[Q, i], X[Q + 1, i], X[Q + 2, i], X[Q + 3, i])
        p_d, v_d, a_d = _reference(U, i, tau, t2, t3, t4)
        R = rotmat(q[0], q[1], q[2], q[3])
        f, M = se3_control(p, v, R, w, p_d, v_d, a_d, _column(U, HEADING, i), _column(U, OMEGA_D, i),
                           _column(U, ALPHA_D, i), feedforward, U[MASK, i] != 0.0,
                           k_x, k_v, k_R, k_Omega, mass, J, tan_max_tilt, min_lift)
        speeds = allocate(f, M, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max)
        gain = (U[GAIN, i], U[GAIN + 1, i], U[GAIN + 2, i], U[GAIN + 3, i])
        thrust, torque = wrench(speeds, gain, mixer)
        ext = no_wind
        if has_wind:
            ext, moment = wind_load(R, _column(U, WIND, i), drag, mass, arm)
            torque = _add(torque, moment)
        if has_force:
            ext = _add(ext, _column(U, FORCE, i))
        p, v, q, w = rk4(p, v, q, w, thrust, torque, ext, mass, J, gyro, h)
        for k in range(3):
            X[P + k, i], X[V + k, i], X[W + k, i] = p[k], v[k], w[k]
        for k in range(4):
            X[Q + k, i], Wr[k, i] = q[k], speeds[k]


@_inline
def _reference(U, i, tau, t2, t3, t4):
    """(p_d, v_d, a_d) of agent i at τ s after the tick: the quartic Taylor polynomial
    p + τ v + τ²/2 a + τ³/6 j + τ⁴/24 s (and its derivatives) on TRACK rows (the coefficients are
    zero elsewhere)."""
    if tau == 0.0:
        return _column(U, P_REF, i), _column(U, V_REF, i), _column(U, A_REF, i)
    p = (U[P_REF, i] + tau * U[DV, i] + t2 * U[DA, i] + t3 * U[DJ, i] + t4 * U[DS, i],
         U[P_REF + 1, i] + tau * U[DV + 1, i] + t2 * U[DA + 1, i] + t3 * U[DJ + 1, i] + t4 * U[DS + 1, i],
         U[P_REF + 2, i] + tau * U[DV + 2, i] + t2 * U[DA + 2, i] + t3 * U[DJ + 2, i] + t4 * U[DS + 2, i])
    v = (U[V_REF, i] + tau * U[DA, i] + t2 * U[DJ, i] + t3 * U[DS, i],
         U[V_REF + 1, i] + tau * U[DA + 1, i] + t2 * U[DJ + 1, i] + t3 * U[DS + 1, i],
         U[V_REF + 2, i] + tau * U[DA + 2, i] + t2 * U[DJ + 2, i] + t3 * U[DS + 2, i])
    a = (U[A_REF, i] + tau * U[DJ, i] + t2 * U[DS, i],
         U[A_REF + 1, i] + tau * U[DJ + 1, i] + t2 * U[DS + 1, i],
         U[A_REF + 2, i] + tau * U[DJ + 2, i] + t2 * U[DS + 2, i])
    return p, v, a
