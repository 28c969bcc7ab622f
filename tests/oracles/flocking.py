"""The NumPy form of the boids' steer: the oracle of the compiled one
(``swarmscene.methods.flocking.kernels.flocking_steer``), which must equal it bit for bit."""

from __future__ import annotations

import numpy as np


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
        i, j: (M,) neighbour pairs, each unordered pair once.
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
