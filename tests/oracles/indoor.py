"""The thesis' indoor method (ch. 5) as one stand-alone loop, outside the engine.

The engine runs the method through the ``indoor_swarm`` formation and the ``potential_barrier``
avoidance; these oracles run the same numerics of ``swarmscene.methods.indoor`` directly, so the
tests can check the plugins against them and check the method without the engine.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import Polygon

from swarmscene.methods.indoor.control import (
    TABLE_5_1,
    IndoorGains,
    IndoorSnapshot,
    follower_input,
    leader_input,
    sense,
)
from swarmscene.methods.indoor.graphs import (
    EdgeList,
    initial_rank_estimate,
    rank_estimate_step,
    virtual_leader,
)
from swarmscene.methods.indoor.sensing import Obstacles, obstacle_tree


class IndoorController:
    """One guidance step of the whole indoor swarm: sensing, graphs, ranks, follower and leader laws.

    Holds the two pieces of state the method carries between steps: the rank estimates rho_bar
    (eq. 5.26) and the leader's way-point index m (Algorithm 1).

    Args:
        n: number of agents N.
        leader: index of the leader (the thesis' agent N).
        waypoints: (n_wp, 2) leader path P, m.
        obstacles: geometries or their STRtree.
        gains: parameters (Table 5.1 by default).
    """

    def __init__(
        self,
        n: int,
        leader: int,
        waypoints: np.ndarray,
        obstacles: Obstacles,
        gains: IndoorGains = TABLE_5_1,
    ) -> None:
        self.n, self.leader, self.gains = n, leader, gains
        self.waypoints = np.asarray(waypoints, dtype=float)
        self.obstacles = obstacle_tree(obstacles)
        self.rho_bar = initial_rank_estimate(n, leader)
        self.m = 0
        self.g_n: EdgeList | None = None
        self.g_sigma: EdgeList | None = None

    def input(self, r: np.ndarray, tree: cKDTree | None = None) -> np.ndarray:
        """The inputs u(k) (N, 2), m per T_s, for positions r(k) (N, 2); advances rho_bar and m.

        ``tree`` is an optional prebuilt cKDTree over the positions (the engine's shared tree).
        """
        return self.input_from(sense(r, self.obstacles, self.gains, tree))

    def input_from(self, snap: IndoorSnapshot) -> np.ndarray:
        """As :meth:`input`, from an already computed :class:`IndoorSnapshot`."""
        g, r = self.gains, snap.r
        self.g_n, self.g_sigma = snap.g_n, snap.g_sigma
        l, has = virtual_leader(r, snap.g_sigma, self.rho_bar)
        u = follower_input(r, snap.g_sigma, snap.o, l, has, g)
        u[self.leader], self.m = leader_input(r, self.leader, snap.g_sigma, self.waypoints, self.m, g)
        self.rho_bar = rank_estimate_step(self.rho_bar, snap.g_sigma, self.leader)
        return u


def random_connected_swarm(
    region: Polygon,
    n: int,
    rng: np.random.Generator,
    min_separation: float = 0.4,
    max_link: float = 0.9,
    anchor: np.ndarray | None = None,
    batch: int = 16,
) -> np.ndarray:
    """A random swarm of ``n`` agents in ``region`` whose disc graph of radius ``max_link`` is connected.

    Random eligible initial state of section 5.4: each new agent is drawn at a distance in
    [min_separation, max_link] from a random earlier agent, and kept if it lies in ``region`` and
    at least ``min_separation`` from every agent (so eq. 5.2 holds with d_c <= min_separation).
    With max_link < d_n and a convex region (or one whose links cannot cross a wall) G_n is
    connected. This runs once per scenario (a loop over agents, not on a per-step path).

    Args:
        region: where agents may be placed.
        n: number of agents.
        rng: the random generator (seeded by the caller).
        min_separation: minimum inter-agent distance, m.
        max_link: maximum distance to the agent it is attached to, m.
        anchor: (2,) first agent's position; a random point of ``region`` by default.
        batch: candidates drawn at once (the first admissible one is kept).

    Returns:
        (n, 2) positions, m.
    """
    minx, miny, maxx, maxy = region.bounds
    if anchor is None:
        while True:
            anchor = rng.uniform((minx, miny), (maxx, maxy))
            if region.contains(shapely.points(anchor)):
                break
    r = np.empty((n, 2))
    r[0] = anchor
    count = 1
    for _ in range(200 * n):  # batches; one agent is accepted per batch, growing outward
        if count == n:
            return r
        parent = r[rng.integers(count, size=batch)]
        rho = rng.uniform(min_separation, max_link, size=batch)
        theta = rng.uniform(0.0, 2.0 * np.pi, size=batch)
        cand = parent + rho[:, None] * np.column_stack([np.cos(theta), np.sin(theta)])
        cand = cand[shapely.contains_xy(region, cand[:, 0], cand[:, 1])]
        if len(cand):
            gap = np.linalg.norm(cand[:, None, :] - r[None, :count, :], axis=2).min(axis=1)
            ok = np.flatnonzero(gap >= min_separation)
            if ok.size:
                r[count] = cand[ok[0]]
                count += 1
    if count < n:
        raise ValueError(f"cannot place {n} agents in the region (placed {count})")
    return r
