"""The boids' steer in one compiled pass over the neighbour pairs (numba, cached on disk).

The sums are those of :mod:`.steering` (cohesion, separation and
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
        i: (M,) first boid of each neighbour pair (each unordered pair once).
        j: (M,) second boid of each pair.
        delta: (A, M) p_j - p_i along the first A steered axes (minimum image where periodic), m.
        heading: (N, 3) d_j of every boid.
        follow: (N,) bool, boids that count as neighbours for cohesion and alignment.
        cohere: cohesion weight, 1/m.
        match: alignment weight.
        separate: separation weight, 1/m.
        separation: the separation distance, m.

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


@numba.njit(cache=True)
def seam_pairs(pos, lo, hi, radius, shifts):
    """Pairs within ``radius`` through the seams of a periodic box (the ones a Euclidean search misses).

    Args:
        pos: (N, 3) positions inside the box on its periodic axes (the first A = ``len(lo)``).
        lo: (A,) lower corner of the box on the periodic axes.
        hi: (A,) upper corner.
        radius: neighbour radius, below half the box's smallest side.
        shifts: (K, A) the images to try, in box units (``periodic_shifts``: half of the 3^A - 1).

    Returns:
        i, j (M,) and p_j - (p_i + shift) on the periodic axes, (A, M): the minimum-image vectors.

    For shift s, only an agent within ``radius`` of the face s carries it across can meet anyone,
    and only agents within ``radius`` of the opposite face can be met: each band is listed, and
    every image p_i + s is tested against the other band (3-D distance, so non-periodic axes count
    as usual). Exact; a few bands of a few agents, so no tree is needed.
    """
    n = pos.shape[0]
    axes = lo.shape[0]
    size = hi - lo
    r2 = radius * radius
    out_i, out_j = [0][:0], [0][:0]
    out_d = [0.0][:0]
    source = np.empty(n, np.int64)
    target = np.empty(n, np.int64)
    image = np.empty(3)
    for s in range(shifts.shape[0]):
        ns = nt = 0
        for a in range(n):
            near_from = near_to = True
            for k in range(axes):
                if shifts[s, k] > 0:
                    near_from = near_from and pos[a, k] <= lo[k] + radius
                    near_to = near_to and pos[a, k] >= hi[k] - radius
                elif shifts[s, k] < 0:
                    near_from = near_from and pos[a, k] >= hi[k] - radius
                    near_to = near_to and pos[a, k] <= lo[k] + radius
            if near_from:
                source[ns] = a
                ns += 1
            if near_to:
                target[nt] = a
                nt += 1
        for u in range(ns):
            a = source[u]
            for k in range(3):
                image[k] = pos[a, k] + shifts[s, k] * size[k] if k < axes else pos[a, k]
            for v in range(nt):
                b = target[v]
                d2 = 0.0
                for k in range(3):
                    diff = pos[b, k] - image[k]
                    d2 += diff * diff
                if d2 <= r2:
                    out_i.append(a)
                    out_j.append(b)
                    for k in range(axes):
                        out_d.append(pos[b, k] - image[k])
    m = len(out_i)
    i = np.empty(m, np.int64)
    j = np.empty(m, np.int64)
    delta = np.empty((axes, m))
    for p in range(m):
        i[p] = out_i[p]
        j[p] = out_j[p]
        for k in range(axes):
            delta[k, p] = out_d[p * axes + k]
    return i, j, delta
