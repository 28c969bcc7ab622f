"""Safety barrier certificates for single integrators (Wang, Ames, Egerstedt 2017), decentralised.

Symbols of Wang, Ames, Egerstedt, "Safety barrier certificates for collisions-free multirobot
systems", IEEE T-RO 33(3), 2017, section III (single integrators p_i' = u_i), and Borrmann, Wang,
Ames, Egerstedt, "Control barrier certificates for safe swarm behavior", ADHS 2015:

- pairwise barrier h_ij = |p_i - p_j|^2 - D_s^2 (safe set h_ij >= 0);
- its derivative along the inputs: dh_ij/dt = 2 (p_i - p_j)^T (u_i - u_j);
- the barrier certificate dh_ij/dt >= -gamma kappa(h_ij), kappa(h) = h^p (p = 1 linear, as in the
  issue; the Robotarium uses p = 3), i.e. the linear constraint on the inputs
      -2 (p_i - p_j)^T (u_i - u_j) <= gamma kappa(h_ij);
- obstacles: h_io = |p_i - o_i|^2 - D_o^2 with o_i the nearest obstacle point, -2 (p_i - o_i)^T u_i
  <= gamma kappa(h_io), all of it for agent i (responsibility 1);
- the minimally invasive input: u* = argmin sum_i |u_i - u_i^nom|^2 subject to all constraints.

Decentralised form (the paper's distributed certificates with equal responsibilities): each pair's
constraint is split half and half, agent i keeping -2 (p_i - p_j)^T u_i <= gamma kappa(h_ij) / 2
(and agent j the mirror one); both halves together imply the joint constraint. Against a neighbour
that does not avoid (a failed vehicle: u_j = 0) agent i keeps the whole right-hand side. The QP
then decouples into one small QP per agent, a projection onto half-planes; with the speed limit
|u_i| <= v_max added as a disc it is exactly the problem of :mod:`.halfplanes`, solved for all
agents at once, exactly (not iteratively). Where the constraints leave nothing in the disc (agents
already inside D_s, squeezed from both sides) the fallback minimises the largest violation with
obstacle constraints kept hard.

Discrete time: with the input held over a period T (zero-order hold) a single integrator gives
h(t + T) = h + 2 T e^T du + T^2 |du|^2 >= (1 - gamma T) h when the constraint holds (p = 1), so the
set h >= 0 stays invariant between ticks for gamma T <= 1, not only in the continuous limit.
"""

from __future__ import annotations

import numpy as np

from .halfplanes import _dot, closest_velocity, detour_if_blocked, halfplane_from_normal


def class_k(h: np.ndarray, power: int) -> np.ndarray:
    """kappa(h) = sign(h) |h|^p: an extended class-K function for every p >= 1."""
    return np.sign(h) * np.abs(h) ** power if power != 1 else h


