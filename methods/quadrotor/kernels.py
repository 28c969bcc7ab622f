"""Compiled kernels of the ``quadrotor`` dynamics: one call per guidance tick, one per physics step.

:func:`latch_references` is ``Quadrotor.control`` (the references of a tick and their flatness
feed-forward) and :func:`step_swarm` is ``Quadrotor.step`` (all sub-steps of one physics step:
reference propagation, SE(3) control, allocation, rotor health, wind and RK4), for all agents in
one call. Both compute each agent with 3-vectors as tuples, in the order of the numpy formulas they
replace (tests/oracles/quadrotor.py), so the two agree to round-off: only the summation order
inside numpy's small matrix products may differ. The physics step runs its agents as SIMD lanes
(:func:`step_swarm`), in float64 or, with ``dynamics.dtype=float32``, float32 (:func:`lit`).

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
from numba.extending import intrinsic, overload

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
loops over agents have no call left (a call keeps a loop from vectorising) and pass no array whose
reference count would be kept."""


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


@intrinsic
def _sqrt(typingctx, x):
    """√x as LLVM's sqrt intrinsic: IEEE's correctly rounded square root, the same bits as libm's,
    which numba's ``math.sqrt`` calls (and a call keeps the loop over agents from vectorising)."""
    def codegen(context, builder, signature, args):
        return builder.call(builder.module.declare_intrinsic("llvm.sqrt", [args[0].type]), args)
    return x(x), codegen


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
def desired_force(p, v, p_d, v_d, a_d, position, k_x, k_v, mass, min_lift):
    """F = -k_x e_x - k_v e_v + m g e_3 + m a_d (Lee et al.'s desired force, z up), e_x dropped when
    not ``position``, F_z kept >= ``min_lift`` m g; its tilt is capped next (:func:`cap_tilt`)."""
    w = lit(mass, 1.0) if position else lit(mass, 0.0)
    F0 = -k_x * ((p[0] - p_d[0]) * w) - k_v * (v[0] - v_d[0]) + mass * a_d[0]
    F1 = -k_x * ((p[1] - p_d[1]) * w) - k_v * (v[1] - v_d[1]) + mass * a_d[1]
    F2 = -k_x * ((p[2] - p_d[2]) * w) - k_v * (v[2] - v_d[2]) + mass * a_d[2]
    g = lit(mass, GRAVITY)
    return (F0, F1, max(F2 + mass * g, min_lift * mass * g))


@_inline
def cap_tilt(F, tan_max_tilt):
    """F with its tilt capped, |F_xy| <= F_z tan (its horizontal part scaled down). ``math.hypot`` is
    libm's, so this runs agent by agent between the two vectorised parts of a sub-step."""
    one = lit(F[2], 1.0)
    shrink = min(one, F[2] * tan_max_tilt / max(math.hypot(F[0], F[1]), lit(F[2], 1e-12)))
    return (F[0] * shrink, F[1] * shrink, F[2])


