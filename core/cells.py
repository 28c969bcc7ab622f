"""Compiled cell lists: the closest pair of a swarm, its pairs within a radius and whether its
disk graph is connected, without a k-d tree (numba, cached on disk).

The safety monitor asks every tick for the smallest distance between two agents. A k-d tree
answers in O(N log N) but costs its build and a 2-nearest query for every agent: about 50 us at
N = 100 and 450 us at N = 1,000, more than a compiled rigid-body step of the same swarm. A uniform
grid of cells, filled by a counting sort and searched cell by cell in compiled code, does the same
exact job in a few microseconds per hundred agents.

Exactness. With cells of side c, every pair closer than c lies in the same or in adjacent cells,
so the smallest distance found among those neighbours is the true minimum whenever it is at most
c. The side is first chosen so that there are about N / 2 cells over the swarm's bounding box
(pigeonhole: some cell holds two agents, so a pair is found; axes along which the box is nearly
flat get one cell); if the best found is longer than c,
the search runs once more with c equal to it, which then contains the closest pair. Distances are
summed axis by axis as the k-d tree sums them, so the result equals the tree's to the bit.

Connectivity. :func:`disk_graph_connected` joins every pair of members within the radius by
union-find while walking the same cells (side at least the radius), and stops at the first union
that leaves one component: a connected swarm usually answers after a fraction of its pairs, with
no pair list and no sparse matrix.

Pairs. :func:`pairs_within` lists the pairs within a radius (cells at least that wide) with their
squared distances, in lexicographic order: the engine's shared pair list
(:meth:`swarmscene.core.sensing.Sensing.pairs`), with no tree to build (1,000 boids in flocks: 192
against 245 us), and its distances make the monitor's closest pair free.

This module imports numba: it is imported only for swarms of more than
``core.vectors.DENSE_POINTS`` agents (closest pair, pairs), ``core.sensing.DENSE_LIMIT``
members (connectivity) or any swarm in a periodic space (connectivity on a torus), so a small run
in open space never pays numba's start-up.
"""

from __future__ import annotations

import math

import numba
import numpy as np

CELLS_MAX = 2.0**40
"""The most cells along one axis a grid is asked about: counts are clamped to it before they become
integers (a point at 1e300 m would overflow the conversion); a grid that large is never laid."""
SPAN_MAX = 1e308
"""The largest extent along an axis counted (two finite coordinates may lie further apart than
the largest double: their difference is then infinite)."""


@numba.njit(cache=True)
def _extent(points: np.ndarray, k: int):
    """Smallest and largest coordinate along axis k (loops: axis reductions cost compile time)."""
    lo = hi = points[0, k]
    for i in range(points.shape[0]):
        lo = min(lo, points[i, k])
        hi = max(hi, points[i, k])
    return lo, hi


@numba.njit(cache=True)
def _finite(points: np.ndarray) -> bool:
    """Every coordinate finite (a NaN or an infinity has no cell: its index would be garbage)."""
    for i in range(points.shape[0]):
        for k in range(points.shape[1]):
            if not math.isfinite(points[i, k]):
                return False
    return True


@numba.njit(cache=True, inline="always")  # a call per pair costs more than the sum itself
def _dist2(points: np.ndarray, i: int, j: int) -> float:
    """Squared distance of points i and j, summed axis by axis as a k-d tree sums it."""
    d2 = 0.0
    for k in range(points.shape[1]):
        diff = points[j, k] - points[i, k]
        d2 += diff * diff
    return d2


@numba.njit(cache=True)
def _join(parent: np.ndarray, a: int, b: int) -> bool:
    """Union of the components of a and b (union-find, smaller index as root); True if they were two."""
    a, b = _root(parent, a), _root(parent, b)
    if a == b:
        return False
    parent[max(a, b)] = min(a, b)
    return True


@numba.njit(cache=True)
def _grid(points: np.ndarray, side: float):
    """Cell coordinates of every point (N, 3), grid shape (3,), and the points sorted by cell:
    ``order[start[q]:start[q + 1]]`` are the points of cell q (counting sort, O(N + cells))."""
    n, dim = points.shape
    lo = np.zeros(3)
    shape = np.ones(3, np.int64)
    for k in range(dim):
        lo[k], hi = _extent(points, k)
        shape[k] = int((hi - lo[k]) / side) + 1
    coord = np.zeros((n, 3), np.int64)
    cell = np.empty(n, np.int64)
    for i in range(n):
        for k in range(dim):
            coord[i, k] = int((points[i, k] - lo[k]) / side)
        cell[i] = (coord[i, 0] * shape[1] + coord[i, 1]) * shape[2] + coord[i, 2]
    start, order = _sorted_by_cell(cell, shape[0] * shape[1] * shape[2])
    return coord, shape, start, order


