"""Issue 20: the compiled per-tick kernels of the indoor swarm against their numpy oracle.

Graphs must be the same edge for edge (and in the same order) under every reading of eq.
5.15-5.16; obstacle points, line of sight, inputs and ranks the same to the bit (the kernels keep
numpy's arithmetic order, see methods/indoor/kernels.py). Random swarms in the corridor, L and
building maps, the walls both as the maps' line segments and as the engine's wall polygons.
"""

from dataclasses import replace

import numpy as np
import pytest
import shapely
from oracles import indoor_graphs as oracle
from oracles.indoor import leader_input
from shapely import STRtree

from swarmscene.methods.indoor.control import (
    TABLE_5_1,
    IndoorSnapshot,
    avoidance_terms,
    formation_step,
    psi_com,
    psi_con,
    w_col,
    w_led,
    w_obs,
)
from swarmscene.methods.indoor.graphs import (
    DEACTIVATION_CANDIDATES,
    EdgeList,
    deactivation_rules,
    max_rank,
    rank_estimate_step,
    tick_graphs,
    virtual_leader,
)
from swarmscene.methods.indoor.maps import building, l_corridor, straight_corridor
from swarmscene.methods.indoor.sensing import nearest_obstacle, nearest_points, sensing_pairs

G = TABLE_5_1
MAPS = {"corridor": straight_corridor(0.7), "l_corridor": l_corridor(0.8), "building": building()}


def _obstacles(mp, polygons):
    """The map's walls as segments, or as the engine's 0.1 m wall polygons."""
    return STRtree(mp.wall_polygons() if polygons else mp.walls)


def _swarm(mp, seed, n=None):
    """Agents strewn over the free space, ~2 per m^2 (mean degree ~6), many near walls."""
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = mp.free_space.bounds
    if mp.name == "building":  # the start hall, the corridor mouth and the ring corridor's corner
        x0, y0, x1, y1 = 0.0, 12.0, 14.0, 22.0
    n = n or (300 if mp.name == "building" else 160)
    r = rng.uniform((x0, y0), (x1, y1), size=(40 * n, 2))
    r = r[shapely.contains_xy(mp.free_space, r[:, 0], r[:, 1])]
    return r[:n]


CASES = [(name, seed, polygons) for name in MAPS for seed in range(2) for polygons in (False, True)]


@pytest.mark.parametrize("name, seed, polygons", CASES)
def test_graphs_equal_the_numpy_oracle_under_every_reading(name, seed, polygons):
    mp = MAPS[name]
    r = _swarm(mp, seed)
    walls = _obstacles(mp, polygons)
    _, dist = oracle_nearest(r, walls)
    clearance = np.minimum(dist, G.l_o)
    g_n_oracle = oracle.neighbour_graph(r, walls, G.d_n, G.d_l, clearance=clearance)
    assert len(g_n_oracle) > 2 * len(r)  # dense: both rules fire (checked below)
    for reading in DEACTIVATION_CANDIDATES:
        g_n, g_sigma = tick_graphs(r, walls, G.d_n, G.d_l, G.phi_d, reading, clearance=clearance)
        np.testing.assert_array_equal(g_n.i, g_n_oracle.i)
        np.testing.assert_array_equal(g_n.j, g_n_oracle.j)
        expect = oracle.sigma_graph(r, g_n_oracle, G.phi_d, reading)
        assert type(g_sigma) is type(expect)
        np.testing.assert_array_equal(g_sigma.i, expect.i)
        np.testing.assert_array_equal(g_sigma.j, expect.j)
        assert len(g_sigma) < len(g_n) if reading != "directed" else len(g_sigma) < 2 * len(g_n)
        # The arc layout the kernel fills in is the one EdgeList would compute.
        fresh = type(expect)(expect.n, expect.i, expect.j)
        for got, want in zip(g_sigma.directed(), fresh.directed(), strict=True):
            np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(g_sigma.indptr, fresh.indptr)
        for perspective in ("i", "j"):
            got = deactivation_rules(r, g_n, G.phi_d, perspective, reading)
            want = oracle.deactivation_rules(r, g_n_oracle, G.phi_d, perspective, reading)
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])


@pytest.mark.parametrize("name", list(MAPS))
def test_line_of_sight_without_certificates_equals_shapely(name):
    mp = MAPS[name]
    for polygons in (False, True):
        walls = _obstacles(mp, polygons)
        r = _swarm(mp, 7)
        got = sensing_pairs(r, G.d_s, walls, G.d_l)
        want = oracle.sensing_pairs(r, G.d_s, walls, G.d_l)
        assert set(map(tuple, got.tolist())) == set(map(tuple, want.tolist()))
        assert 0 < len(got) < len(oracle.candidate_pairs(r, G.d_s))  # walls block some


def oracle_nearest(r, walls):
    """Nearest obstacle within l_o by the engine's bounded search and shapely's nearest points."""
    from swarmscene.core.environment import nearest_within

    index, dist = nearest_within(walls, r, G.l_o)
    return oracle.nearest_points(r, walls.geometries, index), dist


