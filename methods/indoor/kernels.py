"""Compiled per-tick kernels of the thesis' indoor swarm (Karydes 2020, chapter 5; issue 20).

One call per tick senses (:func:`snapshot_kernel`: the nearest obstacle points o_i, eq. 5.32, and
:func:`graphs_kernel`: G_n with line of sight, eq. 5.7-5.12, and G_sigma by the deactivation rules,
eq. 5.13-5.22, under each reading of eq. 5.15-5.16), one computes the formation terms, the
leader's input and the rank step (:func:`formation_kernel`, eq. 5.24-5.26, 5.37-5.44), one the
avoidance terms (:func:`avoidance_kernel`, eq. 5.32-5.36), one the saturated command
(:func:`barrier_kernel`, eq. 5.30), one the maximum rank (:func:`max_rank_kernel`, eq. 5.23). They
replace dozens of small numpy calls whose fixed overhead dominated the tick; the
numpy formulation they replace is kept as the test oracle (tests/oracles/indoor_graphs.py).

Arithmetic: every float operation is written in the order of the numpy code it replaces (sums in
the order ``np.bincount`` accumulates them, i.e. arc order; no fastmath, so no contraction into
FMA), so the results are bit-identical. Two numpy operations use BLAS, whose dot product fuses a
multiply-add: Algorithm 1's ``np.dot`` and the 1-D ``np.linalg.norm``; the kernel calls ``np.dot``
for those too (numba reaches the same BLAS kernel). The line-of-sight and nearest-point geometry
follows GEOS' formulas (``Distance::pointToSegment``, ``segmentToSegment``,
``LineSegment::closestPoint``, compiled once for the engine in ``core/footprints.py``), which
shapely computed before.

Arc order of a graph (what :meth:`EdgeList.directed` returns and what the sums follow): for an
undirected graph with edges sorted by (i, j), agent s lists first its neighbours above s, then
those below, each ascending; for an arc list (directed reading) its neighbours ascending.

Importing this module imports numba (~0.2 s); it is imported at first use, never at plugin
registration (start-up, issue 20).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from swarmscene.core.footprints import closest_point as _closest_point
from swarmscene.core.footprints import inside as _inside
from swarmscene.core.footprints import point_segment_distance as _point_segment_distance
from swarmscene.core.footprints import segment_distance as _segment_distance

READINGS = {"neighbours": 0, "common": 1, "directed": 2}
"""Codes of the ``deactivation_candidates`` readings of eq. 5.15-5.16 passed to the kernels."""


# --- geometry (on core/footprints.py's GEOS formulas: line of sight and nearest points equal shapely's)


@numba.njit(cache=True, error_model="numpy")
def _segment_clear(ax, ay, bx, by, seg, geom_start, polygonal, bbox, d_l):
    """Line of sight of eq. 5.8: segment AB farther than d_l from every obstacle geometry.

    Inclusive like shapely's ``dwithin`` (a segment exactly at d_l is blocked); an end point
    inside a polygon is at distance 0.
    """
    lo_x, hi_x = min(ax, bx), max(ax, bx)
    lo_y, hi_y = min(ay, by), max(ay, by)
    for g in range(geom_start.size - 1):
        # Envelope distance first (GEOS' short-cut): most walls are far from the segment.
        ex = max(0.0, max(bbox[g, 0] - hi_x, lo_x - bbox[g, 2]))
        ey = max(0.0, max(bbox[g, 1] - hi_y, lo_y - bbox[g, 3]))
        if math.sqrt(ex * ex + ey * ey) > d_l:
            continue
        start, stop = geom_start[g], geom_start[g + 1]
        if polygonal[g] and (_inside(ax, ay, seg, start, stop) or _inside(bx, by, seg, start, stop)):
            return False
        for k in range(start, stop):
            if _segment_distance(ax, ay, bx, by, seg[k, 0], seg[k, 1], seg[k, 2], seg[k, 3]) <= d_l:
                return False
    return True


@numba.njit(cache=True, error_model="numpy")
def nearest_points_kernel(r, index, seg, geom_start, polygonal):
    """o_i, the point of obstacle ``index[i]`` closest to r_i (eq. 5.32), (N, 2); NaN where -1.

    GEOS' ``DistanceOp`` nearest points: r_i itself inside a polygon, else the closest point of
    the first ring segment (rings in order) at the smallest ``pointToSegment`` distance.
    """
    n = r.shape[0]
    o = np.full((n, 2), np.nan)
    for i in range(n):
        g = index[i]
        if g < 0:
            continue
        px, py = r[i, 0], r[i, 1]
        start, stop = geom_start[g], geom_start[g + 1]
        if polygonal[g] and _inside(px, py, seg, start, stop):
            o[i, 0], o[i, 1] = px, py
            continue
        best = np.inf
        for k in range(start, stop):
            ax, ay, bx, by = seg[k, 0], seg[k, 1], seg[k, 2], seg[k, 3]
            dist = _point_segment_distance(px, py, ax, ay, bx, by)
            if dist < best:
                best = dist
                o[i, 0], o[i, 1] = _closest_point(px, py, ax, ay, bx, by)
    return o


# --- graphs G_n and G_sigma (eq. 5.7-5.22) -----------------------------------------------------


@numba.njit(cache=True, error_model="numpy")
def _csr(n, i, j):
    """Arc order of an undirected edge list sorted by (i, j): (indptr, dst, edge of each arc)."""
    indptr = np.zeros(n + 1, dtype=np.intp)
    for k in range(i.size):
        indptr[i[k] + 1] += 1
        indptr[j[k] + 1] += 1
    for a in range(n):
        indptr[a + 1] += indptr[a]
    fill = indptr[:-1].copy()
    dst = np.empty(2 * i.size, dtype=np.intp)
    edge = np.empty(2 * i.size, dtype=np.intp)
    for k in range(i.size):  # neighbours above each agent, ascending (edges sorted by (i, j))
        dst[fill[i[k]]] = j[k]
        edge[fill[i[k]]] = k
        fill[i[k]] += 1
    for k in range(i.size):  # then those below, ascending
        dst[fill[j[k]]] = i[k]
        edge[fill[j[k]]] = k
        fill[j[k]] += 1
    return indptr, dst, edge


@numba.njit(cache=True, error_model="numpy")
def neighbour_edges(r, pairs, clearance, d_l, seg, geom_start, polygonal, bbox):
    """E_n (eq. 5.11-5.12): the candidate ``pairs`` within d_n whose segment keeps d_l clearance.

    A pair certified by its ends' obstacle clearances (c_i + c_j >= ||r_ij|| + 2 d_l, see
    ``sensing.sensing_pairs``) skips the segment test. Returns (i, j) sorted by (i, j), i < j.
    """
    p = pairs.shape[0]
    n = r.shape[0]
    keep = np.ones(p, dtype=np.bool_)
    if geom_start.size > 1:
        for k in range(p):
            a, b = pairs[k, 0], pairs[k, 1]
            gx, gy = r[b, 0] - r[a, 0], r[b, 1] - r[a, 1]
            length = math.sqrt(gx * gx + gy * gy)
            if clearance[a] + clearance[b] < length + 2.0 * d_l:
                keep[k] = _segment_clear(r[a, 0], r[a, 1], r[b, 0], r[b, 1], seg, geom_start, polygonal, bbox, d_l)
    return _sorted_edges(n, pairs, keep)


@numba.njit(cache=True, error_model="numpy")
def _sorted_edges(n, pairs, keep):
    """The kept pairs as edges (i < j) sorted by (i, j): a counting sort by i, then an insertion
    sort of each agent's handful of j (linear, unlike a sort of all the keys)."""
    start = np.zeros(n + 1, dtype=np.intp)
    for k in range(pairs.shape[0]):
        if keep[k]:
            start[min(pairs[k, 0], pairs[k, 1]) + 1] += 1
    for a in range(n):
        start[a + 1] += start[a]
    fill = start[:-1].copy()
    i = np.empty(start[n], dtype=np.intp)
    j = np.empty(start[n], dtype=np.intp)
    for k in range(pairs.shape[0]):
        if keep[k]:
            lo, hi = min(pairs[k, 0], pairs[k, 1]), max(pairs[k, 0], pairs[k, 1])
            q = fill[lo]
            fill[lo] += 1
            while q > start[lo] and j[q - 1] > hi:
                j[q] = j[q - 1]
                q -= 1
            j[q] = hi
    for a in range(n):
        i[start[a]:start[a + 1]] = a
    return i, j


