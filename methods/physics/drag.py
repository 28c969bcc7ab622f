"""Drag: rotor drag, linear in airspeed (Foerster 2015), and the body's parasitic drag, quadratic.

Rotor drag (Foerster, J., "System Identification of the Crazyflie 2.0 Nano Quadrocopter", BSc
thesis, ETH Zürich 2015, section 4.3; the model of gym-pybullet-drones ``_drag``):

    F_a = -K_aero θ̇_Σ R^T v   (body frame),   a = R F_a / m = -(θ̇_Σ / m) R K_aero R^T v

with K_aero = diag(9.1785e-7, 9.1785e-7, 10.311e-7) kg/rad and θ̇_Σ the sum of the rotor speeds
(rad/s; four at hover, 6064 rad/s, where K_aero θ̇_Σ / m = 0.206 1/s sideways).

Body drag (parasitic, quadratic): a = -(c_b / m) |v| v with c_b = ½ ρ C_D A (kg/m). The default
c_b = ½ 1.225 kg/m^3 x 1.18 x 1.5e-3 m^2 = 1.08e-3 kg/m is an estimate, not a published
identification: C_D = 1.18 of a flat plate broadside (Hoerner, Fluid-Dynamic Drag, 1965) and a
frontal area of 15 cm^2 for the Crazyflie's 92 x 92 mm frame seen edge-on with its deck.

v is the velocity relative to still air. A declared wind model adds the wind's part
R D R^T w itself (Dynamics.wind_acceleration), so with both the total is linear in w - v.
"""

from __future__ import annotations

import numpy as np


def rotor_drag(vel, rot, rotor_sum, k_aero, mass: float) -> np.ndarray:
    """a (N, 3) m/s^2 = -(θ̇_Σ / m) R K_aero R^T v (``rot`` (N, 3, 3) body to world, or None: level)."""
    vel = np.asarray(vel, dtype=float)
    k = np.asarray(k_aero, dtype=float)
    if rot is None:
        body = vel * k
    else:
        body = np.einsum("nij,nj->ni", rot, np.einsum("nji,nj->ni", rot, vel) * k)
    return -(np.asarray(rotor_sum, dtype=float) / mass)[:, None] * body


def body_drag(vel, c_body: float, mass: float) -> np.ndarray:
    """a (N, 3) m/s^2 = -(c_b / m) |v| v."""
    vel = np.asarray(vel, dtype=float)
    speed = np.sqrt(np.einsum("ij,ij->i", vel, vel))
    return -(c_body / mass) * speed[:, None] * vel
