"""Geometric tracking controller on SE(3) (Lee, Leok and McClamroch, CDC 2010), vectorised.

Written in the engine's frames (world z up, body front-left-up, thrust +z_b), so Lee's z-down
formulas change the sign of gravity only:

    e_x = p - p_d, e_v = v - v_d
    F   = -k_x e_x - k_v e_v + m g e_3 + m a_d            (desired force, world)
    f   = F · R e_3                                        (collective thrust)
    R_d = [x_d, y_d, F/|F|], heading from ψ_d              (see flatness.heading_axes)
    e_R = ½ (R_d^T R - R^T R_d)^∨,  e_Ω = Ω - R^T R_d Ω_d
    M   = -k_R e_R - k_Ω e_Ω + Ω × J Ω - J (Ω × R^T R_d Ω_d - R^T R_d Ω̇_d)

The feed-forward a_d, Ω_d, Ω̇_d comes from differential flatness (Mellinger and Kumar 2011) of the
reference's acceleration, jerk, snap and yaw (:func:`flatness.flat_state`); Lee's Ω_d is the rate of
R_d, which also contains the feedback's own rate: using the reference's rates is the usual choice
(Mellinger and Kumar) and avoids differentiating measured errors.

Two safeguards (not in Lee's paper, needed when setpoints jump): the desired force keeps a
vertical component of at least ``min_lift`` m g, and its tilt from vertical is capped at
``max_tilt`` by shortening the horizontal part (altitude has priority over lateral motion).
Gains are given as natural frequencies and damping ratios and scaled by the airframe's m and J,
so one set of numbers behaves alike on a 27 g and a 1 kg quadrotor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .flatness import heading_axes
from .model import GRAVITY, Airframe, cross_rows


@dataclass(frozen=True)
class SE3Gains:
    """Lee et al.'s gains: k_x N/m, k_v N s/m (scalars), k_R N m/rad, k_Ω N m s/rad ((3,) per body axis)."""

    k_x: float
    k_v: float
    k_R: np.ndarray
    k_Omega: np.ndarray


def se3_gains(airframe: Airframe, position_omega: float = 4.0, position_xi: float = 0.9,
              attitude_omega: float = 25.0, attitude_xi: float = 0.8,
              yaw_omega: float = 8.0) -> SE3Gains:
    """Gains giving each linearised loop the natural frequency ω_n (rad/s) and damping ξ asked:
    k_x = m ω_n^2, k_v = 2 ξ m ω_n; k_R = J ω_R^2, k_Ω = 2 ξ_R J ω_R (yaw axis at ``yaw_omega``).

    The attitude loop should be several times faster than the position loop (time-scale
    separation of the cascade, thesis 3.2.1) and slow against the physics rate (ω_R dt << 1).
    """
    m, J = airframe.mass, airframe.J
    w_att = np.array([attitude_omega, attitude_omega, yaw_omega])
    return SE3Gains(
        k_x=m * position_omega**2,
        k_v=2.0 * position_xi * m * position_omega,
        k_R=J * w_att**2,
        k_Omega=2.0 * attitude_xi * J * w_att,
    )


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
        R, R_d: (N, 3, 3) attitude and desired attitude. omega: (N, 3) body rates.
        omega_d, alpha_d: (N, 3) desired body rates and their derivative, in the desired frame,
            or ``None`` for zero (hover-like references: skips two batched products).
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
        p, v: (N, 3) position and velocity. R: (N, 3, 3) attitude. omega: (N, 3) body rates.
        p_d, v_d, a_d: (N, 3) reference and its feed-forward acceleration. yaw_d: (N,) ψ_d.
        omega_d, alpha_d: (N, 3) flatness feed-forward body rates and acceleration (None: zero).
        position_mask: (N,) bool, False where only velocity is tracked.
        heading: optional (N, 3) ``flatness.heading_vector(yaw_d)``, reused while ψ_d is held.
    """
    F = desired_force(p, v, p_d, v_d, a_d, gains, airframe.mass, position_mask, max_tilt)
    thrust = (F * R[:, :, 2]).sum(axis=1)
    b3 = F / np.linalg.norm(F, axis=1, keepdims=True)
    b1, b2 = heading_axes(b3, yaw_d, heading)
    R_d = np.stack([b1, b2, b3], axis=2)
    M, _ = attitude_torque(R, omega, R_d, omega_d, alpha_d, gains, airframe.J)
    return np.maximum(thrust, 0.0), M, R_d