@numba.njit(cache=True, error_model="numpy")
def _arc_rules(r, nx, ny, indptr, dst, a, b, phi_d, common, mark, cand, side, both):
    """Rules 5.18 and 5.21 for the arc a -> b of G_n as agent a evaluates them.

    Candidates m in N_a(G_n) other than b (``common``: also in N_b, flagged in ``mark``) that lie
    in A_ab and B_ab (eq. 5.15-5.16). Rule 1: |phi(r_ma, r_ba)| < phi_d (eq. 5.17-5.18); rule 2:
    m in C (phi < 0) and n in D (phi > 0) with ||r_nm|| < ||r_ba|| (eq. 5.19-5.21). Without
    ``both`` rule 2 is skipped once rule 1 fired (only their union is wanted). ``nx``, ``ny``:
    the neighbours' coordinates in arc order (r[dst], gathered once: the scan reads them in
    sequence, three times faster than through ``dst``).
    """
    xa, ya = r[a, 0], r[a, 1]
    ex, ey = r[b, 0] - xa, r[b, 1] - ya
    d_sq = ex * ex + ey * ey
    rule1 = False
    count = 0
    for k in range(indptr[a], indptr[a + 1]):
        mx, my = nx[k] - xa, ny[k] - ya
        bx, by = mx - ex, my - ey
        # m in A_ab and in B_ab (numpy's ``** 2`` is this product). b itself is not: its squared
        # distance is d_sq exactly. One branch for both tests (``&``).
        inside = (mx * mx + my * my < d_sq) & (bx * bx + by * by < d_sq)
        if common:
            inside &= mark[dst[k]]
        if not inside:
            continue
        phi = (my * ex - mx * ey) / d_sq
        if abs(phi) < phi_d:
            rule1 = True
            if not both:
                return True, False
        if phi != 0.0:
            cand[count] = k  # the arc a -> m: its coordinates are nx[k], ny[k]
            side[count] = phi > 0.0
            count += 1
    return rule1, _crossing(nx, ny, cand, side, count, d_sq)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _crossing(nx, ny, cand, side, count, d_sq):
    """Rule 5.21: two of the ``count`` candidates, one on each side of the edge (``side``), are
    closer to each other than the edge is long (squared length ``d_sq``)."""
    for u in range(count):
        if side[u]:
            continue
        cx, cy = nx[cand[u]], ny[cand[u]]
        for v in range(count):
            if side[v]:
                dx, dy = nx[cand[v]] - cx, ny[cand[v]] - cy
                if dx * dx + dy * dy < d_sq:
                    return True
    return False


