"""Indoor swarming, thesis section 5.2: single-integrator agents, collision model, LOS sensing.

Karydes (2020), chapter 5. The swarm is planar: ``r`` is an (N, 2) array of positions in the
world x-y plane (x east, y north, metres); a caller holding (N, 3) world positions passes
``pos[:, :2]``. Obstacles are shapely 2 geometries (wall segments, polygons), given either as a
sequence or as a prebuilt :class:`shapely.STRtree`; ``None`` or an empty sequence is open space.

Every per-step function is vectorised: candidate pairs come from one :class:`scipy.spatial.cKDTree`
(a prebuilt tree may be passed, e.g. the engine's per-step shared tree over (N, 3) positions of a
swarm flying at one altitude, whose distances then equal the planar ones), and the per-tick
geometric tests (line of sight, nearest obstacle points) are one compiled call each
(``kernels.py``, GEOS' formulas on the walls' segments, so they agree with shapely bit for bit).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property
from typing import TYPE_CHECKING, TypeAlias

import numpy as np
import scipy  # submodules load at first use (start-up: this module is imported at registration)
import shapely
from shapely import STRtree
from shapely.geometry.base import BaseGeometry

from swarmscene.core.environment import NO_FOOTPRINTS, footprint_arrays, nearest_within
from swarmscene.core.environment import segments_clear as segments_clear_of
from swarmscene.core.vectors import clip_norm, min_pair_distance

if TYPE_CHECKING:  # pragma: no cover
    from scipy.spatial import cKDTree

Obstacles: TypeAlias = Sequence[BaseGeometry] | STRtree | None


class ObstacleTree(STRtree):
    """An STRtree that keeps the compiled kernels' form of its obstacles (:attr:`footprints`).

    The footprint arrays belong to the obstacle set they describe: built on first use, they live
    and die with this tree (the engine's :class:`~swarmscene.core.environment.Environment` keeps
    its own the same way).
    """

    @cached_property
    def footprints(self) -> tuple[np.ndarray, ...]:
        """:func:`~swarmscene.core.environment.footprint_arrays` of :attr:`geometries`."""
        return footprint_arrays(self.geometries)


def obstacle_tree(obstacles: Obstacles) -> STRtree | None:
    """The STRtree over ``obstacles`` (an :class:`ObstacleTree` if a sequence is given), or
    ``None`` for open space."""
    if obstacles is None:
        return None
    if isinstance(obstacles, STRtree):
        return obstacles if len(obstacles.geometries) else None
    geoms = np.asarray(list(obstacles), dtype=object)
    return ObstacleTree(geoms) if geoms.size else None


def saturate(w: np.ndarray, limit: float) -> np.ndarray:
    """Scale each row of ``w`` (N, 2) down to norm ``limit`` when it exceeds it (thesis eq. 5.30)."""
    return clip_norm(w, limit)


def single_integrator_step(r: np.ndarray, u: np.ndarray, u_max: float) -> np.ndarray:
    """r(k+1) = r(k) + u(k) with ||u(k)|| <= u_max (thesis eq. 5.1).

    ``u`` is a displacement per sampling period T_s (m), so a velocity is ``u / T_s``. The bound
    u_max is the hardware limit; an input above it is clipped, not rejected.
    """
    return r + saturate(u, u_max)


def pairwise_min_distance(r: np.ndarray) -> float:
    """Smallest inter-agent distance ||r_i - r_j||, m (``inf`` for fewer than two agents)."""
    return min_pair_distance(r)


def collision_free(r: np.ndarray, d_c: float) -> bool:
    """Collision condition ||r_i - r_j|| >= d_c for every pair (thesis eq. 5.2)."""
    return pairwise_min_distance(r) >= d_c


def nearest_obstacle(
    r: np.ndarray, obstacles: Obstacles, max_distance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Closest detected obstacle point o_i and its distance (thesis eq. 5.9-5.10, 5.32).

    The closest point of all obstacles is always visible (a geometry hiding it would be closer),
    so the argmin of eq. 5.32 over the visible set O_i is the plain nearest point, restricted to
    the sensing range (eq. 5.9). The engine's bounded search (core.environment.nearest_within) and one
    ``shapely.shortest_line``.

    Args:
        r: (N, 2) positions, m.
        obstacles: geometries or their STRtree.
        max_distance: detection range, m (d_s; a smaller range such as l_o is exact for callers
            that ignore obstacles beyond it, and faster).

    Returns:
        o: (N, 2) nearest obstacle point, NaN where nothing lies within ``max_distance``.
        dist: (N,) its distance, m; ``inf`` where nothing was detected.
    """
    n = len(r)
    tree = obstacle_tree(obstacles)
    if tree is None or n == 0:
        return np.full((n, 2), np.nan), np.full(n, np.inf)
    index, dist = nearest_within(tree, r, max_distance)  # the engine's own bounded search
    return nearest_points(r, tree, index), dist


def nearest_points(r: np.ndarray, geometries: np.ndarray | STRtree, index: np.ndarray) -> np.ndarray:
    """o_i, the point of obstacle ``geometries[index[i]]`` (or the tree's) closest to r_i (eq. 5.32), (N, 2);
    NaN where ``index`` is -1 (nothing detected). One compiled call (GEOS' nearest-point formulas,
    so the points equal ``shapely.shortest_line``'s)."""
    from .kernels import nearest_points_kernel  # numba loads at first use, not at registration

    seg, geom_start, polygonal, _ = kernel_obstacles(geometries)
    r = np.ascontiguousarray(r, dtype=float)
    return nearest_points_kernel(r, np.asarray(index, dtype=np.intp), seg, geom_start, polygonal)


