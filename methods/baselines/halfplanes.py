"""The closest point of a speed disc cut by half-planes, for many agents at once (RVO2's programs).

Each agent a has up to L half-planes in its velocity plane, written as RVO2's ``Line``: a point
``q`` on the boundary and a unit ``direction`` d; the allowed side is on the left of d,

    det(d, q - v) <= 0     (equivalently n . (v - q) >= 0 with the inward normal n = (-d_y, d_x)),

and a disc |v| <= r (the speed limit). :func:`closest_velocity` returns for every agent the allowed
velocity closest to its preferred one, i.e. the quadratic program

    v* = argmin |v - v_pref|^2   s.t.  every half-plane,  |v| <= r,

solved exactly by the incremental algorithm of van den Berg et al. 2011 (section 5.2), as RVO2
(Agent.cc) implements it: ``linearProgram2`` visits the half-planes in order; when the current
optimum violates half-plane k, the new one lies on its boundary line and ``linearProgram1`` finds it
as the closest point of a segment (the line cut by the disc and by half-planes 0..k-1). When the
half-planes leave nothing inside the disc, ``linearProgram3`` (the paper's section 5.3 "dense
situations") returns the velocity that minimises the largest penetration of the soft half-planes
while the first ``n_hard`` ones (obstacles) stay hard.

Lock-step vectorisation: the loops over half-planes are kept (L is a handful: the nearest
neighbours), but every step of them runs for all agents at once on (M, L, 2) arrays, with padded
half-planes masked out by ``valid``. One tick is therefore about L x (a few dozen numpy calls),
whatever N; the fallback of dense situations costs about L times more, for the rows that need it.
Results agree with RVO2's float arithmetic to its float precision (tests compare them).
"""

from __future__ import annotations

import numpy as np

EPSILON = 1e-9
"""RVO_EPSILON of RVO2 (1e-5 in float there): lines closer to parallel than this are parallel."""


