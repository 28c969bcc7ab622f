"""APF ("physicomimetic") navigation with flight levels (Karydes 2020, thesis section 4.3.3).

An agent navigating to a target t_i (its formation slot, or home) flies one flight level away
from the target level and follows the horizontal velocity reference

    v_inf,i = v_col,i + v_tar,i                                   (eq. 4.22)
    v_col,i = sum_{j in F_i} psi_col(||r_j - r_i||) (r_j - r_i) / ||r_j - r_i||   (eq. 4.23-4.24)
    v_tar,i = psi_tar(||H t_i - r_i||) (H t_i - r_i) / ||H t_i - r_i||            (eq. 4.25-4.26)
    v_i     = v_inf,i saturated to the norm v_sat                 (eq. 4.21)

where F_i are the agents on agent i's flight level (|dz| < 2/3 d_c). Within d_c / 2 of its
target horizontally (eq. 4.27) it switches to 3-D position control on t_i, and it has arrived
when ||t_i - r_i|| < eps_r (eq. 4.28).

Frames. Everything here is in the engine's world frame (x east, y north, z up). The one place
the thesis' NED frame matters is the flight level: the thesis sets the altitude reference
r_z = t_i^T z_o - d_c with z_o pointing Down, i.e. d_c *above* the target level (the thesis'
results say the follower "uses the APF navigation algorithm to go above its position in
formation"). In z-up that is ``t_z + d_c``: see :func:`flight_level_altitude`. It is a
parameter (``level_offset``) so a scenario can fly the level below instead.

Choices where the text is loose:
- psi_col and the unit vectors of eq. 4.23 use the horizontal separation: the reference is a
  horizontal velocity, agents in F_i differ in height by less than 2/3 d_c, and the horizontal
  distance is never larger than the 3-D one, so the repulsion is never weaker than the 3-D form.
- F_i is drawn from every agent (navigating or not) within 2 d_c (beyond it psi_col = 0); the
  thesis' sensing graph G_sigma is assumed to reach that far.
- Two agents at the very same horizontal point have no repulsion direction; they are pushed
  apart along world x (lower index towards -x), a fixed, documented tie-break.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy  # scipy.spatial loads on first use (start-up of unrelated runs)

from swarmscene.core.vectors import clip_norm

if TYPE_CHECKING:  # pragma: no cover
    from scipy.spatial import cKDTree

LEVEL_BAND = 2.0 / 3.0
"""Agents with |dz| < LEVEL_BAND * d_c are on the same flight level (F_i of section 4.3.3)."""


def collision_gain(z: np.ndarray, d_c: float, v_sat: float) -> np.ndarray:
    """psi_col(z) of eq. 4.24: v_sat (z / d_c - 2) below 2 d_c, else 0 (<= -v_sat for z <= d_c)."""
    z = np.asarray(z, dtype=float)
    return np.where(z < 2.0 * d_c, v_sat * (z / d_c - 2.0), 0.0)


def target_gain(z: np.ndarray, d_c: float, v_sat: float) -> np.ndarray:
    """psi_tar(z) of eq. 4.26: v_sat z / d_c below d_c, else v_sat."""
    z = np.asarray(z, dtype=float)
    return np.where(z < d_c, v_sat * z / d_c, v_sat)


def saturate(v: np.ndarray, v_sat: float) -> np.ndarray:
    """Eq. 4.21: scale each row of ``v`` (N, k) down to norm v_sat when it is longer."""
    return clip_norm(v, v_sat)


def flight_level_altitude(target_z: np.ndarray, d_c: float, level_offset: float = 1.0) -> np.ndarray:
    """Altitude reference of a navigating agent: t_z + level_offset d_c (world z up).

    ``level_offset = +1`` is the thesis (NED t^T z_o - d_c, one level above the target).
    """
    return np.asarray(target_z, dtype=float) + level_offset * d_c


def same_level_pairs(
    pos: np.ndarray, d_c: float, tree: cKDTree | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i < j) on the same flight level and within 2 d_c horizontally.

    Args:
        pos: (N, 3) world positions.
        d_c: collision-free distance d_c, m.
        tree: optional cKDTree over ``pos`` (3-D) or over ``pos[:, :2]`` (2-D), e.g. the engine's
            shared per-step tree; built here when absent.

    Returns:
        pairs (P, 2) int and their horizontal offsets r_j - r_i, (P, 2).
    """
    pos = np.asarray(pos, dtype=float)
    if tree is None:
        tree = scipy.spatial.cKDTree(pos)
    if tree.m == 3:
        radius = d_c * np.hypot(2.0, LEVEL_BAND)  # reaches every same-level pair within 2 d_c
    elif tree.m == 2:
        radius = 2.0 * d_c
    else:
        raise ValueError(f"neighbour tree must be built on 2-D or 3-D positions (got {tree.m}-D)")
    pairs = tree.query_pairs(radius, output_type="ndarray")
    if pairs.size == 0:
        return np.empty((0, 2), dtype=np.intp), np.empty((0, 2))
    delta = pos[pairs[:, 1]] - pos[pairs[:, 0]]
    keep = (np.abs(delta[:, 2]) < LEVEL_BAND * d_c) & (np.hypot(delta[:, 0], delta[:, 1]) < 2.0 * d_c)
    return pairs[keep], delta[keep, :2]


