"""The NumPy forms of the boids' steer and seam pairs: the oracles of the compiled ones
(``swarmscene.methods.flocking.kernels``), which must equal them (the steer bit for bit, the seam
pairs as a set with the same minimum-image vectors)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from swarmscene.plugins.formation.reynolds_flocking import periodic_shifts


def flocking_steer(
    i: np.ndarray,
    j: np.ndarray,
    delta: np.ndarray,
    heading: np.ndarray,
    follow: np.ndarray,
    p,
) -> tuple[np.ndarray, np.ndarray]:
    """Sum of cohesion, separation and alignment for every boid, and its neighbour count |N_i|.

    Args:
        i: (M,) first boid of each neighbour pair (each unordered pair once).
        j: (M,) second boid of each pair.
        delta: (A, M) p_j - p_i along the first A steered axes (minimum image where periodic), m;
            A = 2 in a planar flock (its z steer stays 0), else 3.
        heading: (N, 3) d_j of every boid.
        follow: (N,) bool, boids that count as neighbours for cohesion and alignment.
        p: the weights and the separation distance.

    Returns:
        steer (N, 3) = c_i + s_i + m_i (not yet divided by |N_i|), and |N_i| (N,).

    Each pair is visited once and feeds both ends (delta_ji = -delta_ij): per axis two weighted
    ``bincount`` over the M pairs, plus two over the few pairs closer than ``separation``. Arrays
    are axis-major and contiguous: a 1-D gather is several times faster than a row gather.
    """
    n = heading.shape[0]
    steer = np.zeros((n, 3))
    if len(i) == 0:
        return steer, np.zeros(n)
    everyone = bool(follow.all())
    f_i = None if everyone else follow[i].astype(float)
    f_j = None if everyone else follow[j].astype(float)
    close = np.flatnonzero(np.einsum("km,km->m", delta, delta) < p.separation * p.separation)
    close_i, close_j = i[close], j[close]
    for k in range(delta.shape[0]):
        d_k = delta[k]
        h_k = np.ascontiguousarray(heading[:, k])
        to_i = p.cohere * d_k + p.match * h_k.take(j)  # what boid i takes from its neighbour j
        to_j = p.match * h_k.take(i) - p.cohere * d_k  # and j from i
        if not everyone:
            to_i *= f_j
            to_j *= f_i
        s_k = np.bincount(i, to_i, n) + np.bincount(j, to_j, n)
        if close.size:  # separation: -separate * sum over close neighbours of delta_ij
            near = d_k.take(close)
            s_k -= p.separate * (np.bincount(close_i, near, n) - np.bincount(close_j, near, n))
        steer[:, k] = s_k
    if everyone:
        count = (np.bincount(i, minlength=n) + np.bincount(j, minlength=n)).astype(float)
    else:
        count = np.bincount(i, f_j, n) + np.bincount(j, f_i, n)
    return steer, count


def seam_pairs(
    pos: np.ndarray, tree: cKDTree, lo: np.ndarray, hi: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs within ``radius`` through the seams of a periodic box (the ones a Euclidean tree misses).

    Args:
        pos: (N, 3) positions inside the box on its periodic axes (the first A = ``len(lo)``).
        tree: the k-d tree over ``pos`` (the tick's shared one).
        lo: (A,) lower corner of the box on the periodic axes.
        hi: (A,) upper corner.
        radius: neighbour radius, below half the box's smallest side.

    Returns:
        i, j (M,) and p_j - (p_i + shift) on the periodic axes, (A, M): the minimum-image vectors.

    For each shift s, only agents within ``radius`` of the face that s carries them across can meet
    anyone: their images p_i + s are queried against the tree (3-D distance, so non-periodic axes
    count as usual).
    """
    axes, size = len(lo), hi - lo
    agents, images = [], []
    for shift in periodic_shifts(axes):
        near = np.ones(len(pos), dtype=bool)
        for k in np.flatnonzero(shift):
            near &= pos[:, k] <= lo[k] + radius if shift[k] > 0 else pos[:, k] >= hi[k] - radius
        idx = np.flatnonzero(near)
        image = pos[idx].copy()
        image[:, :axes] += shift * size
        agents.append(idx)
        images.append(image)
    agents_all, images_all = np.concatenate(agents), np.concatenate(images)
    if agents_all.size == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), np.zeros((axes, 0))
    # One tree over every image, one query against the shared tree.
    hits = cKDTree(images_all).sparse_distance_matrix(tree, radius, output_type="ndarray")
    row, j = hits["i"], hits["j"]
    delta = (pos[j, :axes] - images_all[row, :axes]).T
    return agents_all[row], j, np.ascontiguousarray(delta)
