"""Hexagonal formation pattern and optimal slot assignment (Karydes 2020, thesis section 4.3.2).

The pattern places the leader at node 0 and M >= N - 1 offsets on a triangular lattice of
spacing d_r (the Voronoi cells of the nodes are regular hexagons, Fig. 4.6-4.7), inside a
hexagonal contour of radius rho_max whose outer ring is pruned from the corners inwards
(eq. 4.8-4.11). Followers are assigned to offsets by a rectangular linear assignment that
minimises the total horizontal distance plus a periphery penalty (eq. 4.12-4.13).

Frames. The thesis works in NED: its frame {o} has x_o = North, y_o = East, and the formation
yaw alpha turns x_h from North towards East. All lattice maths here is done in that North-East
plane (``*_ne`` arrays, columns (north, east)); the one conversion to the engine's world frame
(x east, y north, z up) is :func:`ne_to_world_xy`, applied to produce ``HexPattern.offsets_xy``.
The assignment takes and returns world-frame data only (distances are frame-invariant).

Choices where the text is loose (each documented where it is made):
- eq. 4.10 says pruning keeps "M >= N"; the offsets exclude the leader, so what the pruning rule
  actually guarantees (and what the assignment needs) is M >= N - 1, with 0 <= M - N + 1 <= 11.
- "adjacent Voronoi cells" is taken on the lattice cells of Fig. 4.8 (bounded hexagons), not on
  the unbounded cells of the pruned point set, whose hull ridges would join far-apart offsets.
- "rounded up to the nearest decimetre" is implemented as rounding to the nearest decimetre;
  costs are then exact integers (decimetres), so ties are exact and the solution is a
  deterministic function of the id-ordered inputs.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy  # scipy.spatial loads on first use (start-up of unrelated runs)

from swarmscene.methods.assignment import solve_square

if TYPE_CHECKING:  # pragma: no cover
    import networkx as nx

# ---------------------------------------------------------------------------------------------
# Hexagonal axial frame {h} (eq. 4.3-4.7)
# ---------------------------------------------------------------------------------------------


def hex_to_ne_matrix(d_r: float, alpha: float = 0.0) -> np.ndarray:
    """T_h^o of eq. 4.5: maps axial coordinates r^h to North-East metres r^o = T_h^o r^h.

    Its columns are the axial axes x_h = d_r R_alpha x_o and y_h = d_r/2 R_alpha (x_o + sqrt(3) y_o)
    of eq. 4.3, expressed in the thesis frame {o} (North, East).
    """
    return d_r * np.array(
        [[np.cos(alpha), np.cos(alpha + np.pi / 3)], [np.sin(alpha), np.sin(alpha + np.pi / 3)]]
    )


def ne_to_hex_matrix(d_r: float, alpha: float = 0.0) -> np.ndarray:
    """T_o^h of eq. 4.5, the inverse of :func:`hex_to_ne_matrix`.

    Its rows are the dual basis (x~_h, y~_h) of eq. 4.7, so r^T x~_h and r^T y~_h are the two
    axial coordinates of a North-East vector r.
    """
    s, c = np.sin(alpha), np.cos(alpha)
    s3, c3 = np.sin(alpha + np.pi / 3), np.cos(alpha + np.pi / 3)
    return 2.0 / (np.sqrt(3.0) * d_r) * np.array([[s3, -c3], [-s, c]])


def dual_basis(d_r: float, alpha: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(x~_h, y~_h) of eq. 4.7, computed literally from x_h, y_h and S = [[0, 1], [-1, 0]]."""
    t = hex_to_ne_matrix(d_r, alpha)
    x_h, y_h = t[:, 0], t[:, 1]
    s = np.array([[0.0, 1.0], [-1.0, 0.0]])
    den = x_h @ s @ y_h
    return s @ y_h / den, -(s @ x_h) / den


