"""Obstacle footprints as segment arrays, and compiled distance queries over them (numba).

GEOS (through shapely) answers the engine's obstacle queries one call per batch, but on a
hundred agents among a building's walls its fixed cost per call and the point geometries it
must build are most of the work. The functions here compute the same distances with GEOS' own
formulas (``Distance::pointToSegment``, ``segmentToSegment``, ``LineSegment::closestPoint``; a
point inside a polygon is at distance 0), so they equal shapely's to the bit, on the footprints
as arrays (:func:`swarmscene.core.environment.footprint_arrays`): ring or line segments
``seg`` (S, 4), geometry g owning ``seg[geom_start[g]:geom_start[g + 1]]``, ``polygonal`` (G,).

The thesis' indoor sensing (``methods/indoor/kernels.py``) builds its line of sight and nearest
obstacle points on these primitives. This module imports numba: the engine imports it only for
swarms of more than ``core.vectors.DENSE_POINTS`` agents (start-up of small runs).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, error_model="numpy")
def point_distance(px, py, ax, ay):
    """Distance between the points p and a."""
    dx = px - ax
    dy = py - ay
    return math.sqrt(dx * dx + dy * dy)


@numba.njit(cache=True, error_model="numpy")
def point_segment_distance(px, py, ax, ay, bx, by):
    """Distance from p to segment AB (GEOS ``Distance::pointToSegment``)."""
    if ax == bx and ay == by:
        return point_distance(px, py, ax, ay)
    len2 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay)
    r = ((px - ax) * (bx - ax) + (py - ay) * (by - ay)) / len2
    if r <= 0.0:
        return point_distance(px, py, ax, ay)
    if r >= 1.0:
        return point_distance(px, py, bx, by)
    s = ((ay - py) * (bx - ax) - (ax - px) * (by - ay)) / len2
    return abs(s) * math.sqrt(len2)


@numba.njit(cache=True, error_model="numpy")
def segment_distance(ax, ay, bx, by, cx, cy, dx, dy):
    """Distance between segments AB and CD (GEOS ``Distance::segmentToSegment``): 0 if they meet."""
    if ax == bx and ay == by:
        return point_segment_distance(ax, ay, cx, cy, dx, dy)
    if cx == dx and cy == dy:
        return point_segment_distance(dx, dy, ax, ay, bx, by)
    crossing = (
        min(cx, dx) <= max(ax, bx) and max(cx, dx) >= min(ax, bx)
        and min(cy, dy) <= max(ay, by) and max(cy, dy) >= min(ay, by)
    )
    if crossing:
        denom = (bx - ax) * (dy - cy) - (by - ay) * (dx - cx)
        if denom == 0.0:
            crossing = False
        else:
            r = ((ay - cy) * (dx - cx) - (ax - cx) * (dy - cy)) / denom
            s = ((ay - cy) * (bx - ax) - (ax - cx) * (by - ay)) / denom
            crossing = not (r < 0.0 or r > 1.0 or s < 0.0 or s > 1.0)
    if crossing:
        return 0.0
    return min(
        min(point_segment_distance(ax, ay, cx, cy, dx, dy), point_segment_distance(bx, by, cx, cy, dx, dy)),
        min(point_segment_distance(cx, cy, ax, ay, bx, by), point_segment_distance(dx, dy, ax, ay, bx, by)),
    )


@numba.njit(cache=True, error_model="numpy")
def inside(px, py, seg, start, stop):
    """Point p inside the polygon whose ring segments are seg[start:stop] (even-odd crossings)."""
    inside = False
    for k in range(start, stop):
        ax, ay, bx, by = seg[k, 0], seg[k, 1], seg[k, 2], seg[k, 3]
        if (ay > py) != (by > py):
            x = ax + (py - ay) * (bx - ax) / (by - ay)
            if px < x:
                inside = not inside
    return inside


@numba.njit(cache=True, error_model="numpy")
def closest_point(px, py, ax, ay, bx, by):
    """GEOS ``LineSegment::closestPoint``: the projection inside the segment, else the nearer end."""
    if px == ax and py == ay:
        factor = 0.0
    elif px == bx and py == by:
        factor = 1.0
    else:
        dx, dy = bx - ax, by - ay
        len2 = dx * dx + dy * dy
        factor = ((px - ax) * dx + (py - ay) * dy) / len2
    if factor > 0.0 and factor < 1.0:
        return ax + factor * (bx - ax), ay + factor * (by - ay)
    if point_distance(ax, ay, px, py) < point_distance(bx, by, px, py):
        return ax, ay
    return bx, by


@numba.njit(cache=True, error_model="numpy")
def footprint_distance(px, py, seg, start, stop, polygonal):
    """Distance from p to the geometry owning seg[start:stop]: 0 inside a polygon (GEOS)."""
    if polygonal and inside(px, py, seg, start, stop):
        return 0.0
    best = np.inf
    for k in range(start, stop):
        dist = point_segment_distance(px, py, seg[k, 0], seg[k, 1], seg[k, 2], seg[k, 3])
        if dist < best:
            best = dist
    return best


@numba.njit(cache=True, error_model="numpy")
def nearest_of_candidates(xy, point, geom, seg, geom_start, polygonal, max_distance):
    """Each point's nearest geometry among its candidate (point, geometry) pairs, within
    ``max_distance``: index (-1 beyond) and distance (``inf`` beyond). A tie goes to the candidate
    listed first, as a stable sort of the candidates by (point, distance) gives it."""
    n = xy.shape[0]
    nearest = np.full(n, -1, np.int64)
    distance = np.full(n, np.inf)
    best = np.full(n, np.inf)
    for c in range(point.size):
        i, g = point[c], geom[c]
        dist = footprint_distance(xy[i, 0], xy[i, 1], seg, geom_start[g], geom_start[g + 1], polygonal[g])
        if dist < best[i]:
            best[i] = dist
            if dist <= max_distance:
                nearest[i] = g
                distance[i] = dist
    return nearest, distance
