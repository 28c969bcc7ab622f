"""The thesis' indoor method (ch. 5) as one stand-alone loop, outside the engine.

The engine runs the method through the ``indoor_swarm`` formation and the ``potential_barrier``
avoidance, whose per-tick inputs are compiled kernels (``swarmscene.methods.indoor.kernels``);
these oracles are the numpy formulation (the follower law ``follower_input`` and Algorithm 1's
``leader_input``, moved here from the package in issue 20), so the tests can check the plugins
and kernels against them and check the method without the engine.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import Polygon

from oracles.indoor_graphs import nearest_points, neighbour_graph, rank_estimate_step, sigma_graph
from swarmscene.core.environment import nearest_within
from swarmscene.methods.indoor.control import (
    TABLE_5_1,
    IndoorGains,
    IndoorSnapshot,
    PairGeometry,
    psi_col,
    psi_com,
    psi_con,
    w_led,
    w_obs,
)
from swarmscene.methods.indoor.graphs import EdgeList, initial_rank_estimate, virtual_leader
from swarmscene.methods.indoor.sensing import Obstacles, obstacle_tree, saturate


def sense(
    r: np.ndarray, obstacles: Obstacles, g: IndoorGains = TABLE_5_1, tree: cKDTree | None = None
) -> IndoorSnapshot:
    """The numpy sensing of one step (eq. 5.4-5.22): o_i by shapely, G_n and G_sigma by
    :mod:`oracles.indoor_graphs` (the package's ``control.sense`` runs the kernels)."""
    reach = min(g.l_o, g.d_s)
    tree_o = obstacle_tree(obstacles)
    if tree_o is None:
        o, dist = np.full((len(r), 2), np.nan), np.full(len(r), np.inf)
    else:
        index, dist = nearest_within(tree_o, r, reach)
        o = nearest_points(r, tree_o.geometries, index)
    g_n = neighbour_graph(r, tree_o, g.d_n, g.d_l, tree, np.minimum(dist, reach))
    return IndoorSnapshot(r, o, dist, g_n, sigma_graph(r, g_n, g.phi_d, g.deactivation_candidates))


def follower_input(
    r: np.ndarray,
    g_sigma: EdgeList,
    o: np.ndarray,
    l: np.ndarray,  # noqa: E741 (l_i, the virtual leaders: thesis eq. 5.41)
    has_neighbour: np.ndarray,
    g: IndoorGains = TABLE_5_1,
) -> np.ndarray:
    """u_i = sat(w_obs + w_col + w_con + w_com + w_led, u_sat) (thesis eq. 5.30-5.31), all agents.

    The caller overwrites the leader's row with :func:`leader_input`.
    """
    pg = PairGeometry.of(r, g_sigma)
    psi = psi_col(pg.length, g) + psi_con(pg.length, g) + psi_com(pg.length, g)
    w = w_obs(r, o, g) + pg.sum(psi) + w_led(r, l, has_neighbour, g)
    return saturate(w, g.u_sat)


def leader_direction(r_leader: np.ndarray, waypoints: np.ndarray, m: int) -> tuple[np.ndarray, int]:
    """Algorithm 1 of the thesis: unit direction w_N to the target way-point and its index m.

    Advances m while the leader has passed p_m along the next segment,
    (p_{m+1} - p_m)^T (r_N - p_m) >= 0 (0-based indices here). Returns a zero direction once the
    leader sits on the final way-point.
    """
    last = len(waypoints) - 1
    while m < last and np.dot(waypoints[m + 1] - waypoints[m], r_leader - waypoints[m]) >= 0.0:
        m += 1
    d = waypoints[m] - r_leader
    norm = float(np.hypot(d[0], d[1]))
    return (d / norm if norm > 1e-12 else np.zeros(2)), m


def leader_input(
    r: np.ndarray,
    leader: int,
    g_sigma: EdgeList,
    waypoints: np.ndarray,
    m: int,
    g: IndoorGains = TABLE_5_1,
) -> tuple[np.ndarray, int]:
    """u_N = w_N min(u_lsat, u_lcon) (thesis eq. 5.43-5.44, Algorithm 1).

    u_lsat = alpha_lsat u_sat; u_lcon = max(0, alpha_lcon d_n - min_j ||r_j - r_N||) over the
    leader's G_sigma neighbours (0 when it has none: it waits for the swarm). Choice: at the final
    way-point the step is also capped by the remaining distance, so the leader stops on it instead
    of chattering around it.

    Returns:
        u_N: (2,) leader input, m per T_s; m: the new way-point index.
    """
    direction, m = leader_direction(r[leader], waypoints, m)
    src, dst = g_sigma.directed()
    nb = dst[src == leader]  # N_N(G_sigma) as the leader sees it (an ArcList is directed)
    nearest = np.linalg.norm(r[nb] - r[leader], axis=1).min() if nb.size else np.inf
    u_lcon = max(0.0, g.alpha_lcon * g.d_n - nearest)
    magnitude = min(g.alpha_lsat * g.u_sat, u_lcon)
    if m == len(waypoints) - 1:
        magnitude = min(magnitude, float(np.linalg.norm(waypoints[m] - r[leader])))
    return direction * magnitude, m


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
        l_i, has = virtual_leader(r, snap.g_sigma, self.rho_bar)
        u = follower_input(r, snap.g_sigma, snap.o, l_i, has, g)
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
