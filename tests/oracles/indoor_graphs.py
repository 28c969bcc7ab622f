"""The numpy formulation of the indoor swarm's per-tick graphs, the oracle of the compiled kernels.

Karydes (2020), chapter 5. Until issue 20 this was the package's hot path
(``swarmscene.methods.indoor.sensing`` / ``graphs``); the package now runs the compiled kernels of
``swarmscene.methods.indoor.kernels`` and the tests compare them with these functions: graphs edge
for edge, positions and inputs to the bit (tests/methods/indoor/test_kernels.py). The geometry
here is shapely's (GEOS), the sets are vectorised numpy and scipy.sparse.csgraph.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import shapely
from scipy.sparse.csgraph import breadth_first_order

from swarmscene.methods.indoor.graphs import DEACTIVATION_CANDIDATES, ArcList, EdgeList
from swarmscene.methods.indoor.sensing import candidate_pairs, obstacle_tree, segments_clear

if TYPE_CHECKING:  # pragma: no cover
    from scipy.spatial import cKDTree

    from swarmscene.methods.indoor.sensing import Obstacles


def nearest_points(r: np.ndarray, geometries: np.ndarray, index: np.ndarray) -> np.ndarray:
    """o_i, the point of obstacle ``geometries[index[i]]`` closest to r_i (eq. 5.32), (N, 2);
    NaN where ``index`` is -1 (nothing detected). One vectorised ``shapely.shortest_line``."""
    o = np.full((len(r), 2), np.nan)
    agent = np.flatnonzero(index >= 0)
    if agent.size:
        lines = shapely.shortest_line(shapely.points(r[agent]), geometries[index[agent]])
        o[agent] = shapely.get_coordinates(lines).reshape(-1, 2, 2)[:, 1]
    return o



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
        (P, 2) int array of pairs (i < j).
    """
    pairs = candidate_pairs(r, d_range, tree) if candidates is None else candidates
    tree_o = obstacle_tree(obstacles)
    if tree_o is None or len(pairs) == 0:
        return pairs
    ri, rj = r[pairs[:, 0]], r[pairs[:, 1]]
    if clearance is None:
        return pairs[segments_clear(ri, rj, tree_o, d_l)]
    gap = rj - ri
    length = np.sqrt(np.einsum("ij,ij->i", gap, gap))
    unsure = np.flatnonzero(clearance[pairs[:, 0]] + clearance[pairs[:, 1]] < length + 2.0 * d_l)
    keep = np.ones(len(pairs), dtype=bool)
    keep[unsure] = segments_clear(ri[unsure], rj[unsure], tree_o, d_l)
    return pairs[keep]