@numba.njit(cache=True)
def _closest_d2(points: np.ndarray, side: float) -> float:
    """Smallest squared distance between a point and a later one in its own or an adjacent cell."""
    n = points.shape[0]
    coord, shape, start, order = _grid(points, side)
    best = np.inf
    for i in range(n):  # the cell walk is written out in each walker: a shared one (a buffer of
        # candidates) measured 1.2-2x slower
        for x in range(max(coord[i, 0] - 1, 0), min(coord[i, 0] + 2, shape[0])):
            for y in range(max(coord[i, 1] - 1, 0), min(coord[i, 1] + 2, shape[1])):
                for z in range(max(coord[i, 2] - 1, 0), min(coord[i, 2] + 2, shape[2])):
                    q = (x * shape[1] + y) * shape[2] + z
                    for s in range(start[q], start[q + 1]):
                        j = order[s]
                        if j <= i:
                            continue
                        best = min(best, _dist2(points, i, j))
    return best


@numba.njit(cache=True)
def _cell_side(points: np.ndarray) -> float:
    """Side of cubic cells giving about N / 2 cells over the bounding box (0: a single point).

    The box may be flat along some axes (a swarm at one altitude whose z differs by micrometres):
    the cells then span the d widest axes, for the largest d whose side is no longer than the
    d-th widest extent; a 3-D count over a flat box would ask for millions of empty cells.
    """
    n, dim = points.shape
    extent = np.zeros(dim)
    for k in range(dim):
        lo, hi = _extent(points, k)
        extent[k] = hi - lo
    for a in range(1, dim):  # widest first (plain loops: np.sort costs seconds of compile time)
        b = a
        while b > 0 and extent[b - 1] < extent[b]:
            extent[b - 1], extent[b] = extent[b], extent[b - 1]
            b -= 1
    cells = max(0.5 * n, 1.0)
    for d in range(dim, 0, -1):
        if extent[d - 1] <= 0.0:
            continue
        volume = 1.0
        for k in range(d):
            volume *= extent[k]
        side = (volume / cells) ** (1.0 / d)
        if side <= extent[d - 1]:
            return side
    return extent[0]


@numba.njit(cache=True)
def _wide_side(points: np.ndarray, radius: float) -> float:
    """Cells at least ``radius`` wide, and no fewer than about 2 N over the bounding box (0: a
    single point): every pair within the radius lies in the same or adjacent cells."""
    return max(radius, _cell_side(points) * 0.25 ** (1.0 / points.shape[1]))


@numba.njit(cache=True)
def closest_pair_distance(points: np.ndarray) -> float:
    """Smallest distance between two of ``points`` (N, D), D <= 3, N >= 2; exact (see module).
    Raises ValueError for a coordinate that is not finite (it has no cell)."""
    if not _finite(points):
        raise ValueError("closest_pair_distance: every coordinate must be finite")
    side = _cell_side(points)
    if side == 0.0:
        return 0.0  # every point at one place
    best = _closest_d2(points, side)
    if best > side * side:  # the closest pair may span two cells: search again with cells that wide
        best = _closest_d2(points, np.sqrt(best) * (1.0 + 1e-12))
    return np.sqrt(best)