@numba.njit(cache=True, error_model="numpy")
def _arc_off(r, nx, ny, indptr, a, b, phi_d, cand, side):
    """Rule 5.18 or 5.21 fires on the arc a -> b (candidates m in N_a(G_n), as printed).

    :func:`_arc_rules` specialised to the per-tick question, whether the edge goes: no flags in
    the scan, and the first rule that fires ends it (about twice as fast).
    """
    xa, ya = r[a, 0], r[a, 1]
    ex, ey = r[b, 0] - xa, r[b, 1] - ya
    d_sq = ex * ex + ey * ey
    count = 0
    for k in range(indptr[a], indptr[a + 1]):
        mx, my = nx[k] - xa, ny[k] - ya
        bx, by = mx - ex, my - ey
        if not ((mx * mx + my * my < d_sq) & (bx * bx + by * by < d_sq)):  # A_ab and B_ab
            continue
        phi = (my * ex - mx * ey) / d_sq
        if abs(phi) < phi_d:
            return True
        if phi != 0.0:
            cand[count] = k
            side[count] = phi > 0.0
            count += 1
    return _crossing(nx, ny, cand, side, count, d_sq)


@numba.njit(cache=True, error_model="numpy")
def _gathered(r, dst):
    """The neighbours' coordinates in arc order, r[dst] column by column."""
    nx, ny = np.empty(dst.size), np.empty(dst.size)
    for q in range(dst.size):
        nx[q], ny[q] = r[dst[q], 0], r[dst[q], 1]
    return nx, ny