@_inline
def attitude_torque(R, omega, R_d, omega_d, alpha_d, feedforward, k_R, k_Omega, J):
    """Lee et al.'s moment (body FLU), A = R_d^T R:
    e_R = ½ (A - A^T)^∨, e_Ω = Ω - A^T Ω_d,
    M = -k_R e_R - k_Ω e_Ω + Ω × J Ω - J (Ω × A^T Ω_d - A^T Ω̇_d) (Ω_d = Ω̇_d = 0 without
    ``feedforward``). Both forms are computed and one is chosen (a select, not a branch, so that the
    loop over agents vectorises)."""
    c0, c1, c2 = _columns(R)
    d0, d1, d2 = _columns(R_d)
    A = ((_dot(d0, c0), _dot(d0, c1), _dot(d0, c2)),   # A_ij = Σ_k (R_d)_ki R_kj, k in order
         (_dot(d1, c0), _dot(d1, c1), _dot(d1, c2)),
         (_dot(d2, c0), _dot(d2, c1), _dot(d2, c2)))
    half = lit(J[0], 0.5)
    e_R = (half * (A[2][1] - A[1][2]), half * (A[0][2] - A[2][0]), half * (A[1][0] - A[0][1]))
    gyro = _cross(omega, (omega[0] * J[0], omega[1] * J[1], omega[2] * J[2]))
    M = (-k_R[0] * e_R[0] + gyro[0], -k_R[1] * e_R[1] + gyro[1], -k_R[2] * e_R[2] + gyro[2])
    plain = (M[0] - k_Omega[0] * omega[0], M[1] - k_Omega[1] * omega[1], M[2] - k_Omega[2] * omega[2])
    w_d = (A[0][0] * omega_d[0] + A[1][0] * omega_d[1] + A[2][0] * omega_d[2],
           A[0][1] * omega_d[0] + A[1][1] * omega_d[1] + A[2][1] * omega_d[2],
           A[0][2] * omega_d[0] + A[1][2] * omega_d[1] + A[2][2] * omega_d[2])
    a_d = (A[0][0] * alpha_d[0] + A[1][0] * alpha_d[1] + A[2][0] * alpha_d[2],
           A[0][1] * alpha_d[0] + A[1][1] * alpha_d[1] + A[2][1] * alpha_d[2],
           A[0][2] * alpha_d[0] + A[1][2] * alpha_d[1] + A[2][2] * alpha_d[2])
    c = _cross(omega, w_d)
    full = (M[0] - k_Omega[0] * (omega[0] - w_d[0]) - J[0] * (c[0] - a_d[0]),
            M[1] - k_Omega[1] * (omega[1] - w_d[1]) - J[1] * (c[1] - a_d[1]),
            M[2] - k_Omega[2] * (omega[2] - w_d[2]) - J[2] * (c[2] - a_d[2]))
    return full if feedforward else plain