def kernel_obstacles(geometries: np.ndarray | STRtree | None) -> tuple[np.ndarray, ...]:
    """The engine's :func:`~swarmscene.core.environment.footprint_arrays` of an obstacle set (its
    STRtree or the tree's ``geometries``): an :class:`ObstacleTree`'s own (converted once for the
    set), else converted on this call."""
    if geometries is None:
        return NO_FOOTPRINTS
    if isinstance(geometries, ObstacleTree):
        return geometries.footprints
    if isinstance(geometries, STRtree):
        geometries = geometries.geometries
    return footprint_arrays(geometries)


def obstacle_free(r: np.ndarray, obstacles: Obstacles, d_o: float) -> bool:
    """Obstacle condition ||r_i - r_o|| >= d_o for every obstacle point r_o (thesis eq. 5.3)."""
    _, dist = nearest_obstacle(r, obstacles, max_distance=d_o)
    return bool(np.all(dist >= d_o))


def segments_clear(a: np.ndarray, b: np.ndarray, obstacles: Obstacles, d_l: float) -> np.ndarray:
    """LOS clearance of the segments L_ab: every point at least d_l from obstacles (eq. 5.4, 5.8).

    Args:
        a: (P, 2) segment start points, m.
        b: (P, 2) segment end points, m.
        obstacles: geometries or their STRtree.
        d_l: clearance distance d_l, m.

    Returns:
        (P,) bool, True where the segment keeps clearance d_l. A segment exactly at d_l counts as
        blocked (shapely's ``dwithin`` is inclusive), a measure-zero difference from eq. 5.8.
    """
    return segments_clear_of(obstacle_tree(obstacles), a, b, d_l)  # the engine's LOS test


def candidate_pairs(r: np.ndarray, radius: float, tree: cKDTree | None = None) -> np.ndarray:
    """Index pairs (i < j) with ||r_i - r_j|| <= radius, shape (P, 2), from one cKDTree (eq. 5.7)."""
    tree = scipy.spatial.cKDTree(r) if tree is None else tree
    pairs = tree.query_pairs(radius, output_type="ndarray")
    return pairs.reshape(-1, 2).astype(np.intp, copy=False)


def sensing_pairs(
    r: np.ndarray,
    d_range: float,
    obstacles: Obstacles,
    d_l: float,
    tree: cKDTree | None = None,
    clearance: np.ndarray | None = None,
    candidates: np.ndarray | None = None,
) -> np.ndarray:
    """Pairs of agents that sense each other: range and line of sight (thesis eq. 5.7-5.8).

    With ``d_range = d_s`` this is the edge set E_s; with ``d_range = d_n`` it is directly E_n
    (eq. 5.12), since E_n = E_s restricted to lengths <= d_n and d_n < d_s: the hot path never
    builds G_s. A third agent does not block sensing (section 5.2.4).

    Pairs whose LOS is certified by the agents' own clearances skip the shapely test: a point of
    L_ij at distance t from r_i is at least max(c_i - t, c_j - (d_ij - t)) from obstacles, whose
    minimum over t is (c_i + c_j - d_ij) / 2, so c_i + c_j >= d_ij + 2 d_l proves eq. 5.8.

    Args:
        r: (N, 2) positions, m.
        d_range: sensing range, m.
        obstacles: geometries or their STRtree.
        d_l: LOS clearance d_l, m.
        tree: prebuilt cKDTree over the positions (planar, or 3D at one altitude).
        clearance: (N,) lower bounds of each agent's obstacle distance (e.g. from
            :func:`nearest_obstacle`, where ``inf`` beyond its range must first be replaced by
            that range); ``None`` tests every pair with shapely.
        candidates: (P, 2) the pairs within ``d_range`` if already listed (the engine's cached
            ``Sensing.pairs``); ``None`` lists them from ``tree``.

    Returns:
        (P, 2) int array of pairs (i < j), sorted. One compiled call (the segment test uses
        GEOS' segment distance, as shapely's ``dwithin`` did).
    """
    from .kernels import neighbour_edges  # numba loads at first use, not at registration

    pairs = candidate_pairs(r, d_range, tree) if candidates is None else candidates
    if clearance is None:  # no certificate: every pair gets the segment test
        clearance = np.full(len(r), -np.inf)
    i, j = neighbour_edges(
        np.ascontiguousarray(r, dtype=float), np.asarray(pairs, dtype=np.intp).reshape(-1, 2),
        np.asarray(clearance, dtype=float), float(d_l), *kernel_obstacles(obstacle_tree(obstacles)),
    )
    return np.stack([i, j], axis=1)


def obstacle_point_visible(
    r: np.ndarray, r_o: np.ndarray, obstacles: Obstacles, d_s: float
) -> np.ndarray:
    """Whether agent i detects obstacle point r_o[i] (thesis eq. 5.9-5.10), vectorised over rows.

    Eq. 5.10 asks r_o to be the first obstacle point on the ray from r_i through r_o, i.e. the
    half-open segment [r_i, r_o) meets no obstacle. The segment is shortened by 1e-9 of its length
    so that the obstacle carrying r_o itself does not count as hiding it.

    Args:
        r: (P, 2) agent positions, m.
        r_o: (P, 2) points on obstacles, m.
        obstacles: geometries or their STRtree.
        d_s: sensing range, m.

    Returns:
        (P,) bool.
    """
    in_range = np.linalg.norm(r_o - r, axis=1) <= d_s
    tree = obstacle_tree(obstacles)
    if tree is None:
        return in_range
    tip = r + (1.0 - 1e-9) * (r_o - r)
    lines = shapely.linestrings(np.stack([r, tip], axis=1))
    hit, _ = tree.query(lines, predicate="intersects")
    unhidden = np.ones(len(r), dtype=bool)
    unhidden[hit] = False
    return in_range & unhidden