@pytest.mark.parametrize("polygons", [False, True])
def test_nearest_obstacle_points_equal_shapely_to_the_bit(polygons):
    mp = building()
    walls = _obstacles(mp, polygons)
    rng = np.random.default_rng(3)
    r = rng.uniform((-0.5, -0.5), (28.5, 22.5), size=(4000, 2))  # inside walls too (polygons)
    index, _ = __import__("swarmscene.core.environment", fromlist=["x"]).nearest_within(walls, r, 1.0)
    assert (index >= 0).sum() > 1000
    np.testing.assert_array_equal(nearest_points(r, walls.geometries, index),
                                  oracle.nearest_points(r, walls.geometries, index))
    o, dist = nearest_obstacle(r, walls, 1.0)
    np.testing.assert_array_equal(o, oracle.nearest_points(r, walls.geometries, index))


def _oracle_formation(snap, rho_bar, leader, waypoints, m, g):
    """The formation plugin's numpy tick before issue 20: w_con + w_com + w_led, the leader's row."""
    l_i, has = virtual_leader(snap.r, snap.g_sigma, rho_bar)
    pg = snap.pair_geometry
    w = pg.sum(psi_con(pg.length, g) + psi_com(pg.length, g)) + w_led(snap.r, l_i, has, g)
    w[leader], m = leader_input(snap.r, leader, snap.g_sigma, waypoints, m, g)
    return w, m, oracle.rank_estimate_step(rho_bar, snap.g_sigma, leader)


@pytest.mark.parametrize("reading", DEACTIVATION_CANDIDATES)
@pytest.mark.parametrize("name", ["corridor", "building"])
def test_inputs_and_ranks_equal_the_numpy_oracle_to_the_bit(name, reading):
    mp = MAPS[name]
    g = replace(G, deactivation_candidates=reading)
    walls = _obstacles(mp, True)
    rng = np.random.default_rng(11)
    r = _swarm(mp, 5, n=120)
    o, dist = oracle_nearest(r, walls)
    g_n, g_sigma = tick_graphs(r, walls, g.d_n, g.d_l, g.phi_d, reading, clearance=np.minimum(dist, g.l_o))
    snap = IndoorSnapshot(r, o, dist, g_n, g_sigma)
    assert np.isfinite(o[:, 0]).sum() > 10  # agents near walls: w_obs acts
    # Ranks mid-way through their convergence, so surrogate leaders differ from agent to agent.
    rho_bar = rng.integers(0, 6, size=len(r))
    rho_bar[0] = 0
    for m in (0, 5, len(mp.waypoints) - 1):  # Algorithm 1 at its start, mid-path and at the end
        got = formation_step(snap, rho_bar, 0, mp.waypoints, m, g)
        want = _oracle_formation(snap, rho_bar, 0, mp.waypoints, m, g)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1] == want[1]
        np.testing.assert_array_equal(got[2], want[2])
    np.testing.assert_array_equal(avoidance_terms(snap, g), w_obs(r, o, g) + w_col(r, snap.pair_geometry, g))
    np.testing.assert_array_equal(rank_estimate_step(rho_bar, g_sigma, 0),
                                  oracle.rank_estimate_step(rho_bar, g_sigma, 0))


@pytest.mark.parametrize("seed", range(4))
def test_max_rank_equals_the_scipy_oracle(seed):
    rng = np.random.default_rng(seed)
    n = 60
    pairs = rng.integers(0, n, size=(70 + 20 * seed, 2))
    pairs = np.unique(np.sort(pairs[pairs[:, 0] != pairs[:, 1]], axis=1), axis=0)
    graph = EdgeList.from_pairs(n, pairs)
    for leader in (0, 17):
        got, want = max_rank(graph, leader), oracle.max_rank(graph, leader)
        assert got[0] == want[0]
        np.testing.assert_array_equal(got[1], want[1])


@pytest.mark.parametrize("reading", DEACTIVATION_CANDIDATES)
def test_engine_snapshot_path_equals_the_oracle(reading):
    """sense_indexed (the plugins' path: the engine's nearest-obstacle index, o_i and both graphs
    in one call) gives the oracle's o_i to the bit and its graphs edge for edge."""
    from swarmscene.core.environment import nearest_within
    from swarmscene.methods.indoor.control import sense_indexed
    from swarmscene.methods.indoor.sensing import kernel_obstacles

    mp = MAPS["l_corridor"]
    g = replace(G, deactivation_candidates=reading)
    walls = _obstacles(mp, True)
    r = _swarm(mp, 9)
    index, dist = nearest_within(walls, r, g.l_o)
    pairs = oracle.candidate_pairs(r, g.d_n)
    snap = sense_indexed(r, kernel_obstacles(walls), g, index, dist, pairs)
    np.testing.assert_array_equal(snap.o, oracle.nearest_points(r, walls.geometries, index))
    g_n = oracle.neighbour_graph(r, walls, g.d_n, g.d_l, clearance=np.minimum(dist, g.l_o), candidates=pairs)
    g_sigma = oracle.sigma_graph(r, g_n, g.phi_d, reading)
    for got, want in ((snap.g_n, g_n), (snap.g_sigma, g_sigma)):
        np.testing.assert_array_equal(got.i, want.i)
        np.testing.assert_array_equal(got.j, want.j)