@_inline
def se3_control(F, R, omega, y_c, omega_d, alpha_d, feedforward, k_R, k_Omega, J):
    """Collective thrust f = max(F·R e_3, 0) and moment M of Lee et al.'s tracking law for the
    desired force F (:func:`desired_force`, :func:`cap_tilt`), with b_3d = F / |F| and the heading
    axes b_1d = (y_c × b_3d) / |y_c × b_3d|, b_2d = b_3d × b_1d (the heading convention of
    flatness.py)."""
    thrust = F[0] * R[0][2] + F[1] * R[1][2] + F[2] * R[2][2]
    b3 = _div(F, _sqrt(_dot(F, F)))
    b1 = _cross(y_c, b3)
    b1 = _div(b1, _sqrt(_dot(b1, b1)))
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
    ``mixer_inverse`` is indexed [r][c] (the step passes it as nested tuples); written out rotor by
    rotor, no loop and no array."""
    f = min(max(thrust, thrust_min), thrust_max)
    T = mixer_inverse
    b0, b1, b2, b3 = f * T[0][0], f * T[1][0], f * T[2][0], f * T[3][0]
    d0 = M[0] * T[0][1] + M[1] * T[0][2] + M[2] * T[0][3]
    d1 = M[0] * T[1][1] + M[1] * T[1][2] + M[2] * T[1][3]
    d2 = M[0] * T[2][1] + M[1] * T[2][2] + M[2] * T[2][3]
    d3 = M[0] * T[3][1] + M[1] * T[3][2] + M[2] * T[3][3]
    room = min(min(min(min(lit(f, np.inf), _room(b0, d0, w2_min, w2_max)), _room(b1, d1, w2_min, w2_max)),
                   _room(b2, d2, w2_min, w2_max)), _room(b3, d3, w2_min, w2_max))
    lam = min(room, lit(f, 1.0))
    return (_sqrt(min(max(b0 + lam * d0, w2_min), w2_max)), _sqrt(min(max(b1 + lam * d1, w2_min), w2_max)),
            _sqrt(min(max(b2 + lam * d2, w2_min), w2_max)), _sqrt(min(max(b3 + lam * d3, w2_min), w2_max)))


@_inline
def _room(base, delta, w2_min, w2_max):
    """The largest λ keeping base + λ δ in [w2_min, w2_max] (δ = 0: as good as unbounded; in float32
    the floor 1e-300 is 0, and λ = ±inf or nan, which the ``min`` over the rotors passes over)."""
    return (w2_max - base if delta > 0.0 else base - w2_min) / max(abs(delta), lit(delta, 1e-300))


@_inline
def wrench(w, gain, mixer):
    """Thrust T and moment M (eq. 3.15) of rotors turning at ``gain`` ϖ (4-tuples): a rotor
    keeping a fraction φ of its thrust and drag torque turns at an effective sqrt(φ) ϖ.
    ``mixer`` is indexed [r][c] (nested tuples)."""
    w0, w1, w2, w3 = w[0] * gain[0], w[1] * gain[1], w[2] * gain[2], w[3] * gain[3]
    w0, w1, w2, w3 = w0 * w0, w1 * w1, w2 * w2, w3 * w3
    m = mixer
    return (w0 * m[0][0] + w1 * m[0][1] + w2 * m[0][2] + w3 * m[0][3],
            (w0 * m[1][0] + w1 * m[1][1] + w2 * m[1][2] + w3 * m[1][3],
             w0 * m[2][0] + w1 * m[2][1] + w2 * m[2][2] + w3 * m[2][3],
             w0 * m[3][0] + w1 * m[3][1] + w2 * m[3][2] + w3 * m[3][3]))


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
    norm = _sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
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


# The lanes: one flat array of ROWS rows of STRIDE columns, a column per agent (structure of arrays;
# :func:`_to_lanes`). The state p, v, q, ω:
P, V, Q, W = 0, 3, 6, 10
# the held inputs: the tick's reference p, v, a and its Taylor coefficients v, a, jerk, snap (zero
# off TRACK rows), the heading y_c, Ω_d, Ω̇_d, the position mask (1 or 0), the rotor gains, the wind
# and the force per mass
P_REF, V_REF, A_REF, DV, DA, DJ, DS = 13, 16, 19, 22, 25, 28, 31
HEADING, OMEGA_D, ALPHA_D, MASK, GAIN, WIND, FORCE = 34, 37, 40, 43, 44, 48, 51
# and what a sub-step computes: the commanded rotor speeds, the desired force F
SPEED, FORCE_D = 54, 58
ROWS = 61
BLOCK = 64
"""Agents stepped together as lanes: their rows, ~35 kB, stay in the core's first-level cache
through the sub-steps."""
STRIDE = BLOCK + 8
"""Columns of a row, 8 spare: with rows a power of two of bytes apart, the rows would share a few
cache sets and evict one another (measured: 1.6x slower at 256 columns)."""


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
    SE(3) law (:func:`desired_force`, :func:`cap_tilt`, :func:`se3_control`), allocation with
    limits (eq. 3.16, :func:`allocate`), the rotors' real wrench (eq. 3.15) at ``rotor_gain`` =
    sqrt(health) times the commanded speeds, the wind's force and moment when ``has_wind``
    (:func:`wind_load`), the force per mass ``force`` when ``has_force`` (the disturbances' force
    phase, held over the step), then RK4 (:func:`rk4`). ``rotor_speed`` receives the last
    commanded speeds.

    The agents are stepped as SIMD lanes: ``BLOCK`` at a time, copied into a structure of arrays
    (a column per agent), each sub-step is two loops over the columns that the compiler
    vectorises (:func:`_force_lanes`, :func:`_step_lanes`: one instruction for 4 agents in
    float64, 8 in float32) around the tilt cap agent by agent (:func:`_cap_tilt_lanes`). Each
    agent's arithmetic is the same, in the same order, as when agents were stepped one by one
    (the branches of the law are selects between values computed either way), so the bits are.
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
    lanes = np.zeros(ROWS * STRIDE, J.dtype)  # zeros: the columns past a short block stay finite
    taylor = np.empty(5, J.dtype)
    # the constants as tuples, read once: a loop that reads an array it might also write (for all
    # the compiler knows) needs a runtime check per array before it vectorises
    J, gyro, k_R, k_Omega, drag = _three(J), _three(gyro), _three(k_R), _three(k_Omega), _three(drag)
    mixer, mixer_inverse = _four_by_four(mixer), _four_by_four(mixer_inverse)
    for first in range(start, stop, BLOCK):
        count = min(first + BLOCK, stop) - first
        _to_lanes(first, count, lanes, pos, vel, quat, omega, p_ref, v_ref, a_ref, dv, da, dj, ds, heading,
                  position_mask, omega_d, alpha_d, rotor_gain, wind, has_wind, force, has_force)
        for sub in range(substeps):
            for k in range(4):
                taylor[k] = weights[sub, k]
            taylor[4] = h
            _force_lanes(count, lanes, taylor, k_x, k_v, mass, min_lift)
            _cap_tilt_lanes(count, lanes, tan_max_tilt)
            _step_lanes(count, lanes, taylor, feedforward, mass, J, gyro, k_R, k_Omega, mixer, mixer_inverse,
                        thrust_min, thrust_max, w2_min, w2_max, has_wind, arm, drag, has_force)
        for j in range(count):
            i = first + j
            for k in range(3):
                pos[i, k], vel[i, k] = lanes[_at(P + k, j)], lanes[_at(V + k, j)]
                omega[i, k] = lanes[_at(W + k, j)]
            for k in range(4):
                quat[i, k], rotor_speed[i, k] = lanes[_at(Q + k, j)], lanes[_at(SPEED + k, j)]


@_jit
def _to_lanes(first, count, A, pos, vel, quat, omega, p_ref, v_ref, a_ref, dv, da, dj, ds, heading,
              position_mask, omega_d, alpha_d, rotor_gain, wind, has_wind, force, has_force):
    """Agents ``first:first + count`` into columns 0, 1, ... of the lanes ``A`` (the rows above),
    from the engine's (N, k) arrays."""
    for j in range(count):
        i = first + j
        for k in range(3):
            A[_at(P + k, j)], A[_at(V + k, j)], A[_at(W + k, j)] = pos[i, k], vel[i, k], omega[i, k]
            A[_at(P_REF + k, j)], A[_at(V_REF + k, j)], A[_at(A_REF + k, j)] = p_ref[i, k], v_ref[i, k], a_ref[i, k]
            A[_at(DV + k, j)], A[_at(DA + k, j)] = dv[i, k], da[i, k]
            A[_at(DJ + k, j)], A[_at(DS + k, j)] = dj[i, k], ds[i, k]
            A[_at(HEADING + k, j)], A[_at(OMEGA_D + k, j)] = heading[i, k], omega_d[i, k]
            A[_at(ALPHA_D + k, j)] = alpha_d[i, k]
            A[_at(WIND + k, j)] = wind[i, k] if has_wind else 0.0
            A[_at(FORCE + k, j)] = force[i, k] if has_force else 0.0
        for k in range(4):
            A[_at(Q + k, j)], A[_at(GAIN + k, j)] = quat[i, k], rotor_gain[i, k]
        A[_at(MASK, j)] = 1.0 if position_mask[i] else 0.0


