"""Environment queries against independent geometry, and the shared k-d tree against brute force."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Point, box

from swarmscene.core.environment import Environment
from swarmscene.core.sensing import Sensing
from swarmscene.core.state import WorldState


@pytest.fixture
def env():
    # A unit-radius pillar at the origin and a 2 m x 1 m block at x in [4, 6], y in [-0.5, 0.5].
    return Environment([Point(0, 0).buffer(1.0, quad_segs=256), box(4, -0.5, 6, 0.5)])


def test_clearance_is_signed_distance(env):
    pts = np.array([[3.0, 0.0, 5.0], [0.0, 2.0, 0.0], [0.5, 0.0, 0.0], [5.0, 0.0, 0.0], [5.0, 2.5, 0.0]])
    expected = [1.0, 1.0, -0.5, -0.5, 2.0]
    assert env.clearance(pts) == pytest.approx(expected, abs=1e-4)


def test_nearest_point(env):
    pts = np.array([[3.0, 0.0], [0.0, -3.0], [5.0, 3.0]])
    expected = [[4.0, 0.0], [0.0, -1.0], [5.0, 0.5]]
    assert env.nearest_point(pts) == pytest.approx(np.array(expected), abs=1e-4)


def test_line_of_sight_and_clearance(env):
    a = np.array([[-3.0, 0.0], [-3.0, 1.5], [2.0, 1.0], [2.0, -2.0]])
    b = np.array([[3.0, 0.0], [3.0, 1.5], [8.0, 1.0], [2.0, 2.0]])
    assert env.line_of_sight(a, b).tolist() == [False, True, True, True]
    # With 0.6 m clearance the segment 0.5 m from the block and the pillar is blocked.
    assert env.line_of_sight(a, b, clearance=0.6).tolist() == [False, False, False, True]


def test_empty_environment():
    env = Environment()
    assert np.isinf(env.clearance(np.zeros((3, 3)))).all()
    assert env.line_of_sight(np.zeros((2, 2)), np.ones((2, 2))).all()
    assert not env.contains(np.zeros((2, 2))).any()


def test_sensing_pairs_nearest_and_connectivity_match_brute_force():
    rng = np.random.default_rng(3)
    pos = rng.uniform(0, 20, size=(300, 3))
    world = WorldState.at_rest(pos)
    sensing = Sensing(world, Environment(), comm_range=3.0)
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    i, j = np.nonzero(np.triu(d < 2.0, k=1))
    assert sorted(map(tuple, sensing.pairs(2.0).tolist())) == sorted(zip(i.tolist(), j.tolist(), strict=True))
    np.fill_diagonal(d, np.inf)
    assert sensing.nearest[0] == pytest.approx(d.min(axis=1))
    import networkx as nx

    graph = nx.Graph()
    graph.add_nodes_from(range(300))
    graph.add_edges_from(zip(*np.nonzero(d < 3.0), strict=True))
    assert sensing.comm_connected == nx.is_connected(graph)
    assert nx.utils.graphs_equal(sensing.comm_graph, graph)
    hops = sensing.hop_distances(0)
    expected = nx.single_source_shortest_path_length(graph, 0)
    assert all(hops[k] == v for k, v in expected.items())


@pytest.mark.parametrize("n", [5, 60, 400])
def test_connectivity_matches_networkx_small_and_large(n):
    import networkx as nx

    rng = np.random.default_rng(n)
    for radius in (1.5, 3.0, 6.0):
        pos = rng.uniform(0, np.sqrt(n) * 2.0, size=(n, 3)) * [1, 1, 0]
        world = WorldState.at_rest(pos)
        world.comm_ok[0] = False  # non-members are ignored
        members = np.arange(1, n)
        d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
        graph = nx.Graph()
        graph.add_nodes_from(members)
        graph.add_edges_from((a, b) for a, b in zip(*np.nonzero(d <= radius), strict=True) if a in members and b in members and a != b and a > 0 and b > 0)
        assert Sensing(world, Environment(), comm_range=radius).comm_connected == nx.is_connected(graph)


def test_bounded_clearance_is_exact_inside_its_range(env):
    pts = np.array([[3.0, 0.0], [0.0, 2.0], [0.5, 0.0], [5.0, 2.5], [20.0, 20.0]])
    full = env.clearance(pts)
    bounded = env.clearance(pts, max_distance=1.5)
    near = full < 1.5
    assert bounded[near] == pytest.approx(full[near])
    assert np.isinf(bounded[~near]).all()
    world = WorldState.at_rest(np.column_stack([pts, np.zeros(5)]))
    sensing = Sensing(world, env, comm_range=3.0)
    assert np.array_equal(sensing.clearance_within(1.5), bounded)
    _ = sensing.clearance  # once the exact array exists, bounded views derive from it
    assert np.array_equal(sensing.clearance_within(1.5), bounded)


def test_nearest_obstacle_index_and_bounded_query_match_brute_force(env):
    rng = np.random.default_rng(5)
    pts = rng.uniform(-3, 9, size=(400, 2))
    index, clearance = env.nearest_obstacle(pts)
    each = np.array([[g.distance(Point(p)) for g in env.obstacles] for p in pts])
    assert index.tolist() == each.argmin(axis=1).tolist()
    outside = clearance > 0
    assert clearance[outside] == pytest.approx(each.min(axis=1)[outside], abs=1e-12)
    assert (clearance[~outside] <= 0).all() and env.contains(pts[~outside]).all()
    b_index, b_clearance = env.nearest_obstacle(pts, max_distance=0.8)
    near = clearance <= 0.8
    assert b_index[near].tolist() == index[near].tolist()
    assert np.array_equal(b_clearance[near], clearance[near])
    assert (b_index[~near] == -1).all() and np.isinf(b_clearance[~near]).all()


def test_one_obstacle_query_per_tick_serves_every_range(env, monkeypatch):
    """Narrower ranges are filtered from the widest one asked, this tick or the last one."""
    rng = np.random.default_rng(6)
    world = WorldState.at_rest(np.column_stack([rng.uniform(-3, 9, size=(200, 2)), np.zeros(200)]))
    calls = []
    query = env.nearest_obstacle
    monkeypatch.setattr(env, "nearest_obstacle", lambda p, r=None, c=None: calls.append(r) or query(p, r, c))
    first = Sensing(world, env, comm_range=3.0)
    narrow, wide = first.obstacle_nearest(0.5), first.obstacle_nearest(0.7)
    assert calls == [0.5, 0.7]
    for radius, (idx, clr) in ((0.5, narrow), (0.7, wide)):
        direct_idx, direct_clr = query(world.pos, radius)
        assert np.array_equal(idx, direct_idx) and np.array_equal(clr, direct_clr)
    second = Sensing(world, env, comm_range=3.0, previous=first)
    again = second.obstacle_nearest(0.5), second.obstacle_nearest(0.7), second.clearance_within(0.3)
    assert calls == [0.5, 0.7, 0.7]  # the second tick asks the tree once, at 0.7 m
    assert np.array_equal(again[0][1], narrow[1]) and np.array_equal(again[1][0], wide[0])
    assert np.array_equal(again[2], np.where(narrow[1] <= 0.3, narrow[1], np.inf))


def test_pairs_of_the_previous_ticks_range_are_listed_once_and_give_the_separation(monkeypatch):
    import swarmscene.core.sensing as sensing_module

    rng = np.random.default_rng(8)
    world = WorldState.at_rest(rng.uniform(0, 10, size=(150, 3)))
    d = np.linalg.norm(world.pos[:, None] - world.pos[None], axis=2)
    first = Sensing(world, Environment(), comm_range=3.0)
    first.pairs(1.5)
    second = Sensing(world, Environment(), comm_range=3.0, previous=first)
    walks = []
    listed = sensing_module.pairs_within
    monkeypatch.setattr(sensing_module, "pairs_within", lambda pos, r: walks.append(r) or listed(pos, r))
    np.fill_diagonal(d, np.inf)
    assert second.min_separation == pytest.approx(d.min())  # listed at 1.5 m for the caller to come
    for radius in (1.5, 0.7):
        i, j = np.nonzero(np.triu(d <= radius, k=1))
        assert sorted(map(tuple, second.pairs(radius).tolist())) == sorted(zip(i.tolist(), j.tolist(), strict=True))
    assert walks == [1.5]


def test_a_prefetch_does_not_keep_itself_alive():
    """Pairs listed for the separation only (nobody asked) are not listed again on the next tick."""
    world = WorldState.at_rest(np.random.default_rng(9).uniform(0, 10, size=(100, 3)))
    first = Sensing(world, Environment(), comm_range=3.0)
    first.pairs(2.0)
    second = Sensing(world, Environment(), comm_range=3.0, previous=first)
    _ = second.min_separation
    assert list(second._pairs) == [2.0]
    third = Sensing(world, Environment(), comm_range=3.0, previous=second)
    _ = third.min_separation
    assert third._pairs == {} and third.min_separation == pytest.approx(second.min_separation)


def test_obstacle_candidates_carried_between_ticks_give_the_exact_nearest(env, monkeypatch):
    """The Verlet list: exact at every tick, and the tree is walked only when agents moved far."""
    rng = np.random.default_rng(12)
    world = WorldState.at_rest(np.column_stack([rng.uniform(-2, 8, size=(80, 2)), np.zeros(80)]))
    walks = []
    near_pairs = env.near_pairs
    monkeypatch.setattr(env, "near_pairs", lambda p, r: walks.append(r) or near_pairs(p, r))
    sensing = None
    for _ in range(40):
        world.pos[:, :2] += rng.normal(0, 0.01, size=(80, 2))
        sensing = Sensing(world, env, comm_range=3.0, previous=sensing)
        index, clearance = sensing.obstacle_nearest(0.7)
        direct_index, direct_clearance = env.nearest_obstacle(world.pos, 0.7)
        assert np.array_equal(index, direct_index) and np.array_equal(clearance, direct_clearance)
    assert 1 <= len(walks) < 20  # ~0.03 m per tick against a 0.175 m margin


def test_distance_of_a_point_set_is_its_smallest_clearance(env):
    pts = np.array([[3.0, 0.0], [0.0, 2.5], [5.0, 2.5], [-4.0, -4.0]])
    assert env.distance(pts) == pytest.approx(env.clearance(pts).min(), abs=1e-12)
    assert env.distance(np.array([[5.0, 0.0], [9.0, 9.0]])) == 0.0  # one inside the block
    assert Environment().distance(pts) == np.inf
