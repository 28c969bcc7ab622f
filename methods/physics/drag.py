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

import math

import numba
import numpy as np


def rotor_drag(vel, quat, rotor_sum, k_aero, mass: float) -> np.ndarray:
    """a (N, 3) m/s^2 = -(θ̇_Σ / m) R K_aero R^T v, R of the body-to-world quaternions ``quat``
    (N, 4) (w, x, y, z), or level when None. Compiled (one pass over the agents)."""
    vel = np.ascontiguousarray(vel, dtype=np.float64)
    k = np.ascontiguousarray(k_aero, dtype=np.float64)
    rotor_sum = np.ascontiguousarray(rotor_sum, dtype=np.float64)
    if quat is None:
        return -(rotor_sum / mass)[:, None] * (vel * k)
    return _rotor_drag(vel, np.ascontiguousarray(quat, dtype=np.float64), rotor_sum, k, mass, 0.0)[0]


def drag_acceleration(vel, quat, rotor_sum, k_aero, mass: float, c_body: float) -> tuple[np.ndarray, float]:
    """:func:`rotor_drag` + :func:`body_drag` in one compiled pass (``quat`` None: level), and the
    largest magnitude of it (m/s^2)."""
    if quat is None:
        acc = rotor_drag(vel, None, rotor_sum, k_aero, mass) + body_drag(vel, c_body, mass)
        return acc, float(np.sqrt(np.einsum("ij,ij->i", acc, acc)).max(initial=0.0))
    return _rotor_drag(np.ascontiguousarray(vel, dtype=np.float64), np.ascontiguousarray(quat, dtype=np.float64),
                       np.ascontiguousarray(rotor_sum, dtype=np.float64),
                       np.ascontiguousarray(k_aero, dtype=np.float64), mass, c_body)


@numba.njit(cache=True)
def _rotor_drag(vel, quat, rotor_sum, k, mass, c_body):
    out = np.empty_like(vel)
    peak = 0.0
    for i in range(vel.shape[0]):
        w, x, y, z = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
        r = ((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
             (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
             (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))
        c = -rotor_sum[i] / mass
        b0 = c * k[0] * (r[0][0] * vel[i, 0] + r[1][0] * vel[i, 1] + r[2][0] * vel[i, 2])
        b1 = c * k[1] * (r[0][1] * vel[i, 0] + r[1][1] * vel[i, 1] + r[2][1] * vel[i, 2])
        b2 = c * k[2] * (r[0][2] * vel[i, 0] + r[1][2] * vel[i, 1] + r[2][2] * vel[i, 2])
        q = -c_body / mass * math.sqrt(vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
        for j in range(3):
            out[i, j] = r[j][0] * b0 + r[j][1] * b1 + r[j][2] * b2
            if c_body != 0.0:
                out[i, j] += q * vel[i, j]
        peak = max(peak, math.sqrt(out[i, 0] ** 2 + out[i, 1] ** 2 + out[i, 2] ** 2))
    return out, peak


def body_drag(vel, c_body: float, mass: float) -> np.ndarray:
    """a (N, 3) m/s^2 = -(c_b / m) |v| v."""
    vel = np.asarray(vel, dtype=float)
    speed = np.sqrt(np.einsum("ij,ij->i", vel, vel))
    return -(c_body / mass) * speed[:, None] * vel
