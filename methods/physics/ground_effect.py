"""Ground effect: a rotor near the ground makes more thrust (Cheeseman and Bennett 1955).

    T_IGE / T_OGE = 1 / (1 - (R / (4 z))²)                                  (C-B eq. 10)

for a rotor of radius R at height z above the ground, at equal power (Cheeseman, I. C. and
Bennett, W. E., "The effect of the ground on a helicopter rotor in forward flight", ARC R&M
3021, 1955; the model gym-pybullet-drones' ground effect follows, Shi et al., ICRA 2019, eq. 1).
The extra thrust per mass is (T_IGE / T_OGE - 1) τ, τ the rotors' thrust per mass
(:mod:`.thrust`), along the thrust.

Regularisation: the ratio is singular at z = R / 4 and the image-vortex derivation holds for
z / R >~ 0.5 (Cheeseman and Bennett's own range); z is taken as at least ``min_height``
(default R / 2: a ratio of at most 4 / 3). z is the vehicle's height above the floor (the rotor
plane at the centre of mass, level).
"""

from __future__ import annotations

import numpy as np


def thrust_ratio(z, rotor_radius: float, min_height: float = 0.0) -> np.ndarray:
    """T_IGE / T_OGE at heights ``z`` (m) above the ground (``min_height`` = 0: the published law)."""
    z = np.maximum(np.asarray(z, dtype=float), min_height)
    return 1.0 / (1.0 - (rotor_radius / (4.0 * z)) ** 2)
