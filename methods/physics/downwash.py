"""Downwash: the force of the rotors above on a vehicle below (empirical), and the keep-out ellipsoid.

Model (gym-pybullet-drones, ``BaseAviary._downwash``; Panerati et al., "Learning to Fly - a Gym
Environment with PyBullet Physics for Reinforcement Learning of Multi-agent Quadcopter Control",
IROS 2021; fitted to experiments at the UTIAS Dynamic Systems Lab by SiQi Zhou). A vehicle j at
height Δz > 0 above vehicle i and at horizontal distance r from it pushes i down with

    F_z = -α exp(-½ (r / β)²),   α = C_1 (R_p / (4 Δz))²,   β = C_2 Δz + C_3        (N)

with C_1 = 2267.18 N, C_2 = 0.16, C_3 = -0.11 m and the propeller radius R_p = 0.0231 m
(Crazyflie 2.x, :mod:`.crazyflie`); the forces of every vehicle above add.

Regularisation (the published fit is singular twice):

* the plume width β is zero at Δz = -C_3 / C_2 = 0.6875 m (0/0 straight below, a force that
  jumps from α to 0 a millimetre aside) and shrinks as Δz grows towards it. Here
  β_reg = sqrt(β² + β_min²) with β_min = ``min_width`` (default 2 R_p = 0.046 m, the rotor's
  diameter: a plume is never narrower than the disc that makes it); β_min = 0 is the published fit.
* α grows as 1 / Δz² as Δz -> 0 (two vehicles at one height). Δz is taken as at least
  ``min_height`` (default 0.1 m, about a Crazyflie's span: closer, the two vehicles overlap).

Reach: vehicles farther than ``reach_z`` above or ``reach_r`` aside are left out (the default
3 m and 1 m leave out at most α(3 m) = 0.0084 N, 3 % of a Crazyflie's weight). The neighbours
are found in compiled code (numba) on a dense grid of x-y cells at least ``reach_r`` wide, filled
by a counting sort, so the cost is O(N) for a swarm that is not stacked in one column.

Strength: at Δz = 0.5 m straight below the fit gives 0.30 N, more than a Crazyflie's weight
(0.26 N); Neural-Swarm's measurements (Shi et al., ICRA 2020, Fig. 3) show about 0.1 N at 0.2 m.
The plugin's ``scale`` multiplies the force (a sweep over it shows how much the outcome depends on
the fit).

Keep-out ellipsoid (Preiss et al., IROS 2017; Crazyswarm's planners): vehicles i and j are in
conflict when ||E^-1 (p_i - p_j)|| < 1, E = diag(0.12, 0.12, 0.3) m. :func:`downwash_field`
measures the smallest such norm among the pairs it visits (pairs within ``reach_r`` aside and
``reach_z`` apart in height, so every pair inside an ellipsoid no larger than them).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .cells import xy_cells


def downwash_force(dz, r, c1: float, c2: float, c3: float, rotor_radius: float,
                   min_width: float = 0.0, min_height: float = 0.0):
    """F (N, downward magnitude) on a vehicle Δz below and r aside of another (module docstring),
    vectorised; ``min_width`` = ``min_height`` = 0: the published fit."""
    dz = np.maximum(np.asarray(dz, dtype=float), min_height)
    alpha = c1 * (rotor_radius / (4.0 * dz)) ** 2
    beta2 = (c2 * dz + c3) ** 2 + min_width**2
    return alpha * np.exp(-0.5 * np.asarray(r, dtype=float) ** 2 / beta2)


@numba.njit(cache=True)
def downwash_field(pos, c1, c2, c3, rotor_radius, min_width, min_height, reach_r, reach_z, radii):
    """Downwash forces and keep-out conflicts of a swarm, in one pass over neighbouring cells.

    Args:
        pos: (N, 3) positions, m.
        c1: C_1, N.
        c2: C_2.
        c3: C_3, m.
        rotor_radius: R_p, m.
        min_width: β_min, m (0: the published fit).
        min_height: the least Δz, m.
        reach_r: the plume's horizontal reach, m.
        reach_z: its vertical reach, m.
        radii: (3,) the keep-out ellipsoid's radii, m.

    Returns:
        force (N,) N downward on each vehicle (summed over the vehicles above it), its largest, the smallest
        ellipsoid norm ||E^-1 (p_i - p_j)|| over the pairs visited (inf: none), and the pairs
        (M, 2) with a norm below 1 (i < j).
    """
    n = pos.shape[0]
    force = np.zeros(n)
    conflicts = np.empty((0, 2), np.int64)
    best = np.inf
    if n < 2:
        return force, 0.0, best, conflicts
    cx, cy, nx, ny, order, start, _ = xy_cells(pos, reach_r)
    found = []
    r2_reach = reach_r * reach_r
    for i in range(n):
        for x in range(max(cx[i] - 1, 0), min(cx[i] + 2, nx)):
            for y in range(max(cy[i] - 1, 0), min(cy[i] + 2, ny)):
                q = x * ny + y
                for s in range(start[q], start[q + 1]):
                    j = order[s]
                    dz = pos[j, 2] - pos[i, 2]
                    if dz < 0.0 or (dz == 0.0 and j <= i) or dz > reach_z:
                        continue
                    ex = pos[j, 0] - pos[i, 0]
                    ey = pos[j, 1] - pos[i, 1]
                    r2 = ex * ex + ey * ey
                    if r2 > r2_reach:
                        continue
                    e = math.sqrt((ex / radii[0]) ** 2 + (ey / radii[1]) ** 2 + (dz / radii[2]) ** 2)
                    best = min(best, e)
                    if e < 1.0:
                        found.append((min(i, j), max(i, j)))
                    if dz > 0.0:  # j above i: its plume pushes i down
                        h = max(dz, min_height)
                        alpha = c1 * (rotor_radius / (4.0 * h)) ** 2
                        b = c2 * h + c3
                        force[i] += alpha * math.exp(-0.5 * r2 / (b * b + min_width * min_width))
    if len(found):
        conflicts = np.empty((len(found), 2), np.int64)
        for m in range(len(found)):
            conflicts[m, 0], conflicts[m, 1] = found[m]
    return force, force.max(), best, conflicts


def keep_out_norm(d, radii) -> np.ndarray:
    """||E^-1 d|| of displacements ``d`` (..., 3) for the ellipsoid of ``radii`` (3,) m."""
    return np.sqrt(np.sum((np.asarray(d, dtype=float) / np.asarray(radii, dtype=float)) ** 2, axis=-1))