@numba.njit(cache=True, error_model="numpy")
def _edges_off(r, i, j, indptr, dst, phi_d, union):
    """(2, P) bool: whether agent i's rules cut edge (i, j), and agent j's (eq. 5.15-5.21, the
    literal candidates m in N(G_n)). ``union``: j's view is skipped where i's already cut it."""
    off = np.zeros((2, i.size), dtype=np.bool_)
    degree_max = 0
    for a in range(indptr.size - 1):
        degree_max = max(degree_max, indptr[a + 1] - indptr[a])
    cand = np.empty(degree_max, dtype=np.intp)
    side = np.empty(degree_max, dtype=np.bool_)
    nx, ny = _gathered(r, dst)
    for k in range(i.size):
        off[0, k] = _arc_off(r, nx, ny, indptr, i[k], j[k], phi_d, cand, side)
        if not (union and off[0, k]):
            off[1, k] = _arc_off(r, nx, ny, indptr, j[k], i[k], phi_d, cand, side)
    return off


@numba.njit(cache=True, error_model="numpy")
def deactivation_kernel(r, i, j, phi_d, reading, both):
    """Rules 5.18 and 5.21 on every edge (i, j) of G_n, from both ends (eq. 5.15-5.21).

    ``reading``: :data:`READINGS` code. Returns four (P,) bool arrays: rule 1 and rule 2 as agent
    i sees the edge, then as agent j does; under ``common`` (candidates N_i ∩ N_j) the two views
    are equal by construction and computed once. ``both`` evaluates rule 2 even where rule 1
    fired (for :func:`graphs.deactivation_rules`). The per-tick graphs use :func:`_edges_off`.
    """
    indptr, dst, _ = _csr(r.shape[0], i, j)
    return _rules(r, i, j, indptr, dst, phi_d, reading, both)


@numba.njit(cache=True, error_model="numpy")
def _rules(r, i, j, indptr, dst, phi_d, reading, both):
    """:func:`deactivation_kernel` on G_n given with its arcs (indptr, dst)."""
    n = r.shape[0]
    p = i.size
    rules = np.zeros((4, p), dtype=np.bool_)
    degree_max = 0
    for a in range(n):
        degree_max = max(degree_max, indptr[a + 1] - indptr[a])
    cand = np.empty(degree_max, dtype=np.intp)
    side = np.empty(degree_max, dtype=np.bool_)
    mark = np.zeros(n, dtype=np.bool_)
    nx, ny = _gathered(r, dst)
    common = reading == 1
    for k in range(p):
        a, b = i[k], j[k]
        if common:
            for q in range(indptr[b], indptr[b + 1]):
                mark[dst[q]] = True
        rules[0, k], rules[1, k] = _arc_rules(r, nx, ny, indptr, dst, a, b, phi_d, common, mark, cand, side, both)
        if common:
            for q in range(indptr[b], indptr[b + 1]):
                mark[dst[q]] = False
            rules[2, k], rules[3, k] = rules[0, k], rules[1, k]
        else:
            rules[2, k], rules[3, k] = _arc_rules(r, nx, ny, indptr, dst, b, a, phi_d, False, mark, cand, side, both)
    return rules