def topological_distance(a: np.ndarray, b: np.ndarray | None = None) -> np.ndarray:
    """dist(i, j) of eq. 4.6 between axial nodes ``a`` and ``b`` (default: the leader node 0).

    Args:
        a: integer axial coordinates, shape (..., 2).
        b: integer axial coordinates broadcasting with ``a`` (default: the leader node 0).

    With axial coordinates (q, r) = (h^T x~_h, h^T y~_h) eq. 4.6 reads (|dq| + |dr| + |dq + dr|) / 2,
    the number of lattice edges on a shortest path.
    """
    d = np.asarray(a) if b is None else np.asarray(b) - np.asarray(a)
    dq, dr = d[..., 0], d[..., 1]
    return (np.abs(dq) + np.abs(dr) + np.abs(dq + dr)) // 2


def corner_distance(axial: np.ndarray) -> np.ndarray:
    """kappa_i of eq. 4.11: 0 at the corners of a ring, growing by 1 per node towards the edge centre."""
    q, r = axial[..., 0], axial[..., 1]
    return np.minimum(np.minimum(np.abs(q), np.abs(r)), np.abs(q + r))


# ---------------------------------------------------------------------------------------------
# Pattern size (eq. 4.8-4.11)
# ---------------------------------------------------------------------------------------------


def max_radius(n: int) -> int:
    """rho_max of eq. 4.8: the smallest hexagon of rings 1..rho_max holding N - 1 followers."""
    if n < 2:
        raise ValueError(f"a formation needs a leader and at least one follower (got N = {n})")
    # Exact integer form of ceil(sqrt(1/4 + (N-1)/3) - 1/2): float sqrt can land a hair above an
    # integer when N - 1 = 3 rho (rho + 1) exactly, which would add a whole ring.
    rho = 0
    while 3 * rho * (rho + 1) < n - 1:
        rho += 1
    return rho


def max_offsets(n: int) -> int:
    """M_max of eq. 4.9: number of nodes in rings 1..rho_max (the leader's node excluded)."""
    rho = max_radius(n)
    return 3 * rho * (rho + 1)


def pruning_threshold(n: int) -> int:
    """chi of eq. 4.11: outer-ring nodes with kappa_i < chi are removed (eq. 4.10)."""
    return (max_offsets(n) - n + 7) // 12


def hex_disk(rho: int) -> np.ndarray:
    """Axial coordinates (K, 2) of all nodes with 1 <= dist(i, 0) <= rho.

    Order: by ring, then counter-clockwise in the axial plane starting on the +q axis; the order
    is part of the deterministic tie-breaking (it fixes the column order of the cost matrix).
    """
    q, r = np.meshgrid(np.arange(-rho, rho + 1), np.arange(-rho, rho + 1), indexing="ij")
    nodes = np.stack([q.ravel(), r.ravel()], axis=1)
    ring = topological_distance(nodes)
    nodes, ring = nodes[(ring >= 1) & (ring <= rho)], ring[(ring >= 1) & (ring <= rho)]
    # Angle in the undistorted (alpha = 0) lattice, as an exact integer-free key per ring.
    xy = nodes @ np.array([[1.0, 0.0], [0.5, np.sqrt(3.0) / 2]])
    angle = np.mod(np.arctan2(xy[:, 1], xy[:, 0]), 2 * np.pi)
    order = np.lexsort((np.round(angle, 9), ring))
    return nodes[order]


# ---------------------------------------------------------------------------------------------
# Frames
# ---------------------------------------------------------------------------------------------


def ne_to_world_xy(ne: np.ndarray) -> np.ndarray:
    """(north, east) of the thesis frame {o} -> world (x east, y north): a swap of columns."""
    return np.asarray(ne)[..., ::-1].copy()