@_jit
def _force_lanes(count, A, taylor, k_x, k_v, mass, min_lift):
    """The sub-step's reference (:func:`_reference`, at τ = ``taylor[0]``) and desired force
    (:func:`desired_force`, before its tilt cap) of columns ``0:count``, into the rows FORCE_D;
    vectorised."""
    tau, t2, t3, t4 = taylor[0], taylor[1], taylor[2], taylor[3]
    for i in range(count):
        p_d, v_d, a_d = _reference(A, i, tau, t2, t3, t4)
        F = desired_force(_column(A, P, i), _column(A, V, i), p_d, v_d, a_d, A[_at(MASK, i)] != 0.0,
                          k_x, k_v, mass, min_lift)
        A[_at(FORCE_D, i)], A[_at(FORCE_D + 1, i)], A[_at(FORCE_D + 2, i)] = F


@_jit
def _cap_tilt_lanes(count, A, tan_max_tilt):
    """:func:`cap_tilt` of the rows FORCE_D, column by column (libm's hypot has no vector form)."""
    for i in range(count):
        A[_at(FORCE_D, i)], A[_at(FORCE_D + 1, i)], A[_at(FORCE_D + 2, i)] = cap_tilt(
            _column(A, FORCE_D, i), tan_max_tilt)


@_jit
def _step_lanes(count, A, taylor, feedforward, mass, J, gyro, k_R, k_Omega, mixer, mixer_inverse,
                thrust_min, thrust_max, w2_min, w2_max, has_wind, arm, drag, has_force):
    """The rest of a sub-step of length h = ``taylor[4]`` for columns ``0:count``: the SE(3) law
    for the capped force, allocation, the rotors' wrench, wind and force, RK4; vectorised (every
    helper inlined, no call left, every choice a select, unsigned indices)."""
    h = taylor[4]
    zero = lit(h, 0.0)
    no_wind = (zero, zero, zero)
    for i in range(count):
        p, v, w = _column(A, P, i), _column(A, V, i), _column(A, W, i)
        q = (A[_at(Q, i)], A[_at(Q + 1, i)], A[_at(Q + 2, i)], A[_at(Q + 3, i)])
        R = rotmat(q[0], q[1], q[2], q[3])
        f, M = se3_control(_column(A, FORCE_D, i), R, w, _column(A, HEADING, i), _column(A, OMEGA_D, i),
                           _column(A, ALPHA_D, i), feedforward, k_R, k_Omega, J)
        speeds = allocate(f, M, mixer_inverse, thrust_min, thrust_max, w2_min, w2_max)
        gain = (A[_at(GAIN, i)], A[_at(GAIN + 1, i)], A[_at(GAIN + 2, i)], A[_at(GAIN + 3, i)])
        thrust, torque = wrench(speeds, gain, mixer)
        wind_acc, moment = wind_load(R, _column(A, WIND, i), drag, mass, arm)
        with_moment = _add(torque, moment)
        ext = wind_acc if has_wind else no_wind
        torque = with_moment if has_wind else torque
        with_force = _add(ext, _column(A, FORCE, i))
        ext = with_force if has_force else ext
        p, v, q, w = rk4(p, v, q, w, thrust, torque, ext, mass, J, gyro, h)
        for k in range(3):
            A[_at(P + k, i)], A[_at(V + k, i)], A[_at(W + k, i)] = p[k], v[k], w[k]
        for k in range(4):
            A[_at(Q + k, i)], A[_at(SPEED + k, i)] = q[k], speeds[k]