@numba.njit(cache=True, error_model="numpy")
def _sigma_arcs(n, i, j, off_i, off_j):
    """G_sigma of the directed reading: arcs i -> j unless off_i, j -> i unless off_j, sorted by
    (src, dst). Returns (indptr, src, dst)."""
    count = 0
    for k in range(i.size):
        count += (not off_i[k]) + (not off_j[k])
    key = np.empty(count, dtype=np.int64)
    count = 0
    for k in range(i.size):
        if not off_i[k]:
            key[count] = i[k] * n + j[k]
            count += 1
        if not off_j[k]:
            key[count] = j[k] * n + i[k]
            count += 1
    key.sort()
    src = np.empty(count, dtype=np.intp)
    dst = np.empty(count, dtype=np.intp)
    indptr = np.zeros(n + 1, dtype=np.intp)
    for k in range(count):
        src[k] = key[k] // n
        dst[k] = key[k] - src[k] * n
        indptr[src[k] + 1] += 1
    for a in range(n):
        indptr[a + 1] += indptr[a]
    return indptr, src, dst


@numba.njit(cache=True, error_model="numpy")
def graphs_kernel(r, pairs, clearance, d_l, phi_d, reading, seg, geom_start, polygonal, bbox):
    """G_n and G_sigma of one tick (eq. 5.7-5.22) from the candidate pairs within d_n.

    Returns one int array, the concatenation of (:func:`unpack_graphs` splits it; one array
    because each array handed back to Python costs about a microsecond):
        [|E_n|, |E_sigma|], then n_i, n_j: G_n's edges sorted by (i, j); n_indptr, n_src, n_dst:
        its arcs (arc order); s_i, s_j: G_sigma's edges (undirected readings) or arcs (directed
        reading, sorted by (src, dst)); s_indptr, s_src, s_dst: its arcs (arc order).
    """
    n = r.shape[0]
    n_i, n_j = neighbour_edges(r, pairs, clearance, d_l, seg, geom_start, polygonal, bbox)
    n_indptr, n_dst, n_edge = _csr(n, n_i, n_j)
    n_src = np.empty(n_dst.size, dtype=np.intp)
    for a in range(n):
        n_src[n_indptr[a]:n_indptr[a + 1]] = a
    if reading == 1:  # common candidates: both ends see the same set, one view
        rules = _rules(r, n_i, n_j, n_indptr, n_dst, phi_d, reading, False)
        off_i = rules[0] | rules[1]
        off_j = off_i
    else:
        off = _edges_off(r, n_i, n_j, n_indptr, n_dst, phi_d, reading != 2)
        off_i, off_j = off[0], off[1]
    if reading == 2:
        s_indptr, s_src, s_dst = _sigma_arcs(n, n_i, n_j, off_i, off_j)
        return _pack((n_i, n_j, n_indptr, n_src, n_dst, s_src, s_dst, s_indptr, s_src, s_dst))
    keep = np.empty(n_i.size, dtype=np.bool_)
    count = 0
    for k in range(n_i.size):
        keep[k] = not (off_i[k] or off_j[k])
        count += keep[k]
    s_i = np.empty(count, dtype=np.intp)
    s_j = np.empty(count, dtype=np.intp)
    count = 0
    for k in range(n_i.size):
        if keep[k]:
            s_i[count], s_j[count] = n_i[k], n_j[k]
            count += 1
    # G_sigma's arcs are G_n's with a kept edge, in the same order (a subset of sorted edges).
    s_indptr = np.zeros(n + 1, dtype=np.intp)
    s_src = np.empty(2 * count, dtype=np.intp)
    s_dst = np.empty(2 * count, dtype=np.intp)
    count = 0
    for q in range(n_dst.size):
        if keep[n_edge[q]]:
            s_src[count], s_dst[count] = n_src[q], n_dst[q]
            s_indptr[n_src[q] + 1] += 1
            count += 1
    for a in range(n):
        s_indptr[a + 1] += s_indptr[a]
    return _pack((n_i, n_j, n_indptr, n_src, n_dst, s_i, s_j, s_indptr, s_src, s_dst))


