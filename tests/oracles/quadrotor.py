"""The ``quadrotor`` dynamics' physics as it was before its compiled kernel (issue #20): numpy,
vectorised over agents, one call per formula. The package runs methods/quadrotor/kernels.py; the
tests check it against these functions and :class:`QuadrotorOracle` to round-off.

Moved unchanged from methods/quadrotor/model.py (mixer, RK4), se3_controller.py (Lee et al.'s law),
flatness.py (flat state, heading axes) and plugins/dynamics/quadrotor.py (``control`` and
``step``). Frames and symbols as in those modules.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.methods.quadrotor.flatness import heading_vector
from swarmscene.methods.quadrotor.model import (
    _P1,
    _P2,
    _R_BASIS,
    GRAVITY,
    Airframe,
    _outer,
    cross_rows,
    quat_to_rotmat,
)
from swarmscene.methods.quadrotor.se3_controller import SE3Gains
from swarmscene.plugins.dynamics.quadrotor import Quadrotor

# --------------------------------------------------------------------------- mixer (eq. 3.9-3.16)


def wrench(rotor_speed: np.ndarray, airframe: Airframe) -> tuple[np.ndarray, np.ndarray]:
    """Collective thrust T (N,) N and body torque M (N, 3) N m of rotor speeds (N, 4) (eq. 3.15)."""
    u = (rotor_speed * rotor_speed) @ airframe.mixer.T
    return u[:, 0], u[:, 1:]


def allocate(thrust: np.ndarray, torque: np.ndarray, airframe: Airframe) -> np.ndarray:
    """Rotor speeds (N, 4) rad/s realising thrust (N,) and torque (N, 3) (eq. 3.16), within limits.

    When the exact solution ϖ^2 = T^-1 ũ leaves [ϖ_min^2, ϖ_max^2], thrust has priority: the
    collective thrust is clipped to what four rotors can give, then the torque part is scaled by
    the largest λ in [0, 1] keeping every rotor in range (the torque direction is kept, so the
    attitude loop still turns the right way rather than flipping under a clipped rotor).
    """
    inv = airframe.mixer_inverse
    lo, hi = airframe.rotor_speed_min**2, airframe.rotor_speed_max**2
    thrust = np.clip(thrust, 4.0 * airframe.k_T * lo, 4.0 * airframe.k_T * hi)
    base = thrust[:, None] * inv[:, 0]                  # (N, 4), each within [lo, hi]
    delta = torque @ inv[:, 1:].T                       # (N, 4)
    room = np.where(delta > 0.0, hi - base, base - lo) / np.maximum(np.abs(delta), 1e-300)
    lam = np.minimum(room.min(axis=1), 1.0)
    w2 = np.clip(base + lam[:, None] * delta, lo, hi)
    return np.sqrt(w2)



# --------------------------------------------------------------------------- rigid body (eq. 3.4-3.8)

_Z_BASIS = np.ascontiguousarray(_R_BASIS[:, [2, 5, 8]])  # third column of R: body z in the world
_G_IDX = np.array([[1, 2, 3], [0, 3, 2], [3, 0, 1], [2, 1, 0]])
_G_SIGN = 0.5 * np.array([[-1.0, -1, -1], [1, -1, 1], [1, 1, -1], [-1, 1, 1]])
"""q̇ = (q[:, _G_IDX] * _G_SIGN) @ ω: the matrix form of q̇ = ½ q ⊗ (0, ω)."""


def state_derivative(x: np.ndarray, thrust: np.ndarray, torque: np.ndarray,
                     airframe: Airframe) -> np.ndarray:
    """Right-hand side of eq. 3.4-3.7 (world z up, FLU body) for packed states x = [p v q ω] (N, 13).

    ṗ = v; v̇ = (T / m) R e_3 - g e_3; q̇ = ½ q ⊗ (0, ω) (the quaternion form of Ṙ = R [ω×],
    eq. 3.6, 3.8); J ω̇ = -ω × J ω + M, with (ω × J ω)_i = ω_j ω_k (J_k - J_j) for diagonal J.
    """
    return _rhs(x, (thrust / airframe.mass)[:, None], torque / airframe.J, airframe.gyro)


def _rhs(x: np.ndarray, thrust_per_mass: np.ndarray, torque_per_inertia: np.ndarray,
         gyro: np.ndarray, ext_acc: np.ndarray | None = None) -> np.ndarray:
    """:func:`state_derivative` with the held inputs already divided by m and J (RK4 reuses them)."""
    q = x[:, 6:10]
    w = x[:, 10:13]
    out = np.empty_like(x)
    out[:, 0:3] = x[:, 3:6]
    out[:, 3:6] = (_outer(q) @ _Z_BASIS) * thrust_per_mass
    out[:, 5] -= GRAVITY
    if ext_acc is not None:
        out[:, 3:6] += ext_acc
    out[:, 6:10] = ((q[:, _G_IDX] * _G_SIGN) @ w[:, :, None])[:, :, 0]
    out[:, 10:13] = torque_per_inertia - w[:, _P1] * w[:, _P2] * gyro
    return out


def pack(p, v, q, omega) -> np.ndarray:
    """State arrays -> packed (N, 13) [p v q ω]."""
    return np.concatenate([p, v, q, omega], axis=1)


def rk4(x: np.ndarray, thrust: np.ndarray, torque: np.ndarray, airframe: Airframe,
        dt: float, ext_acc: np.ndarray | None = None) -> np.ndarray:
    """One classical RK4 step of the packed state with thrust (N,) and torque (N, 3) held, and
    optionally an external acceleration ``ext_acc`` (N, 3) m/s^2 (world; e.g. the wind's force per
    mass) held too; the quaternion is renormalised."""
    h = 0.5 * dt
    c = (thrust / airframe.mass)[:, None]
    a = torque / airframe.J
    gyro = airframe.gyro
    k1 = _rhs(x, c, a, gyro, ext_acc)
    k2 = _rhs(x + h * k1, c, a, gyro, ext_acc)
    k3 = _rhs(x + h * k2, c, a, gyro, ext_acc)
    k4 = _rhs(x + dt * k3, c, a, gyro, ext_acc)
    x = x + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
    x[:, 6:10] /= np.sqrt((x[:, 6:10] ** 2).sum(axis=1, keepdims=True))
    return x


def rk4_step(p, v, q, omega, thrust, torque, airframe: Airframe, dt: float):
    """:func:`rk4` on unpacked arrays: returns new (p, v, q, omega)."""
    x = rk4(pack(p, v, q, omega), thrust, torque, airframe, dt)
    return x[:, 0:3], x[:, 3:6], x[:, 6:10], x[:, 10:13]


def step_rotors(p, v, q, omega, rotor_speed, airframe: Airframe, dt: float):
    """Advance one physics step under rotor speeds (N, 4), clipped to the airframe's limits."""
    rotor_speed = np.clip(rotor_speed, airframe.rotor_speed_min, airframe.rotor_speed_max)
    thrust, torque = wrench(rotor_speed, airframe)
    return rk4_step(p, v, q, omega, thrust, torque, airframe, dt)