def det(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """2-D cross product a_x b_y - a_y b_x over the last axis."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def violation(point: np.ndarray, direction: np.ndarray, v: np.ndarray) -> np.ndarray:
    """det(d, q - v) per half-plane, (M, L): > 0 where ``v`` (M, 2) is outside, by that distance."""
    return det(direction, point - v[:, None, :])


def _lp1(point, direction, valid, k, radius, opt, direction_opt):
    """RVO2 ``linearProgram1`` on line k of every row: (result (M, 2), feasible (M,))."""
    q, d = point[:, k], direction[:, k]
    along = _dot(q, d)
    disc = along * along + radius * radius - _dot(q, q)
    ok = disc >= 0.0
    root = np.sqrt(np.maximum(disc, 0.0))
    t_left, t_right = -along - root, -along + root
    if k > 0:
        qj, dj, vj = point[:, :k], direction[:, :k], valid[:, :k]
        den = det(d[:, None, :], dj)
        num = det(dj, q[:, None, :] - qj)
        parallel = np.abs(den) <= EPSILON
        ok &= ~np.any(vj & parallel & (num < 0.0), axis=1)
        t = num / np.where(parallel, 1.0, den)
        bounded = vj & ~parallel
        t_right = np.minimum(t_right, np.min(np.where(bounded & (den >= 0.0), t, np.inf), axis=1))
        t_left = np.maximum(t_left, np.max(np.where(bounded & (den < 0.0), t, -np.inf), axis=1))
    ok &= t_left <= t_right
    if direction_opt:
        t = np.where(_dot(opt, d) > 0.0, t_right, t_left)
    else:
        t = _dot(d, opt - q)
        t = np.where(t < t_left, t_left, np.where(t > t_right, t_right, t))
    return q + t[:, None] * d, ok


def linear_program2(point, direction, valid, radius, opt, direction_opt=False):
    """RVO2 ``linearProgram2`` for every row: (result (M, 2), index of the failing line (M,)).

    Args:
        point: (M, L, 2) a point on each half-plane's boundary line.
        direction: (M, L, 2) the line's direction, unit length (the allowed side on its left).
        valid: (M, L) bool; False rows of padding are ignored.
        radius: (M,) or scalar, the disc |v| <= radius.
        opt: (M, 2) preferred velocity (a unit direction when ``direction_opt``).
        direction_opt: maximise along ``opt`` instead of minimising the distance to it.

    The failing index is L where every half-plane was met (the result is then the optimum).
    """
    m, n_lines = valid.shape
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (m,))
    if direction_opt:
        result = opt * radius[:, None]
    else:
        norm = np.sqrt(_dot(opt, opt))
        result = np.where((norm > radius)[:, None], opt * (radius / np.maximum(norm, 1e-300))[:, None], opt)
    fail = np.full(m, n_lines)
    for k in range(n_lines):
        rows = np.flatnonzero(
            (fail == n_lines) & valid[:, k] & (det(direction[:, k], point[:, k] - result) > 0.0)
        )
        if rows.size == 0:
            continue
        new, ok = _lp1(point[rows], direction[rows], valid[rows], k, radius[rows], opt[rows], direction_opt)
        result[rows[ok]] = new[ok]
        fail[rows[~ok]] = k
    return result, fail


def _projected_lines(point, direction, valid, n_hard, i):
    """The lines of RVO2 ``linearProgram3`` for line i: the hard lines, then for each soft line j < i
    the bisector of lines i and j (where their penetrations are equal), (M, n_hard + i - n_hard)."""
    qi, di = point[:, i][:, None, :], direction[:, i][:, None, :]
    qj, dj = point[:, n_hard:i], direction[:, n_hard:i]
    determinant = det(di, dj)
    parallel = np.abs(determinant) <= EPSILON
    same_way = parallel & (_dot(di, dj) > 0.0)
    crossing = qi + (det(dj, qi - qj) / np.where(parallel, 1.0, determinant))[..., None] * di
    q = np.where(parallel[..., None], 0.5 * (qi + qj), crossing)
    d = dj - di
    d = d / np.maximum(np.sqrt(_dot(d, d)), 1e-300)[..., None]
    keep = valid[:, n_hard:i] & ~same_way
    return (
        np.concatenate([point[:, :n_hard], q], axis=1),
        np.concatenate([direction[:, :n_hard], d], axis=1),
        np.concatenate([valid[:, :n_hard], keep], axis=1),
    )


def linear_program3(point, direction, valid, n_hard, begin, radius, result):
    """RVO2 ``linearProgram3``: the velocity minimising the largest penetration of the soft lines
    (from line ``begin`` (M,) on, each row's failure index) with the first ``n_hard`` kept hard.

    ``result`` (M, 2) is the starting velocity (linearProgram2's last feasible one); returns a copy.
    """
    result = result.copy()
    m, n_lines = valid.shape
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (m,))
    distance = np.zeros(m)
    for i in range(int(begin.min(initial=n_lines)), n_lines):
        rows = np.flatnonzero(
            (begin <= i) & valid[:, i] & (det(direction[:, i], point[:, i] - result) > distance)
        )
        if rows.size == 0:
            continue
        q, d, ok = _projected_lines(point[rows], direction[rows], valid[rows], n_hard, i)
        di = direction[rows, i]
        new, fail = linear_program2(q, d, ok, radius[rows], np.column_stack([-di[:, 1], di[:, 0]]), True)
        # A failure here is floating-point error only (RVO2's comment): keep the last result.
        done = fail == q.shape[1]
        result[rows[done]] = new[done]
        distance[rows] = det(di, point[rows, i] - result[rows])
    return result


def closest_velocity(point, direction, valid, v_pref, radius, n_hard=0):
    """The allowed velocity closest to ``v_pref`` (M, 2) for every row; RVO2's two-stage solve.

    Returns (velocity (M, 2), feasible (M,)): where ``feasible`` is False the half-planes left
    nothing inside the disc and the velocity is :func:`linear_program3`'s least penetration.
    """
    result, fail = linear_program2(point, direction, valid, radius, np.asarray(v_pref, dtype=float))
    infeasible = fail < valid.shape[1]
    if infeasible.any():
        rows = np.flatnonzero(infeasible)
        result[rows] = linear_program3(
            point[rows], direction[rows], valid[rows], n_hard, fail[rows],
            np.broadcast_to(np.asarray(radius, dtype=float), (len(result),))[rows], result[rows],
        )
    return result, ~infeasible


def halfplane_from_normal(normal: np.ndarray, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RVO2 line (point, direction) of the half-plane {v : n . v >= c} for unit normals n (..., 2)
    and offsets c (...): the point c n on its boundary, the direction (n_y, -n_x)."""
    point = offset[..., None] * normal
    direction = np.stack([normal[..., 1], -normal[..., 0]], axis=-1)
    return point, direction


def detour_if_blocked(point, direction, valid, v_pref, angle: float) -> np.ndarray:
    """``v_pref`` (M, 2) turned clockwise (about +z) by ``angle`` rad in the rows where it lies
    outside one of the row's half-planes; the other rows unchanged (a copy).

    The right-hand rule of traffic, added to both baselines as a deliberate deviation from their
    papers: in perfectly symmetric encounters (the antipodal swap) reciprocal avoidance and barrier
    certificates alike settle into a deadlock (a ring of agents pressed against each other round
    the centre, every preferred velocity cut to zero by symmetry; random perturbations average out).
    Turning every blocked agent's preferred velocity to the same side makes the crowd circulate
    round the conflict and leave it. Only the objective changes, never the constraints, so the
    avoidance guarantees are untouched; a turn below 90 degrees keeps the goal attractive.
    """
    if angle == 0.0 or valid.shape[1] == 0:
        return v_pref
    blocked = np.any(valid & (violation(point, direction, v_pref) > 0.0), axis=1)
    c, s = np.cos(angle), np.sin(angle)
    turned = np.column_stack([c * v_pref[:, 0] + s * v_pref[:, 1], -s * v_pref[:, 0] + c * v_pref[:, 1]])
    return np.where(blocked[:, None], turned, v_pref)