@_inline
def _at(row, i):
    """The index of row ``row``, column ``i`` of the lanes, unsigned: numba checks a signed index for
    a negative value (Python's wraparound), and the check keeps a loop from vectorising."""
    return np.uintp(row * STRIDE + i)


@_inline
def _column(A, row, i):
    """Rows row..row+2 of column i, a 3-tuple."""
    return (A[_at(row, i)], A[_at(row + 1, i)], A[_at(row + 2, i)])


@_inline
def _three(a):
    return (a[0], a[1], a[2])


@_inline
def _four_by_four(m):
    return ((m[0, 0], m[0, 1], m[0, 2], m[0, 3]), (m[1, 0], m[1, 1], m[1, 2], m[1, 3]),
            (m[2, 0], m[2, 1], m[2, 2], m[2, 3]), (m[3, 0], m[3, 1], m[3, 2], m[3, 3]))


@_inline
def _reference(A, i, tau, t2, t3, t4):
    """(p_d, v_d, a_d) of column i at τ s after the tick: the quartic Taylor polynomial
    p + τ v + τ²/2 a + τ³/6 j + τ⁴/24 s (and its derivatives) on TRACK rows (the coefficients are
    zero elsewhere); at τ = 0 the latched values themselves (a select: both are computed)."""
    held = (_column(A, P_REF, i), _column(A, V_REF, i), _column(A, A_REF, i))
    p = (A[_at(P_REF, i)] + tau * A[_at(DV, i)] + t2 * A[_at(DA, i)] + t3 * A[_at(DJ, i)] + t4 * A[_at(DS, i)],
         A[_at(P_REF + 1, i)] + tau * A[_at(DV + 1, i)] + t2 * A[_at(DA + 1, i)] + t3 * A[_at(DJ + 1, i)]
         + t4 * A[_at(DS + 1, i)],
         A[_at(P_REF + 2, i)] + tau * A[_at(DV + 2, i)] + t2 * A[_at(DA + 2, i)] + t3 * A[_at(DJ + 2, i)]
         + t4 * A[_at(DS + 2, i)])
    v = (A[_at(V_REF, i)] + tau * A[_at(DA, i)] + t2 * A[_at(DJ, i)] + t3 * A[_at(DS, i)],
         A[_at(V_REF + 1, i)] + tau * A[_at(DA + 1, i)] + t2 * A[_at(DJ + 1, i)] + t3 * A[_at(DS + 1, i)],
         A[_at(V_REF + 2, i)] + tau * A[_at(DA + 2, i)] + t2 * A[_at(DJ + 2, i)] + t3 * A[_at(DS + 2, i)])
    a = (A[_at(A_REF, i)] + tau * A[_at(DJ, i)] + t2 * A[_at(DS, i)],
         A[_at(A_REF + 1, i)] + tau * A[_at(DJ + 1, i)] + t2 * A[_at(DS + 1, i)],
         A[_at(A_REF + 2, i)] + tau * A[_at(DJ + 2, i)] + t2 * A[_at(DS + 2, i)])
    return held if tau == 0.0 else (p, v, a)