def repulsion_velocity(
    pos: np.ndarray, d_c: float, v_sat: float, tree: cKDTree | None = None
) -> np.ndarray:
    """v_col of eq. 4.23 for every agent, (N, 2): sum of psi_col over same-level neighbours."""
    pos = np.asarray(pos, dtype=float)
    n = pos.shape[0]
    pairs, delta = same_level_pairs(pos, d_c, tree)
    dist = np.hypot(delta[:, 0], delta[:, 1])
    coincident = dist < 1e-9
    unit = np.where(coincident[:, None], [1.0, 0.0], delta / np.where(coincident, 1.0, dist)[:, None])
    # psi_col < 0: agent i is pushed along -(r_j - r_i), agent j along +(r_j - r_i).
    push = collision_gain(dist, d_c, v_sat)[:, None] * unit
    v = np.empty((n, 2))
    for axis in range(2):
        v[:, axis] = np.bincount(pairs[:, 0], push[:, axis], n) - np.bincount(pairs[:, 1], push[:, axis], n)
    return v


def attraction_velocity(pos: np.ndarray, targets: np.ndarray, d_c: float, v_sat: float) -> np.ndarray:
    """v_tar of eq. 4.25, (N, 2): towards H t_i with speed psi_tar of the horizontal distance."""
    delta = np.asarray(targets, dtype=float)[:, :2] - np.asarray(pos, dtype=float)[:, :2]
    dist = np.linalg.norm(delta, axis=1)
    unit = delta / np.maximum(dist, np.finfo(float).tiny)[:, None]
    return target_gain(dist, d_c, v_sat)[:, None] * unit


def navigation_velocity(
    pos: np.ndarray, targets: np.ndarray, d_c: float, v_sat: float, tree: cKDTree | None = None
) -> np.ndarray:
    """Horizontal velocity reference v_i of eq. 4.21-4.22 for every agent, (N, 2), |v_i| <= v_sat."""
    v_inf = repulsion_velocity(pos, d_c, v_sat, tree) + attraction_velocity(pos, targets, d_c, v_sat)
    return saturate(v_inf, v_sat)


def close_to_target(pos: np.ndarray, targets: np.ndarray, d_c: float) -> np.ndarray:
    """Eq. 4.27: ||H (t_i - r_i)|| < d_c / 2, when APF hands over to position control. (N,) bool."""
    delta = np.asarray(targets, dtype=float)[:, :2] - np.asarray(pos, dtype=float)[:, :2]
    return np.linalg.norm(delta, axis=1) < 0.5 * d_c


def arrived_on_target(pos: np.ndarray, targets: np.ndarray, eps_r: float) -> np.ndarray:
    """Eq. 4.28: ||t_i - r_i|| < eps_r, the end of APF navigation. (N,) bool."""
    return np.linalg.norm(np.asarray(targets, dtype=float) - np.asarray(pos, dtype=float), axis=1) < eps_r


@dataclass
class ApfCommand:
    """What APF navigation asks of each agent this tick (world frame).

    Attributes:
        position_mode: (N,) bool; True: 3-D position control on the target (eq. 4.27 holds),
            False: horizontal velocity ``vel_xy`` with altitude held at ``z_ref``.
        vel_xy: (N, 2) m/s, horizontal velocity reference (zero where ``position_mode``).
        z_ref: (N,) m, altitude reference (the flight level, or the target's altitude).
        arrived: (N,) bool, eq. 4.28.
    """

    position_mode: np.ndarray
    vel_xy: np.ndarray
    z_ref: np.ndarray
    arrived: np.ndarray


def apf_navigation(
    pos: np.ndarray,
    targets: np.ndarray,
    d_c: float,
    v_sat: float,
    eps_r: float,
    tree: cKDTree | None = None,
    level_offset: float = 1.0,
) -> ApfCommand:
    """One APF navigation tick for every agent (section 4.3.3).

    Every agent's reference is computed; the caller applies it to the agents that are
    navigating (FORM or STOP states) and keeps the others (leader, FLOW) on their own control.
    Those others still repel navigating agents that share their flight level.

    Args:
        pos: (N, 3) world positions r_i.
        targets: (N, 3) world targets t_i (all at one altitude in the thesis).
        d_c: collision-free distance, m.
        v_sat: speed bound, m/s.
        eps_r: arrival tolerance, m.
        tree: optional shared cKDTree over ``pos`` (see :func:`same_level_pairs`).
        level_offset: flight level in units of d_c above the target level (thesis: +1).
    """
    targets = np.asarray(targets, dtype=float)
    position_mode = close_to_target(pos, targets, d_c)
    vel_xy = navigation_velocity(pos, targets, d_c, v_sat, tree)
    vel_xy[position_mode] = 0.0
    z_ref = np.where(position_mode, targets[:, 2], flight_level_altitude(targets[:, 2], d_c, level_offset))
    return ApfCommand(
        position_mode=position_mode,
        vel_xy=vel_xy,
        z_ref=z_ref,
        arrived=arrived_on_target(pos, targets, eps_r),
    )