# --------------------------------------------------------------------------- flatness


@dataclass
class FlatState:
    """Attitude-level state implied by flat outputs, for N agents.

    Attributes:
        R: (N, 3, 3) attitude, body to world (columns x_b, y_b, z_b).
        omega: (N, 3) body rates, rad/s, body frame.
        alpha: (N, 3) body angular acceleration ω̇, rad/s^2, body frame.
        thrust: (N,) collective thrust per unit mass |a + g e_3|, m/s^2.
        thrust_rate: (N,) its time derivative, m/s^3.
    """

    R: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    thrust: np.ndarray
    thrust_rate: np.ndarray


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a * b).sum(axis=1)


def normalize_with_derivatives(n, n_dot, n_ddot):
    """u = n / |n| and its first two time derivatives, for (N, 3) arrays.

    With ν = |n|: u̇ = (ṅ - (u·ṅ) u) / ν, ü = (n̈ - ν̈ u - 2 ν̇ u̇) / ν, ν̇ = u·ṅ, ν̈ = u̇·ṅ + u·n̈.
    """
    nu = np.linalg.norm(n, axis=1)[:, None]
    u = n / nu
    nu_dot = _dot(u, n_dot)[:, None]
    u_dot = (n_dot - nu_dot * u) / nu
    nu_ddot = (_dot(u_dot, n_dot) + _dot(u, n_ddot))[:, None]
    u_ddot = (n_ddot - nu_ddot * u - 2.0 * nu_dot * u_dot) / nu
    return u, u_dot, u_ddot


def heading_axes(z_b: np.ndarray, yaw: np.ndarray | None = None, y_c: np.ndarray | None = None):
    """Body axes (x_b, y_b) of thrust direction z_b (N, 3) and yaw ψ (N,) (module docstring);
    pass ``y_c`` = :func:`heading_vector` (ψ) instead of ψ to reuse it while ψ is held."""
    y_c = heading_vector(yaw) if y_c is None else y_c
    x_b = cross_rows(y_c, z_b)
    x_b /= np.linalg.norm(x_b, axis=1, keepdims=True)
    return x_b, cross_rows(z_b, x_b)


