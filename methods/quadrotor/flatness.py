"""Differential flatness of the quadrotor (Mellinger and Kumar 2011), vectorised over agents.

The flat outputs σ = (p, ψ) and their derivatives (velocity, acceleration a, jerk j, snap s, yaw
rate ψ̇ and yaw acceleration ψ̈) determine the attitude R, body rates ω, angular acceleration α and
the collective thrust of a quadrotor exactly (the "endogenous transformation" the VRB paper uses in
section III to turn every vehicle's flat outputs into feed-forward inputs of an SE(3) controller).
World frame z up (core/state.py), body frame front-left-up, thrust along +z_b.

Heading convention: the body x axis is chosen perpendicular to y_c = (-sin ψ, cos ψ, 0), i.e.
x_b = (y_c × z_b) / |y_c × z_b|, y_b = z_b × x_b. Its horizontal projection then points exactly along
ψ, so ψ is the ZYX (yaw-pitch-roll) Euler yaw of R, the sequence the thesis uses (eq. 3.1-3.2).
(Mellinger and Kumar project x_c = (cos ψ, sin ψ, 0) instead, which makes ψ a ZXY yaw.) The
construction is singular only at ±90° of roll.

Use:
    ff = flat_state(acc, jerk, snap, yaw, yaw_rate, yaw_acc)   # attitude, rates, thrust / m
    thrust, torque = flat_inputs(ff, mass, inertia)           # open-loop inputs (N, N m)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import GRAVITY, cross_rows


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


def heading_vector(yaw: np.ndarray) -> np.ndarray:
    """y_c = (-sin ψ, cos ψ, 0) (N, 3): the horizontal direction the body x axis is kept normal to."""
    return np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], axis=1)


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
        acc, jerk, snap: (N, 3) p̈, p⃛, p⁗ in the world frame.
        yaw, yaw_rate, yaw_acc: (N,) ψ, ψ̇, ψ̈ (rates default to zero).

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