@numba.njit(cache=True)
def _root(parent: np.ndarray, i: int) -> int:
    """Representative of i's component, halving the path on the way (union-find)."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def disk_graph_connected(points: np.ndarray, radius: float) -> bool:
    """True when the graph joining points (N, D) at most ``radius`` apart is connected (N >= 1).

    Exact: distances are compared as squared sums against radius^2, as the dense test does. With
    cells narrower than radius / sqrt(3), the points of a cell are all joined to each other, so a
    cell is joined whole, and two cells (at most two apart on each axis) are joined by the first
    pair found within the radius, skipped when union-find already has them in one component: a
    dense flock costs about one test per pair of neighbouring cells, not one per pair of agents.
    A sparse swarm (cells that narrow would outnumber the agents by far) is tested pair by pair.
    Raises ValueError for a coordinate that is not finite (it has no cell).
    """
    if not _finite(points):
        raise ValueError("disk_graph_connected: every coordinate must be finite")
    n = points.shape[0]
    fine = radius / math.sqrt(3.0) * (1.0 - 1e-9)  # margin: a cell's diagonal stays below radius
    coarse = _wide_side(points, 0.0)  # about 2 N cells
    if coarse <= 0.0:
        return True  # every point at one place
    if fine < coarse:
        return _connected_by_pairs(points, radius, max(radius, coarse))
    coord, shape, start, order = _grid(points, fine)
    parent = np.arange(n)
    components = n - _join_cells_whole(parent, start, order)
    if components == 1:
        return True
    r2 = radius * radius
    for q in range(start.size - 1):
        if start[q] == start[q + 1]:
            continue
        cz = q % shape[2]
        cy = (q // shape[2]) % shape[1]
        cx = q // (shape[1] * shape[2])
        for x in range(max(cx - 2, 0), min(cx + 3, shape[0])):
            for y in range(max(cy - 2, 0), min(cy + 3, shape[1])):
                for z in range(max(cz - 2, 0), min(cz + 3, shape[2])):
                    q2 = (x * shape[1] + y) * shape[2] + z
                    if q2 <= q or start[q2] == start[q2 + 1]:
                        continue
                    a, b = order[start[q]], order[start[q2]]
                    if _root(parent, a) == _root(parent, b) or not _cells_meet(points, order, start, q, q2, r2):
                        continue
                    _join(parent, a, b)
                    components -= 1
                    if components == 1:
                        return True
    return components == 1


@numba.njit(cache=True)
def inside_box(points: np.ndarray, size: np.ndarray) -> bool:
    """Every point's first ``size.size`` coordinates lie in [0, size)."""
    for i in range(points.shape[0]):
        for k in range(size.size):
            if not 0.0 <= points[i, k] < size[k]:
                return False
    return True


