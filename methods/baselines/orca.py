"""Optimal Reciprocal Collision Avoidance (van den Berg, Guy, Lin, Manocha 2011), planar, vectorised.

Notation of the paper ("Reciprocal n-body collision avoidance", ISRR 2009 / STAR 70, 2011):

- VO^tau_{A|B} (eq. 2): relative velocities v_A - v_B that bring discs of radii r_A + r_B into contact
  within the time horizon tau; its boundary is a cone of two legs, truncated by the cut-off disc of
  centre (p_B - p_A)/tau and radius (r_A + r_B)/tau.
- u (eq. 3): the vector from v_A - v_B to the closest point of that boundary; n its outward normal.
- ORCA^tau_{A|B} (eq. 4): the half-plane {v : (v - (v_A + u/2)) . n >= 0}: A takes half of the
  change (responsibility 1/2). A static neighbour (a failed vehicle, which hovers) takes none, so
  A takes all of it: {v : (v - (v_A + u)) . n >= 0}.
- Eq. 5: v_A^new = argmin_{v in ORCA^tau_A} |v - v_A^pref|, ORCA^tau_A = D(0, v_max) cut by every
  neighbour's half-plane; solved by :mod:`.halfplanes` (section 5.2; section 5.3's fallback when
  the half-planes leave nothing in the disc).
- Agents already overlapping (|p_B - p_A| <= r_A + r_B) use the cut-off disc of one time step
  (RVO2: "collision, project on cut-off circle of time timeStep"), so they separate within it.

Static obstacles enter as half-planes kept hard by the fallback (RVO2's ``numObstLines``); see
:func:`obstacle_lines` for the form used here (the nearest obstacle point, not RVO2's polygon
edges). The branch structure and arithmetic follow RVO2 ``Agent::computeNewVelocity`` line by line,
so the lines and velocities can be checked against it (tests/methods/baselines).
"""

from __future__ import annotations

import numpy as np

from .halfplanes import _dot, closest_velocity, det, detour_if_blocked, halfplane_from_normal