@numba.njit(cache=True, error_model="numpy")
def snapshot_kernel(r, index, dist, reach, pairs, d_l, phi_d, reading, seg, geom_start, polygonal, bbox):
    """One tick's sensing in one call: o_i (:func:`nearest_points_kernel`, eq. 5.32) and the
    graphs (:func:`graphs_kernel`) with the line-of-sight certificates min(dist_i, reach)."""
    o = nearest_points_kernel(r, index, seg, geom_start, polygonal)
    clearance = np.minimum(dist, reach)
    return o, graphs_kernel(r, pairs, clearance, d_l, phi_d, reading, seg, geom_start, polygonal, bbox)


@numba.njit(cache=True, error_model="numpy")
def _pack(parts):
    """[|E_n|, |E_sigma|] and the ten arrays of :func:`graphs_kernel`, concatenated."""
    size = 2
    for part in parts:
        size += part.size
    out = np.empty(size, dtype=np.intp)
    out[0], out[1] = parts[0].size, parts[5].size
    at = 2
    for part in parts:
        out[at:at + part.size] = part
        at += part.size
    return out


def unpack_graphs(out: np.ndarray, n: int, directed: bool) -> tuple[np.ndarray, ...]:
    """The ten arrays of :func:`graphs_kernel`'s packed result (views, no copy)."""
    p, q = int(out[0]), int(out[1])
    sizes = (p, p, n + 1, 2 * p, 2 * p, q, q, n + 1, q if directed else 2 * q, q if directed else 2 * q)
    views, at = [], 2
    for size in sizes:
        views.append(out[at:at + size])
        at += size
    return tuple(views)


# --- ranks (eq. 5.23, 5.26) ---------------------------------------------------------------------


@numba.njit(cache=True, error_model="numpy")
def max_rank_kernel(indptr, dst, leader):
    """max_i rho_i over a breadth-first search from the leader (eq. 5.23; N when an agent is cut
    off) and the (N,) mask of agents reached."""
    n = indptr.size - 1
    depth = np.full(n, -1, dtype=np.int64)
    queue = np.empty(n, dtype=np.intp)
    depth[leader] = 0
    queue[0] = leader
    head, tail = 0, 1
    while head < tail:
        a = queue[head]
        head += 1
        for k in range(indptr[a], indptr[a + 1]):
            b = dst[k]
            if depth[b] < 0:
                depth[b] = depth[a] + 1
                queue[tail] = b
                tail += 1
    reached = depth >= 0
    if tail < n:
        return n, reached
    return depth[queue[n - 1]], reached


@numba.njit(cache=True, error_model="numpy")
def _neighbour_min(indptr, dst, values, a, empty):
    best = empty
    for k in range(indptr[a], indptr[a + 1]):
        best = min(best, values[dst[k]])
    return best


@numba.njit(cache=True, error_model="numpy")
def rank_step_kernel(indptr, dst, rho_bar, leader):
    """rho_bar_i(k+1) = min over N_i(G_sigma) of rho_bar_j(k) + 1, capped at N; leader 0 (eq. 5.26)."""
    n = rho_bar.size
    new = np.empty(n, dtype=rho_bar.dtype)
    for a in range(n):
        new[a] = min(_neighbour_min(indptr, dst, rho_bar, a, n) + 1, n)
    new[leader] = 0
    return new


# --- potentials and inputs (eq. 5.24-5.25, 5.30-5.44) --------------------------------------------


@numba.njit(cache=True, error_model="numpy")
def _hyperbolic(x, gain, eps):
    """K ((1 + eps) / (x + eps) - 1) eps (shape of eq. 5.34, 5.36, 5.38)."""
    return gain * ((1.0 + eps) / (x + eps) - 1.0) * eps


@numba.njit(cache=True, error_model="numpy")
def _repulsion(z, d_min, l_max, gain, eps):
    """psi_obs / psi_col (eq. 5.34, 5.36): -K at d_min (held below), 0 beyond l_max."""
    x = max((z - d_min) / (l_max - d_min), 0.0)
    if x <= 1.0:
        return -_hyperbolic(min(x, 1.0), gain, eps)
    return 0.0