@numba.njit(cache=True)
def torus_disk_graph_connected(points: np.ndarray, radius: float, size: np.ndarray) -> bool:
    """:func:`disk_graph_connected` in a periodic space: the first ``size.size`` axes of
    ``points`` (N, D) wrap, the points lying in [0, size) along them, and two points are linked
    when their minimum-image distance is at most ``radius`` (each wrapped axis' difference folded
    into [-size / 2, size / 2] as a k-d tree with a ``boxsize`` folds it, then summed axis by axis).

    As :func:`disk_graph_connected`: cells narrower than radius / sqrt(3) are cliques joined
    whole, and two cells up to ``reach`` apart on each axis (their wrapped neighbours included)
    are joined by the first pair found within the radius, skipped when union-find already has them
    in one component. A box too short for distinct neighbour cells along a wrapped axis, or a swarm
    too sparse for such cells, is tested pair by pair (:func:`_torus_connected_by_pairs`). The
    periodic k-d tree listed every pair and a sparse matrix labelled the components.

    Raises ValueError for a coordinate that is not finite (as the k-d tree does): it has no cell.
    """
    n, dim = points.shape
    if not _finite(points):
        raise ValueError("torus_disk_graph_connected: every coordinate must be finite")
    fine = radius / math.sqrt(3.0) * (1.0 - 1e-9)  # margin: a cell's diagonal stays below radius
    if n < 2 or fine <= 0.0:
        return n < 2 or _torus_connected_by_pairs(points, radius, size)
    lo, side, shape, reach = _torus_cells(points, size, fine, radius)
    if float(shape[0]) * float(shape[1]) * float(shape[2]) > _cells_budget(n):  # sparse: most cells empty
        return _torus_connected_by_pairs(points, radius, size)
    for k in range(size.size):
        if shape[k] < 2 * reach[k] + 1:  # the neighbours -reach..reach would repeat cells
            return _torus_connected_by_pairs(points, radius, size)
    coord, start, order = _torus_grid(points, lo, side, shape)
    parent = np.arange(n)
    components = n - _join_cells_whole(parent, start, order)
    if components == 1:
        return True
    r2 = radius * radius
    wrapped = size.size
    for q in range(start.size - 1):
        if start[q] == start[q + 1]:
            continue
        c = (q // (shape[1] * shape[2]), (q // shape[2]) % shape[1], q % shape[2])
        for dx in range(-reach[0], reach[0] + 1):
            x = _neighbour_cell(c[0] + dx, shape[0], 0 < wrapped)
            if x < 0:
                continue
            for dy in range(-reach[1], reach[1] + 1):
                y = _neighbour_cell(c[1] + dy, shape[1], 1 < wrapped)
                if y < 0:
                    continue
                for dz in range(-reach[2], reach[2] + 1):
                    z = _neighbour_cell(c[2] + dz, shape[2], 2 < wrapped)
                    if z < 0:
                        continue
                    q2 = (x * shape[1] + y) * shape[2] + z
                    if q2 <= q or start[q2] == start[q2 + 1]:
                        continue
                    a, b = order[start[q]], order[start[q2]]
                    if _root(parent, a) == _root(parent, b):
                        continue
                    if not _torus_cells_meet(points, order, start, q, q2, r2, size):
                        continue
                    _join(parent, a, b)
                    components -= 1
                    if components == 1:
                        return True
    return components == 1


@numba.njit(cache=True)
def _cells_budget(n: int) -> float:
    """The most cells a grid over n points may have: beyond, most cells are empty and a counting
    sort over them costs more than the points."""
    return 8.0 * n + 64.0


@numba.njit(cache=True)
def _wrapped_cells(length: float, width: float) -> int:
    """Cells at least ``width`` wide along a wrapped axis ``length`` long (floor), or one where
    fewer than three would fit (the neighbours -1, 0, +1 would repeat cells)."""
    cells = min(np.floor(length / width), CELLS_MAX)
    return int(cells) if cells >= 3 else 1


@numba.njit(cache=True)
def _pair_cells(points: np.ndarray, size: np.ndarray, width: float) -> float:
    """How many cells :func:`_torus_connected_by_pairs` lays with cells ``width`` wide: the wrapped
    axes' (:func:`_wrapped_cells`) times the others' over the points' extent."""
    total = 1.0
    for k in range(points.shape[1]):
        if k < size.size:
            total *= _wrapped_cells(size[k], width)
        else:
            lo, hi = _extent(points, k)
            span = min(hi - lo, SPAN_MAX)  # a difference of two finite coordinates may overflow
            total *= min(np.floor(span / width), CELLS_MAX) + 1.0
    return total


@numba.njit(cache=True)
def _neighbour_cell(c: int, cells: int, wraps: bool) -> int:
    """Cell coordinate ``c`` along an axis of ``cells`` cells, wrapped around if the axis wraps;
    -1 outside an axis that does not."""
    if wraps:
        return c % cells
    return c if 0 <= c < cells else -1


@numba.njit(cache=True)
def _torus_cells(points: np.ndarray, size: np.ndarray, width: float, radius: float):
    """The grid of cells at most ``width`` wide over a periodic space: per axis its origin, cell
    side, cell count and the reach (how many cells apart two points within ``radius`` can lie).
    A wrapped axis is cut into equal cells over [0, size); another spans the points' extent."""
    lo = np.zeros(3)
    side = np.ones(3)
    shape = np.ones(3, np.int64)
    reach = np.zeros(3, np.int64)
    for k in range(points.shape[1]):
        if k < size.size:
            shape[k] = max(int(math.ceil(min(size[k] / width, CELLS_MAX))), 1)
            side[k] = size[k] / shape[k]
        else:
            lo[k], hi = _extent(points, k)
            side[k] = width
            shape[k] = int(min(min(hi - lo[k], SPAN_MAX) / width, CELLS_MAX)) + 1
        reach[k] = int(radius / side[k]) + 1  # cells m apart hold points (m - 1) sides apart at least
    return lo, side, shape, reach


@numba.njit(cache=True)
def _torus_grid(points: np.ndarray, lo: np.ndarray, side: np.ndarray, shape: np.ndarray):
    """Every point's cell coordinates and the points sorted by cell (:func:`_sorted_by_cell`)."""
    n = points.shape[0]
    coord = np.zeros((n, 3), np.int64)
    cell = np.empty(n, np.int64)
    for i in range(n):
        for k in range(points.shape[1]):
            # clamped before the conversion: the rounding at the top, and a span that overflowed
            coord[i, k] = int(min((points[i, k] - lo[k]) / side[k], shape[k] - 1))
        cell[i] = (coord[i, 0] * shape[1] + coord[i, 1]) * shape[2] + coord[i, 2]
    start, order = _sorted_by_cell(cell, shape[0] * shape[1] * shape[2])
    return coord, start, order


@numba.njit(cache=True)
def _torus_cells_meet(points, order, start, q, q2, r2, size) -> bool:
    """Some point of cell q and some point of cell q2 are at most sqrt(r2) apart (minimum image)."""
    for s in range(start[q], start[q + 1]):
        for t in range(start[q2], start[q2 + 1]):
            if _torus_dist2(points, order[s], order[t], size) <= r2:
                return True
    return False


@numba.njit(cache=True)
def _torus_connected_by_pairs(points: np.ndarray, radius: float, size: np.ndarray) -> bool:
    """:func:`torus_disk_graph_connected` pair by pair, over cells at least ``radius`` wide (one
    cell along a wrapped axis shorter than three of them), so that every linked pair lies in the
    same or adjacent cells. The cells are widened, doubling, until there are at most
    :func:`_cells_budget` of them: a box many radii wide (a 10 km torus at a 1 m range) would
    otherwise ask for a counting sort over ~10^8 mostly empty cells every tick."""
    n, dim = points.shape
    wrapped = size.size
    width = radius * (1.0 + 1e-9) if radius > 0.0 else 1.0  # margin: a cell never narrower than radius
    while _pair_cells(points, size, width) > _cells_budget(n):  # ends: at width inf every axis has one cell
        width *= 2.0
    lo, side, shape, _ = _torus_cells(points, size, width, radius)
    for k in range(wrapped):
        shape[k] = _wrapped_cells(size[k], width)
        side[k] = size[k] / shape[k]
    coord, start, order = _torus_grid(points, lo, side, shape)
    parent = np.arange(n)
    components = n
    r2 = radius * radius
    for i in range(n):
        for dx in range(-1 if shape[0] > 1 else 0, 2 if shape[0] > 1 else 1):
            x = _neighbour_cell(coord[i, 0] + dx, shape[0], 0 < wrapped)
            if x < 0:
                continue
            for dy in range(-1 if shape[1] > 1 else 0, 2 if shape[1] > 1 else 1):
                y = _neighbour_cell(coord[i, 1] + dy, shape[1], 1 < wrapped)
                if y < 0:
                    continue
                for dz in range(-1 if shape[2] > 1 else 0, 2 if shape[2] > 1 else 1):
                    z = _neighbour_cell(coord[i, 2] + dz, shape[2], 2 < wrapped)
                    if z < 0:
                        continue
                    q = (x * shape[1] + y) * shape[2] + z
                    for s in range(start[q], start[q + 1]):
                        j = order[s]
                        if j <= i or _torus_dist2(points, i, j, size) > r2:
                            continue
                        if _join(parent, i, j):
                            components -= 1
                            if components == 1:
                                return True
    return components == 1


@numba.njit(cache=True, inline="always")
def _torus_dist2(points: np.ndarray, i: int, j: int, size: np.ndarray) -> float:
    """Squared minimum-image distance of points i and j (the first ``size.size`` axes wrap)."""
    d2 = 0.0
    for k in range(points.shape[1]):
        diff = points[j, k] - points[i, k]
        if k < size.size:
            half = 0.5 * size[k]
            if diff < -half:
                diff = size[k] + diff
            elif diff > half:
                diff = diff - size[k]
        d2 += diff * diff
    return d2


@numba.njit(cache=True)
def _sorted_by_cell(cell: np.ndarray, cells: int):
    """Counting sort of the points by cell: ``order[start[q]:start[q + 1]]`` are cell q's."""
    start = np.zeros(cells + 1, np.int64)
    for i in range(cell.size):
        start[cell[i] + 1] += 1
    for q in range(cells):
        start[q + 1] += start[q]
    fill = start[:-1].copy()
    order = np.empty(cell.size, np.int64)
    for i in range(cell.size):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return start, order


@numba.njit(cache=True)
def _join_cells_whole(parent: np.ndarray, start: np.ndarray, order: np.ndarray) -> int:
    """Join the points of each cell into one component (cells narrower than the radius over
    sqrt(3) are cliques); returns how many unions merged two components."""
    merged = 0
    for q in range(start.size - 1):
        for s in range(start[q] + 1, start[q + 1]):
            if _join(parent, order[start[q]], order[s]):
                merged += 1
    return merged


@numba.njit(cache=True)
def _cells_meet(points, order, start, q, q2, r2) -> bool:
    """Some point of cell q and some point of cell q2 are at most sqrt(r2) apart."""
    for s in range(start[q], start[q + 1]):
        for t in range(start[q2], start[q2 + 1]):
            if _dist2(points, order[s], order[t]) <= r2:
                return True
    return False


@numba.njit(cache=True)
def _connected_by_pairs(points: np.ndarray, radius: float, side: float) -> bool:
    """:func:`disk_graph_connected` pair by pair, over cells at least ``radius`` wide (``side``),
    so that every joined pair lies in the same or adjacent cells."""
    n = points.shape[0]
    coord, shape, start, order = _grid(points, side)
    parent = np.arange(n)
    components = n
    r2 = radius * radius
    for i in range(n):
        for x in range(max(coord[i, 0] - 1, 0), min(coord[i, 0] + 2, shape[0])):
            for y in range(max(coord[i, 1] - 1, 0), min(coord[i, 1] + 2, shape[1])):
                for z in range(max(coord[i, 2] - 1, 0), min(coord[i, 2] + 2, shape[2])):
                    q = (x * shape[1] + y) * shape[2] + z
                    for s in range(start[q], start[q + 1]):
                        j = order[s]
                        if j <= i:
                            continue
                        if _dist2(points, i, j) <= r2 and _join(parent, i, j):
                            components -= 1
                            if components == 1:
                                return True
    return components == 1


@numba.njit(cache=True)
def pairs_within(points: np.ndarray, radius: float):
    """Every pair (i < j) of points (N, D) at most ``radius`` apart, in lexicographic order, shape
    (M, 2), and its squared distance (M,) summed axis by axis (as a k-d tree and the dense pass
    sum it). One walk over the cells, point by point, into arrays that double when full; each
    point's later neighbours are then put in order (short runs). The arrays are grown to hold a
    point's candidates before its walk: a walk that might replace them inside compiled slower
    (1.6x as long for 100 agents in one dense flock, 1.2x for the flocking preset's states).
    Raises ValueError for a coordinate that is not finite (it has no cell)."""
    if not _finite(points):
        raise ValueError("pairs_within: every coordinate must be finite")
    n = points.shape[0]
    side = _wide_side(points, radius)
    if side <= 0.0:
        side = 1.0  # every point at one place: one cell
    coord, shape, start, order = _grid(points, side)
    r2 = radius * radius
    pairs = np.empty((4 * n + 16, 2), np.int64)
    d2s = np.empty(4 * n + 16)
    m = 0
    for i in range(n):
        first = m
        candidates = 0
        for x in range(max(coord[i, 0] - 1, 0), min(coord[i, 0] + 2, shape[0])):
            for y in range(max(coord[i, 1] - 1, 0), min(coord[i, 1] + 2, shape[1])):
                q = (x * shape[1] + y) * shape[2]
                z0, z1 = max(coord[i, 2] - 1, 0), min(coord[i, 2] + 2, shape[2])
                candidates += start[q + z1] - start[q + z0]
        while m + candidates > len(d2s):
            pairs, d2s = _grown(pairs, d2s)
        for x in range(max(coord[i, 0] - 1, 0), min(coord[i, 0] + 2, shape[0])):
            for y in range(max(coord[i, 1] - 1, 0), min(coord[i, 1] + 2, shape[1])):
                for z in range(max(coord[i, 2] - 1, 0), min(coord[i, 2] + 2, shape[2])):
                    q = (x * shape[1] + y) * shape[2] + z
                    for s in range(start[q], start[q + 1]):
                        j = order[s]
                        if j <= i:
                            continue
                        d2 = _dist2(points, i, j)
                        if d2 > r2:
                            continue
                        pairs[m, 0] = i
                        pairs[m, 1] = j
                        d2s[m] = d2
                        m += 1
        for a in range(first + 1, m):  # i's neighbours in increasing order (insertion sort)
            j, d2 = pairs[a, 1], d2s[a]
            b = a - 1
            while b >= first and pairs[b, 1] > j:
                pairs[b + 1, 1] = pairs[b, 1]
                d2s[b + 1] = d2s[b]
                b -= 1
            pairs[b + 1, 1] = j
            d2s[b + 1] = d2
    return pairs[:m].copy(), d2s[:m].copy()


@numba.njit(cache=True)
def _grown(pairs: np.ndarray, d2s: np.ndarray):
    """The arrays at twice their length, contents kept."""
    bigger = np.empty((2 * len(d2s), 2), np.int64)
    bigger_d2 = np.empty(2 * len(d2s))
    for a in range(len(d2s)):  # loops: a 2-D slice assignment costs seconds of compile time
        bigger[a, 0] = pairs[a, 0]
        bigger[a, 1] = pairs[a, 1]
        bigger_d2[a] = d2s[a]
    return bigger, bigger_d2
