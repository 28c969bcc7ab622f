"""The boids' steer in one compiled pass over the neighbour pairs (numba, cached on disk).

The sums are those of ``plugins/formation/reynolds_flocking.py`` (cohesion, separation and
alignment; see its docstring for the rule), accumulated in the order NumPy's ``bincount`` takes
them, pair by pair, into separate sums that are added as the NumPy form adds them: the result is
bit for bit that of the NumPy form kept in ``tests/oracles/flocking.py``, at a tenth of its cost
(1,000 boids, ~30,000 pairs: ~0.15 ms against ~1.5 ms of gathers and bincounts).

Imported by the formation when it is built, not when it is registered (numba's start-up).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def flocking_steer(i, j, delta, heading, follow, cohere, match, separate, separation):
    """Sum of cohesion, separation and alignment for every boid, and its neighbour count |N_i|.

    Args:
        i, j: (M,) neighbour pairs, each unordered pair once.
        delta: (A, M) p_j - p_i along the first A steered axes (minimum image where periodic), m.
        heading: (N, 3) d_j of every boid.
        follow: (N,) bool, boids that count as neighbours for cohesion and alignment.
        cohere, match, separate: the weights; separation: the separation distance, m.
    Returns:
        steer (N, 3) = c_i + s_i + m_i (not yet divided by |N_i|), and |N_i| (N,).
    """
    n = heading.shape[0]
    axes, m = delta.shape
    steer = np.zeros((n, 3))
    count = np.zeros(n)
    if m == 0:
        return steer, count
    everyone = True
    for a in range(n):
        everyone = everyone and follow[a]
    close = np.zeros(m, np.bool_)
    limit = separation * separation
    for p in range(m):
        d2 = 0.0
        for k in range(axes):
            d2 += delta[k, p] * delta[k, p]
        close[p] = d2 < limit
    to_i_sum = np.zeros(n)  # what each boid takes from the neighbours it is i of
    to_j_sum = np.zeros(n)  # and from those it is j of
    near_i = np.zeros(n)
    near_j = np.zeros(n)
    for k in range(axes):
        to_i_sum[:] = 0.0
        to_j_sum[:] = 0.0
        near_i[:] = 0.0
        near_j[:] = 0.0
        any_close = False
        for p in range(m):
            a, b = i[p], j[p]
            to_i = cohere * delta[k, p] + match * heading[b, k]
            to_j = match * heading[a, k] - cohere * delta[k, p]
            if not everyone:
                to_i *= 1.0 if follow[b] else 0.0
                to_j *= 1.0 if follow[a] else 0.0
            to_i_sum[a] += to_i
            to_j_sum[b] += to_j
            if close[p]:  # separation: -separate * sum over close neighbours of delta_ij
                near_i[a] += delta[k, p]
                near_j[b] += delta[k, p]
                any_close = True
        for a in range(n):
            s = to_i_sum[a] + to_j_sum[a]
            if any_close:
                s -= separate * (near_i[a] - near_j[a])
            steer[a, k] = s
    # |N_i|: every neighbour when all are followed, else only the followed ones
    to_i_sum[:] = 0.0
    to_j_sum[:] = 0.0
    for p in range(m):
        a, b = i[p], j[p]
        to_i_sum[a] += 1.0 if everyone or follow[b] else 0.0
        to_j_sum[b] += 1.0 if everyone or follow[a] else 0.0
    for a in range(n):
        count[a] = to_i_sum[a] + to_j_sum[a]
    return steer, count