@numba.njit(cache=True, error_model="numpy")
def _psi_con(z, d_n, l_n, gain, eps):
    """psi_con (eq. 5.38): 0 below l_n, +K_con at d_n, 0 beyond."""
    x = (z - d_n) / (l_n - d_n)
    if x >= 0.0 and x <= 1.0:
        return _hyperbolic(x, gain, eps)
    return 0.0


@numba.njit(cache=True, error_model="numpy")
def _psi_com(z, d_c, d_n, gain, span):
    """psi_com (eq. 5.40), span = alpha_com (d_n - d_c)."""
    if z >= d_c and z <= d_n:
        return gain * ((z - d_c) / span - 1.0)
    return 0.0


@numba.njit(cache=True, error_model="numpy")
def _unit(r, a, b):
    """||r_ba|| and e_ab = r_ba / max(||r_ba||, 1e-12) (``control.PairGeometry``)."""
    dx, dy = r[b, 0] - r[a, 0], r[b, 1] - r[a, 1]
    length = math.sqrt(dx * dx + dy * dy)
    scale = max(length, 1e-12)
    return length, dx / scale, dy / scale


@numba.njit(cache=True, error_model="numpy")
def _leader_input(r, leader, indptr, dst, waypoints, m, d_n, u_sat, alpha_lsat, alpha_lcon):
    """u_N = w_N min(u_lsat, u_lcon) (eq. 5.43-5.44, Algorithm 1); returns (u_x, u_y, m).

    Algorithm 1's projection and the final distance use ``np.dot`` as the numpy code did (BLAS
    fuses the multiply-add there, so a scalar expression would differ in the last bit).
    """
    last = waypoints.shape[0] - 1
    rl = r[leader].copy()
    while m < last and np.dot(waypoints[m + 1] - waypoints[m], rl - waypoints[m]) >= 0.0:
        m += 1
    dx, dy = waypoints[m, 0] - rl[0], waypoints[m, 1] - rl[1]
    norm = math.hypot(dx, dy)
    wx, wy = (dx / norm, dy / norm) if norm > 1e-12 else (0.0, 0.0)
    nearest = np.inf
    for k in range(indptr[leader], indptr[leader + 1]):
        b = dst[k]
        ex, ey = r[b, 0] - rl[0], r[b, 1] - rl[1]
        nearest = min(nearest, math.sqrt(ex * ex + ey * ey))
    u_lcon = alpha_lcon * d_n - nearest
    u_lcon = u_lcon if u_lcon > 0.0 else 0.0
    magnitude = alpha_lsat * u_sat
    magnitude = u_lcon if u_lcon < magnitude else magnitude
    if m == last:
        v = waypoints[m] - rl
        rest = math.sqrt(np.dot(v, v))
        magnitude = rest if rest < magnitude else magnitude
    return wx * magnitude, wy * magnitude, m


