"""SwarmLab's metrics from neighbour lists and sparse graphs (methods/swarmlab/metrics.py) against a
line-by-line transcription of compute_swarm_performance.m (tests/oracles/swarmlab.py): equal to
1e-9, on random swarms, lattices with ties at the topological cut, coincident agents, a swarm
split in two, and the sparse lambda_2 path of large swarms."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from oracles.swarmlab import compute_neighborhood, distance_matrix, swarm_performance
from scipy.spatial import cKDTree

from swarmscene.methods.swarmlab.metrics import (
    adjacency,
    graph_metrics,
    neighbourhood,
    obstacle_safety,
    order,
    safety,
    union_and_connectivity,
)

TOL = 1e-9


def fast(pos, vel, r, max_neig, r_coll, dense_limit=400):
    tree = cKDTree(pos)
    hood = neighbourhood(pos, r, max_neig, tree)
    union, alg_conn, n_cc = graph_metrics(hood, dense_limit)
    sparse = union_and_connectivity(adjacency(hood), 0)  # the sparse path, whatever the size
    assert sparse[2] == n_cc and abs(sparse[0] - union) <= TOL and abs(sparse[1] - alg_conn) <= TOL
    return safety(pos, r_coll, tree), order(vel, hood), union, alg_conn


def assert_equal_to_definition(pos, vel, r, max_neig, r_coll, dense_limit=400):
    got = fast(pos, vel, r, max_neig, r_coll, dense_limit)
    want = swarm_performance(pos, vel, r, max_neig, r_coll)[:4]
    for name, g, w in zip(("safety", "order", "union", "alg_conn"), got, want, strict=True):
        assert abs(g - w) <= TOL, f"{name}: {g} != {w}"
    return got


def neighbour_matrix(pos, r, max_neig):
    hood = neighbourhood(pos, r, max_neig)
    m = np.zeros((len(pos), len(pos)))
    m[hood.source, hood.target] = 1
    return m


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize(("n", "r", "max_neig", "r_coll"), [(40, 150.0, 10, 0.5), (60, 4.0, 5, 0.8), (25, 3.0, 30, 1.0)])
def test_metrics_equal_the_definition_on_random_swarms(seed, n, r, max_neig, r_coll):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-6, 6, (n, 3))
    vel = rng.normal(size=(n, 3))
    assert_equal_to_definition(pos, vel, r, max_neig, r_coll)


@pytest.mark.parametrize("max_neig", [1, 3, 4, 6, 8])
def test_ties_at_the_topological_cut_go_to_the_lower_index_as_matlab_sorts(max_neig):
    """A cubic lattice: each inner agent has 6 neighbours at exactly the same distance, so the cut
    at max_neig splits ties, which the definition breaks by index (MATLAB's stable sort)."""
    g = np.arange(4) * 2.0
    pos = np.array([[x, y, z] for x in g for y in g for z in g]) + np.array([10.3, -4.7, 1.1])
    vel = np.random.default_rng(1).normal(size=pos.shape)
    np.testing.assert_array_equal(neighbour_matrix(pos, 150.0, max_neig),
                                  compute_neighborhood(distance_matrix(pos), 150.0, max_neig))
    assert_equal_to_definition(pos, vel, 150.0, max_neig, 0.5)


def test_coincident_agents_and_agents_at_rest():
    """Agents on top of each other (distance 0: each is the other's neighbour) and at rest (a
    cosine with a zero velocity counts 0, where the MATLAB divides by zero)."""
    rng = np.random.default_rng(3)
    pos = rng.uniform(-2, 2, (12, 3))
    pos[5] = pos[4]
    pos[9] = pos[4]
    vel = rng.normal(size=(12, 3))
    vel[[0, 4]] = 0.0
    np.testing.assert_array_equal(neighbour_matrix(pos, 150.0, 3), compute_neighborhood(distance_matrix(pos), 150.0, 3))
    _, got_order, _, _ = assert_equal_to_definition(pos, vel, 150.0, 3, 0.5)
    assert 0.0 < got_order < 1.0


def test_a_swarm_split_in_two_has_union_of_its_components_and_no_connectivity():
    rng = np.random.default_rng(4)
    pos = np.vstack([rng.uniform(0, 3, (10, 3)), rng.uniform(100, 103, (7, 3))])
    vel = rng.normal(size=pos.shape)
    got_safety, _, union, alg_conn = assert_equal_to_definition(pos, vel, 10.0, 10, 0.5)
    assert union == pytest.approx((17 - 2) / 16) and alg_conn == 0.0


def test_safety_counts_the_pairs_closer_than_twice_r_coll():
    """Three agents on a line 0.9 m and 1.1 m apart, r_coll = 0.5: one pair of three is closer than
    1 m, so S = 1 - 1/3; a pair exactly 2 r_coll apart does not count (strict, as the MATLAB)."""
    pos = np.array([[0.0, 0, 0], [0.9, 0, 0], [2.0, 0, 0]])
    assert safety(pos, 0.5) == pytest.approx(1 - 1 / 3, abs=1e-15)
    assert safety(np.array([[0.0, 0, 0], [1.0, 0, 0]]), 0.5) == 1.0
    assert safety(pos[:1], 0.5) == 1.0


def test_order_of_a_swarm_flying_one_way_is_one_and_of_opposed_pairs_minus_one():
    pos = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    hood = neighbourhood(pos, 150.0, 10)
    assert order(np.array([[1.0, 0, 0], [2.0, 0, 0]]), hood) == pytest.approx(1.0)
    assert order(np.array([[1.0, 0, 0], [-3.0, 0, 0]]), hood) == pytest.approx(-1.0)


@pytest.mark.parametrize("seed", range(2))
def test_sparse_lambda_2_equals_the_dense_eigenvalues(seed):
    """Above the dense limit lambda_2 comes from shift-invert Lanczos on the sparse Laplacian: the
    same value as every eigenvalue of the dense one."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 12, (300, 3))
    vel = rng.normal(size=pos.shape)
    got = assert_equal_to_definition(pos, vel, 150.0, 8, 0.5, dense_limit=50)
    assert got[3] > 0  # connected: a non-trivial lambda_2 was compared


def test_obstacle_safety_and_clearance_of_a_map_against_each_obstacle():
    """S_obs counts (agent, obstacle) pairs with the agent inside; per-obstacle shapely tests as
    the oracle. None without obstacles (the MATLAB writes 0)."""
    obstacles = [shapely.Point(0, 0).buffer(1.0), shapely.box(3, 3, 5, 5)]
    xy = np.array([[0.2, 0.1], [4.0, 4.5], [10.0, 0.0], [0.9, 0.0], [4.9, 3.1]])
    inside = np.array([[shapely.contains_xy(g, x, y) for g in obstacles] for x, y in xy])
    assert inside.sum() == 4
    assert obstacle_safety(int(inside.sum()), len(xy), len(obstacles)) == pytest.approx(1 - 4 / 10)
    assert obstacle_safety(0, 5, 0) is None
