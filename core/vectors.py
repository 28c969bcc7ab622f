"""Small vectorised helpers shared by the kernel and plugins."""

from __future__ import annotations

from functools import lru_cache

import numpy as np


def every(mask: np.ndarray) -> bool:
    """``mask.all()`` of a bool array without ndarray.all's Python-level wrapper (a per-tick test)."""
    return np.count_nonzero(mask) == mask.size


def rows_of(index: np.ndarray) -> np.ndarray | slice:
    """Sorted row indices as a slice when they are consecutive (one failed vehicle, say), else as
    they are: reading or writing rows through a slice costs a third of a fancy index."""
    if index.size and index[-1] - index[0] == index.size - 1:
        return slice(int(index[0]), int(index[-1]) + 1)
    return index


def clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    """Scale each row of ``v`` (N, k) down so that none is longer than ``limit``; shorter rows
    (and zero rows) are returned unchanged. The saturation of thesis eq. 4.21 and 5.30."""
    norm = np.sqrt(np.einsum("...i,...i->...", v, v))  # one C call per step (hot path)
    # No row too long (and a limit the 1e-300 floor cannot undercut): every factor below is 1.0.
    if isinstance(limit, (int, float)) and 1e-300 <= limit >= np.maximum.reduce(norm, None, initial=0.0):
        return v * 1.0  # the product below with a factor of exactly 1.0: a copy, same dtype
    return v * np.minimum(1.0, limit / np.maximum(norm[..., None], 1e-300))


def wrap(pos: np.ndarray, lo: np.ndarray | float, size: np.ndarray) -> np.ndarray:
    """Positions folded into the periodic box [lo, lo + size) (per column of ``lo``/``size``)."""
    q = np.mod(pos - lo, size)
    q[q >= size] = 0.0  # np.mod of a tiny negative can round up to exactly `size`
    return q + lo if np.any(lo) else q


DENSE_POINTS = 32
"""Up to this many points, pair queries test every pair in one pass: as fast as building a k-d
tree for so few, and a small swarm's run then never imports scipy.spatial (a quarter of a second
of the command line's start-up)."""


@lru_cache(maxsize=DENSE_POINTS + 1)
def _upper_pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.triu_indices(n, 1)


@lru_cache(maxsize=DENSE_POINTS + 1)
def upper_pair_array(n: int) -> np.ndarray:
    """Every index pair (i < j, lexicographic) of ``n`` points, shape (M, 2); made once per ``n``
    (read-only: select from it, never write)."""
    pairs = np.column_stack(_upper_pairs(n))
    pairs.flags.writeable = False
    return pairs


def dense_pair_dist2(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair (i < j, in lexicographic order) of ``points`` (N, D) and its squared distance,
    summed axis by axis as a k-d tree sums it (so distances agree with the tree's to the bit)."""
    i, j = _upper_pairs(len(points))
    if points.dtype != np.float64:  # each axis's differences in their own type, summed in float64
        d2 = np.zeros(i.size)
        for k in range(points.shape[1]):
            diff = points[j, k] - points[i, k]
            d2 += diff * diff
        return i, j, d2
    diff = points.take(j, axis=0)
    diff -= points.take(i, axis=0)
    diff *= diff
    # ((dx^2 + dy^2) + dz^2), left to right: the tree's order (one pass per axis cost 3x more calls)
    d2 = diff[:, 0] + diff[:, 1] if points.shape[1] > 1 else diff[:, 0].copy()
    for k in range(2, points.shape[1]):
        d2 += diff[:, k]
    return i, j, d2


def dense_pair_dist2_batch(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`dense_pair_dist2` of B point sets at once: ``points`` (B, N, D) float64, the pairs
    (i < j) and their squared distances (B, M), each row the bits of that set's own call (the same
    elementwise differences, squares and axis sums, in the same order)."""
    i, j = _upper_pairs(points.shape[1])
    diff = points.take(j, axis=1)
    diff -= points.take(i, axis=1)
    diff *= diff
    d2 = diff[:, :, 0] + diff[:, :, 1] if points.shape[2] > 1 else diff[:, :, 0].copy()
    for k in range(2, points.shape[2]):
        d2 += diff[:, :, k]
    return i, j, d2


def pairs_within(points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (i < j, in lexicographic order) of ``points`` (N, D) at most ``radius`` apart,
    shape (M, 2), and its squared distance (M,): one dense pass for at most ``DENSE_POINTS``
    points, a compiled cell list for more (:func:`.cells.pairs_within`; no tree to build: 1,000
    boids in flocks, 192 us against 245 us for a k-d tree's build and ``query_pairs``). Both sum
    distances as the tree does, so they agree with it to the bit.
    """
    if len(points) <= DENSE_POINTS:
        d2 = dense_pair_dist2(points)[2]
        near = d2 <= radius * radius
        return upper_pair_array(len(points))[near], d2[near]
    from .cells import pairs_within as listed  # imports numba: only swarms this large pay for it

    return listed(np.ascontiguousarray(points, dtype=float), float(radius))


def quat_yaw(quat: np.ndarray) -> np.ndarray:
    """The heading about world z of the body x axis, rad, from attitude quaternions (w, x, y, z)
    along the last axis (any leading shape): atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))."""
    w, x, y, z = np.moveaxis(np.asarray(quat, float), -1, 0)
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def ellipsoid_norm(d: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """||E^-1 d|| of each displacement ``d`` (M, 3), E = diag(``radii``) (3,), m: below 1 inside the
    ellipsoid. The keep-out ellipsoid of Crazyswarm's planners (Preiss et al., "Downwash-aware
    trajectory planning for large quadrotor teams", IROS 2017; radii 0.12, 0.12, 0.3 m). Summed
    ((x/rx)^2 + (y/ry)^2) + (z/rz)^2, left to right, so a scalar transcription gives the same bits."""
    s = d / radii
    s *= s
    return np.sqrt(s[:, 0] + s[:, 1] + s[:, 2])


def min_distance_between(a: np.ndarray, b: np.ndarray) -> float:
    """Smallest distance between a row of ``a`` (M, 2) and a row of ``b`` (F, 2), m; ``inf`` if
    either is empty. The closest pair across two sets (agents against failed vehicles), with the
    squares summed x then y as :func:`min_pair_distance` and a k-d tree sum them (the same distance
    to the bit), in a few small array operations: CEM runs it every tick after a hand-back.
    """
    if a.shape[0] == 0 or b.shape[0] == 0:
        return float("inf")
    dx = a[:, 0, None] - b[None, :, 0]
    dy = a[:, 1, None] - b[None, :, 1]
    return float(np.sqrt((dx * dx + dy * dy).min()))


def min_pair_distance(points: np.ndarray) -> float:
    """Smallest distance between two of ``points`` (N, D), m; ``inf`` for fewer than two.

    Every pair for at most ``DENSE_POINTS`` points, a compiled cell list for more (:mod:`.cells`:
    exact, and cheaper than even a 2-nearest query of a k-d tree already built: 7 against ~35 us
    at N = 100). Both sum distances as the tree does, so they agree with it to the bit. The one
    implementation behind the safety monitor's separation, CEM's theorem preconditions and the
    thesis' collision condition (eq. 5.2).
    """
    if len(points) < 2:
        return float("inf")
    if len(points) <= DENSE_POINTS:
        return float(np.sqrt(dense_pair_dist2(points)[2].min()))
    from .cells import closest_pair_distance  # imports numba: only swarms this large pay for it

    return float(closest_pair_distance(np.ascontiguousarray(points, dtype=float)))
