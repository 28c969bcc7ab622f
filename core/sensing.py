"""The tick's shared spatial queries: one pair list per step, shared by every plugin and monitor.

Despite its name (kept: every plugin's signature reads ``sensing``), :class:`Sensing` is the
engine's per-tick query cache (neighbour pairs, nearest obstacles, the communication graph, and
the :meth:`Sensing.shared` memo), not a sensor model: what an agent can see under the thesis'
line-of-sight rules is ``swarmscene.methods.indoor.sensing``.

The kernel builds a :class:`Sensing` snapshot after each physics update; observers read it at the
end of the tick and the formation/avoidance plugins read the same object at the start of the next
one, so the agents' pairs are listed once per guidance step (a dense pass for a few agents, a
compiled cell list for more: ``core.vectors.pairs_within``); a k-d tree is built only for a plugin
that asks for :attr:`Sensing.tree`. Queries are lazy and cached: a plugin that never asks for the
communication graph does not pay for it. Their arrays are shared by every reader of the tick, so
they are handed out read-only (:func:`read_only`): copy one to edit it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Generic, TypeVar, cast

import numpy as np
import scipy  # submodules load on first use (scipy.sparse, scipy.spatial): a small swarm needs neither

from .environment import Environment
from .state import WorldState
from .vectors import (
    DENSE_POINTS,
    dense_pair_dist2,
    min_pair_distance,
    pairs_within,
    upper_pair_array,
)

if TYPE_CHECKING:  # pragma: no cover
    import networkx as nx
    from scipy.sparse import csr_matrix
    from scipy.spatial import cKDTree


DENSE_LIMIT = 128
"""Up to this many members, connectivity in open space is a dense reachability sweep (no sparse
overhead); more are joined by union-find over a compiled cell list
(:func:`.cells.disk_graph_connected`), as any number are in a periodic space."""
NEAR_K = 4
"""Nearest neighbours per agent in the shared kNN query (:attr:`Sensing.knn`)."""
T = TypeVar("T")

OBSTACLE_SKIN = 0.25
"""Obstacle candidates are listed this fraction of the range beyond it, and kept from tick to tick
until some agent has moved farther than that margin (a Verlet list)."""


@dataclass(frozen=True)
class ObstacleCandidates:
    """Every (agent, obstacle) pair within ``radius`` of the agents' positions ``xy`` (Verlet list).

    While no agent is farther than ``radius - r`` from its position in ``xy``, the pairs include
    every obstacle within ``r`` of it, so the nearest one is found among them without a tree query.
    """

    xy: np.ndarray
    radius: float
    point: np.ndarray
    geom: np.ndarray

    def cover(self, xy: np.ndarray, reach: float) -> bool:
        """True when the list still holds every obstacle within ``reach`` of each agent at ``xy``."""
        if xy.shape != self.xy.shape or reach > self.radius:
            return False
        moved = xy - self.xy
        moved *= moved  # dx^2 + dy^2 as einsum sums it, with fewer Python-level wrappers
        return bool(np.maximum.reduce(moved[:, 0] + moved[:, 1], initial=0.0) <= (self.radius - reach) ** 2)


class per_tick(Generic[T]):
    """``functools.cached_property`` without its lock: computed at the first read, then a plain
    attribute of this snapshot. A snapshot lives within one tick of one thread, and Python 3.11's
    cached_property takes a class-wide lock on every first read (a few reads a tick, ~0.2 us each
    of a small swarm's tick budget)."""

    def __init__(self, func: Callable[[Any], T]) -> None:
        self.func = func
        self.__doc__ = func.__doc__

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, cls: type | None = None) -> T:
        if obj is None:
            return self  # type: ignore[return-value]
        value = obj.__dict__[self.name] = read_only(self.func(obj))
        return value


