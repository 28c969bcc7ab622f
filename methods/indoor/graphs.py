"""Indoor swarming, thesis sections 5.2.5-5.3.2: graphs G_s, G_n, G_sigma, edge deactivation, ranks.

Karydes (2020), chapter 5. Graphs are simple and undirected over agents 0..N-1; the hot path keeps
them as an :class:`EdgeList` (arrays of pairs i < j) and computes them in compiled kernels
(``kernels.py``: line of sight, deactivation rules, ranks; :func:`tick_graphs` is one tick's
G_n and G_sigma in one call; the numpy formulation is the tests' oracle, tests/oracles/indoor_graphs.py);
:meth:`EdgeList.to_networkx` is for analysis and metrics. The one exception is G_sigma under the
``directed`` reading of eq. 5.15-5.16, an :class:`ArcList`.

Readings where the text is ambiguous (each also stated at the function):
- Deactivation candidates m (eq. 5.15-5.16), option ``deactivation_candidates``:
  ``neighbours`` (the default, the literal reading): m in N_i(G_n) other than j; agent i and
  agent j each evaluate the rules over their own neighbours and the edge is off when either one's
  rule fires
  (sigma_ij = sigma_ji, eq. 5.14, so G_sigma stays undirected). The text claims that i and j
  always agree (after eq. 5.21); they do in open space (an m closer to both ends than ||r_ji|| <=
  d_n is in range of both) but not when a wall hides m from j, and then the "either" rule can cut
  G_sigma where G_n is connected (agent j loses its only link while m, its bridge, is invisible
  to it).
  ``common``: m in N_i(G_n) ∩ N_j(G_n), the common neighbours (i learns N_j by the one-hop
  communication of section 5.2.1). Both agents evaluate the same set, so the symmetry the text
  claims holds by construction, and an edge is dropped only when a path i-m-j of strictly shorter
  G_n edges exists, so G_sigma has exactly the connected components of G_n (induction on edge
  length). This was the code's reading before issue 17; it keeps the property the text argues
  for, at the price of a candidate set the text does not print.
  ``directed``: each agent drops j from its own N_i(G_sigma) when its own rule fires, and keeps
  listening to j otherwise: G_sigma becomes a directed graph (sigma_ij != sigma_ji possible),
  against eq. 5.14's "binary symmetric function"; kept to measure how much the symmetry matters.
- Surrogate leaders (eq. 5.25) are the neighbours of *minimum* estimated rank. The printed "max"
  would send followers away from the leader, contradicting the text ("driven to the leader by the
  means of its surrogate leader") and property 5.29.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy  # scipy.sparse loads at first use (start-up: imported at plugin registration)

from .sensing import Obstacles, candidate_pairs, kernel_obstacles, obstacle_tree, sensing_pairs

if TYPE_CHECKING:  # pragma: no cover
    import networkx as nx
    from scipy.sparse import csr_matrix
    from scipy.spatial import cKDTree


@dataclass(frozen=True)
class EdgeList:
    """A simple undirected graph on ``n`` agents: edge k joins ``i[k] < j[k]``."""

    n: int
    i: np.ndarray
    j: np.ndarray

    @classmethod
    def from_pairs(cls, n: int, pairs: np.ndarray) -> EdgeList:
        """From an (P, 2) array of pairs (either order; duplicates are not allowed), sorted by (i, j)."""
        pairs = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
        lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
        order = np.argsort(lo * n + hi)
        return cls(n, lo[order], hi[order])

    def __len__(self) -> int:
        return len(self.i)

    def lengths(self, r: np.ndarray) -> np.ndarray:
        """(P,) edge lengths ||r_j - r_i||, m."""
        d = r[self.j] - r[self.i]
        return np.sqrt(np.einsum("ij,ij->i", d, d))

    def subgraph(self, keep: np.ndarray) -> EdgeList:
        """The subgraph with the edges where ``keep`` (P,) is True (same nodes)."""
        return EdgeList(self.n, self.i[keep], self.j[keep])

    def directed(self) -> tuple[np.ndarray, np.ndarray]:
        """Both orientations of every edge: (src, dst), each (2P,), sorted by src (cached)."""
        return self._directed

    @cached_property
    def _directed(self) -> tuple[np.ndarray, np.ndarray]:
        src = np.concatenate([self.i, self.j])
        dst = np.concatenate([self.j, self.i])
        # A stable argsort of small unsigned ints is a radix sort: linear, ~10x faster here.
        key = src.astype(np.uint16) if self.n <= 1 << 16 else src
        order = np.argsort(key, kind="stable")
        return src[order], dst[order]

    @cached_property
    def indptr(self) -> np.ndarray:
        """(N + 1,) CSR row pointers of :meth:`directed`: N_i is dst[indptr[i]:indptr[i + 1]]."""
        return np.concatenate([[0], np.cumsum(self.degree())])

    def neighbour_min(self, values: np.ndarray, empty: int | float) -> np.ndarray:
        """(N,) min over N_i of ``values[j]``; ``empty`` where N_i is empty.

        One ``minimum.reduceat`` over the CSR layout of :meth:`directed` (several times cheaper
        than ``minimum.at``); the starts of non-empty rows delimit each row's block exactly.
        """
        _, dst = self.directed()
        out = np.full(self.n, empty, dtype=values.dtype)
        starts = self.indptr[:-1]
        full = self.indptr[1:] > starts
        if dst.size:
            out[full] = np.minimum.reduceat(values[dst], starts[full])
        return out

    def degree(self) -> np.ndarray:
        """(N,) number of neighbours |N_i|."""
        return np.bincount(self.i, minlength=self.n) + np.bincount(self.j, minlength=self.n)

    def csgraph(self) -> csr_matrix:
        """Symmetric (N, N) sparse adjacency for scipy.sparse.csgraph.

        Built straight from the cached CSR arrays with float data, the layout csgraph works on,
        so no COO conversion or dtype copy happens (3x faster on a 100-agent swarm).
        """
        _, dst = self.directed()
        return scipy.sparse.csr_matrix((np.ones(len(dst)), dst, self.indptr), shape=(self.n, self.n))

    def to_networkx(self) -> nx.Graph:
        """The same graph as networkx, for analysis and metrics (not for the per-step path)."""
        import networkx as nx

        graph = nx.Graph()
        graph.add_nodes_from(range(self.n))
        graph.add_edges_from(zip(self.i.tolist(), self.j.tolist(), strict=True))
        return graph

    def edge_set(self) -> set[tuple[int, int]]:
        """Edges as a Python set of (i, j), i < j (tests, analysis)."""
        return set(zip(self.i.tolist(), self.j.tolist(), strict=True))


DEACTIVATION_CANDIDATES = ("neighbours", "common", "directed")
"""Readings of the candidate set m of eq. 5.15-5.16 (see the module docstring); the first is the
literal one and the default."""


@dataclass(frozen=True)
class ArcList(EdgeList):
    """A directed graph on ``n`` agents: arc k means ``j[k]`` is in N_{i[k]} (i listens to j).

    G_sigma under the ``directed`` reading of eq. 5.15-5.16. Arcs are kept sorted by ``i``, so
    :meth:`directed` is the arc list itself and every per-neighbour reduction of :class:`EdgeList`
    (:meth:`neighbour_min`, the control sums) runs over N_i as agent i sees it.
    """

    @classmethod
    def from_arcs(cls, n: int, src: np.ndarray, dst: np.ndarray) -> ArcList:
        """From arcs src -> dst (any order), sorted by (src, dst)."""
        src, dst = np.asarray(src, dtype=np.intp), np.asarray(dst, dtype=np.intp)
        order = np.argsort(src * n + dst)
        return cls(n, src[order], dst[order])

    @cached_property
    def _directed(self) -> tuple[np.ndarray, np.ndarray]:
        return self.i, self.j

    def degree(self) -> np.ndarray:
        """(N,) out-degree |N_i|: the neighbours agent i listens to."""
        return np.bincount(self.i, minlength=self.n)

    def subgraph(self, keep: np.ndarray) -> ArcList:
        """The arcs where ``keep`` (bool, one per arc) is True."""
        return ArcList(self.n, self.i[keep], self.j[keep])

    def to_networkx(self) -> nx.DiGraph:
        """The arcs as a networkx DiGraph on nodes 0..N-1 (analysis and tests, not the hot path)."""
        import networkx as nx

        graph = nx.DiGraph()
        graph.add_nodes_from(range(self.n))
        graph.add_edges_from(zip(self.i.tolist(), self.j.tolist(), strict=True))
        return graph


def mean_degree(graph: EdgeList) -> float:
    """Mean |N_i| over agents (2 |E| / N undirected, |arcs| / N directed; Fig. 5.17)."""
    return graph.directed()[0].size / max(graph.n, 1)


def sensing_graph(
    r: np.ndarray, obstacles: Obstacles, d_s: float, d_l: float, tree: cKDTree | None = None
) -> EdgeList:
    """G_s: agents within d_s of each other with a clear line of sight (thesis eq. 5.7-5.8)."""
    return EdgeList.from_pairs(len(r), sensing_pairs(r, d_s, obstacles, d_l, tree))


def neighbour_graph(
    r: np.ndarray,
    obstacles: Obstacles,
    d_n: float,
    d_l: float,
    tree: cKDTree | None = None,
    clearance: np.ndarray | None = None,
    candidates: np.ndarray | None = None,
) -> EdgeList:
    """G_n: the edges of G_s no longer than d_n (thesis eq. 5.11-5.12), sensed directly at d_n.

    ``clearance`` (N,) lower bounds of obstacle distances let certified pairs skip the shapely
    LOS test; ``candidates`` are the pairs within d_n if already listed (see
    :func:`~.indoor_sensing.sensing_pairs`).
    """
    pairs = sensing_pairs(r, d_n, obstacles, d_l, tree, clearance, candidates)
    return EdgeList.from_pairs(len(r), pairs)


def restrict(graph: EdgeList, r: np.ndarray, d_max: float) -> EdgeList:
    """The subgraph of edges no longer than ``d_max`` (eq. 5.12 applied to G_s)."""
    return graph.subgraph(graph.lengths(r) <= d_max)


def is_connected(graph: EdgeList) -> bool:
    """True when the graph is connected (scipy.sparse.csgraph)."""
    if graph.n <= 1:
        return True
    count, _ = scipy.sparse.csgraph.connected_components(graph.csgraph(), directed=True, connection="weak")
    return count == 1


def flatness(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """phi(p, q) = p^T H q / q^T q with H the +90 degree rotation (thesis eq. 5.17), row-wise.

    |phi(r_mi, r_ji)| is the distance of m from the line of edge (i, j) over the edge length; its
    sign tells the side of the edge on which m lies.
    """
    cross = p[:, 1] * q[:, 0] - p[:, 0] * q[:, 1]
    return cross / np.einsum("ij,ij->i", q, q)


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
    rules = _rules(r, g_n, phi_d, candidates, both=True)
    return (rules[0], rules[1]) if perspective == "i" else (rules[2], rules[3])


def _rules(r: np.ndarray, g_n: EdgeList, phi_d: float, candidates: str, both: bool) -> np.ndarray:
    """(4, P) bool: rules 5.18 and 5.21 seen by agent i, then by agent j (one compiled call)."""
    from .kernels import READINGS, deactivation_kernel  # numba loads at first use

    check_reading(candidates)
    r = np.ascontiguousarray(r, dtype=float)
    i, j = np.asarray(g_n.i, dtype=np.intp), np.asarray(g_n.j, dtype=np.intp)
    return deactivation_kernel(r, i, j, float(phi_d), READINGS[candidates], both)


def deactivated(
    r: np.ndarray, g_n: EdgeList, phi_d: float, candidates: str = "neighbours"
) -> tuple[np.ndarray, np.ndarray]:
    """(P,) bool twice: where agent i's rules fire on edge (i, j), and where agent j's do.

    Under ``"common"`` the two perspectives are equal by construction (computed once).
    """
    rules = _rules(r, g_n, phi_d, candidates, both=False)
    return rules[0] | rules[1], rules[2] | rules[3]


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


def tick_graphs(
    r: np.ndarray,
    obstacles: Obstacles,
    d_n: float,
    d_l: float,
    phi_d: float,
    candidates: str = "neighbours",
    tree: cKDTree | None = None,
    clearance: np.ndarray | None = None,
    pairs: np.ndarray | None = None,
) -> tuple[EdgeList, EdgeList]:
    """G_n and G_sigma of one tick in one compiled call (eq. 5.7-5.22): what
    :func:`neighbour_graph` then :func:`sigma_graph` give, with their arc layouts filled in.

    ``clearance`` (N,) lower bounds of the obstacle distances (line-of-sight certificates, see
    ``sensing.sensing_pairs``; ``None``: every pair is tested); ``pairs`` the candidates within
    d_n if already listed (the engine's ``Sensing.pairs``), else from ``tree`` or a new cKDTree.
    """
    from .kernels import READINGS, graphs_kernel  # numba loads at first use

    check_reading(candidates)
    n = len(r)
    r = np.ascontiguousarray(r, dtype=float)
    if pairs is None:
        pairs = candidate_pairs(r, d_n, tree)
    if clearance is None:
        clearance = np.full(n, -np.inf)
    out = graphs_kernel(
        r, np.asarray(pairs, dtype=np.intp).reshape(-1, 2), np.asarray(clearance, dtype=float),
        float(d_l), float(phi_d), READINGS[candidates], *kernel_obstacles(obstacle_tree(obstacles)),
    )
    return graphs_from_kernel(out, n, candidates)


def check_reading(candidates: str) -> None:
    """Refuse an unknown reading of eq. 5.15-5.16."""
    if candidates not in DEACTIVATION_CANDIDATES:
        raise ValueError(f"deactivation_candidates: {candidates!r}, allowed {DEACTIVATION_CANDIDATES}")


def graphs_from_kernel(out: np.ndarray, n: int, candidates: str) -> tuple[EdgeList, EdgeList]:
    """G_n and G_sigma from the packed result of ``kernels.graphs_kernel`` (views, arcs filled in)."""
    from .kernels import unpack_graphs

    n_i, n_j, n_indptr, n_src, n_dst, s_i, s_j, s_indptr, s_src, s_dst = unpack_graphs(
        out, n, candidates == "directed"
    )
    g_n = _with_arcs(EdgeList(n, n_i, n_j), n_indptr, n_src, n_dst)
    kind = ArcList if candidates == "directed" else EdgeList
    return g_n, _with_arcs(kind(n, s_i, s_j), s_indptr, s_src, s_dst)


def _with_arcs(graph: EdgeList, indptr: np.ndarray, src: np.ndarray, dst: np.ndarray) -> EdgeList:
    """``graph`` with the cached arc layout (:meth:`EdgeList.directed`, ``indptr``) filled in
    from the kernel, which lists arcs in the same order."""
    graph.__dict__["_directed"] = (src, dst)
    graph.__dict__["indptr"] = indptr
    return graph


def ranks(graph: EdgeList, leader: int) -> np.ndarray:
    """rho_i = dist(i, N), hops to the leader (thesis eq. 5.23); agents cut off get rank n.

    Rank n (never reached by a connected agent, whose rank is at most n - 1) marks the loss of
    connectivity, so "max rank < N" is the thesis' success condition.
    """
    n = graph.n
    # A breadth-first tree's depths are the hop distances; scipy's traversal is ~10x cheaper
    # than its shortest_path on a 100-agent G_n, and pointer doubling reads the depths off the
    # predecessor array in O(log depth) vectorised passes.
    _, pred = scipy.sparse.csgraph.breadth_first_order(
        graph.csgraph(), leader, directed=True, return_predecessors=True
    )
    parent = np.where(pred >= 0, pred, np.arange(n))  # the leader and unreached agents: roots
    depth = (parent != np.arange(n)).astype(np.int64)
    while True:
        grand = parent[parent]
        if np.array_equal(grand, parent):
            break
        depth += depth[parent]
        parent = grand
    reached = parent == leader
    return np.where(reached, depth, n)


def max_rank(graph: EdgeList, leader: int) -> tuple[int, np.ndarray]:
    """max_i rho_i (eq. 5.23; N when an agent is cut off) and the (N,) mask of agents reached.

    What the success criterion needs, without every rank: one compiled breadth-first search.
    """
    from .kernels import max_rank_kernel  # numba loads at first use

    _, dst = graph.directed()
    rank, reached = max_rank_kernel(graph.indptr, np.asarray(dst, dtype=np.intp), leader)
    return int(rank), reached


def initial_rank_estimate(n: int, leader: int) -> np.ndarray:
    """rho_bar(0): N - 1 for followers, 0 for the leader (thesis eq. 5.26)."""
    rho_bar = np.full(n, n - 1, dtype=np.int64)
    rho_bar[leader] = 0
    return rho_bar


def rank_estimate_step(rho_bar: np.ndarray, g_sigma: EdgeList, leader: int) -> np.ndarray:
    """rho_bar_i(k+1) = min over N_i(G_sigma) of rho_bar_j(k) + 1 (thesis eq. 5.26).

    The leader keeps 0. The estimate is capped at N: an agent with no neighbour, or in a component
    without the leader (whose minimum would otherwise grow by one every step), reads N = "lost".
    """
    from .kernels import rank_step_kernel  # numba loads at first use

    _, dst = g_sigma.directed()
    return rank_step_kernel(g_sigma.indptr, np.asarray(dst, dtype=np.intp), rho_bar, leader)


def virtual_leader(
    r: np.ndarray, g_sigma: EdgeList, rho_bar: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """l_i, the mean position of agent i's surrogate leaders (thesis eq. 5.24-5.25).

    Surrogate leaders S_i are the G_sigma neighbours of minimum estimated rank (the printed max is
    a typo, see the module docstring).

    Returns:
        l: (N, 2) virtual leader positions, m; r_i itself where i has no neighbour.
        has_neighbour: (N,) bool, N_i(G_sigma) non-empty (eq. 5.41 sets w_led = 0 otherwise).
    """
    n = len(r)
    src, dst = g_sigma.directed()
    best = g_sigma.neighbour_min(rho_bar, np.iinfo(rho_bar.dtype).max)
    surrogate = rho_bar[dst] == best[src]
    s, d = src[surrogate], dst[surrogate]
    count = np.bincount(s, minlength=n)
    has = count > 0
    l_i = r.astype(float, copy=True)
    sx = np.bincount(s, weights=r[d, 0], minlength=n)
    sy = np.bincount(s, weights=r[d, 1], minlength=n)
    l_i[has, 0] = sx[has] / count[has]
    l_i[has, 1] = sy[has] / count[has]
    return l_i, has