# ---------------------------------------------------------------------------------------------
# The pattern
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HexPattern:
    """The M offsets of the hexagonal formation for a swarm of N agents (leader included).

    Attributes:
        n: swarm size N (leader included).
        d_r: reference neighbour distance d_r, m (lattice spacing).
        alpha: formation yaw alpha, rad, thesis convention (from North towards East).
        axial: (M, 2) int, axial coordinates h_j^h of the offsets (eq. 4.4), leader excluded.
        rho_max: rho_max of eq. 4.8.
        m_max: M_max of eq. 4.9 (before pruning).
        chi: chi of eq. 4.11.
    """

    n: int
    d_r: float
    alpha: float
    axial: np.ndarray
    rho_max: int
    m_max: int
    chi: int

    @property
    def m(self) -> int:
        """M, number of offsets kept after pruning."""
        return self.axial.shape[0]

    @cached_property
    def rho(self) -> np.ndarray:
        """(M,) int, radius rho_j = dist(j, 0) of each offset."""
        return topological_distance(self.axial)

    @cached_property
    def periphery(self) -> np.ndarray:
        """(M,) bool, gamma_j of eq. 4.12: True on the outer ring rho_j = rho_max."""
        return self.rho == self.rho_max

    @cached_property
    def offsets_ne(self) -> np.ndarray:
        """(M, 2) offsets h_j in metres, thesis frame (north, east) (eq. 4.4)."""
        return self.axial @ hex_to_ne_matrix(self.d_r, self.alpha).T

    @cached_property
    def offsets_xy(self) -> np.ndarray:
        """(M, 2) offsets h_j in metres, world frame (x east, y north)."""
        return ne_to_world_xy(self.offsets_ne)

    @cached_property
    def periphery_penalty(self) -> np.ndarray:
        """(M,) gamma_j rho_j d_r of eq. 4.12, metres."""
        return np.where(self.periphery, self.rho * self.d_r, 0.0)


def hex_pattern(n: int, d_r: float, alpha: float = 0.0) -> HexPattern:
    """Build the pruned hexagonal pattern for N agents (eq. 4.8-4.11).

    All nodes of rings 1..rho_max are taken (M_max of them), then the outer-ring nodes with
    kappa_i < chi are removed, i.e. the 12 chi - 6 nodes nearest the six corners, which are the
    farthest from the leader. This leaves M = M_max - 12 chi + 6 offsets when chi >= 1, so that
    M - N + 1 = (M_max - N + 7) mod 12, between 0 and 11.
    """
    rho_max = max_radius(n)
    chi = pruning_threshold(n)
    nodes = hex_disk(rho_max)
    outer = topological_distance(nodes) == rho_max
    keep = ~outer | (corner_distance(nodes) >= chi)
    return HexPattern(
        n=n,
        d_r=float(d_r),
        alpha=float(alpha),
        axial=nodes[keep],
        rho_max=rho_max,
        m_max=3 * rho_max * (rho_max + 1),
        chi=chi,
    )


def formation_graph(pattern: HexPattern) -> nx.Graph:
    """G_h: the leader node 0 and offsets 1..M, joined when their Voronoi cells are adjacent.

    The cells are those of the lattice (Fig. 4.8): the Voronoi diagram is computed on the kept
    nodes padded with every other lattice node up to ring rho_max + 1, so each kept node's cell is
    the bounded hexagon of side d_r / 2 and two kept nodes share a ridge exactly when they are
    lattice neighbours, d_r apart. Node attributes: ``axial``, ``xy`` (world frame, m), ``rho``;
    edge attribute ``length`` (m). Offset j of the pattern is node j + 1.
    """
    import networkx as nx  # 0.1 s to import: only the outdoor mission pays it, once per pattern

    kept = np.vstack([np.zeros((1, 2), dtype=int), pattern.axial])
    ring = hex_disk(pattern.rho_max + 1)
    kept_keys = {tuple(a) for a in kept.tolist()}
    padding = np.array([a for a in ring.tolist() if tuple(a) not in kept_keys])
    points_ne = np.vstack([kept, padding]) @ hex_to_ne_matrix(pattern.d_r, pattern.alpha).T
    ridges = scipy.spatial.Voronoi(points_ne).ridge_points
    ridges = ridges[(ridges < kept.shape[0]).all(axis=1)]

    xy = ne_to_world_xy(points_ne[: kept.shape[0]])
    graph = nx.Graph()
    for node in range(kept.shape[0]):
        graph.add_node(node, axial=tuple(kept[node]), xy=xy[node], rho=int(topological_distance(kept[node])))
    lengths = np.linalg.norm(xy[ridges[:, 0]] - xy[ridges[:, 1]], axis=1)
    graph.add_edges_from(
        (int(i), int(j), {"length": float(length)}) for (i, j), length in zip(ridges, lengths, strict=True)
    )
    return graph