def read_only(value: T) -> T:
    """``value`` with every array in it (itself, or the items of a tuple) as a read-only view.

    A tick's answers are shared: the safety monitor and every plugin read the same arrays, so a
    plugin that edited one in place (``dist, _ = sensing.nearest; dist[dist > r] = r``) would
    silently change what the others see and what the monitor judges. A read-only view makes that
    edit fail at once (``ValueError: assignment destination is read-only``); copy to edit.
    """
    if isinstance(value, np.ndarray):
        view = value.view()
        view.setflags(write=False)  # (not ``view.flags.writeable = False``: a flags object a call, 1.5x slower)
        return cast("T", view)
    if isinstance(value, tuple) and type(value) is tuple:  # not a named tuple: its own fields stay
        items: tuple[Any, ...] = value
        return cast("T", tuple([read_only(item) for item in items]))  # a list: no generator a call
    return value


def _dense_connected(pos: np.ndarray, radius: float) -> bool:
    """Connectivity of the disk graph of a few points by breadth-first sweeps of a boolean matrix."""
    diff = pos[:, None, :] - pos[None, :, :]
    adjacent = np.einsum("ijk,ijk->ij", diff, diff) <= radius * radius
    reached = adjacent[0].copy()
    count = 0
    while (new := int(reached.sum())) != count:
        count = new
        reached = adjacent[reached].any(axis=0)
    return count == len(pos)


def _linked_by_sweeps(n: int, i: np.ndarray, j: np.ndarray, start: int) -> np.ndarray:
    """(n,) bool: the agents reached from ``start`` over the links (i[k], j[k])."""
    adjacent = np.zeros((n, n), dtype=bool)
    adjacent[i, j] = True
    adjacent[j, i] = True
    reached = adjacent[start].copy()
    reached[start] = True
    count = 0
    while (new := int(reached.sum())) != count:
        count = new
        reached |= adjacent[reached].any(axis=0)
    return reached


