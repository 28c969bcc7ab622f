"""The rotors' thrust per unit mass of each vehicle, read from the world state (m/s^2, world frame).

The effects that scale with thrust (ground effect, the battery's limit) and rotor drag need what
the rotors do now; each dynamics model tells it differently:

* rotor-level models (``world.rotor_speed`` and ``world.quat``, the ``quadrotor``):
  τ = k_T Σ ϖ_r² / m R e_3, the speeds the controller commanded in the last physics step;
* models with an acceleration input (``world.acc``, the ``double_integrator``): τ = u + g e_3
  (the attitude loop taken as perfect, thesis 3.2.2);
* kinematic models (neither): hover, τ = g e_3.
"""

from __future__ import annotations

import numba
import numpy as np

from .crazyflie import GRAVITY


def body_z(quat: np.ndarray) -> np.ndarray:
    """R e_3 (N, 3) of body-to-world quaternions (w, x, y, z)."""
    w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    return np.column_stack((2.0 * (w * y + x * z), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z))


def thrust_per_mass(world, k_T: float, mass: float) -> np.ndarray:
    """τ (N, 3) m/s^2 of every vehicle (module docstring)."""
    if world.rotor_speed is not None and world.quat is not None:
        return _rotor_thrust(np.ascontiguousarray(world.rotor_speed, dtype=np.float64),
                             np.ascontiguousarray(world.quat, dtype=np.float64), k_T / mass)
    tau = np.zeros((world.n, 3)) if world.acc is None else np.array(world.acc, dtype=float)
    tau[:, 2] += GRAVITY
    return tau


@numba.njit(cache=True)
def _rotor_thrust(rotor_speed, quat, k):
    """k Σ ϖ_r² R e_3 per agent (compiled: one pass, no temporaries)."""
    out = np.empty((quat.shape[0], 3))
    for i in range(quat.shape[0]):
        w2 = 0.0
        for r in range(rotor_speed.shape[1]):
            w2 += rotor_speed[i, r] * rotor_speed[i, r]
        w, x, y, z = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
        c = k * w2
        out[i, 0] = c * 2.0 * (w * y + x * z)
        out[i, 1] = c * 2.0 * (y * z - w * x)
        out[i, 2] = c * (w * w - x * x - y * y + z * z)
    return out


def rotor_speed_sum(world, hover_speed: float) -> np.ndarray:
    """Σ_r ϖ_r (N,) rad/s: the rotors' speeds where the model has them, else four at hover."""
    if world.rotor_speed is not None:
        return world.rotor_speed.sum(axis=1)
    return np.full(world.n, 4.0 * hover_speed)
