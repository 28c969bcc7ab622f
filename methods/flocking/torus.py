"""The flock's periodic space: Mesa's ``ContinuousSpace(torus=True)`` on the x-y (or x-y-z) axes.

A box ``[lo, hi)`` whose opposite faces are glued: the separation of two boids is the minimum image
of p_j - p_i (the shortest of its periodic copies), and the boids within a radius of boid i are
those of the interior pair list plus the pairs that meet through a seam. The seam pairs come from
the compiled :func:`~.kernels.seam_pairs`, which tests the images of the boids near a face, shifted
by one box length, against the boids near the opposite face: exact while the radius is below half
the box's smallest side (then an unordered pair has one minimum image).
"""

from __future__ import annotations

import numpy as np


def minimum_image(delta: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Shortest periodic representative of difference vectors ``delta`` (M, D) in a box ``size`` (D,)."""
    return delta - size * np.round(delta / size)


def periodic_shifts(axes: int) -> np.ndarray:
    """Half of the 3^A - 1 neighbouring images (first non-zero entry +1), in box units, (K, A).

    With ``vision`` below half the box, an unordered pair has one minimum image, and each
    seam-crossing pair is met through exactly one of these shifts (the other half mirror them).
    """
    grid = np.array(np.meshgrid(*[[-1, 0, 1]] * axes, indexing="ij")).reshape(axes, -1).T
    first = np.array([row[np.flatnonzero(row)[0]] if row.any() else 0 for row in grid])
    return grid[first > 0]


def in_box(pos: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Every position inside ``[lo, hi)`` on the box's axes (``lo``, ``hi`` of length A)."""
    a = len(lo)
    return bool(np.all(pos[:, :a] >= lo) and np.all(pos[:, :a] < hi))


def pair_offsets(pos: np.ndarray, pairs: np.ndarray, axes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Index arrays i, j (M,) of ``pairs`` (M, 2) and p_j - p_i on the first ``axes`` axes, (A, M).

    Axis-major, so each axis is one contiguous 1-D gather (the steer kernel reads it this way).
    """
    i, j = np.ascontiguousarray(pairs[:, 0]), np.ascontiguousarray(pairs[:, 1])
    coords = np.ascontiguousarray(pos[:, :axes].T)
    delta = np.empty((axes, len(i)))
    for k in range(axes):
        np.subtract(coords[k].take(j), coords[k].take(i), out=delta[k])
    return i, j, delta


def torus_neighbours(
    pos: np.ndarray, pairs: np.ndarray, lo: np.ndarray, hi: np.ndarray, radius: float, shifts: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs within ``radius`` in the torus ``[lo, hi)``: the interior ``pairs`` and the seam pairs.

    Args:
        pos: (N, 3) positions inside the box, m.
        pairs: (M, 2) the pairs within ``radius`` by plain distance (the tick's pair list).
        lo: (A,) the box's lower corner on its A periodic axes, m.
        hi: (A,) its upper corner, m.
        radius: neighbour radius, m (below half the box's smallest side).
        shifts: :func:`periodic_shifts` of A, as floats.

    Returns:
        i, j (M',) and the minimum-image p_j - p_i (A, M'), interior pairs first.
    """
    from .kernels import seam_pairs  # numba loads when a flock steers, not at registration

    i, j, delta = pair_offsets(pos, pairs, len(lo))
    si, sj, sdelta = seam_pairs(pos, lo, hi, radius, shifts)
    return np.concatenate([i, si]), np.concatenate([j, sj]), np.concatenate([delta, sdelta], axis=1)