def _candidates(
    graph: EdgeList, a: np.ndarray, b: np.ndarray, common: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All (arc k, agent m) with m in N_a[k](G) other than b[k]; with ``common`` also m in N_b[k].

    The candidate sets of eq. 5.15-5.16 for the arcs a -> b (each edge seen from one endpoint).
    Expands N_a for every arc through the CSR layout, no loop over arcs; ``common`` keeps the m
    adjacent to b, looked up in a dense N x N bitmap (a sorted-key search for very large N).
    Returns (arc, m, pos) with ``pos`` the position of a -> m in :meth:`EdgeList.directed`;
    ``arc`` comes out sorted.
    """
    n = graph.n
    src, dst = graph.directed()
    indptr = graph.indptr
    deg = indptr[a + 1] - indptr[a]
    arc = np.repeat(np.arange(len(a)), deg)
    pos = np.arange(arc.size) + np.repeat(indptr[a] - (np.cumsum(deg) - deg), deg)
    m = dst[pos]
    if not common:
        keep = m != b[arc]
        return arc[keep], m[keep], pos[keep]
    want = b[arc] * n + m  # m = b is never adjacent to b (no self-loops): dropped here too
    if n <= 8192:
        adjacent = np.zeros(n * n, dtype=bool)
        adjacent[src * n + dst] = True
        found = adjacent[want]
    else:
        keys = np.sort(src * n + dst)
        found_at = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
        found = keys[found_at] == want
    return arc[found], m[found], pos[found]



def deactivation_rules(
    r: np.ndarray,
    g_n: EdgeList,
    phi_d: float,
    perspective: str = "i",
    candidates: str = "neighbours",
) -> tuple[np.ndarray, np.ndarray]:
    """The two edge-deactivation rules (thesis eq. 5.15-5.21) per edge of G_n, as one end sees them.

    Rule 1 (eq. 5.18, Fig. 5.3): a candidate m closer to both i and j than they are to each other
    (m in A_ij and B_ij, eq. 5.15-5.16) lies almost on the edge, |phi(r_mi, r_ji)| < phi_d.
    Rule 2 (eq. 5.19-5.21, Fig. 5.4): such agents m on one side (C_ij, phi < 0) and n on the other
    (D_ij, phi > 0) are closer to each other than i to j: (i, j) is the longer crossing diagonal.

    Args:
        r: (N, 2) positions, m.
        g_n: the graph G_n.
        phi_d: flatness threshold phi_d, 0 < phi_d < 1/sqrt(2).
        perspective: ``"i"`` evaluates each edge as agent i does (candidates from N_i, r_ji,
            r_mi), ``"j"`` as agent j does (N_j, r_ij, r_mj).
        candidates: the reading of the candidate set (module docstring): ``"neighbours"`` and
            ``"directed"`` take m in N_i(G_n) (as printed), ``"common"`` m in N_i ∩ N_j, with which
            the two perspectives always agree.

    Returns:
        rule1, rule2: (P,) bool, True where the rule deactivates the edge.
    """
    a, b = (g_n.i, g_n.j) if perspective == "i" else (g_n.j, g_n.i)
    return _arc_rules(r, g_n, a, b, phi_d, candidates == "common")


def _arc_rules(
    r: np.ndarray, g_n: EdgeList, a: np.ndarray, b: np.ndarray, phi_d: float, common: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Rules 5.18 and 5.21 for the arcs a -> b of G_n, each evaluated by agent a (Q,) bool."""
    q = len(a)
    arc, m, pos = _candidates(g_n, a, b, common)
    x, y = r[:, 0], r[:, 1]
    ex, ey = x[b] - x[a], y[b] - y[a]  # r_ji per arc, from agent a's point of view
    d_sq = ex * ex + ey * ey
    # m in A_ij first (||r_mi|| < ||r_ji||, eq. 5.15), from the lengths of G_n's directed arcs:
    # it halves the candidates before any per-candidate vector is formed.
    src, dst = g_n.directed()
    arc_sq = (x[dst] - x[src]) ** 2 + (y[dst] - y[src]) ** 2
    in_a = np.flatnonzero(arc_sq[pos] < d_sq[arc])
    arc, m = arc[in_a], m[in_a]
    ex, ey, d_sq = ex[arc], ey[arc], d_sq[arc]
    mx, my = x[m] - x[a[arc]], y[m] - y[a[arc]]  # r_mi
    # ... and in B_ij: closer to j too (eq. 5.16).
    in_b = np.flatnonzero((mx - ex) ** 2 + (my - ey) ** 2 < d_sq)
    arc, m, mx, my, ex, ey, d_sq = (v[in_b] for v in (arc, m, mx, my, ex, ey, d_sq))
    phi = (my * ex - mx * ey) / d_sq  # eq. 5.17, phi(r_mi, r_ji)
    rule1 = np.zeros(q, dtype=bool)
    rule1[arc[np.abs(phi) < phi_d]] = True
    rule2 = _crossing_rule(r, arc, m, phi, d_sq, q)
    return rule1, rule2


def deactivated(
    r: np.ndarray, g_n: EdgeList, phi_d: float, candidates: str = "neighbours"
) -> tuple[np.ndarray, np.ndarray]:
    """(P,) bool twice: where agent i's rules fire on edge (i, j), and where agent j's do.

    Both perspectives are evaluated in one pass over the 2P arcs; under ``"common"`` they are
    equal by construction and computed once.
    """
    if candidates not in DEACTIVATION_CANDIDATES:
        raise ValueError(f"deactivation_candidates: {candidates!r}, allowed {DEACTIVATION_CANDIDATES}")
    p = len(g_n)
    if candidates == "common":
        rule1, rule2 = _arc_rules(r, g_n, g_n.i, g_n.j, phi_d, True)
        off = rule1 | rule2
        return off, off
    a, b = np.concatenate([g_n.i, g_n.j]), np.concatenate([g_n.j, g_n.i])
    rule1, rule2 = _arc_rules(r, g_n, a, b, phi_d, False)
    off = rule1 | rule2
    return off[:p], off[p:]


def _crossing_rule(
    r: np.ndarray, edge: np.ndarray, m: np.ndarray, phi: np.ndarray, d_sq: np.ndarray, p: int
) -> np.ndarray:
    """Eq. 5.21 on the candidates of A_ij & B_ij: exists (m, n) in C_ij x D_ij, ||r_nm|| < ||r_ji||.

    ``edge`` must be sorted; every (m in C_ij, n in D_ij) pair of an edge is enumerated at once.
    """
    c, d = phi < 0, phi > 0
    c_edge, c_m, c_len = edge[c], m[c], d_sq[c]
    d_m = m[d]
    d_count = np.bincount(edge[d], minlength=p)
    d_start = np.cumsum(d_count) - d_count
    reps = d_count[c_edge]
    total = int(reps.sum())
    rule2 = np.zeros(p, dtype=bool)
    if total == 0:
        return rule2
    ci = np.repeat(np.arange(len(c_edge)), reps)
    offset = np.arange(total) - np.repeat(np.cumsum(reps) - reps, reps)
    n_of = d_m[d_start[c_edge[ci]] + offset]
    m_of = c_m[ci]
    dx, dy = r[n_of, 0] - r[m_of, 0], r[n_of, 1] - r[m_of, 1]
    rule2[c_edge[ci[dx * dx + dy * dy < c_len[ci]]]] = True
    return rule2


def edge_activation(
    r: np.ndarray, g_n: EdgeList, phi_d: float, candidates: str = "neighbours"
) -> np.ndarray:
    """sigma_ij per edge of G_n: 0 if rule (5.18) or (5.21) holds, else 1 (thesis eq. 5.22).

    Under ``"neighbours"`` the edge is off when either end's rules fire, so sigma_ij = sigma_ji
    (eq. 5.14); ``"directed"`` has no single sigma_ij (use :func:`sigma_graph`).
    """
    if candidates == "directed":
        raise ValueError("edge_activation: the directed reading has one sigma per arc, see sigma_graph")
    off_i, off_j = deactivated(r, g_n, phi_d, candidates)
    return ~(off_i | off_j)


def sigma_graph(
    r: np.ndarray, g_n: EdgeList, phi_d: float, candidates: str = "neighbours"
) -> EdgeList:
    """G_sigma: the edges of G_n with sigma_ij = 1 (thesis eq. 5.13-5.14, 5.22).

    Under ``"directed"`` an :class:`ArcList`: arc i -> j kept unless agent i's rules fire on
    (i, j), arc j -> i unless agent j's do.
    """
    off_i, off_j = deactivated(r, g_n, phi_d, candidates)
    if candidates != "directed":
        return g_n.subgraph(~(off_i | off_j))
    src = np.concatenate([g_n.i[~off_i], g_n.j[~off_j]])
    dst = np.concatenate([g_n.j[~off_i], g_n.i[~off_j]])
    return ArcList.from_arcs(g_n.n, src, dst)



def max_rank(graph: EdgeList, leader: int) -> tuple[int, np.ndarray]:
    """max_i rho_i (eq. 5.23; N when an agent is cut off) and the (N,) mask of agents reached.

    What the success criterion needs, without every rank: a breadth-first order lists agents by
    non-decreasing rank, so the largest is the depth of the last one, read by walking its
    predecessors back to the leader (max rank steps).
    """
    order, pred = breadth_first_order(graph.csgraph(), leader, directed=True, return_predecessors=True)
    reached = np.zeros(graph.n, dtype=bool)
    reached[order] = True
    if order.size < graph.n:
        return graph.n, reached
    depth, v, pred = 0, int(order[-1]), pred.tolist()
    while v != leader:
        v, depth = pred[v], depth + 1
    return depth, reached



def rank_estimate_step(rho_bar: np.ndarray, g_sigma: EdgeList, leader: int) -> np.ndarray:
    """rho_bar_i(k+1) = min over N_i(G_sigma) of rho_bar_j(k) + 1 (thesis eq. 5.26).

    The leader keeps 0. The estimate is capped at N: an agent with no neighbour, or in a component
    without the leader (whose minimum would otherwise grow by one every step), reads N = "lost".
    """
    n = len(rho_bar)
    new = np.minimum(g_sigma.neighbour_min(rho_bar, n) + 1, n)
    new[leader] = 0
    return new




def neighbour_graph(r, obstacles, d_n, d_l, tree=None, clearance=None, candidates=None) -> EdgeList:
    """G_n (eq. 5.11-5.12) from :func:`sensing_pairs`."""
    return EdgeList.from_pairs(len(r), sensing_pairs(r, d_n, obstacles, d_l, tree, clearance, candidates))