def flat_state(
    acc: np.ndarray,
    jerk: np.ndarray,
    snap: np.ndarray,
    yaw: np.ndarray,
    yaw_rate: np.ndarray | None = None,
    yaw_acc: np.ndarray | None = None,
) -> FlatState:
    """Attitude, body rates, angular acceleration and thrust of flat outputs (Mellinger and Kumar
    2011, sec. III; VRB paper sec. III).

    Args:
        acc: (N, 3) p̈ in the world frame.
        jerk: (N, 3) p⃛.
        snap: (N, 3) p⁗.
        yaw: (N,) ψ.
        yaw_rate: (N,) ψ̇ (default zero).
        yaw_acc: (N,) ψ̈ (default zero).

    The thrust vector per unit mass is t = a + g e_3, so z_b = t / |t|, and its derivatives follow
    from ṫ = j, ẗ = s; the body rates are read from R^T Ṙ = [ω×] (eq. 3.6):
    ω = (z_b·ẏ_b, x_b·ż_b, y_b·ẋ_b), and α is their derivative.
    """
    n = acc.shape[0]
    yaw_rate = np.zeros(n) if yaw_rate is None else yaw_rate
    yaw_acc = np.zeros(n) if yaw_acc is None else yaw_acc
    t = acc + np.array([0.0, 0.0, GRAVITY])
    z, z_d, z_dd = normalize_with_derivatives(t, jerk, snap)

    c, s = np.cos(yaw), np.sin(yaw)
    zero = np.zeros(n)
    y_c = np.stack([-s, c, zero], axis=1)
    y_c_d = yaw_rate[:, None] * np.stack([-c, -s, zero], axis=1)
    y_c_dd = yaw_acc[:, None] * np.stack([-c, -s, zero], axis=1) + (yaw_rate**2)[:, None] * np.stack(
        [s, -c, zero], axis=1)
    m = cross_rows(y_c, z)
    m_d = cross_rows(y_c_d, z) + cross_rows(y_c, z_d)
    m_dd = cross_rows(y_c_dd, z) + 2.0 * cross_rows(y_c_d, z_d) + cross_rows(y_c, z_dd)
    x, x_d, x_dd = normalize_with_derivatives(m, m_d, m_dd)
    y = cross_rows(z, x)
    y_d = cross_rows(z_d, x) + cross_rows(z, x_d)
    y_dd = cross_rows(z_dd, x) + 2.0 * cross_rows(z_d, x_d) + cross_rows(z, x_dd)

    omega = np.stack([_dot(z, y_d), _dot(x, z_d), _dot(y, x_d)], axis=1)
    alpha = np.stack([
        _dot(z_d, y_d) + _dot(z, y_dd),
        _dot(x_d, z_d) + _dot(x, z_dd),
        _dot(y_d, x_d) + _dot(y, x_dd),
    ], axis=1)
    thrust = np.linalg.norm(t, axis=1)
    return FlatState(R=np.stack([x, y, z], axis=2), omega=omega, alpha=alpha, thrust=thrust,
                     thrust_rate=_dot(z, jerk))