@lru_cache(maxsize=8)
def _nothing_near(n: int) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Sensing.obstacle_nearest`'s answer when no obstacle is in range: index -1 and
    clearance ``inf`` for each of ``n`` agents, read-only templates (each tick hands out copies:
    two calls instead of np.full's Python-level four)."""
    index, clearance = np.full(n, -1), np.full(n, np.inf)
    index.flags.writeable = clearance.flags.writeable = False
    return index, clearance


def _renumber(n: int, members: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edges between members, with members renumbered 0..m-1."""
    index = np.full(n, -1)
    index[members] = np.arange(members.size)
    return index[edges[:, 0]], index[edges[:, 1]]


class Sensing:
    """What can be known about the swarm at one instant.

    Args:
        world: the state to sense (positions are read, not copied: build a new Sensing after
            the state changes).
        environment: the obstacle map.
        comm_range: communication range, m.
        previous: the last tick's snapshot, if any. The widest ranges its callers asked for
            (pairs, obstacles) are queried at once here, so that every narrower request of this
            tick, in whatever order the monitor and the plugins make them, is filtered from one
            tree walk (see :meth:`pairs`, :meth:`obstacle_nearest`).
    """

    def __init__(
        self,
        world: WorldState,
        environment: Environment,
        comm_range: float,
        previous: Sensing | None = None,
    ) -> None:
        self.world = world
        self._n = world.n  # agents (read a few times a tick; a property of the world)
        self.environment = environment
        self.comm_range = comm_range
        self._pairs: dict[float, np.ndarray] = {}
        self._pair_d2: dict[float, np.ndarray] = {}  # the listed pairs' squared lengths
        self._nearest: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._none_within = -1.0  # m: no obstacle within this range of any agent (-1: not known)
        # Widest range asked of this snapshot ("asked") and of the previous one ("hint"), m.
        self.asked = {"pairs": 0.0, "obstacles": 0.0}
        self._hint = dict(previous.asked) if previous is not None else dict(self.asked)
        self._candidates: ObstacleCandidates | None = previous._candidates if previous is not None else None
        # Whether this snapshot's nearest neighbours (knn) were read, and whether the previous one's
        # were: a batch answers them ahead (prefetch) for the small worlds whose last tick read them.
        self._knn_read = False
        self._knn_hint = previous._knn_read if previous is not None else False
        self._knn_ahead: tuple[np.ndarray, np.ndarray] | None = None
        # comm_members as bytes, their count, which pairs join two members (mask; indices, or
        # None when every agent is a member)
        self._members_memo: tuple[bytes, int, np.ndarray, np.ndarray | None] | None = (
            previous._members_memo if previous is not None else None)
        self._shared: dict[str, tuple[Hashable, Any]] = {}
        # (lo, size) of the formation's periodic box (a torus), kept from tick to tick; None: plain space
        self.periodic: tuple[np.ndarray, np.ndarray] | None = previous.periodic if previous is not None else None

    def shared(self, name: str, params: Hashable, compute: Callable[[], T]) -> T:
        """Derived data several plugins need this tick, computed once by the first caller.

        The thesis' formation and avoidance terms both read the graph G_sigma, for example: the
        first asks ``shared("thesis.indoor_snapshot", params, build)`` and builds it, the second
        gets the same object. The memo lives on this tick's Sensing, so it dies with the tick.

        Args:
            name: what the data is (prefix it with the method's name).
            params: the parameters it is computed with. A second caller asking for ``name`` with
                other parameters gets a ``ValueError`` naming both: two plugins would otherwise
                silently disagree about one quantity.
            compute: builds the data (called at most once per tick and name).
        """
        if name in self._shared:
            known, value = self._shared[name]
            if known != params:
                raise ValueError(
                    f"{name} was computed this tick with {known} and is asked for with {params}: "
                    "the plugins sharing it must be configured with the same parameters"
                )
            return value
        value = compute()
        self._shared[name] = (params, value)
        return value

    @per_tick
    def tree(self) -> cKDTree:
        """k-d tree over all agents' positions (failed ones included: they are still obstacles)."""
        return scipy.spatial.cKDTree(self.world.pos)

    def pairs(self, radius: float) -> np.ndarray:
        """Index pairs (i < j, lexicographic) of agents at most ``radius`` m apart, shape (M, 2);
        cached per radius, with their squared lengths.

        Filtered from the list of a larger cached radius when there is one (exact, and cheaper than
        listing again: the separation check reuses the connectivity or flocking pairs); the first
        query lists the pairs at the widest radius the previous tick was asked for.
        """
        self.asked["pairs"] = max(self.asked["pairs"], radius)
        return read_only(self._listed_pairs(radius))

    def _listed_pairs(self, radius: float) -> np.ndarray:
        """:meth:`pairs` without recording the request (a prefetch must not feed its own hint)."""
        if radius not in self._pairs and self._every_pair is not None:
            d2 = self._every_pair[2]  # a few agents: filtered from every pair, as pairs_within does
            near = d2 <= radius * radius
            self._pairs[radius], self._pair_d2[radius] = upper_pair_array(self._n)[near], d2[near]
        if radius not in self._pairs:
            larger = [r for r in self._pairs if r >= radius]
            if larger:
                wide = min(larger)
                keep = self._pair_d2[wide] <= radius * radius
                self._pairs[radius] = self._pairs[wide][keep]
                self._pair_d2[radius] = self._pair_d2[wide][keep]
            else:
                reach = max(radius, self._hint["pairs"])
                self._pairs[reach], self._pair_d2[reach] = pairs_within(self.world.pos, reach)
                return self._listed_pairs(radius)
        return self._pairs[radius]

    @per_tick
    def _every_pair(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Every pair (i < j) and its squared length, listed once per snapshot of at most
        ``DENSE_POINTS`` agents (``None`` for more): the pairs at any radius, the closest pair and
        the communication graph are all read from this one pass (a pass per query cost ~5 us each,
        most of a small swarm's tick)."""
        if self._n > DENSE_POINTS:
            return None
        return dense_pair_dist2(self.world.pos)

    @per_tick
    def min_separation(self) -> float:
        """Smallest distance between two agents, m (``inf`` with fewer than two).

        Free when any pair list is cached and not empty (its closest pair is the closest overall:
        a closer pair would be in it); else from the kNN query if it ran; else ``min_pair_distance``.
        When the previous tick was asked for pairs, they are listed now (the same caller will
        ask again), which makes this free.
        """
        if self._n < 2:
            return float("inf")
        if self._every_pair is not None:  # the closest of every pair: the same sum, so the same bits
            return math.sqrt(np.minimum.reduce(self._every_pair[2]))
        if not self._pairs and self._hint["pairs"] > 0:
            self._listed_pairs(self._hint["pairs"])
        for radius in sorted(self._pairs):
            if len(self._pairs[radius]):
                return float(np.sqrt(self._pair_d2[radius].min()))
        if "knn" in self.__dict__:
            return float(self.knn[0][:, 0].min())
        return min_pair_distance(self.world.pos)

    @per_tick
    def knn(self) -> tuple[np.ndarray, np.ndarray]:
        """Distances and indices of each agent's ``NEAR_K`` nearest others, shape (N, <= NEAR_K).

        One query shared by :attr:`nearest`, the policy observations and, when it ran, the
        separation monitor (column 0 is the nearest other agent); ``inf`` / N mark missing
        neighbours in tiny swarms.
        """
        self._knn_read = True
        if self._knn_ahead is not None:  # answered with the batch's other small worlds (prefetch)
            return self._knn_ahead
        n = self.world.n
        k = min(n, NEAR_K + 1)
        dist, idx = self.tree.query(self.world.pos, k=k)
        dist, idx = dist.reshape(n, k)[:, 1:], idx.reshape(n, k)[:, 1:]  # drop each agent itself
        return dist, idx

    @per_tick
    def nearest(self) -> tuple[np.ndarray, np.ndarray]:
        """For each agent: distance to its nearest other agent (m, ``inf`` if alone) and its index."""
        n = self.world.n
        if n < 2:
            return np.full(n, np.inf), np.full(n, -1)
        dist, idx = self.knn
        return dist[:, 0], idx[:, 0]

    @per_tick
    def clearance(self) -> np.ndarray:
        """Signed distance from each agent to the nearest obstacle, m (``inf`` in open space)."""
        return self.environment.clearance(self.world.pos)

    def clearance_within(self, radius: float) -> np.ndarray:
        """Signed clearance, exact where it is at most ``radius`` m and ``inf`` beyond; cached
        per radius. Much cheaper than :attr:`clearance` near many obstacles: use it whenever only
        nearby obstacles matter (repulsion ranges, safety checks)."""
        if "clearance" in self.__dict__:
            full = self.clearance
            return read_only(np.where(full <= radius, full, np.inf))
        return self.obstacle_nearest(radius)[1]

    def nothing_within(self, radius: float) -> bool:
        """Whether this tick has already shown that no obstacle is within ``radius`` m of any agent
        (a query at that range or wider found none; a batch's ``prefetch`` shows it for the worlds
        far from every obstacle): then :meth:`obstacle_nearest` at ``radius`` finds none. False when
        that is not known; no query is made either way. Counts as asking at ``radius``, as a query
        would (the next tick's first query works at the widest range asked)."""
        self.asked["obstacles"] = max(self.asked["obstacles"], radius)
        return radius <= self._none_within

    def obstacle_nearest(self, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Each agent's nearest obstacle within ``radius`` m: its index in
        ``environment.obstacles`` (-1 beyond) and the signed clearance (``inf`` beyond); cached.

        The first query of a tick works at the widest range the previous tick was asked for;
        narrower requests are filtered from it, exactly. So the safety monitor's horizon and a
        plugin's sensing range, asked in either order, cost one search per tick, and that search
        picks each agent's nearest obstacle among the candidates of a Verlet list
        (:class:`ObstacleCandidates`) instead of walking the obstacle tree.
        """
        self.asked["obstacles"] = max(self.asked["obstacles"], radius)
        return read_only(self._obstacle_nearest(radius))

    def _obstacle_nearest(self, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`obstacle_nearest` on the snapshot's own (writable) arrays."""
        if radius <= self._none_within:  # nothing within a wider range: nothing within this one
            return self._nearest[self._none_within]
        if radius not in self._nearest:
            wider = [r for r in self._nearest if r >= radius]
            if wider:
                index, clearance = self._nearest[min(wider)]
                beyond = clearance > radius
                self._nearest[radius] = (np.where(beyond, -1, index), np.where(beyond, np.inf, clearance))
            else:
                reach = max(radius, self._hint["obstacles"])
                candidates = self._obstacle_candidates(reach)
                if candidates is None or candidates[0].size == 0:  # open space, or none in reach
                    self._none_within = reach
                    index, clearance = _nothing_near(self._n)
                    self._nearest[reach] = (index.copy(), clearance.copy())
                    return self._nearest[reach]
                self._nearest[reach] = self.environment.nearest_obstacle(self.world.pos, reach, candidates)
                return self._obstacle_nearest(radius)
        return self._nearest[radius]

    def _obstacle_candidates(self, reach: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The Verlet list of (agent, obstacle) pairs covering ``reach``, rebuilt when stale."""
        if self.environment.empty:
            return None
        xy = self.world.pos[:, :2]
        if self._candidates is None or not self._candidates.cover(xy, reach):
            radius = reach * (1.0 + OBSTACLE_SKIN)
            self._candidates = ObstacleCandidates(xy.copy(), radius, *self.environment.near_pairs(xy, radius))
        return self._candidates.point, self._candidates.geom

    @per_tick
    def comm_members(self) -> np.ndarray:
        """Agents taking part in communication: healthy and with a working radio."""
        return self.world.healthy & self.world.comm_ok

    @per_tick
    def comm_edges(self) -> np.ndarray:
        """Links (i < j) of the communication graph: pairs within range, both ends members."""
        return self._comm_links[0]

    @per_tick
    def _comm_links(self) -> tuple[np.ndarray, np.ndarray]:
        """:attr:`comm_edges` and their squared lengths (from the pair list's own)."""
        pairs = self.pairs(self.comm_range)
        links = self.comm_members[pairs[:, 0]] & self.comm_members[pairs[:, 1]]
        return pairs[links], self._pair_d2[self.comm_range][links]

    @per_tick
    def comm_adjacency(self) -> csr_matrix:
        """Symmetric sparse adjacency of the communication graph (range ``comm_range``)."""
        n = self.world.n
        edges = self.comm_edges
        i, j = edges[:, 0], edges[:, 1]
        data = np.ones(2 * len(i), dtype=np.int8)
        return scipy.sparse.coo_matrix((data, (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()

    @per_tick
    def comm_connected(self) -> bool:
        """True when the communication graph over its members is connected (one member counts).

        Exact, with no pair list: at most ``DENSE_POINTS`` agents read it from every pair's length
        (:meth:`_few_connected`); up to ``DENSE_LIMIT`` members sweep a dense reachability matrix;
        more are joined by union-find over a compiled cell list, which stops at the first link
        that leaves a single component (1,000 boids in a 20 m range: ~0.2 ms, against ~6 ms for
        listing the ~60,000 links and labelling the components of a sparse matrix). In a periodic
        space every member count takes the wrapping cell list (:meth:`_periodic_connected`).
        """
        if self.periodic is not None:
            return self._periodic_connected()
        if self._every_pair is not None:
            return self._few_connected()
        members = np.flatnonzero(self.comm_members)
        m = members.size
        if m <= 1:
            return True
        if m <= DENSE_LIMIT:
            return _dense_connected(self.world.pos[members], self.comm_range)
        from .cells import disk_graph_connected  # imports numba: only swarms this large pay for it

        return bool(disk_graph_connected(np.ascontiguousarray(self.world.pos[members]), self.comm_range))

    def _periodic_connected(self) -> bool:
        """:attr:`comm_connected` in a periodic space (a torus): links by the minimum-image distance,
        so two agents a range apart across a seam of the box are linked, as they are in the space
        the formation flies (Euclidean distance inside the box split a flock that crossed a seam).
        Union-find over a compiled cell list that wraps (:func:`.cells.torus_disk_graph_connected`,
        whose oracle is scipy's periodic k-d tree: tests/core/test_cells.py), for any number of
        members: at 100 boids ~10 us against ~200 us for the tree's links and a sparse labelling."""
        members = np.flatnonzero(self.comm_members)
        if members.size <= 1:
            return True
        from .cells import torus_disk_graph_connected  # imports numba: only periodic spaces pay for it

        lo, size = cast("tuple[np.ndarray, np.ndarray]", self.periodic)
        return bool(torus_disk_graph_connected(self._folded(members, lo, size), self.comm_range,
                                               np.asarray(size, dtype=float)))

    def _folded(self, members: np.ndarray, lo: np.ndarray, size: np.ndarray) -> np.ndarray:
        """The members' positions (float64, C order) with the periodic axes folded into
        [0, size): ``(p - lo) mod size``. The world's own array, read only, when every agent is a
        member, the box starts at 0 and the wrap phase left every coordinate inside it (the fold
        then changes no bit); a copy otherwise."""
        pos = self.world.pos
        a = lo.size
        if members.size == self.world.n and not lo.any() and pos.dtype == np.float64 \
                and pos.flags.c_contiguous:
            from .cells import inside_box  # a compiled pass: numpy's column min and max cost 0.3 ms at 10,000

            if inside_box(pos, np.asarray(size, dtype=float)):
                return pos
        pos = np.array(pos[members], dtype=float)
        wrapped = np.mod(pos[:, :a] - lo, size)
        pos[:, :a] = np.where(wrapped >= size, 0.0, wrapped)  # rounding can reach size itself
        return pos

    def _few_connected(self) -> bool:
        """:attr:`comm_connected` of a few agents, from :attr:`_every_pair`: a complete graph at once
        (every member within range of every other, the usual case), else by reachability sweeps."""
        members = self.comm_members
        # called only when _every_pair is not None (a few agents); cast: no work per tick
        i, j, d2 = cast("tuple[np.ndarray, np.ndarray, np.ndarray]", self._every_pair)
        key = members.tobytes()  # the members change only with events: their pairs are kept
        if self._members_memo is None or self._members_memo[0] != key:
            m, both = int(np.count_nonzero(members)), members[i] & members[j]
            self._members_memo = (key, m, both, None if m == members.size else np.flatnonzero(both))
        _, m, both, member_pairs = self._members_memo
        if m <= 1:
            return True
        r2 = self.comm_range * self.comm_range
        among = d2 if member_pairs is None else d2.take(member_pairs)
        if np.maximum.reduce(among) <= r2:  # every member in range of every other
            return True
        link = (d2 <= r2) & both
        first = int(np.argmax(members))
        reached = _linked_by_sweeps(self.world.n, i[link], j[link], first)
        return int(reached.sum()) == m

    def comm_spanning_tree(self) -> np.ndarray | None:
        """Links (i, j), shape (m - 1, 2), of a minimum spanning tree of the communication graph
        over its m members, lengths as weights; ``None`` when the graph is not connected.

        Its links are the shortest that keep the members connected, so they are the last to
        stretch out of range: :class:`~swarmscene.core.monitors.ConnectivityCertificate` keeps
        one from tick to tick as a proof of connectivity.
        """
        members = np.flatnonzero(self.comm_members)
        m = members.size
        if m <= 1:
            return np.zeros((0, 2), dtype=np.intp)
        edges = self.comm_edges
        i, j = _renumber(self.world.n, members, edges)
        # csgraph reads a zero weight as a missing link: co-located members weigh a little.
        length = np.maximum(np.sqrt(self._comm_links[1]), 1e-12)
        weights = scipy.sparse.coo_matrix((length, (i, j)), shape=(m, m))
        tree = scipy.sparse.csgraph.minimum_spanning_tree(weights).tocoo()
        if tree.nnz != m - 1:
            return None
        return np.column_stack([members[tree.row], members[tree.col]])

    def hop_distances(self, source: int) -> np.ndarray:
        """Hops from ``source`` to every agent over the communication graph (``inf`` if unreachable)."""
        return scipy.sparse.csgraph.shortest_path(self.comm_adjacency, unweighted=True, indices=source)

    @per_tick
    def comm_graph(self) -> nx.Graph:
        """The communication graph as a networkx graph, for analysis and metrics (not hot loops)."""
        import networkx as nx  # 0.1 s to import: only the analyses that ask for it pay

        graph = nx.Graph()
        graph.add_nodes_from(np.flatnonzero(self.comm_members).tolist())
        rows, cols = self.comm_adjacency.nonzero()
        graph.add_edges_from((int(a), int(b)) for a, b in zip(rows, cols, strict=True) if a < b)
        return graph
