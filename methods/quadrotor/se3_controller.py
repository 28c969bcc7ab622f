"""Geometric tracking controller on SE(3) (Lee, Leok and McClamroch, CDC 2010): the law and its gains.

Written in the engine's frames (world z up, body front-left-up, thrust +z_b), so Lee's z-down
formulas change the sign of gravity only:

    e_x = p - p_d, e_v = v - v_d
    F   = -k_x e_x - k_v e_v + m g e_3 + m a_d            (desired force, world)
    f   = F · R e_3                                        (collective thrust)
    R_d = [x_d, y_d, F/|F|], heading from ψ_d              (flatness' heading convention)
    e_R = ½ (R_d^T R - R^T R_d)^∨,  e_Ω = Ω - R^T R_d Ω_d
    M   = -k_R e_R - k_Ω e_Ω + Ω × J Ω - J (Ω × R^T R_d Ω_d - R^T R_d Ω̇_d)

The feed-forward a_d, Ω_d, Ω̇_d comes from differential flatness (Mellinger and Kumar 2011) of the
reference's acceleration, jerk, snap and yaw (:func:`kernels.flat_rates`); Lee's Ω_d is the rate of
R_d, which also contains the feedback's own rate: using the reference's rates is the usual choice
(Mellinger and Kumar) and avoids differentiating measured errors.

Two safeguards (not in Lee's paper, needed when setpoints jump): the desired force keeps a
vertical component of at least ``min_lift`` m g, and its tilt from vertical is capped at
``max_tilt`` by shortening the horizontal part (altitude has priority over lateral motion).
Gains are given as natural frequencies and damping ratios and scaled by the airframe's m and J,
so one set of numbers behaves alike on a 27 g and a 1 kg quadrotor.

The law runs compiled, per agent, in :func:`kernels.desired_force` (with ``min_lift`` = 0.2),
:func:`kernels.cap_tilt` and :func:`kernels.se3_control`; its numpy form is the tests' oracle
(tests/oracles/quadrotor.py). This module keeps the gain synthesis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Airframe


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
