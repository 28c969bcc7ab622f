"""Compiled per-step forms of :mod:`.battery` and :mod:`.ground_effect` (numba): one pass over the
vehicles, no temporaries.

:func:`battery_step` is :mod:`.battery`'s functions composed for one physics step, loop by loop,
and :func:`ground_lift` :func:`.ground_effect.thrust_ratio` applied to the thrust (tests/methods/physics
compare them to 1e-12); the NumPy functions stay the documented form.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def battery_step(charge, depleted, tau, dt, mass, weight, capacity, v_full, v_empty, resistance, cutoff,
                 hover_power, thrust_to_weight):
    """Draw one step of thrust ``tau`` (N, 3) m/s^2 from the cells: update ``charge`` (N,) and
    ``depleted`` (N,) bool in place; return the terminal voltages (N,), the cut acceleration
    (N, 3) m/s^2 (-the thrust the cells cannot give, per mass, along tau) and which vehicles ran out
    in this step (N,) bool."""
    n = charge.shape[0]
    voltage = np.empty(n)
    cut = np.zeros((n, 3))
    out = np.zeros(n, np.bool_)
    lowest = v_full
    for i in range(n):
        tx, ty, tz = tau[i, 0], tau[i, 1], tau[i, 2]
        thrust = mass * math.sqrt(tx * tx + ty * ty + tz * tz)
        v_oc = v_empty + (v_full - v_empty) * charge[i]
        v_c = max(cutoff, 0.5 * v_oc)
        cap = v_c * (v_oc - v_c) / resistance if v_oc > cutoff else 0.0
        x = max(thrust, 0.0) / weight
        demand = hover_power * x * math.sqrt(x)  # P_h x^(3/2)
        p = min(demand, cap)
        amps = 0.0
        if not depleted[i]:
            amps = (v_oc - math.sqrt(max(v_oc * v_oc - 4.0 * resistance * p, 0.0))) / (2.0 * resistance)
        voltage[i] = v_oc - amps * resistance
        lowest = min(lowest, voltage[i])
        charge[i] = max(charge[i] - amps * dt / (3600.0 * capacity), 0.0)
        if not depleted[i] and (charge[i] <= 0.0 or v_oc <= cutoff):
            depleted[i] = True
            out[i] = True
        v = voltage[i] / v_full
        t_max = thrust_to_weight * weight * v * v
        # the thrust is cut where it exceeds T_max or needs more power than the cap (T_c < T exactly
        # when P(T) > P_c, P increasing): T_c, a cube root, only then
        if depleted[i] or thrust > t_max or demand > cap:
            available = 0.0
            if not depleted[i]:
                available = min(t_max, weight * (max(cap, 0.0) / hover_power) ** (2.0 / 3.0))
            if thrust > available:
                f = (thrust - available) / thrust
                cut[i, 0], cut[i, 1], cut[i, 2] = -f * tx, -f * ty, -f * tz
    return voltage, cut, out, lowest


@numba.njit(cache=True)
def ground_lift(z, tau, floor, rotor_radius, min_height):
    """(T_IGE / T_OGE - 1) tau per vehicle (N, 3) m/s^2 at heights ``z`` (N,) above ``floor``, and the
    largest ratio applied."""
    n = z.shape[0]
    out = np.empty((n, 3))
    peak = 1.0
    for i in range(n):
        h = max(z[i] - floor, min_height)
        q = rotor_radius / (4.0 * h)
        ratio = 1.0 / (1.0 - q * q)
        peak = max(peak, ratio)
        for j in range(3):
            out[i, j] = (ratio - 1.0) * tau[i, j]
    return out, peak