def barrier_lines(
    offset: np.ndarray, safe_distance: float, gamma: float, power: int, share: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The half-planes -2 e^T u <= share gamma kappa(h), h = |e|^2 - D^2, in RVO2 line form.

    Args:
        offset: (..., 2) e = p_i - p_j (or p_i - o_i), m.
        safe_distance: D, m.
        gamma: barrier gain, 1/s (times m^(2 - 2p) for p != 1).
        power: p of kappa.
        share: responsibility: 1/2 between avoiding agents, 1 against static ones.

    Writing n = e / |e|, the constraint is n^T u >= -share gamma kappa(h) / (2 |e|).
    """
    dist = np.sqrt(_dot(offset, offset))
    h = dist * dist - safe_distance * safe_distance
    normal = offset / np.maximum(dist, 1e-300)[..., None]
    bound = -np.asarray(share) * gamma * class_k(h, power) / (2.0 * np.maximum(dist, 1e-300))
    return halfplane_from_normal(normal, bound)


def safe_velocities(
    pos: np.ndarray,
    u_nom: np.ndarray,
    neighbours: np.ndarray,
    valid: np.ndarray,
    static: np.ndarray,
    safe_distance: float,
    gamma: float,
    power: int,
    v_max: float,
    obstacle: tuple[np.ndarray, np.ndarray, np.ndarray, float] | None = None,
    detour: float = 0.0,
    deadlock_turn: float = 0.0,
    deadlock_ratio: float = 0.1,
) -> tuple[np.ndarray, np.ndarray]:
    """The minimally invasive inputs u_i* of the decentralised certificates (planar, x-y).

    Args:
        pos: (N, 2) positions, m.
        u_nom: (N, 2) nominal velocities, m/s.
        neighbours: (N, K) neighbour table (:func:`.neighbour_table`).
        valid: (N, K) bool, which of its entries are neighbours (the rest is padding).
        static: (N,) bool, neighbours that do not avoid (responsibility 1 against them).
        safe_distance: D_s, m.
        gamma: the certificate's gain in dh/dt >= -gamma h^p.
        power: its exponent p.
        v_max: |u_i| <= v_max, m/s.
        obstacle: optional (normal (N, 2), clearance (N,), near (N,) bool, D_o) of each agent's
            nearest obstacle point: its barrier is a hard constraint.
        detour: rad, the right-hand rule of :func:`.detour_if_blocked` (0: none).
        deadlock_turn: rows found in a deadlock are solved again with the nominal turned clockwise
            by this angle, rad (0: never).
        deadlock_ratio: a row is in a deadlock when its filtered input is shorter than this
            fraction of the nominal one.

    Returns:
        (u (N, 2), feasible (N,)): where not feasible, the least-violation fallback was used.
    """
    share = np.where(static[neighbours], 1.0, 0.5)
    point, direction = barrier_lines(pos[:, None, :] - pos[neighbours], safe_distance, gamma, power, share)
    nominal = detour_if_blocked(point, direction, valid, u_nom, detour)
    n_hard = 0
    if obstacle is not None:
        normal, clearance, near, d_o = obstacle
        # Inside an obstacle (clearance < 0) the barrier is evaluated just outside its boundary:
        # h < 0 there, so the constraint asks to leave along the normal as fast as possible.
        q, d = barrier_lines(normal * np.maximum(clearance, 1e-3)[:, None], d_o, gamma, power, 1.0)
        point = np.concatenate([q[:, None], point], axis=1)
        direction = np.concatenate([d[:, None], direction], axis=1)
        valid = np.concatenate([near[:, None], valid], axis=1)
        n_hard = 1
    u, feasible = closest_velocity(point, direction, valid, nominal, v_max, n_hard)
    if deadlock_turn > 0.0:
        u, feasible = _escape_deadlocks(point, direction, valid, nominal, v_max, n_hard, u, feasible,
                                        deadlock_turn, deadlock_ratio)
    return u, feasible


def _escape_deadlocks(point, direction, valid, nominal, v_max, n_hard, u, feasible, turn, ratio):
    """Re-solve the rows that the filter stopped (|u*| < ratio |u^nom|: a deadlock in the sense of
    Grover et al. 2021, e.g. an agent pressed into the gap between two neighbours that sit on their
    goals and, at rest, never yield) with the nominal input turned by ``turn`` rad to either side;
    each keeps the faster of the two (clockwise on a tie), so it slides along the obstruction."""
    stopped = np.flatnonzero(_dot(u, u) < ratio * ratio * _dot(nominal, nominal))
    if stopped.size == 0:
        return u, feasible
    u, feasible = u.copy(), feasible.copy()
    rows = (point[stopped], direction[stopped], valid[stopped])
    best, best_ok = None, None
    for side in (1.0, -1.0):
        c, s = np.cos(turn), side * np.sin(turn)
        v = nominal[stopped]
        turned = np.column_stack([c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1]])
        cand, ok = closest_velocity(*rows, turned, v_max, n_hard)
        if best is None:
            best, best_ok = cand, ok
        else:
            faster = _dot(cand, cand) > _dot(best, best) + 1e-12
            best = np.where(faster[:, None], cand, best)
            best_ok = np.where(faster, ok, best_ok)
    u[stopped], feasible[stopped] = best, best_ok
    return u, feasible


def influence_range(safe_distance: float, gamma: float, power: int, v_max: float) -> float:
    """Distance beyond which no pairwise half-constraint can be active inside the speed disc, m.

    -2 e^T u_i <= gamma kappa(h) / 2 holds for every |u_i| <= v_max once 2 d v_max <= gamma
    kappa(d^2 - D^2) / 2; the smallest such d (bisection on the monotone condition).
    """
    lo, hi = safe_distance, safe_distance + 1.0
    while 4.0 * hi * v_max > gamma * class_k(np.asarray(hi * hi - safe_distance**2), power):
        hi *= 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if 4.0 * mid * v_max > gamma * class_k(np.asarray(mid * mid - safe_distance**2), power):
            lo = mid
        else:
            hi = mid
    return float(hi)

