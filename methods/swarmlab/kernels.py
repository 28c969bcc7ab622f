"""Compiled SwarmLab metrics of one swarm state (numba): one pass per sample for the ``swarmlab`` observer.

Source: E. Soria, F. Schiano, D. Floreano, "SwarmLab: a Matlab drone swarm simulator", IROS 2020,
section IV-C (``math_tools/compute_swarm_performance.m``, ``compute_neighborhood.m``); the
definitions, symbols and the departures where the MATLAB divides by zero are in
:mod:`swarmscene.methods.swarmlab.metrics`. This module computes the same numbers without Python
and NumPy call overhead (a hundred agents' vectorised calls cost more than their arithmetic), in
one call per sample, :func:`swarm_sample`:

* :func:`neighbour_lists`: every agent's list M_j, the others within r cut to the ``max_neig``
  lowest by (distance, index) (MATLAB's stable sort), and the pairs closer than 2 r_coll (safety).
  The distances are pdist's: each pair's sum of squares in coordinate order, then its root, so an
  equal distance is equal here as in the definition. The sums pre-select (a sum above
  ``square_bound(d)`` has its root above d) and the roots decide. The previous sample's lists
  make it cheap: the furthest of agent j's previous members, now, is a distance no nearer than its
  new list's last (they are as many agents as the list holds), so the agents beyond it are dropped
  without a branch; when none is left but the members, the list stands;
* :func:`order_parameter`: Phi; :func:`undirected_graph`: A = (M + M^T) > 0 as adjacency lists;
  :func:`components`: its connected components (union U);
* :func:`certified_lambda2`: lambda_2 of the Laplacian L = D - A of a connected graph, with a proof
  that it is within ``CERT_RTOL * ||L||_inf`` of the true value, or a refusal; then
  :func:`dense_lambda2` takes it from all of the dense Laplacian's eigenvalues, as the definition.

lambda_2 (the certificate). For x orthogonal to the constant vector 1, the Rayleigh quotient
theta = x^T L x / x^T x bounds lambda_2 from above (Courant-Fischer: lambda_2 is the least quotient
on the complement of 1, L's null space). From below, Temple's inequality: if theta < b <= lambda_3,
then lambda_2 >= theta - ||L x - theta x||^2 / (b - theta) (x of unit length). The bound b on
lambda_3 comes from Sylvester's law of inertia: the number of negative pivots of an LDL^T
factorisation of L - sigma I is the number of eigenvalues below sigma; two (0 and lambda_2) prove
lambda_3 >= sigma. (One proves lambda_2 >= sigma, which certifies theta directly when sigma is
that near.) The factorisation is unpivoted, so its pivots are those of a nearby matrix: by the
backward error bound of Gaussian elimination (Higham, Accuracy and Stability of Numerical
Algorithms, 2nd ed., Theorem 9.3), L^ D^ L^T = L - sigma I + E with |E| <= gamma (|L - sigma I| +
|L^||D^||L^^T|), gamma = (w + 2) u / (1 - (w + 2) u) for inner products of at most w + 1 terms, u
the unit round-off; the count is exact for L - sigma I + E, and Weyl's inequality moves each
eigenvalue by at most ||E||_2, which is bounded (:func:`factor`) and taken off sigma. Both bounds
of lambda_2 are within ``CERT_RTOL * ||L||_inf`` of theta or the value is refused; the rounding
of theta and of the residual themselves is allowed for on top (``ROUNDING_ALLOWANCE``
(N + max degree) u ||L||_inf, the order of LAPACK's own error). A double lambda_2 (lambda_2 =
lambda_3, as on a symmetric lattice) has no shift with exactly two eigenvalues below it and is
refused unless the start vector is an eigenvector.

The vector x comes from a Krylov space of the shift-inverted Laplacian, (L - sigma I)^-1, solved
with the same factorisation, and a Rayleigh-Ritz projection with L (its small eigenproblems by
Jacobi rotations). It starts from the previous sample's Fiedler vector, smoothed by a few lazy
random-walk steps (the first sample: the positions' widest coordinate), and sigma from the middle
of the previous sample's lambda_2 and lambda_3: with 0 and lambda_2 below it, the shift-inverted
operator has lambda_2 alone at its negative end, which a Krylov space finds in four or five
solves. A shift above lambda_3 is followed by the start vector's quotient, then one just below 0
and the middle of what that finds (``FACTORISATIONS_MAX``). The factorisation runs in the
envelope of the rows ordered by x (a spectral ordering: neighbours in the graph are near each
other in x, so the envelope is narrow; about 7,000 multiply-adds for a hundred boids).

Compiled on first use and cached beside this module (``cache=True``); plain arrays and scalars in,
tuples out.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from swarmscene.methods.cem.numerics import JIT

UNIT_ROUNDOFF = 2.0**-53
"""u, the unit round-off of IEEE double precision."""
SUBNORMAL_SLACK = 4.0 * 2.0**-1074
"""Added to :func:`square_bound`: four units of the subnormal spacing, the rounding of a square
that underflows."""
CERT_RTOL = 1e-12
"""The certified bound on |lambda_2 - theta|, relative to ||L||_inf = 2 max degree (4e-11 on
lambda_2 for degrees up to twenty, 4e-13 on lambda_2 / N at N = 100: far below the tests' 1e-9)."""
ROUNDING_ALLOWANCE = 8.0
"""The rounding of theta and of the residual themselves, in units of (N + max degree) u ||L||_inf."""
DROP_MAX = 4
"""Up to this many candidates beyond an agent's list are dropped one by one; more are first cut by a
histogram of their distances (:func:`_tighten`), then ranked by insertion if still more."""
TIGHTEN_BINS = 32
"""Bins of :func:`_tighten`'s histogram."""
KRYLOV_MAX = 10
"""The largest Krylov space per factorisation (a few steps reach the certificate from a warm start)."""
FACTORISATIONS_MAX = 4
"""Shifts tried per sample before the dense eigenvalues are taken instead: the previous sample's,
the start vector's Rayleigh quotient, one below 0, and midway between the lambda_2 and lambda_3
found from there."""
SMOOTHING_STEPS = 4
"""Lazy random-walk steps on the start vector before it orders the rows (:func:`_smooth`)."""
RITZ_FROM = 5
"""The first Krylov space, after the start vector alone, where the certificate is tried (each
try solves a small eigenproblem; a warm start rarely passes with fewer vectors)."""
COLD_SHIFT = -1e-3
"""sigma for a sample without a usable previous shift, relative to ||L||_inf: just below 0, where
(L - sigma I)^-1 is positive definite on the complement of 1 and lambda_2 is its largest eigenvalue."""

JACOBI_SWEEPS_MAX = 30
"""Sweeps of the Ritz problems' Jacobi rotations at most (they converge quadratically: a handful)."""

LISTS_FLOATS = 6
"""The lists' and order's floats per agent in :func:`workspace`: the coordinates (3), row, dist, speed."""

CERTIFIED, REFUSED = 0, 1
"""The status of :func:`certified_lambda2`: theta is lambda_2 within the bound, or no proof was found."""


@njit(**JIT)
def graph_ints(n, size):
    """The integers :func:`undirected_graph` takes of its buffer: N agents' lists of at most ``size``."""
    return 5 * n + 2 + 3 * n * size


@njit(**JIT)
def lambda_floats(n):
    """The floats :func:`certified_lambda2` takes of its buffer for N agents."""
    k = KRYLOV_MAX
    return 2 * k * n + 3 * k * k + n * n + 3 * n


def workspace(n, size):
    """(fwork, iwork): every buffer of :func:`swarm_sample` for N agents' lists of at most ``size``,
    allocated once per run (``WarmStart``), so that a sample allocates nothing."""
    floats = LISTS_FLOATS * n + lambda_floats(n)
    ints = n + TIGHTEN_BINS + graph_ints(n, size) + 2 * n
    return np.empty(floats), np.empty(ints, dtype=np.int64)


# ---- one sample's graph: distances, neighbour lists, safety, order, components -----------------


@njit(**JIT)
def squares_from(coords, j, row):
    """row[i] = sum_c (p_i,c - p_j,c)^2, pdist's sum of squares in coordinate order (its root is
    the definition's distance; agent i's sum to j equals j's to i bit for bit, the differences only
    changing sign); row[j] = NaN, which no test passes: an agent is not its own neighbour.
    ``coords`` is (dim, N): one coordinate's differences are contiguous and vectorise."""
    dim, n = coords.shape
    row[:] = 0.0
    for c in range(dim):
        pj = coords[c, j]
        for i in range(n):
            delta = coords[c, i] - pj
            row[i] += delta * delta
    row[j] = np.nan


@njit(**JIT)
def square_bound(d):
    """A sum of squares above which the root is surely above d: d^2 with a few units of round-off
    to spare (fl(sqrt(s)) > d for every s > this, sqrt being correctly rounded and monotone), so a
    test on the sums drops only what the test on the roots would. A few of the smallest subnormals
    are added for a d whose square underflows (a collision radius under ~1e-154 m: the bound was
    0, and a pair at distance 0 went uncounted); above, they vanish in the rounding."""
    return d * d * (1.0 + 16.0 * UNIT_ROUNDOFF) + SUBNORMAL_SLACK


@njit(**JIT)
def nearest_within(row, r, cut, listed, dist, bins, out):
    """compute_neighborhood.m for one agent from its sums of squares ``row``: the others within r
    (d <= r), cut to the ``len(out)`` lowest by (distance, index), into out[:count] in index
    order; returns the count (M is a set: only which agents are listed matters, not their order).

    ``cut`` is a distance no nearer than the list's last (the furthest of as many agents as the
    list holds, or inf): the agents surely beyond it or r are dropped on their sums first, without
    a branch or a root; of the rest, those beyond r, then the last by (distance, index) until the
    list fits (a tie goes to the lower index: MATLAB's stable sort). The previous sample's list
    being mostly this one, few or none are left over."""
    size = len(out)
    limit = square_bound(min(cut, r))
    m = 0
    for i in range(len(row)):
        listed[m] = i
        m += np.int64(row[i] <= limit)
    within = 0
    for t in range(m):
        d = math.sqrt(row[listed[t]])
        listed[within] = listed[t]
        dist[within] = d
        within += np.int64(d <= r)
    if within - size > DROP_MAX:  # a far cut (the first sample, a member that wrapped around a torus)
        within = _tighten(dist, listed, within, size, bins)
        if within - size > DROP_MAX:
            return _insert(dist, listed, within, out)
    while within > size:
        _drop_last(dist, listed, within)
        within -= 1
    out[:within] = listed[:within]
    return within


@njit(**JIT)
def _tighten(dist, listed, m, size, bins):
    """Keep of listed[:m] (in index order) those no further than a tighter cut, and return how many:
    the distances are counted into ``len(bins)`` equal bins between their least and greatest, and the
    cut is the furthest member of the first bins that hold ``size`` of them (as many agents as the
    list holds: no nearer than its last). Those kept are the agents of those bins, tested by their bin:
    a distance's bin never decreases with it (a difference, a product and a truncation, each
    monotone), so it is in the first bins exactly when it is no further than that cut, and the cut
    itself need not be found. Three passes without a data-dependent branch."""
    lo, hi = np.inf, -np.inf
    for t in range(m):
        lo = min(lo, dist[t])
        hi = max(hi, dist[t])
    nb = len(bins)
    if not hi > lo:
        return m
    scale = nb / (hi - lo)
    bins[:] = 0
    for t in range(m):
        bins[min(np.int64((dist[t] - lo) * scale), nb - 1)] += 1
    last, held = 0, bins[0]
    while held < size:
        last += 1
        held += bins[last]
    kept = 0
    for t in range(m):
        d = dist[t]
        listed[kept] = listed[t]
        dist[kept] = d
        kept += np.int64(min(np.int64((d - lo) * scale), nb - 1) <= last)
    return kept


@njit(**JIT)
def _drop_last(dist, listed, m):
    """Remove the last of listed[:m] by (dist, index), keeping the others' order (index order)."""
    worst = 0
    for t in range(1, m):
        if dist[t] >= dist[worst]:  # at a tie the later, higher index is the last
            worst = t
    for t in range(worst, m - 1):
        dist[t] = dist[t + 1]
        listed[t] = listed[t + 1]


@njit(**JIT)
def _insert(dist, listed, m, out):
    """out[:] = the first len(out) of listed[:m] by (dist, index), nearest first, by insertion (many
    to drop: the first sample, an agent that wrapped around a torus). Returns len(out)."""
    size = len(out)
    best = np.empty(size)
    c = 0
    for t in range(m):
        d = dist[t]
        if c == size and not d < best[size - 1]:
            continue
        slot = c if c < size else size - 1
        c = min(c + 1, size)
        while slot > 0 and best[slot - 1] > d:  # strict: an equal distance stays behind
            best[slot] = best[slot - 1]
            out[slot] = out[slot - 1]
            slot -= 1
        best[slot] = d
        out[slot] = listed[t]
    return size


@njit(**JIT)
def neighbour_lists(pos, r, r_coll, nbr, count, listed_before, coords, row, listed, dist, bins):
    """Every agent's neighbour list (nbr[j, :count[j]]) and the pairs closer than 2 r_coll.

    With ``listed_before``, nbr and count hold the previous sample's lists: while agent j's
    previous list is full, the furthest of its members now is a cut no nearer than the new list's
    last (they are as many agents as the list holds), which drops most agents before the ranking;
    when no other agent is within the cut (and it is within r), the members are the nearest and
    the list stands (most agents, most samples). j's old list is read before its new one is written.
    Agent j's sums of squares and how many may be closer than 2 r_coll are one pass over the others
    (:func:`squares_counted`); its previous members' furthest is read from them, and how many others
    are within it is a second, vectorised pass. Buffers (``workspace``): coords (dim, N) (the
    positions transposed into it), row, listed, dist (N,) and bins (``TIGHTEN_BINS``,)."""
    n = pos.shape[0]
    for c in range(pos.shape[1]):
        for i in range(n):
            coords[c, i] = pos[i, c]
    size = nbr.shape[1]
    limit = 2.0 * r_coll
    near = square_bound(limit)
    close = 0
    for j in range(n):
        maybe = squares_counted(coords, j, row, near)
        if maybe:  # a root only for the rare pairs that may be close (each pair once: i > j)
            for i in range(j + 1, n):
                if row[i] < near and math.sqrt(row[i]) < limit:
                    close += 1
        cut = np.inf
        if listed_before and count[j] == size:
            furthest = 0.0  # the largest of the members' sums of squares
            for m in range(size):
                furthest = max(furthest, row[nbr[j, m]])
            cut = math.sqrt(furthest)
            if cut <= r:
                stand = square_bound(cut)
                within = 0
                for i in range(n):  # row[j] is NaN: j is not counted
                    within += np.int64(row[i] <= stand)
                if within == count[j]:
                    continue  # no other agent as near as the furthest member: the list stands as it was
        count[j] = nearest_within(row, r, cut, listed, dist, bins, nbr[j])
    return close


@njit(**JIT)
def squares_counted(coords, j, row, near):
    """row = agent j's sums of squares (:func:`squares_from`, row[j] = NaN), and, from the same pass,
    how many others have a sum below ``near``. Three coordinates (the engine's) are one loop without
    a branch, which vectorises; the sums' order of terms is squares_from's, so each sum is equal to
    it bit for bit."""
    n = coords.shape[1]
    maybe = 0
    if coords.shape[0] == 3:
        xj, yj, zj = coords[0, j], coords[1, j], coords[2, j]
        for i in range(n):
            dx = coords[0, i] - xj
            dy = coords[1, i] - yj
            dz = coords[2, i] - zj
            s = dx * dx + dy * dy + dz * dz  # (dx^2 + dy^2) + dz^2, as squares_from adds them
            row[i] = s
            maybe += np.int64(s < near)
    else:
        squares_from(coords, j, row)
        row[j] = 0.0
        for i in range(n):
            maybe += np.int64(row[i] < near)
    row[j] = np.nan
    return maybe - 1  # j's own sum, 0, was counted below near (> 0)


@njit(**JIT)
def order_parameter(vel, nbr, count, speed):
    """Phi = (1/N) sum_j (1/|N_j|) sum_{i in N_j} cos(v_j, v_i): 1 for an agent without neighbours,
    0 for a cosine with a zero velocity (the MATLAB divides by zero). ``speed``: an (N,) buffer."""
    n, dim = vel.shape
    for i in range(n):
        s = 0.0
        for c in range(dim):
            s += vel[i, c] * vel[i, c]
        speed[i] = math.sqrt(s)
    total = 0.0
    for j in range(n):
        if count[j] == 0:
            total += 1.0
            continue
        part = 0.0
        for m in range(count[j]):
            i = nbr[j, m]
            dot = 0.0
            for c in range(dim):
                dot += vel[j, c] * vel[i, c]
            norm = speed[j] * speed[i]
            if norm > 0:
                part += dot / norm
        total += part / count[j]
    return total / n


@njit(**JIT)
def undirected_graph(nbr, count, iwork):
    """A = (M + M^T) > 0 as adjacency lists (CSR: ``indices[indptr[i]:indptr[i + 1]]`` are i's
    neighbours) and the degrees: agent i's own list joined with the agents that list i (M^T), each
    once (a stamp per agent marks those met). The arrays are views of ``iwork`` (at least
    ``graph_ints(N, max list)`` integers)."""
    n = len(count)
    size = nbr.shape[1]
    indptr = iwork[:n + 1]
    deg = iwork[n + 1:2 * n + 1]
    stamp = iwork[2 * n + 1:3 * n + 1]
    fill = iwork[3 * n + 1:4 * n + 1]
    inptr = iwork[4 * n + 1:5 * n + 2]
    listers = iwork[5 * n + 2:5 * n + 2 + n * size]
    indices = iwork[5 * n + 2 + n * size:5 * n + 2 + 3 * n * size]
    inptr[:] = 0
    for j in range(n):
        for m in range(count[j]):
            inptr[nbr[j, m] + 1] += 1
    for i in range(n):
        inptr[i + 1] += inptr[i]
    fill[:] = inptr[:n]
    for j in range(n):
        for m in range(count[j]):
            i = nbr[j, m]
            listers[fill[i]] = j
            fill[i] += 1
    indptr[0] = 0
    stamp[:] = -1
    e = 0
    for i in range(n):
        for m in range(count[i]):  # i's own list: distinct agents
            u = nbr[i, m]
            stamp[u] = i
            indices[e] = u
            e += 1
        for m in range(inptr[i], inptr[i + 1]):  # those listing i, less those i lists too
            u = listers[m]
            indices[e] = u
            e += np.int64(stamp[u] != i)
        indptr[i + 1] = e
        deg[i] = e - indptr[i]
    return indptr, indices[:e], deg


@njit(**JIT)
def components(indptr, indices, seen, queue):
    """The number of connected components (breadth-first, as network_components.m); ``seen`` and
    ``queue``: (N,) integer buffers."""
    n = len(indptr) - 1
    seen[:] = 0
    found = 0
    for start in range(n):
        if seen[start]:
            continue
        found += 1
        seen[start] = 1
        queue[0] = start
        head, tail = 0, 1
        while head < tail:
            v = queue[head]
            head += 1
            for e in range(indptr[v], indptr[v + 1]):
                u = indices[e]
                if not seen[u]:
                    seen[u] = 1
                    queue[tail] = u
                    tail += 1
    return found


@njit(**JIT)
def swarm_sample(pos, vel, r, r_coll, nbr, count, listed_before, x, sigma, order, fwork, iwork):
    """One sample of at least two agents (module docstring).

    Args:
        pos: positions (N, dim), m.
        vel: velocities (N, dim), m/s.
        r: metric radius, m.
        r_coll: collision radius, m.
        nbr: (N, min(max_neig, N - 1)) neighbour lists, in: the previous sample's (with
            ``listed_before``), out: this sample's (``count`` beside them).
        count: (N,) list lengths, in and out.
        listed_before: whether nbr and count hold a previous sample's lists.
        x: (N,) the Fiedler vector, in: the previous sample's (zeros: none), out: this sample's.
        sigma: the previous sample's next shift (:func:`certified_lambda2`; <= 0: none).
        order: (N,) the previous factorisation's row order, in, and this one's, out (a permutation
            of the agents; any, the first time: it only speeds the sort).
        fwork: the floats of :func:`workspace` (N, max_neig): nothing is allocated per sample.
        iwork: the integers of :func:`workspace` (N, max_neig).

    Returns:
        (S, Phi, U, lambda_2 / N, components, certified, next sigma, factorisations, Krylov
        vectors): lambda_2 0 for more than one component (no computation), from the dense
        Laplacian's eigenvalues when no certificate is found (certified False).
    """
    n, dim = pos.shape
    size = nbr.shape[1]
    lists_f, lists_i = fwork[:LISTS_FLOATS * n], iwork[:n + TIGHTEN_BINS]
    coords = lists_f[:dim * n].reshape((dim, n)) if dim <= 3 else np.empty((dim, n))
    row, dist, speed = lists_f[3 * n:4 * n], lists_f[4 * n:5 * n], lists_f[5 * n:6 * n]
    close = neighbour_lists(pos, r, r_coll, nbr, count, listed_before, coords, row, lists_i[:n], dist,
                            lists_i[n:])
    safety = 1.0 - close / (n * (n - 1) / 2)
    phi = order_parameter(vel, nbr, count, speed)
    graph_i = iwork[n + TIGHTEN_BINS:]
    indptr, indices, deg = undirected_graph(nbr, count, graph_i)
    rest_i = graph_i[graph_ints(n, size):]
    n_cc = components(indptr, indices, rest_i[:n], rest_i[n:2 * n])
    union = (n - n_cc) / (n - 1)
    if n_cc > 1:  # one zero eigenvalue per component: lambda_2 = 0
        return safety, phi, union, 0.0, n_cc, False, sigma, 0, 0
    lambda_f = fwork[LISTS_FLOATS * n:]
    _start_vector(x, pos, lambda_f[:n].reshape((1, n)))
    lam2, status, sigma, factorisations, vectors = certified_lambda2(indptr, indices, deg, x, sigma, order,
                                                                     lambda_f, rest_i)
    if status != CERTIFIED:
        lam2 = dense_lambda2(indptr, indices, deg)
    return safety, phi, union, lam2 / n, n_cc, status == CERTIFIED, sigma, factorisations, vectors


@njit(**JIT)
def dense_lambda2(indptr, indices, deg):
    """lambda_2 of the graph's dense Laplacian (LAPACK's symmetric eigenvalues, as the definition):
    the value when no certificate is found."""
    n = len(deg)
    lap = np.zeros((n, n))
    for i in range(n):
        lap[i, i] = deg[i]
        for e in range(indptr[i], indptr[i + 1]):
            lap[i, indices[e]] = -1.0
    return np.linalg.eigvalsh(lap)[1]


# ---- lambda_2: Laplacian products, the envelope LDL^T, the certificate ---------------------------


@njit(**JIT)
def _start_vector(x, pos, spare):
    """x orthonormalised against 1: the previous Fiedler vector; without one (zeros), the positions'
    widest coordinate (a geometric graph's Fiedler vector varies along it); else the indices.
    ``spare``: any (1, N) array (only its type is used)."""
    none = spare[:0]
    if _orthonormalise(x, none, 0) >= 1e-8:
        return
    widest, spread = 0, -1.0
    for c in range(pos.shape[1]):
        v = pos[:, c].var()
        if v > spread:
            widest, spread = c, v
    x[:] = pos[:, widest]
    if _orthonormalise(x, none, 0) < 1e-8:  # all agents at one value of every coordinate
        x[:] = np.arange(len(x)) - (len(x) - 1) / 2.0
        _orthonormalise(x, none, 0)


@njit(**JIT)
def laplacian_times(indptr, indices, deg, x, out):
    """out = L x = D x - A x."""
    for i in range(len(deg)):
        s = deg[i] * x[i]
        for e in range(indptr[i], indptr[i + 1]):
            s -= x[indices[e]]
        out[i] = s


@njit(**JIT)
def envelope(indptr, indices, perm, inv, first):
    """The envelope of L with its rows in the order ``perm`` (row k is agent perm[k]): row k's
    first column in first[k]. Returns the widest row's width below the diagonal."""
    width = 0
    for k in range(len(perm)):
        v = perm[k]
        f = k
        for e in range(indptr[v], indptr[v + 1]):
            f = min(f, inv[indices[e]])
        first[k] = f
        width = max(width, k - f)
    return width


@njit(**JIT)
def factor(indptr, indices, deg, sigma, perm, inv, first, a, d):
    """Unpivoted LDL^T of P (L - sigma I) P^T in its envelope: row i of the unit lower factor in
    a[i, first[i]:i], the pivots in d. Returns (negative pivots, ||E||_2 bound), the bound inf when
    a pivot is zero (no count then).

    Row by row (bordering): with w_k = l_ik d_k kept in row i until the row is done,
    w_j = a_ij - sum_k w_k l_jk and d_i = a_ii - sum_k w_k l_ik. The bound (module docstring):
    gamma (||L - sigma I||_inf + || |L^||D^||L^^T| ||_2), the latter at most the trace
    sum_{i,k} l_ik^2 |d_k| (|L^||D^||L^^T| = B B^T, B = |L^||D^|^(1/2), and ||B B^T||_2 <= ||B||_F^2),
    summed as the entries come; gamma = gamma_{w+2} for inner products of at most w + 1 terms (w
    the widest row), doubled for these sums' own rounding."""
    n = len(perm)
    norm_a = 0.0
    trace = 0.0
    width = 0
    for i in range(n):
        fi = first[i]
        width = max(width, i - fi)
        for k in range(fi, i):
            a[i, k] = 0.0
        v = perm[i]
        diag = deg[v] - sigma
        norm_a = max(norm_a, abs(diag) + deg[v])
        for e in range(indptr[v], indptr[v + 1]):
            c = inv[indices[e]]
            if c < i:
                a[i, c] = -1.0
        for j in range(fi, i):
            s = a[i, j]
            for k in range(max(fi, first[j]), j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s
        s = diag
        for k in range(fi, i):
            w = a[i, k]
            lik = w / d[k]
            s -= w * lik
            trace += abs(w * lik)
            a[i, k] = lik
        if s == 0.0:
            return 0, np.inf
        d[i] = s
        trace += abs(s)
        a[i, i] = 1.0
    negatives = 0
    for i in range(n):
        negatives += np.int64(d[i] < 0)
    m = (width + 2) * UNIT_ROUNDOFF
    return negatives, 2.0 * m / (1.0 - m) * (norm_a + trace)


@njit(**JIT)
def solve(perm, first, a, d, b, out, work):
    """out = (L - sigma I)^-1 b from the factorisation (forward by rows, the pivots, back by columns)."""
    n = len(perm)
    for i in range(n):
        s = b[perm[i]]
        for k in range(first[i], i):
            s -= a[i, k] * work[k]
        work[i] = s
    for i in range(n):
        work[i] /= d[i]
    for i in range(n - 1, -1, -1):
        xi = work[i]
        for k in range(first[i], i):
            work[k] -= a[i, k] * xi
    for i in range(n):
        out[perm[i]] = work[i]


@njit(**JIT)
def _smooth(indptr, indices, deg, x, work):
    """x <- (x + D^-1 A x) / 2, one step of the lazy random walk: it damps the components of the
    large eigenvalues, so neighbours' values draw together and x orders the rows into a narrower
    envelope (and is nearer the Fiedler vector)."""
    for i in range(len(deg)):
        s = 0.0
        for e in range(indptr[i], indptr[i + 1]):
            s += x[indices[e]]
        work[i] = 0.5 * (x[i] + s / deg[i])
    x[:] = work


@njit(**JIT)
def sort_by(x, perm):
    """perm <- the agents in ascending (x, index) order, np.argsort(x, kind="mergesort")'s (a stable
    sort: equal values in index order), by insertion from perm's previous order, which is nearly
    sorted when x is near the vector that ordered it (a few dozen moves for a hundred boids instead
    of a merge sort); when x's sign flipped (its first agent above its last), the order is reversed
    first. Any permutation in gives the same order out: only the number of moves depends on it."""
    n = len(perm)
    if n > 1 and x[perm[0]] > x[perm[n - 1]]:
        for k in range(n // 2):
            perm[k], perm[n - 1 - k] = perm[n - 1 - k], perm[k]
    for t in range(1, n):
        v = perm[t]
        xv = x[v]
        s = t
        while s > 0:
            u = perm[s - 1]
            if x[u] < xv or (x[u] == xv and u < v):
                break
            perm[s] = u
            s -= 1
        perm[s] = v


@njit(**JIT)
def _orthonormalise(v, basis, count):
    """v against the constant vector and basis[:count] (modified Gram-Schmidt, twice: a solve near
    an eigenvalue makes v nearly parallel to earlier vectors), then to unit length; returns its
    norm after the projections relative to before (0: nothing new, or not finite)."""
    before = math.sqrt(np.dot(v, v))
    for _ in range(2):
        v -= v.mean()
        for q in range(count):
            v -= np.dot(basis[q], v) * basis[q]
    after = math.sqrt(np.dot(v, v))
    if not (after > 0 and before < np.inf):
        return 0.0
    v /= after
    return after / before


@njit(**JIT)
def _ritz(basis, image, gram, k, x, lx, small):
    """Rayleigh-Ritz with L on span(basis[:k]) (``image`` = L basis, ``gram`` = basis^T L basis,
    filled as the vectors came): the lowest Ritz vector in x, L x in lx, and the second Ritz value
    (>= lambda_3; inf for one vector). ``small``: a (2, K, K) buffer, K >= k."""
    if k == 1:
        x[:] = basis[0]
        lx[:] = image[0]
        return np.inf
    h = small[0, :k, :k]
    h[:, :] = gram[:k, :k]
    vectors = _jacobi(h, small[1, :k, :k])
    lowest, second = 0, 1
    if h[1, 1] < h[0, 0]:
        lowest, second = 1, 0
    for q in range(2, k):
        if h[q, q] < h[lowest, lowest]:
            lowest, second = q, lowest
        elif h[q, q] < h[second, second]:
            second = q
    x[:] = 0.0
    lx[:] = 0.0
    for a in range(k):
        x += vectors[a, lowest] * basis[a]
        lx += vectors[a, lowest] * image[a]
    return h[second, second]


@njit(**JIT)
def _jacobi(h, v):
    """The eigenvectors of the small symmetric h (columns of the result), its eigenvalues left on its
    diagonal: cyclic Jacobi rotations until the off-diagonal is negligible (Golub and Van Loan,
    Matrix Computations, 4th ed., algorithm 8.5.3; a few sweeps for the Ritz problems here, cheaper
    than a LAPACK call at this size). Only the Ritz values' accuracy matters, and Jacobi's is that of
    the matrix's entries. ``v``: a (k, k) buffer, returned."""
    k = h.shape[0]
    v[:, :] = 0.0
    for p in range(k):
        v[p, p] = 1.0
    for _ in range(JACOBI_SWEEPS_MAX):
        off = 0.0
        scale = 0.0
        for p in range(k):
            scale += h[p, p] * h[p, p]
            for q in range(p + 1, k):
                off += h[p, q] * h[p, q]
        if off <= (UNIT_ROUNDOFF * UNIT_ROUNDOFF) * scale:
            break
        for p in range(k - 1):
            for q in range(p + 1, k):
                if h[p, q] == 0.0:
                    continue
                tau = (h[q, q] - h[p, p]) / (2.0 * h[p, q])
                t = (1.0 if tau >= 0 else -1.0) / (abs(tau) + math.sqrt(1.0 + tau * tau))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = t * c
                for m in range(k):  # h <- h J (columns p, q)
                    hp, hq = h[m, p], h[m, q]
                    h[m, p], h[m, q] = c * hp - s * hq, s * hp + c * hq
                for m in range(k):  # h <- J^T h (rows p, q)
                    hp, hq = h[p, m], h[q, m]
                    h[p, m], h[q, m] = c * hp - s * hq, s * hp + c * hq
                for m in range(k):
                    vp, vq = v[m, p], v[m, q]
                    v[m, p], v[m, q] = c * vp - s * vq, s * vp + c * vq
    return v


@njit(**JIT)
def _temple(x, lx, sigma, negatives, error):
    """(theta, its proven distance to lambda_2 or inf, ||L x - theta x||^2) for x ~ 1 and
    lx = L x: Temple's bound with b = sigma - ||E|| <= lambda_3 when two pivots are negative;
    theta - b when one is (then b <= lambda_2 <= theta)."""
    norm = math.sqrt(np.dot(x, x))
    theta = np.dot(x, lx) / (norm * norm)
    res = 0.0
    for i in range(len(x)):
        e = (lx[i] - theta * x[i]) / norm
        res += e * e
    b = sigma - error
    if negatives == 2 and theta < b:
        return theta, res / (b - theta), res
    if negatives == 1:
        return theta, max(theta - b, 0.0), res
    return theta, np.inf, res


@njit(**JIT)
def _next_shift(theta, theta3, sigma, negatives):
    """The next sample's first shift: midway between the lambda_2 and lambda_3 found, or the shift
    that proved lambda_3 >= sigma when lambda_3 was not estimated, or none (<= 0: from below 0)."""
    if theta < theta3 < np.inf:
        return 0.5 * (theta + theta3)
    return sigma if negatives == 2 else 0.0


@njit(**JIT)
def certified_lambda2(indptr, indices, deg, x, sigma0, order, fwork, iwork):
    """lambda_2 of the connected graph's Laplacian with its proof (module docstring).

    Args:
        indptr: where each agent's neighbours start in ``indices`` (:func:`undirected_graph`).
        indices: the agents' neighbours, listed together.
        deg: the degrees.
        x: the start vector (the previous Fiedler vector; not constant), overwritten with the
            Fiedler vector found.
        sigma0: the first shift (between the previous lambda_2 and lambda_3), or a value <= 0.
        order: (N,) a permutation of the agents (the previous sample's row order), in; the rows'
            order by the start vector, out (:func:`sort_by`).
        fwork: at least ``lambda_floats(N)`` floats (:func:`workspace`).
        iwork: at least 2 N integers.

    Returns:
        (theta, status, next sigma, factorisations, Krylov vectors): theta within
        CERT_RTOL ||L||_inf of lambda_2 when status is CERTIFIED; next sigma the middle of the
        lambda_2 and lambda_3 found, for the next sample.
    """
    n = len(deg)
    norm_l = 2.0 * deg.max()
    tol = CERT_RTOL * norm_l
    rounding = ROUNDING_ALLOWANCE * (n + deg.max()) * UNIT_ROUNDOFF * norm_l
    kmax = min(KRYLOV_MAX, n - 1)
    used = 0
    basis = fwork[used:used + kmax * n].reshape((kmax, n))
    used += kmax * n
    image = fwork[used:used + kmax * n].reshape((kmax, n))
    used += kmax * n
    gram = fwork[used:used + kmax * kmax].reshape((kmax, kmax))
    used += kmax * kmax
    small = fwork[used:used + 2 * kmax * kmax].reshape((2, kmax, kmax))
    used += 2 * kmax * kmax
    a = fwork[used:used + n * n].reshape((n, n))
    used += n * n
    lx, d, work = fwork[used:used + n], fwork[used + n:used + 2 * n], fwork[used + 2 * n:used + 3 * n]
    inv, first = iwork[:n], iwork[n:2 * n]
    if _orthonormalise(x, basis, 0) < 1e-8:  # (nearly) constant: no direction to start from
        x[:] = np.arange(n) - (n - 1) / 2.0
        _orthonormalise(x, basis, 0)
    for _ in range(SMOOTHING_STEPS):
        _smooth(indptr, indices, deg, x, lx)
    _orthonormalise(x, basis, 0)
    sort_by(x, order)
    perm = order
    for k in range(n):
        inv[perm[k]] = k
    envelope(indptr, indices, perm, inv, first)
    laplacian_times(indptr, indices, deg, x, lx)
    quotient = np.dot(x, lx)  # >= lambda_2: between lambda_2 and lambda_3 when x is near the Fiedler vector
    shifts = (sigma0, quotient, COLD_SHIFT * norm_l)  # the previous sample's, x's quotient, below 0
    tried = 0 if sigma0 > 0 else 1
    theta, theta3 = np.inf, np.inf
    vectors = 0
    factorisations = 0
    fresh = True  # lx is still L x of the start vector: the first Krylov space's L basis[0] is a copy
    while factorisations < FACTORISATIONS_MAX:
        sigma = shifts[tried] if tried < 3 else 0.5 * (theta + theta3)
        negatives, error = factor(indptr, indices, deg, sigma, perm, inv, first, a, d)
        factorisations += 1
        if not error < np.inf:
            return theta, REFUSED, sigma, factorisations, vectors
        if negatives >= 3 and tried < 2:  # sigma above lambda_3: the next shift, lower
            tried += 1
            continue
        basis[0] = x
        if fresh:
            image[0] = lx  # the same product, the same bits
        else:
            laplacian_times(indptr, indices, deg, basis[0], image[0])
        fresh = False  # from here on the Ritz vector and its orthonormalisation change x
        gram[0, 0] = np.dot(basis[0], image[0])
        k = 1
        while True:
            if k == 1 or k >= RITZ_FROM:
                second = _ritz(basis, image, gram, k, x, lx, small)
                if second < np.inf:  # (one vector has no second Ritz value: keep the previous shift's)
                    theta3 = second
                theta, bound, res = _temple(x, lx, sigma, negatives, error)
                if bound + rounding <= tol:
                    return theta, CERTIFIED, _next_shift(theta, theta3, sigma, negatives), factorisations, vectors
                if k == kmax or (negatives < 2 and k > 1 and 2.0 * res / (theta3 - theta) + rounding <= 0.5 * tol):
                    break  # the space is full, or x would pass at a shift midway to lambda_3: shift there
            solve(perm, first, a, d, basis[k - 1], basis[k], work)
            vectors += 1
            if _orthonormalise(basis[k], basis, k) < 1e-12:  # an invariant subspace: nothing new
                break
            laplacian_times(indptr, indices, deg, basis[k], image[k])
            for q in range(k + 1):
                gram[q, k] = gram[k, q] = np.dot(basis[q], image[k])
            k += 1
        _orthonormalise(x, basis, 0)
        if not theta < theta3 < np.inf:
            break
        tried = 3  # from now on, midway between the lambda_2 and lambda_3 found
    return theta, REFUSED, _next_shift(theta, theta3, sigma, 0), factorisations, vectors
