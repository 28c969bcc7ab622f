"""Crazyflie-class parameters of the physics models, each with its source (SI units).

The vehicle is the Crazyflie 2.x of the engine's ``quadrotor`` airframe ``crazyflie``
(methods/quadrotor/model.py): 27 g, thrust coefficient k_T = 3.16e-10 N/rpm^2 (Foerster 2015,
as gym-pybullet-drones' ``cf2x.urdf`` carries it), thrust-to-weight 2.25.
"""

from __future__ import annotations

import math

GRAVITY = 9.81
"""m/s^2, as the quadrotor model's (methods/quadrotor/model.py)."""
MASS = 0.027
"""kg: the Crazyflie 2.x's mass (Foerster 2015; gym-pybullet-drones cf2x.urdf)."""
K_T = 3.16e-10 * (60.0 / (2.0 * math.pi)) ** 2
"""N/(rad/s)^2: thrust per rotor speed squared (Foerster 2015's 3.16e-10 N/rpm^2 in rad/s)."""
HOVER_ROTOR_SPEED = math.sqrt(MASS * GRAVITY / (4.0 * K_T))
"""rad/s: each rotor's speed at hover, sqrt(m g / (4 k_T)) (~1516 rad/s)."""
THRUST_TO_WEIGHT = 2.25
"""Maximum thrust over weight at a full battery (gym-pybullet-drones cf2x.urdf ``thrust2weight``)."""
ROTOR_RADIUS = 2.31348e-2
"""m: propeller radius R_p (gym-pybullet-drones cf2x.urdf ``prop_radius``; 46 mm propellers)."""
K_AERO = (9.1785e-7, 9.1785e-7, 10.311e-7)
"""kg/rad: rotor drag coefficients along the body axes x, y, z (Foerster 2015, Table 4.3 K_aero;
cf2x.urdf ``drag_coeff_xy``, ``drag_coeff_z``): F = -K_aero (sum of rotor speeds) R^T v."""
DOWNWASH_COEFFICIENTS = (2267.18, 0.16, -0.11)
"""(C_1 N, C_2, C_3 m): the downwash fit of gym-pybullet-drones (cf2x.urdf ``dw_coeff_1..3``,
UTIAS DSL experiments by SiQi Zhou; Panerati et al., IROS 2021)."""
KEEP_OUT_RADII = (0.12, 0.12, 0.3)
"""m: the keep-out ellipsoid of a Crazyflie in Crazyswarm-style planning, radii along x, y, z
(Preiss, Hönig, Ayanian, Sukhatme, "Downwash-aware trajectory planning for large quadrotor teams",
IROS 2017: E = diag(0.12, 0.12, 0.3)); two vehicles collide when ||E^-1 (p_i - p_j)|| < 1."""
BATTERY_CAPACITY = 0.250
"""Ah: the Crazyflie 2.1's stock 1S LiPo, 250 mAh (Bitcraze datasheet)."""
BATTERY_FULL = 4.2
"""V: a 1S LiPo's open-circuit voltage when full."""
BATTERY_EMPTY = 3.0
"""V: its open-circuit voltage at the end of discharge (the cut-off of a 1S LiPo)."""
BATTERY_RESISTANCE = 0.2
"""Ohm: internal resistance of a 250 mAh 1S LiPo (an assumption of the right order: 0.1-0.3 Ohm
measured on cells of this size)."""
FLIGHT_TIME = 7.0 * 60.0
"""s: the Crazyflie 2.1's hover flight time on the stock battery (Bitcraze datasheet: 7 min)."""
RHO_AIR = 1.225
"""kg/m^3: air density at sea level (ISA)."""
