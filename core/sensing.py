"""Sensing and communication: one k-d tree per step, shared by every plugin and monitor.

The kernel builds a :class:`Sensing` snapshot after each physics update; observers read it at the
end of the tick and the formation/avoidance plugins read the same object at the start of the next
one, so the tree over the agents' positions is built exactly once per guidance step. Queries are
lazy and cached: a plugin that never asks for the communication graph does not pay for it.
"""

from __future__ import annotations

from functools import cached_property

import networkx as nx
import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import connected_components, shortest_path
from scipy.spatial import cKDTree

from .environment import Environment
from .state import WorldState


class Sensing:
    """What can be known about the swarm at one instant.

    Args:
        world: the state to sense (positions are read, not copied: build a new Sensing after
            the state changes).
        environment: the obstacle map.
        comm_range: communication range, m.
        previous: the previous tick's snapshot; results that depend only on the graph (not on
            exact positions) are reused when the graph has not changed.
    """

    def __init__(
        self,
        world: WorldState,
        environment: Environment,
        comm_range: float,
        previous: "Sensing | None" = None,
    ) -> None:
        self.world = world
        self.environment = environment
        self.comm_range = comm_range
        self._pairs: dict[float, np.ndarray] = {}
        self._previous = previous
        if previous is not None:
            previous._previous = None  # keep one snapshot back, never a chain

    @cached_property
    def tree(self) -> cKDTree:
        """k-d tree over all agents' positions (failed ones included: they are still obstacles)."""
        return cKDTree(self.world.pos)

    def pairs(self, radius: float) -> np.ndarray:
        """Index pairs (i < j) of agents closer than ``radius`` m, shape (M, 2); cached per radius."""
        if radius not in self._pairs:
            self._pairs[radius] = self.tree.query_pairs(radius, output_type="ndarray")
        return self._pairs[radius]

    @cached_property
    def nearest(self) -> tuple[np.ndarray, np.ndarray]:
        """For each agent: distance to its nearest other agent (m, ``inf`` if alone) and its index."""
        n = self.world.n
        if n < 2:
            return np.full(n, np.inf), np.full(n, -1)
        dist, idx = self.tree.query(self.world.pos, k=2)
        return dist[:, 1], idx[:, 1]

    @cached_property
    def clearance(self) -> np.ndarray:
        """Signed distance from each agent to the nearest obstacle, m (``inf`` in open space)."""
        return self.environment.clearance(self.world.pos)

    @cached_property
    def comm_members(self) -> np.ndarray:
        """Agents taking part in communication: healthy and with a working radio."""
        return self.world.healthy & self.world.comm_ok

    @cached_property
    def comm_adjacency(self) -> csr_matrix:
        """Symmetric sparse adjacency of the communication graph (range ``comm_range``)."""
        n = self.world.n
        pairs = self.pairs(self.comm_range)
        keep = self.comm_members[pairs[:, 0]] & self.comm_members[pairs[:, 1]]
        i, j = pairs[keep, 0], pairs[keep, 1]
        data = np.ones(2 * len(i), dtype=np.int8)
        return coo_matrix((data, (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()

    @cached_property
    def _comm_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Members and the (i < j) pairs among them: the communication graph, exactly."""
        pairs = self.pairs(self.comm_range)
        keep = self.comm_members[pairs[:, 0]] & self.comm_members[pairs[:, 1]]
        return self.comm_members, pairs[keep]

    def _same_graph_as_previous(self) -> bool:
        prev = self._previous
        if prev is None or "comm_connected" not in prev.__dict__:
            return False
        members, edges = self._comm_edges
        prev_members, prev_edges = prev._comm_edges
        return np.array_equal(members, prev_members) and np.array_equal(edges, prev_edges)

    @cached_property
    def comm_connected(self) -> bool:
        """True when the communication graph over its members is connected (one member counts)."""
        if self._same_graph_as_previous():
            return self._previous.comm_connected  # a formation in flight rarely changes its graph
        members = np.flatnonzero(self.comm_members)
        m = members.size
        if m <= 1:
            return True
        _, edges = self._comm_edges
        if len(edges) < m - 1:
            return False  # a spanning tree needs m - 1 edges
        # Renumber members 0..m-1 and build one upper-triangular matrix: cheaper than slicing
        # the full adjacency.
        index = np.full(self.world.n, -1)
        index[members] = np.arange(m)
        i, j = index[edges[:, 0]], index[edges[:, 1]]
        graph = coo_matrix((np.ones(i.size, dtype=np.int8), (i, j)), shape=(m, m))
        count, _ = connected_components(graph, directed=False)
        return count == 1

    def hop_distances(self, source: int) -> np.ndarray:
        """Hops from ``source`` to every agent over the communication graph (``inf`` if unreachable)."""
        return shortest_path(self.comm_adjacency, unweighted=True, indices=source)

    @cached_property
    def comm_graph(self) -> nx.Graph:
        """The communication graph as a networkx graph, for analysis and metrics (not hot loops)."""
        graph = nx.Graph()
        graph.add_nodes_from(np.flatnonzero(self.comm_members).tolist())
        rows, cols = self.comm_adjacency.nonzero()
        graph.add_edges_from((int(a), int(b)) for a, b in zip(rows, cols) if a < b)
        return graph