# ---------------------------------------------------------------------------------------------
# Assignment (eq. 4.12-4.13)
# ---------------------------------------------------------------------------------------------

DECIMETRE = 0.1
"""Resolution of the assignment costs, m (thesis: distances rounded to the decimetre)."""


def _distance_dm(pattern: HexPattern, follower_xy: np.ndarray, leader_xy: np.ndarray) -> np.ndarray:
    """||h_j + r_N - r_i|| in whole decimetres, float64 (exact integers), shape (K, M)."""
    slots = pattern.offsets_xy + np.asarray(leader_xy, dtype=float)[:2]
    dist = scipy.spatial.distance.cdist(np.asarray(follower_xy, dtype=float)[:, :2], slots)
    dist *= 1.0 / DECIMETRE
    return np.rint(dist, out=dist)


def _penalty_dm(pattern: HexPattern) -> np.ndarray:
    """gamma_j rho_j d_r of eq. 4.12 in whole decimetres, float64, shape (M,)."""
    return np.rint(pattern.periphery_penalty / DECIMETRE)


def assignment_cost(
    pattern: HexPattern, follower_xy: np.ndarray, leader_xy: np.ndarray
) -> np.ndarray:
    """C~ of eq. 4.12 in integer decimetres, shape (K, M), for K followers in the given order.

    c~_ij = ||h_j - h_0 + r_N - r_i|| + gamma_j rho_j d_r, h_0 = 0, using horizontal world
    positions (the altitude is ignored by the assignment, as in the thesis).
    """
    cost = _distance_dm(pattern, follower_xy, leader_xy) + _penalty_dm(pattern)
    return cost.astype(np.int64)


def solve_assignment(cost: np.ndarray, column_penalty: np.ndarray | None = None) -> np.ndarray:
    """Minimal-cost assignment of every row of a rectangular (K, M) cost, K <= M (eq. 4.13).

    Returns the column of each row, shape (K,). ``column_penalty`` (M,) is the part of ``cost``
    that depends on the column only (the periphery penalty); it is moved onto the M - K dummy
    rows of eq. 4.13: in the square problem every column is matched exactly once, so subtracting
    p_j from a whole column changes every assignment's cost by the same -sum(p) and the optimum
    is unchanged, while the real rows become plain distances that the shortest-augmenting-path
    solver matches far faster (and the dummy rows take up the penalised columns first).
    The square problem is solved exactly by scipy's ``linear_sum_assignment`` (Jonker-Volgenant
    shortest augmenting paths), warm-started for large swarms by
    :func:`~swarmscene.methods.assignment.solve_square`.
    """
    if column_penalty is None:
        column_penalty = np.zeros(cost.shape[1])
    return solve_square(_square_problem(cost - column_penalty, column_penalty))[: cost.shape[0]]


