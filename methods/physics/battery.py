"""A battery: state of charge, voltage sag under load, and the thrust it can still give.

Per vehicle and physics step dt, from the thrust T the rotors make (:mod:`.thrust`):

    P = P_h (T / (m g))^(3/2)                      electrical power, W (momentum theory: induced
                                                   power ∝ T^(3/2), Leishman, Principles of
                                                   Helicopter Aerodynamics, 2006, eq. 2.16)
    V_oc = V_e + (V_f - V_e) s                     open-circuit voltage, linear in the charge s
    I = (V_oc - sqrt(V_oc² - 4 R_i P)) / (2 R_i)   the current that delivers P through R_i
                                                   (P = (V_oc - I R_i) I, the smaller root)
    V = V_oc - I R_i                               terminal voltage (the sag)
    s <- s - I dt / (3600 Q)                       Coulomb counting, Q in Ah
    T_max = (T/W)_max m g (V / V_f)²               the rotors' speed is proportional to the motor
                                                   voltage and thrust to its square

The cell never draws its terminal voltage under the cut-off V_c: the power is capped at
P_c = V_c (V_oc - V_c) / R_i (the power at I = (V_oc - V_c) / R_i; at most V_oc² / (4 R_i), the
cell's maximum), so the thrust is also capped at T_c = m g (P_c / P_h)^(2/3), and the thrust the
vehicle gets is min(T, T_max, T_c). A vehicle whose charge reaches 0 or whose open-circuit voltage
falls to the cut-off is depleted: its thrust is cut (an event, ``battery_depleted``) and it falls.

Crazyflie-class parameters (:mod:`.crazyflie`): Q = 0.25 Ah, V_f = 4.2 V, V_e = 3.0 V,
R_i = 0.2 Ohm (assumed), cut-off 2.8 V, and P_h = 5.88 W: the hover power at which a full cell
lasts the datasheet's 7 min of hover under this model (sag and cut-off included;
:data:`HOVER_POWER`).
"""

from __future__ import annotations

import numpy as np

from swarmscene.core.events import EventKindPlugin

HOVER_POWER = 5.88
"""W: P_h of a Crazyflie 2.1 (a full 250 mAh cell hovers 420 s to the 2.8 V cut-off with R_i = 0.2 Ohm)."""
CUTOFF = 2.8
"""V: the terminal voltage under which a vehicle is cut off (a 1S LiPo's protection level)."""


def power(thrust, hover_power: float, weight: float) -> np.ndarray:
    """P (W) = P_h (T / (m g))^(3/2) of thrusts ``thrust`` (N)."""
    return hover_power * (np.maximum(np.asarray(thrust, dtype=float), 0.0) / weight) ** 1.5


def open_circuit_voltage(charge, v_full: float, v_empty: float) -> np.ndarray:
    """V_oc = V_e + (V_f - V_e) s."""
    return v_empty + (v_full - v_empty) * np.asarray(charge, dtype=float)


def current(v_oc, p, resistance: float) -> np.ndarray:
    """I (A) that delivers P through R_i: (V_oc - sqrt(V_oc² - 4 R_i P)) / (2 R_i), at most V_oc / (2 R_i)."""
    disc = np.maximum(v_oc * v_oc - 4.0 * resistance * p, 0.0)
    return (v_oc - np.sqrt(disc)) / (2.0 * resistance)


def power_cap(v_oc, cutoff: float, resistance: float) -> np.ndarray:
    """P_c (W) = V_c (V_oc - V_c) / R_i, at most V_oc² / (4 R_i); 0 where V_oc <= V_c."""
    v_oc = np.asarray(v_oc, dtype=float)
    v_c = np.maximum(cutoff, 0.5 * v_oc)  # past the maximum-power point, the maximum itself
    return np.where(v_oc > cutoff, v_c * (v_oc - v_c) / resistance, 0.0)


def thrust_at_power(p, hover_power: float, weight: float) -> np.ndarray:
    """T (N) = m g (P / P_h)^(2/3): the thrust that power ``p`` (W) makes (inverse of :func:`power`)."""
    return weight * (np.maximum(np.asarray(p, dtype=float), 0.0) / hover_power) ** (2.0 / 3.0)


def max_thrust(voltage, thrust_to_weight: float, weight: float, v_full: float) -> np.ndarray:
    """T_max (N) = (T/W)_max m g (V / V_f)²."""
    return thrust_to_weight * weight * (np.asarray(voltage, dtype=float) / v_full) ** 2


class BatteryDepleted(EventKindPlugin):
    """A vehicle's battery ran out: its thrust is cut and it falls (a failure, moved by its
    dynamics until it meets the floor). Raised by the ``battery`` disturbance model."""

    name = "battery_depleted"