def flat_inputs(ff: FlatState, mass: float, inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop collective thrust (N,) N and body torque (N, 3) N m of a flat state (eq. 3.5, 3.7):
    f = m |a + g e_3|, M = J α + ω × J ω, with ``inertia`` the diagonal of J (3,)."""
    J = np.asarray(inertia, dtype=float)
    return mass * ff.thrust, ff.alpha * J + cross_rows(ff.omega, ff.omega * J)


def taylor_propagate(pos, vel, acc, jerk, snap, tau: float):
    """Flat outputs advanced by ``tau`` s along their quartic Taylor polynomial: (p, v, a, j).

    Used between guidance ticks so an inner loop at the physics rate sees a moving reference
    instead of a staircase (exact for trajectories with constant snap)."""
    t2, t3, t4 = tau * tau / 2.0, tau**3 / 6.0, tau**4 / 24.0
    return (pos + tau * vel + t2 * acc + t3 * jerk + t4 * snap,
            vel + tau * acc + t2 * jerk + t3 * snap,
            acc + tau * jerk + t2 * snap,
            jerk + tau * snap)


# --------------------------------------------------------------------------- SE(3) control


def desired_force(p, v, p_d, v_d, a_d, gains: SE3Gains, mass: float,
                  position_mask: np.ndarray | None = None, max_tilt: float = np.radians(45.0),
                  min_lift: float = 0.2) -> np.ndarray:
    """F = -k_x e_x - k_v e_v + m g e_3 + m a_d (N, 3), with the lift/tilt safeguards.

    ``position_mask`` (N,) bool: where False the position error is ignored (velocity mode).
    """
    e_x = p - p_d
    if position_mask is not None:
        e_x = e_x * position_mask[:, None]
    F = -gains.k_x * e_x - gains.k_v * (v - v_d) + mass * a_d
    F[:, 2] = np.maximum(F[:, 2] + mass * GRAVITY, min_lift * mass * GRAVITY)
    h = np.hypot(F[:, 0], F[:, 1])
    h_max = F[:, 2] * np.tan(max_tilt)
    F[:, :2] *= np.minimum(1.0, h_max / np.maximum(h, 1e-12))[:, None]
    return F


def attitude_torque(R, omega, R_d, omega_d, alpha_d, gains: SE3Gains, inertia: np.ndarray):
    """Lee et al.'s moment M (N, 3) and attitude error e_R (N, 3).

    Args:
        R: (N, 3, 3) attitude.
        omega: (N, 3) body rates.
        R_d: (N, 3, 3) desired attitude.
        omega_d: (N, 3) desired body rates, in the desired frame, or ``None`` for zero
            (hover-like references: skips two batched products).
        alpha_d: (N, 3) their derivative, or ``None`` for zero.
        gains: k_R and k_Omega.
        inertia: (3,) diagonal of J.
    """
    A = R_d.transpose(0, 2, 1) @ R                     # R_d^T R
    e_R = 0.5 * (A - A.transpose(0, 2, 1))[:, _VEE_ROW, _VEE_COL]
    J = inertia
    M = -gains.k_R * e_R + cross_rows(omega, omega * J)
    if omega_d is None:
        return M - gains.k_Omega * omega, e_R
    At = A.transpose(0, 2, 1)                          # R^T R_d
    w_d = (At @ omega_d[:, :, None])[:, :, 0]
    a_d = (At @ alpha_d[:, :, None])[:, :, 0]
    return M - gains.k_Omega * (omega - w_d) - J * (cross_rows(omega, w_d) - a_d), e_R


_VEE_ROW, _VEE_COL = [2, 0, 1], [1, 2, 0]
"""(S[2, 1], S[0, 2], S[1, 0]) is the vector of a skew matrix S (the ∨ map, inverse of eq. 3.8)."""


def se3_control(p, v, R, omega, p_d, v_d, a_d, yaw_d, omega_d, alpha_d, gains: SE3Gains,
                airframe: Airframe, position_mask=None, max_tilt: float = np.radians(45.0),
                heading: np.ndarray | None = None):
    """Full tracking law: returns thrust f (N,) N, torque M (N, 3) N m and R_d (N, 3, 3).

    Args:
        p: (N, 3) position.
        v: (N, 3) velocity.
        R: (N, 3, 3) attitude.
        omega: (N, 3) body rates.
        p_d: (N, 3) reference position.
        v_d: (N, 3) reference velocity.
        a_d: (N, 3) feed-forward acceleration.
        yaw_d: (N,) ψ_d.
        omega_d: (N, 3) flatness feed-forward body rates (None: zero).
        alpha_d: (N, 3) flatness feed-forward angular acceleration (None: zero).
        gains: the SE(3) gains.
        airframe: mass and inertia.
        position_mask: (N,) bool, False where only velocity is tracked.
        max_tilt: largest tilt of the desired thrust, rad.
        heading: optional (N, 3) ``flatness.heading_vector(yaw_d)``, reused while ψ_d is held.
    """
    F = desired_force(p, v, p_d, v_d, a_d, gains, airframe.mass, position_mask, max_tilt)
    thrust = (F * R[:, :, 2]).sum(axis=1)
    b3 = F / np.linalg.norm(F, axis=1, keepdims=True)
    b1, b2 = heading_axes(b3, yaw_d, heading)
    R_d = np.stack([b1, b2, b3], axis=2)
    M, _ = attitude_torque(R, omega, R_d, omega_d, alpha_d, gains, airframe.J)
    return np.maximum(thrust, 0.0), M, R_d


# --------------------------------------------------------------------------- the plugin's step


class QuadrotorOracle(Quadrotor):
    """The ``quadrotor`` plugin with its numpy ``control`` and ``step`` (same options, same events)."""

    def control(self, world: WorldState, sp: Setpoints) -> None:
        """Latch this tick's references (zero-order hold, or Taylor propagation in TRACK mode)."""
        n = world.n
        mode = np.where(world.healthy, sp.mode, Mode.HOLD)
        hold = (mode == Mode.HOLD)[:, None]
        zeros = np.zeros((n, 3))
        jerk = zeros if sp.jerk is None else sp.jerk
        snap = zeros if sp.snap is None else sp.snap
        self._p = np.where(world.healthy[:, None], sp.pos, world.pos)
        self._v = np.where(hold, 0.0, sp.vel)
        self._a = np.where(hold, 0.0, sp.acc)
        self._yaw = np.asarray(sp.yaw, dtype=float).copy()
        self._heading = heading_vector(self._yaw)
        self._position_mask = mode != Mode.VELOCITY
        track = (mode == Mode.TRACK)[:, None] & self.params.propagate_reference
        # derivatives used to move the reference during the tick (zero rows: not propagated)
        self._dv = np.where(track, self._v, 0.0)
        self._da = np.where(track, self._a, 0.0)
        self._dj = np.where(track, jerk, 0.0)
        self._ds = np.where(track, snap, 0.0)
        self._tau = 0.0
        if sp.jerk is None and sp.snap is None:
            # constant acceleration and heading: the flat body rates are zero
            self._omega_d = self._alpha_d = None
        else:
            ff = flat_state(self._a, np.where(hold, 0.0, jerk), np.where(hold, 0.0, snap), self._yaw)
            self._omega_d, self._alpha_d = ff.omega, ff.alpha

    def step(self, world: WorldState, dt: float) -> None:
        """Advance the rigid bodies by ``dt`` (in sub-steps of at most ``max_step``)."""
        substeps = max(1, math.ceil(dt / self.params.max_step - 1e-9))
        h = dt / substeps
        af = self.airframe
        x = pack(world.pos, world.vel, world.quat, world.omega)
        for _ in range(substeps):
            p_d, v_d, a_d = self._reference(self._tau)
            thrust, torque, _ = se3_control(
                x[:, 0:3], x[:, 3:6], quat_to_rotmat(x[:, 6:10]), x[:, 10:13], p_d, v_d, a_d,
                self._yaw, self._omega_d, self._alpha_d, self.gains, af, self._position_mask,
                self.max_tilt, self._heading)
            rotor_speed = allocate(thrust, torque, af)
            thrust, torque = wrench(self._effective(rotor_speed), af)   # what the rotors really give
            ext_acc = None
            if world.wind is not None:
                ext_acc, moment = self._wind(x, world.wind, world.wind_moment_arm)
                torque = torque + moment
            x = rk4(x, thrust, torque, af, h, ext_acc)
            self._tau += h
        world.pos[...] = x[:, 0:3]
        world.vel[...] = x[:, 3:6]
        world.quat[...] = x[:, 6:10]
        world.omega[...] = x[:, 10:13]
        world.rotor_speed[...] = rotor_speed

    def _effective(self, rotor_speed: np.ndarray) -> np.ndarray:
        """Rotor speeds giving the thrust the rotors really make: sqrt(kept fraction) ϖ."""
        if self.rotor_health is None:
            return rotor_speed
        return rotor_speed * np.sqrt(self.rotor_health)

    def _wind(self, x: np.ndarray, wind: np.ndarray, arm: float) -> tuple[np.ndarray, np.ndarray]:
        """The wind's acceleration (N, 3) world and moment (N, 3) N m body: a = R D R^T w and
        M = (0, 0, h) x m D R^T w (the drag force acting at the centre of pressure)."""
        R = quat_to_rotmat(x[:, 6:10])
        f_body = np.einsum("nji,nj->ni", R, wind) * np.asarray(self.airframe.drag)  # per mass
        acc = np.einsum("nij,nj->ni", R, f_body)
        m = self.airframe.mass
        moment = np.column_stack([-arm * m * f_body[:, 1], arm * m * f_body[:, 0], np.zeros(len(x))])
        return acc, moment

    def wind_acceleration(self, world: WorldState) -> np.ndarray:
        return self._wind(pack(world.pos, world.vel, world.quat, world.omega), world.wind, 0.0)[0]

    def _reference(self, tau: float):
        """(p_d, v_d, a_d) at ``tau`` s after the tick (Taylor polynomial on TRACK rows)."""
        if tau == 0.0:
            return self._p, self._v, self._a
        t2, t3, t4 = tau * tau / 2.0, tau**3 / 6.0, tau**4 / 24.0
        p = self._p + tau * self._dv + t2 * self._da + t3 * self._dj + t4 * self._ds
        v = self._v + tau * self._da + t2 * self._dj + t3 * self._ds
        a = self._a + tau * self._dj + t2 * self._ds
        return p, v, a