def _square_problem(distance: np.ndarray, column_penalty: np.ndarray, dtype=None) -> np.ndarray:
    """Eq. 4.13 with the column penalty on the dummy rows: real rows, then M - K rows of -p_j.

    ``dtype`` (default: that of the inputs) lets whole-decimetre costs be stored as int32, which
    halves the memory traffic of the warm start's passes over the matrix (about 6 ms at N = 1,000).
    """
    k, m = distance.shape
    if k > m:
        raise ValueError(f"{k} followers but only {m} offsets")
    if dtype is None:
        dtype = np.result_type(distance, column_penalty)
    square = np.empty((m, m), dtype=dtype)
    square[:k] = distance
    square[k:] = -column_penalty
    return square


def assign_offsets(
    pattern: HexPattern,
    follower_ids: np.ndarray,
    follower_xy: np.ndarray,
    leader_xy: np.ndarray,
    current: np.ndarray | None = None,
    switch_margin: float = 0.0,
) -> np.ndarray:
    """Offset index of each follower (eq. 4.12-4.13), deterministic for a given swarm map.

    Followers are ordered by id before the cost matrix is built and costs are rounded to the
    decimetre, as in the thesis, so any agent holding the same map (in any order) computes the
    same assignment; ties between equal-cost assignments are resolved identically everywhere.

    Re-solved every T_s from scratch (the thesis), the optimum flips between near-equal
    assignments from one tick to the next as agents move (for N = 100 packed on a grid, up to 78
    of 99 followers change slot in one tick). ``switch_margin`` adds hysteresis, a choice of
    ours: each follower's ``current`` slot is discounted by that many metres, so a follower only
    changes slot when the total distance drops by more than the margin.

    Args:
        pattern: from :func:`hex_pattern`.
        follower_ids: (K,) distinct ids of the followers (any order).
        follower_xy: (K, 2) or (K, 3) world positions, same order as ``follower_ids``.
        leader_xy: (2,) or (3,) world position of the leader r_N.
        current: (K,) slot each follower holds now (-1: none), same order; None: no hysteresis.
        switch_margin: m, discount on the current slot (rounded to the decimetre).

    Returns:
        (K,) int, index into ``pattern.offsets_xy`` for each follower, in the input order.
    """
    follower_ids = np.asarray(follower_ids)
    order = np.argsort(follower_ids, kind="stable")
    distance = _distance_dm(pattern, np.asarray(follower_xy)[order], leader_xy)
    if current is not None and switch_margin > 0:
        held = np.asarray(current)[order]
        rows = np.flatnonzero(held >= 0)
        distance[rows, held[rows]] -= np.rint(switch_margin / DECIMETRE)
    slots = np.empty(order.size, dtype=np.int64)
    # Whole decimetres: int32 is exact while the costs stay far below 2**31 (2**28 dm = 27,000 km).
    # Bound from the geometry (O(K)) rather than a pass over the matrix.
    reach = np.linalg.norm(np.asarray(follower_xy, dtype=float)[:, :2] - np.asarray(leader_xy, dtype=float)[:2], axis=1)
    bound = (reach.max(initial=0.0) + np.linalg.norm(pattern.offsets_xy, axis=1).max(initial=0.0)) / DECIMETRE
    exact_int32 = bound + abs(switch_margin) / DECIMETRE + 2 < 2**28
    square = _square_problem(distance, _penalty_dm(pattern), np.int32 if exact_int32 else np.int64)
    del distance  # free the float64 matrix before solving: less memory traffic (~4 ms at N = 1,000)
    slots[order] = solve_square(square)[: order.size]
    return slots


def slot_positions(
    pattern: HexPattern, slots: np.ndarray, leader_pos: np.ndarray
) -> np.ndarray:
    """World targets t_i = r_N + h_slot (K, 3) at the leader's altitude (all targets share it)."""
    leader_pos = np.asarray(leader_pos, dtype=float)
    out = np.empty((len(slots), 3))
    out[:, :2] = leader_pos[:2] + pattern.offsets_xy[slots]
    out[:, 2] = leader_pos[2] if leader_pos.size > 2 else 0.0
    return out