@numba.njit(cache=True, error_model="numpy")
def formation_kernel(r, indptr, dst, rho_bar, leader, waypoints, m, gains):
    """The formation's part of eq. 5.30 for every agent, the leader's input and the rank step.

    w_i = sum over N_i(G_sigma) of (psi_con + psi_com)(||r_ji||) e_ij (eq. 5.37-5.40) + w_led
    (eq. 5.41-5.42) toward the virtual leader l_i, the mean of the neighbours of minimum rho_bar
    (eq. 5.24-5.25); row ``leader`` is u_N (eq. 5.43-5.44). ``gains``: (d_c, d_n, l_n, K_con,
    eps_con, K_com, alpha_com, K_led, u_sat, alpha_lsat, alpha_lcon).

    Returns:
        w: (N, 2) m per T_s; m: the leader's way-point index; rho_bar(k+1) (eq. 5.26).
    """
    d_c, d_n, l_n, k_con, eps_con, k_com, alpha_com, k_led, u_sat, alpha_lsat, alpha_lcon = (
        gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6], gains[7], gains[8],
        gains[9], gains[10],
    )
    span = alpha_com * (d_n - d_c)
    n = r.shape[0]
    big = np.iinfo(rho_bar.dtype).max
    w = np.empty((n, 2))
    for a in range(n):
        sx, sy = 0.0, 0.0
        best = _neighbour_min(indptr, dst, rho_bar, a, big)
        lx, ly, count = 0.0, 0.0, 0
        for k in range(indptr[a], indptr[a + 1]):
            b = dst[k]
            length, ux, uy = _unit(r, a, b)
            psi = _psi_con(length, d_n, l_n, k_con, eps_con) + _psi_com(length, d_c, d_n, k_com, span)
            sx += psi * ux
            sy += psi * uy
            if rho_bar[b] == best:  # a surrogate leader (eq. 5.25, minimum rank)
                lx += r[b, 0]
                ly += r[b, 1]
                count += 1
        if count:
            w[a, 0] = sx + k_led * (lx / count - r[a, 0])
            w[a, 1] = sy + k_led * (ly / count - r[a, 1])
        else:
            w[a, 0] = sx + 0.0
            w[a, 1] = sy + 0.0
    w[leader, 0], w[leader, 1], m = _leader_input(
        r, leader, indptr, dst, waypoints, m, d_n, u_sat, alpha_lsat, alpha_lcon
    )
    return w, m, rank_step_kernel(indptr, dst, rho_bar, leader)


@numba.njit(cache=True, error_model="numpy")
def avoidance_kernel(r, o, indptr, dst, gains):
    """w_obs + w_col (eq. 5.32-5.36) for every agent, m per T_s.

    w_obs from the nearest detected obstacle point o_i (NaN rows: none), w_col summed over
    N_i(G_sigma). ``gains``: (d_o, l_o, K_obs, eps_obs, d_c, l_c, K_col, eps_col).
    """
    d_o, l_o, k_obs, eps_obs, d_c, l_c, k_col, eps_col = (
        gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6], gains[7],
    )
    n = r.shape[0]
    w = np.empty((n, 2))
    for a in range(n):
        ox, oy = 0.0, 0.0
        dx, dy = o[a, 0] - r[a, 0], o[a, 1] - r[a, 1]
        dist = math.sqrt(dx * dx + dy * dy)
        if math.isfinite(dist) and dist > 0.0:
            scale = _repulsion(dist, d_o, l_o, k_obs, eps_obs) / dist
            ox, oy = scale * dx, scale * dy
        sx, sy = 0.0, 0.0
        for k in range(indptr[a], indptr[a + 1]):
            length, ux, uy = _unit(r, a, dst[k])
            psi = _repulsion(length, d_c, l_c, k_col, eps_col)
            sx += psi * ux
            sy += psi * uy
        w[a, 0] = ox + sx
        w[a, 1] = oy + sy
    return w


@numba.njit(cache=True, error_model="numpy")
def barrier_kernel(vel, mode, healthy, role, w, T_s, u_sat, exempt_leader, velocity_mode, leader_role):
    """The avoidance's command (eq. 5.30) in place: vel[k, :2] = sat(vel[k, :2] T_s + w[k], u_sat)
    / T_s for the acting agents (healthy; not the leader when ``exempt_leader``) in VELOCITY mode.

    The arithmetic of ``core.vectors.clip_norm``: v min(1, u_sat / max(||v||, 1e-300)). Returns
    how many acting agents are in another mode (the caller gives them the feed-forward).
    """
    others = 0
    for a in range(vel.shape[0]):
        if not healthy[a] or (exempt_leader and role[a] == leader_role):
            continue
        if mode[a] != velocity_mode:
            others += 1
            continue
        vx = vel[a, 0] * T_s + w[a, 0]
        vy = vel[a, 1] * T_s + w[a, 1]
        norm = math.sqrt(vx * vx + vy * vy)
        scale = u_sat / (1e-300 if norm < 1e-300 else norm)  # NaN propagates, as in numpy
        scale = 1.0 if scale > 1.0 else scale
        vel[a, 0] = vx * scale / T_s
        vel[a, 1] = vy * scale / T_s
    return others