def _unit(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    length = np.sqrt(_dot(w, w))
    return w / np.maximum(length, 1e-300)[..., None], length


def _perp_right(unit: np.ndarray) -> np.ndarray:
    """(u_y, -u_x): the line direction whose left side is ``unit``."""
    return np.stack([unit[..., 1], -unit[..., 0]], axis=-1)


def agent_lines(
    rel_pos: np.ndarray,
    rel_vel: np.ndarray,
    vel: np.ndarray,
    combined_radius: float | np.ndarray,
    tau: float,
    time_step: float,
    responsibility: float | np.ndarray = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """ORCA^tau_{A|B} half-planes (eq. 4) of every agent A against each of its neighbours B.

    Args:
        rel_pos: (N, K, 2) p_B - p_A, m.
        rel_vel: (N, K, 2) v_A - v_B, m/s.
        vel: (N, 2) v_A, m/s (the lines pass through v_A + responsibility * u).
        combined_radius: r_A + r_B, m (scalar or (N, K)).
        tau: time horizon tau, s.
        time_step: s; the horizon of the cut-off disc for pairs already in contact.
        responsibility: share of u taken by A: 1/2 (reciprocal), 1 (static B); scalar or (N, K).

    Returns:
        (point, direction), each (N, K, 2), in RVO2's ``Line`` form (allowed side on the left).
    """
    r = np.broadcast_to(np.asarray(combined_radius, dtype=float), rel_pos.shape[:-1])
    dist2 = _dot(rel_pos, rel_pos)
    w = rel_vel - rel_pos / tau  # from the cut-off centre to the relative velocity
    w2 = _dot(w, w)
    along = _dot(w, rel_pos)
    on_cutoff = (along < 0.0) & (along * along > r * r * w2)

    unit_w, w_len = _unit(w)
    dir_cut = _perp_right(unit_w)
    u_cut = (r / tau - w_len)[..., None] * unit_w

    leg = np.sqrt(np.maximum(dist2 - r * r, 0.0))
    x, y = rel_pos[..., 0], rel_pos[..., 1]
    inv = 1.0 / np.maximum(dist2, 1e-300)
    left = det(rel_pos, w) > 0.0
    dir_left = np.stack([x * leg - y * r, x * r + y * leg], axis=-1) * inv[..., None]
    dir_right = -np.stack([x * leg + y * r, -x * r + y * leg], axis=-1) * inv[..., None]
    dir_leg = np.where(left[..., None], dir_left, dir_right)
    u_leg = _dot(rel_vel, dir_leg)[..., None] * dir_leg - rel_vel

    w_hit = rel_vel - rel_pos / time_step
    unit_hit, hit_len = _unit(w_hit)
    dir_hit = _perp_right(unit_hit)
    u_hit = (r / time_step - hit_len)[..., None] * unit_hit

    colliding = (dist2 <= r * r)[..., None]
    cut = on_cutoff[..., None]
    direction = np.where(colliding, dir_hit, np.where(cut, dir_cut, dir_leg))
    u = np.where(colliding, u_hit, np.where(cut, u_cut, u_leg))
    share = np.broadcast_to(np.asarray(responsibility, dtype=float), rel_pos.shape[:-1])
    point = vel[:, None, :] + share[..., None] * u
    return point, direction


def obstacle_lines(
    normal: np.ndarray, clearance: np.ndarray, limit: float, tau_obstacle: float
) -> tuple[np.ndarray, np.ndarray]:
    """A static obstacle's half-plane, responsibility 1: {v : v . n >= -(c - c_s) / tau_obst}.

    n (N, 2) is the unit normal from the agent's nearest obstacle point towards the agent and c (N,)
    its clearance, c_s = ``limit``. The obstacle is replaced by its tangent plane at that point
    (which contains a convex obstacle), and velocities that would cross the plane offset by c_s
    within tau_obst are cut off: the truncated velocity obstacle of a half-space. Planes are
    re-taken every tick, so the agent slides along walls and round corners.
    """
    return halfplane_from_normal(normal, -(clearance - limit) / tau_obstacle)


def new_velocities(
    pos: np.ndarray,
    vel: np.ndarray,
    v_pref: np.ndarray,
    neighbours: np.ndarray,
    valid: np.ndarray,
    static: np.ndarray,
    combined_radius: float,
    tau: float,
    time_step: float,
    v_max: float,
    hard: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    detour: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """v_A^new of eq. 5 for every agent (planar, x-y).

    Args:
        pos: (N, 2) positions, m.
        vel: (N, 2) current velocities, m/s.
        v_pref: (N, 2) preferred velocities, m/s.
        neighbours: (N, K) the neighbour table, nearest first (:func:`.neighbour_table`).
        valid: (N, K) bool, which of its entries are neighbours (the rest is padding).
        static: (N,) bool, agents that do not avoid (failed vehicles): responsibility 1 against them.
        combined_radius: r_A + r_B, m.
        tau: the time horizon, s.
        time_step: the guidance period, s.
        v_max: the speed limit (the disc), m/s.
        hard: optional (point, direction, valid) (N, H, 2/2/-) obstacle half-planes, kept hard.
        detour: rad, the right-hand rule of :func:`.detour_if_blocked` (0: none, as in the paper).

    Returns:
        (velocity (N, 2), feasible (N,)): ``feasible`` False where the fallback of section 5.3 ran.
    """
    rel_pos = pos[neighbours] - pos[:, None, :]
    rel_vel = vel[:, None, :] - vel[neighbours]
    share = np.where(static[neighbours], 1.0, 0.5)
    point, direction = agent_lines(rel_pos, rel_vel, vel, combined_radius, tau, time_step, share)
    v_pref = detour_if_blocked(point, direction, valid, v_pref, detour)
    n_hard = 0
    if hard is not None:
        n_hard = hard[0].shape[1]
        point = np.concatenate([hard[0], point], axis=1)
        direction = np.concatenate([hard[1], direction], axis=1)
        valid = np.concatenate([hard[2], valid], axis=1)
    return closest_velocity(point, direction, valid, v_pref, v_max, n_hard)
