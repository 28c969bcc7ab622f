"""Hexagonal formation pattern and slot assignment (thesis section 4.3.2, eq. 4.3-4.14, Fig. 4.8)."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from swarmscene.methods.outdoor.hex_pattern import (
    assign_offsets,
    assignment_cost,
    corner_distance,
    dual_basis,
    formation_graph,
    hex_pattern,
    hex_to_ne_matrix,
    max_offsets,
    max_radius,
    ne_to_hex_matrix,
    pruning_threshold,
    slot_positions,
    solve_assignment,
    topological_distance,
)

D_R = 5.0  # Table 4.3


# --- pattern size ------------------------------------------------------------------------------


def test_n40_gives_fig_4_8_sizes():
    p = hex_pattern(40, D_R)
    assert (p.rho_max, p.m_max, p.chi, p.m) == (4, 60, 2, 42)
    # The kept outer-ring nodes are the six edge centres (kappa = floor(rho_max / 2) = 2).
    outer = p.axial[p.periphery]
    assert outer.shape[0] == 6
    assert np.all(corner_distance(outer) == 2)


@pytest.mark.parametrize("n", range(2, 201))
def test_pattern_holds_every_follower_with_at_most_11_spare(n):
    p = hex_pattern(n, D_R)
    assert p.m >= n - 1
    assert p.m - n + 1 <= 11
    # chi >= 1 removes 12 chi - 6 outer nodes; chi = 0 removes none.
    spare = (p.m_max - n + 7) % 12 if p.chi >= 1 else p.m_max - n + 1
    assert p.m - n + 1 == spare
    assert len({tuple(a) for a in p.axial.tolist()}) == p.m  # no duplicate offsets
    assert np.all(topological_distance(p.axial) >= 1)  # the leader's node is never an offset


def test_max_radius_matches_eq_4_8_and_is_exact_on_full_hexagons():
    for n in range(2, 400):
        rho = max_radius(n)
        assert 3 * rho * (rho + 1) >= n - 1 > 3 * (rho - 1) * rho
        closed_form = int(np.ceil(np.sqrt(0.25 + (n - 1) / 3) - 0.5 - 1e-12))
        assert rho == closed_form
    # N - 1 = 3 rho (rho + 1): a full hexagon, no extra ring, no pruning.
    for rho in (1, 2, 3, 4):
        n = 3 * rho * (rho + 1) + 1
        assert max_radius(n) == rho and max_offsets(n) == n - 1 and pruning_threshold(n) == 0


def test_pruning_removes_nodes_nearest_the_corners_first():
    p = hex_pattern(40, D_R)
    full = hex_pattern(3 * 4 * 5 + 1, D_R)  # same rho_max, nothing pruned
    removed = {tuple(a) for a in full.axial.tolist()} - {tuple(a) for a in p.axial.tolist()}
    removed = np.array(sorted(removed))
    assert removed.shape[0] == 18
    assert np.all(topological_distance(removed) == 4)
    assert np.all(corner_distance(removed) < 2)
    # They are the farthest from the leader: every kept offset is at least as close as any removed.
    assert np.linalg.norm(p.offsets_ne, axis=1).max() <= np.linalg.norm(
        removed @ hex_to_ne_matrix(D_R).T, axis=1
    ).min() + 1e-9


# --- frames --------------------------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [0.0, 0.3, -2.0])
def test_axial_frame_transforms_are_inverse_and_dual(alpha):
    t_ho, t_oh = hex_to_ne_matrix(D_R, alpha), ne_to_hex_matrix(D_R, alpha)
    np.testing.assert_allclose(t_oh @ t_ho, np.eye(2), atol=1e-12)
    x_dual, y_dual = dual_basis(D_R, alpha)
    np.testing.assert_allclose(np.vstack([x_dual, y_dual]), t_oh, atol=1e-12)
    # Offsets are integer points of the axial frame and exactly d_r apart from the leader on ring 1.
    p = hex_pattern(40, D_R, alpha)
    np.testing.assert_allclose(p.offsets_ne @ t_oh.T, p.axial, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(p.offsets_ne[p.rho == 1], axis=1), D_R)


def test_formation_yaw_and_world_frame():
    # alpha = 0: x_h points North, i.e. world +y; alpha = 90 deg: x_h points East, world +x.
    p0 = hex_pattern(7, D_R, 0.0)
    p90 = hex_pattern(7, D_R, np.pi / 2)
    i = int(np.flatnonzero((p0.axial == [1, 0]).all(axis=1))[0])
    np.testing.assert_allclose(p0.offsets_xy[i], [0.0, D_R], atol=1e-12)
    np.testing.assert_allclose(p90.offsets_xy[i], [D_R, 0.0], atol=1e-12)
    # y_h is x_h turned 60 deg from North towards East (clockwise seen from above in z-up).
    j = int(np.flatnonzero((p0.axial == [0, 1]).all(axis=1))[0])
    np.testing.assert_allclose(p0.offsets_xy[j], [D_R * np.sqrt(3) / 2, D_R / 2], atol=1e-12)


# --- formation graph ------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 8, 19, 40, 97])
def test_graph_edges_are_exactly_d_r_and_cover_every_lattice_neighbour(n):
    p = hex_pattern(n, D_R, 0.4)
    g = formation_graph(p)
    assert g.number_of_nodes() == p.m + 1 and nx.is_connected(g)
    lengths = np.array([d["length"] for *_, d in g.edges(data=True)])
    np.testing.assert_allclose(lengths, D_R, rtol=0, atol=1e-9)
    xy = np.array([g.nodes[k]["xy"] for k in range(p.m + 1)])
    close = np.argwhere(np.abs(np.linalg.norm(xy[:, None] - xy[None], axis=2) - D_R) < 1e-6)
    assert {tuple(sorted(e)) for e in close.tolist()} == {tuple(sorted(e)) for e in g.edges}
    assert max(dict(g.degree).values()) <= 6


def test_topological_distance_is_hop_count_on_full_hexagon():
    p = hex_pattern(37, D_R)  # rho_max = 3, nothing pruned: min degree 3, max 6
    g = formation_graph(p)
    degrees = dict(g.degree).values()
    assert min(degrees) == 3 and max(degrees) == 6
    hops = dict(nx.all_pairs_shortest_path_length(g))
    axial = {k: np.array(g.nodes[k]["axial"]) for k in g}
    for a, b in itertools.combinations(g.nodes, 2):
        assert topological_distance(axial[a], axial[b]) == hops[a][b]


# --- assignment ---------------------------------------------------------------------------------

EQ_4_14 = np.array(
    [[10, 10, 13, 12, 14], [19, 18, 16, 19, 17], [8, 7, 9, 8, 10], [15, 17, 14, 18, 19]]
)


def test_worked_example_eq_4_14_reaches_its_minimal_cost():
    cols = solve_assignment(EQ_4_14)
    assert EQ_4_14[np.arange(4), cols].sum() == 48
    assert tuple(cols) == (0, 4, 1, 2)  # the bold matching of eq. 4.20 (the unique optimum)
    brute = min(
        sum(EQ_4_14[i, c] for i, c in enumerate(perm)) for perm in itertools.permutations(range(5), 4)
    )
    assert brute == 48
    # The square form of eq. 4.13 (one dummy zero row) has the same optimum.
    rows, cols_sq = linear_sum_assignment(np.vstack([EQ_4_14, np.zeros(5, dtype=int)]))
    assert np.vstack([EQ_4_14, np.zeros(5, dtype=int)])[rows, cols_sq].sum() == 48


def test_penalty_moved_to_dummy_rows_keeps_the_optimum():
    rng = np.random.default_rng(3)
    for _ in range(50):
        k, m = rng.integers(1, 6), rng.integers(6, 9)
        dist = rng.integers(0, 30, size=(k, m))
        penalty = rng.choice([0, 25], size=m)
        cost = dist + penalty
        cols = solve_assignment(cost, penalty)
        assert len(set(cols.tolist())) == k
        r, c = linear_sum_assignment(cost)
        assert cost[np.arange(k), cols].sum() == cost[r, c].sum()


def test_cost_is_eq_4_12_in_decimetres():
    p = hex_pattern(8, D_R)
    leader = np.array([10.0, -3.0, 4.0])
    followers = np.array([[10.0, -3.0], [12.34, 1.0]])
    cost = assignment_cost(p, followers, leader)
    expected = np.linalg.norm(p.offsets_xy + leader[:2] - followers[:, None], axis=2) + p.periphery_penalty
    np.testing.assert_array_equal(cost, np.rint(expected * 10))
    # Periphery (ring rho_max = 2) offsets carry rho_max d_r = 10 m.
    assert np.all(p.periphery_penalty[p.periphery] == 2 * D_R)


def _square_tie():
    """Two followers equidistant from two slots (the thesis' alternating-square case)."""
    p = hex_pattern(3, D_R)
    s0, s1 = p.offsets_xy[0], p.offsets_xy[1]
    mid, along = (s0 + s1) / 2, (s1 - s0) / np.linalg.norm(s1 - s0)
    normal = np.array([-along[1], along[0]])
    return p, np.array([mid + 0.3 * normal, mid - 0.3 * normal])


def test_assignment_is_deterministic_under_reordering_with_ties():
    p, followers = _square_tie()
    ids = np.array([17, 4])
    leader = np.zeros(3)
    cost = assignment_cost(p, followers, leader)
    assert cost[0, 0] == cost[0, 1] == cost[1, 0] == cost[1, 1]  # a genuine tie
    reference = dict(zip(ids.tolist(), assign_offsets(p, ids, followers, leader).tolist(), strict=True))
    assert len(set(reference.values())) == 2
    for perm in itertools.permutations(range(2)):
        perm = list(perm)
        got = assign_offsets(p, ids[perm], followers[perm], leader)
        assert dict(zip(ids[perm].tolist(), got.tolist(), strict=True)) == reference
    # Sub-decimetre differences between two agents' maps do not change the answer.
    jitter = followers + np.array([[0.01, -0.02], [-0.015, 0.01]])
    assert dict(zip(ids.tolist(), assign_offsets(p, ids, jitter, leader).tolist(), strict=True)) == reference


def test_assignment_with_many_agents_is_order_independent():
    rng = np.random.default_rng(7)
    n = 60
    p = hex_pattern(n, D_R)
    ids = rng.permutation(1000)[: n - 1]
    xy = np.round(rng.uniform(-15, 15, size=(n - 1, 2)), 1)  # decimetre grid: many exact ties
    leader = np.array([1.0, 2.0])
    reference = dict(zip(ids.tolist(), assign_offsets(p, ids, xy, leader).tolist(), strict=True))
    for _ in range(5):
        perm = rng.permutation(n - 1)
        got = assign_offsets(p, ids[perm], xy[perm], leader)
        assert dict(zip(ids[perm].tolist(), got.tolist(), strict=True)) == reference


def _segments_cross(a, b, c, d):
    def orient(p, q, r):
        return np.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    return orient(a, b, c) * orient(a, b, d) < 0 and orient(c, d, a) * orient(c, d, b) < 0


def test_assigned_paths_do_not_cross_fig_4_9():
    rng = np.random.default_rng(11)
    n = 40
    p = hex_pattern(n, D_R)
    xy = rng.uniform(-20, 20, size=(n - 1, 2))
    leader = np.array([0.0, 0.0])
    slots = assign_offsets(p, np.arange(n - 1), xy, leader)
    assert len(set(slots.tolist())) == n - 1
    targets = slot_positions(p, slots, np.zeros(3))[:, :2]
    for i, j in itertools.combinations(range(n - 1), 2):
        assert not _segments_cross(xy[i], targets[i], xy[j], targets[j])


def test_periphery_penalty_fills_the_interior_first():
    rng = np.random.default_rng(5)
    n = 40  # 36 interior offsets (rings 1-3) for 39 followers
    p = hex_pattern(n, D_R)
    leader = np.array([3.0, -2.0])
    xy = leader + rng.uniform(-1.0, 1.0, size=(n - 1, 2))
    slots = assign_offsets(p, np.arange(n - 1), xy, leader)
    assert set(np.flatnonzero(~p.periphery).tolist()) <= set(slots.tolist())
    assert np.count_nonzero(p.periphery[slots]) == (n - 1) - np.count_nonzero(~p.periphery)


def test_slot_positions_share_the_leader_altitude():
    p = hex_pattern(8, D_R)
    targets = slot_positions(p, np.array([0, 3]), np.array([1.0, 2.0, 4.0]))
    np.testing.assert_allclose(targets[:, 2], 4.0)
    np.testing.assert_allclose(targets[:, :2], p.offsets_xy[[0, 3]] + [1.0, 2.0])


def test_large_swarm_assignment_is_the_rectangular_optimum():
    # N = 300 goes through the multiscale warm start; the result must equal scipy's optimum of C~.
    rng = np.random.default_rng(13)
    n = 300
    p = hex_pattern(n, D_R)
    xy = rng.uniform(0.0, 25.0, size=(n - 1, 2))
    leader = xy.mean(axis=0)
    slots = assign_offsets(p, np.arange(n - 1), xy, leader)
    cost = assignment_cost(p, xy, leader)
    rows, cols = linear_sum_assignment(cost)
    assert len(set(slots.tolist())) == n - 1
    assert cost[np.arange(n - 1), slots].sum() == cost[rows, cols].sum()


def test_switch_margin_keeps_the_current_slot_unless_the_gain_exceeds_it():
    p = hex_pattern(3, D_R)
    s0, s1 = p.offsets_xy[0], p.offsets_xy[1]
    # One follower closer to slot 1 (2.35 m) than to slot 0 (2.65 m), holding slot 0; rounded
    # to whole decimetres (26 and 23) the gain is 0.3 m.
    along = (s1 - s0) / np.linalg.norm(s1 - s0)
    xy = ((s0 + s1) / 2 + 0.15 * along)[None]
    ids, leader = np.array([5]), np.zeros(2)
    assert assign_offsets(p, ids, xy, leader)[0] == 1  # plain optimum
    assert assign_offsets(p, ids, xy, leader, np.array([0]), switch_margin=0.5)[0] == 0
    assert assign_offsets(p, ids, xy, leader, np.array([0]), switch_margin=0.1)[0] == 1
    assert assign_offsets(p, ids, xy, leader, np.array([-1]), switch_margin=0.5)[0] == 1
