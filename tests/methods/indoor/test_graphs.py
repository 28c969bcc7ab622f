"""Thesis sections 5.2.5-5.3.2: graphs G_n / G_sigma, edge deactivation (eq. 5.15-5.22), ranks."""

import networkx as nx
import numpy as np
import pytest
from shapely.geometry import LineString, box

from swarmscene.methods.indoor.graphs import (
    DEACTIVATION_CANDIDATES,
    ArcList,
    EdgeList,
    deactivated,
    deactivation_rules,
    edge_activation,
    flatness,
    initial_rank_estimate,
    is_connected,
    mean_degree,
    neighbour_graph,
    rank_estimate_step,
    ranks,
    restrict,
    sensing_graph,
    sigma_graph,
    virtual_leader,
)
from swarmscene.methods.indoor.maps import building

D_N, D_L, PHI_D = 1.0, 0.05, 0.2  # Table 5.1


def _complete(r):
    n = len(r)
    return EdgeList.from_pairs(n, [(a, b) for a in range(n) for b in range(a + 1, n)])


def _random_swarm(seed, n=40, walls=()):
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.0, np.sqrt(n) * 0.6, size=(n, 2))
    return r, neighbour_graph(r, list(walls), D_N, D_L)


def test_flatness_eq_5_17():
    # m at height 0.08 above the middle of a 0.9 m edge along +x: phi = 0.08 / 0.9, positive on
    # the left of i -> j.
    assert flatness(np.array([[0.45, 0.08]]), np.array([[0.9, 0.0]]))[0] == pytest.approx(0.08 / 0.9)
    assert flatness(np.array([[0.45, -0.08]]), np.array([[0.9, 0.0]]))[0] == pytest.approx(-0.08 / 0.9)


def test_fig_5_3_three_agents_flattened_triangle():
    # Equilateral at rest: nothing is deactivated.
    s = 0.8
    eq = np.array([[0.0, 0.0], [s, 0.0], [s / 2, s * np.sqrt(3) / 2]])
    assert edge_activation(eq, _complete(eq), PHI_D).all()
    # Flattened through a gap: the long edge (0, 1) goes when |phi| = h / 0.9 < phi_d.
    for h, dropped in [(0.08, True), (0.17, True), (0.19, False)]:
        r = np.array([[0.0, 0.0], [0.9, 0.0], [0.45, h]])
        rule1, rule2 = deactivation_rules(r, _complete(r), PHI_D)
        assert rule1.tolist() == [dropped, False, False]  # edges (0,1), (0,2), (1,2)
        assert not rule2.any()


def test_fig_5_3_needs_m_closer_to_both_ends():
    # Agent 2 beyond agent 1 on the line: it is not in A_01 (farther from 0 than 1 is), so (0, 1)
    # stays; instead (0, 2) is the long edge with agent 1 almost on it.
    r = np.array([[0.0, 0.0], [0.5, 0.0], [0.95, 0.02]])
    g = _complete(r)
    sigma = edge_activation(r, g, PHI_D)
    assert dict(zip(sorted(g.edge_set()), sigma.tolist(), strict=True)) == {
        (0, 1): True, (0, 2): False, (1, 2): True}


def test_fig_5_4_four_agents_longest_crossing_edge():
    # Rhombus: diagonals 0-1 (0.9 m) and 2-3 (0.6 m) cross; only the longer one goes (rule 2).
    r = np.array([[0.0, 0.0], [0.9, 0.0], [0.45, -0.3], [0.45, 0.3]])
    g = _complete(r)
    rule1, rule2 = deactivation_rules(r, g, PHI_D)
    assert not rule1.any()
    assert dict(zip(sorted(g.edge_set()), rule2.tolist(), strict=True)) == {
        (0, 1): True, (0, 2): False, (0, 3): False, (1, 2): False, (1, 3): False, (2, 3): False}
    assert len(sigma_graph(r, g, PHI_D)) == 5


def test_fig_5_4_equal_diagonals_are_both_kept():
    # Square: the diagonals are equally long and eq. 5.21 is strict, so neither is dropped.
    r = np.array([[0.0, 0.0], [0.6, 0.6], [0.6, 0.0], [0.0, 0.6]])
    assert edge_activation(r, _complete(r), PHI_D).all()


def _rules_by_the_letter(r, g, phi_d, candidates="neighbours", perspective="i"):
    """Eq. 5.15-5.21 written out per edge and per agent; candidates N_i (or N_i ∩ N_j) in G_n."""
    nb = {a: set() for a in range(g.n)}
    for a, b in g.edge_set():
        nb[a].add(b)
        nb[b].add(a)
    out = []
    for a, b in zip(g.i.tolist(), g.j.tolist(), strict=True):
        if perspective == "j":
            a, b = b, a
        r_ji = r[b] - r[a]
        d = np.linalg.norm(r_ji)
        cand = (nb[a] & nb[b]) if candidates == "common" else nb[a] - {b}
        A = {m for m in cand if np.linalg.norm(r[m] - r[a]) < d}
        B = {m for m in cand if np.linalg.norm(r[m] - r[b]) < d}
        phi = {m: flatness((r[m] - r[a])[None], r_ji[None])[0] for m in A & B}
        rule1 = any(abs(phi[m]) < phi_d for m in A & B)
        C = [m for m in A & B if phi[m] < 0]
        D = [m for m in A & B if phi[m] > 0]
        rule2 = any(np.linalg.norm(r[n] - r[m]) < d for m in C for n in D)
        out.append((rule1, rule2))
    return np.array(out, dtype=bool).reshape(-1, 2)


def _walled_swarm(seed, n=150):
    """Agents strewn over the building's halls and rooms: many links pass near a wall."""
    rng = np.random.default_rng(100 + seed)
    r = rng.uniform((0, 0), (12, 22), size=(n, 2))
    return r, neighbour_graph(r, list(building().walls), D_N, D_L)


@pytest.mark.parametrize("candidates", ["neighbours", "common"])
@pytest.mark.parametrize("seed", range(6))
def test_vectorised_rules_match_the_equations(seed, candidates):
    r, g = _walled_swarm(seed) if seed % 2 else _random_swarm(seed, n=35)
    for perspective in ("i", "j"):
        rule1, rule2 = deactivation_rules(r, g, PHI_D, perspective, candidates)
        expect = _rules_by_the_letter(r, g, PHI_D, candidates, perspective)
        np.testing.assert_array_equal(rule1, expect[:, 0])
        np.testing.assert_array_equal(rule2, expect[:, 1])
        assert rule1.any() and rule2.any()  # the random swarms exercise both rules


# Two configurations where a wall hides the candidate m from j (hand-computed, Table 5.1 values).
# Rule 1: i = 0, j = 1, edge 0.9 m along x; m = 2 at (0.45, 0.1) is 0.461 m from both ends and
# phi = 0.1 / 0.9 = 0.111 < phi_d; the wall's end (0.6, 0.08) passes 0.013 m from segment 2-1
# (< d_l: 2 and 1 do not see each other) but 0.08 m from segment 0-1.
RULE_1 = (np.array([[0.0, 0.0], [0.9, 0.0], [0.45, 0.1]]), [LineString([(0.6, 0.08), (0.6, 0.4)])])
# Rule 2: the rhombus of Fig. 5.4 (diagonals 0-1 0.9 m, 2-3 0.6 m) with a post on segment 3-1 at
# (0.675, 0.15): agent 0 sees m = 2 (phi = -1/3, C_01) and n = 3 (phi = +1/3, D_01), 0.6 < 0.9 m;
# agent 1 sees only 2, so D_10 is empty. |phi| = 1/3 > phi_d: rule 1 does not fire anywhere.
RULE_2 = (np.array([[0.0, 0.0], [0.9, 0.0], [0.45, -0.3], [0.45, 0.3]]),
          [box(0.655, 0.13, 0.695, 0.17)])


def test_rule_1_with_m_hidden_from_j_separates_the_readings():
    r, walls = RULE_1
    g_n = neighbour_graph(r, walls, D_N, D_L)
    assert g_n.edge_set() == {(0, 1), (0, 2)}
    # Literal: agent 0 fires rule 1 on (0, 1), agent 1 (N_1 = {0}) does not; either one suffices.
    assert deactivation_rules(r, g_n, PHI_D, "i", "neighbours")[0].tolist() == [True, False]
    assert deactivation_rules(r, g_n, PHI_D, "j", "neighbours")[0].tolist() == [False, False]
    literal = sigma_graph(r, g_n, PHI_D, "neighbours")
    assert literal.edge_set() == {(0, 2)}
    # ... so G_sigma loses agent 1 while G_n is connected: the literal reading has no
    # connectivity guarantee behind walls.
    assert is_connected(g_n) and not is_connected(literal)
    # Common neighbours: N_0 ∩ N_1 is empty, nothing fires, G_sigma = G_n.
    assert sigma_graph(r, g_n, PHI_D, "common").edge_set() == {(0, 1), (0, 2)}
    # Directed: agent 0 stops listening to 1, agent 1 still follows 0.
    directed = sigma_graph(r, g_n, PHI_D, "directed")
    assert isinstance(directed, ArcList)
    assert directed.edge_set() == {(0, 2), (2, 0), (1, 0)}
    assert directed.degree().tolist() == [1, 1, 1] and mean_degree(directed) == 1.0
    assert mean_degree(literal) == pytest.approx(2 / 3)


def test_rule_2_with_n_hidden_from_j_separates_the_readings():
    r, walls = RULE_2
    g_n = neighbour_graph(r, walls, D_N, D_L)
    assert g_n.edge_set() == {(0, 1), (0, 2), (0, 3), (1, 2), (2, 3)}
    rule1, rule2 = deactivation_rules(r, g_n, PHI_D, "i", "neighbours")
    assert not rule1.any() and rule2.tolist() == [True, False, False, False, False]
    assert not deactivation_rules(r, g_n, PHI_D, "j", "neighbours")[1].any()
    assert sigma_graph(r, g_n, PHI_D, "neighbours").edge_set() == {(0, 2), (0, 3), (1, 2), (2, 3)}
    assert sigma_graph(r, g_n, PHI_D, "common").edge_set() == g_n.edge_set()
    assert sigma_graph(r, g_n, PHI_D, "directed").edge_set() == {
        (1, 0), (0, 2), (2, 0), (0, 3), (3, 0), (1, 2), (2, 1), (2, 3), (3, 2)}


@pytest.mark.parametrize("seed", range(4))
def test_without_walls_the_three_readings_coincide(seed):
    # An m closer to both ends than ||r_ji|| <= d_n is within d_n of j, so with nothing hiding it
    # N_i and N_i ∩ N_j give the same A_ij ∩ B_ij, and i and j agree (the text's symmetry claim).
    r, g = _random_swarm(seed, 60)
    off_i, off_j = deactivated(r, g, PHI_D, "neighbours")
    np.testing.assert_array_equal(off_i, off_j)
    common = sigma_graph(r, g, PHI_D, "common")
    assert sigma_graph(r, g, PHI_D, "neighbours").edge_set() == common.edge_set()
    arcs = sigma_graph(r, g, PHI_D, "directed").edge_set()
    assert arcs == common.edge_set() | {(b, a) for a, b in common.edge_set()}


@pytest.mark.parametrize("seed", range(6))
def test_common_reading_is_symmetric_and_keeps_the_components_of_g_n(seed):
    r, g_n = _walled_swarm(seed)
    from_i = deactivation_rules(r, g_n, PHI_D, "i", "common")
    from_j = deactivation_rules(r, g_n, PHI_D, "j", "common")
    np.testing.assert_array_equal(from_i[0], from_j[0])
    np.testing.assert_array_equal(from_i[1], from_j[1])
    g_sigma = sigma_graph(r, g_n, PHI_D, "common")
    assert len(g_sigma) < len(g_n)
    def comps(g):
        return {frozenset(c) for c in nx.connected_components(g.to_networkx())}
    assert comps(g_sigma) == comps(g_n)


@pytest.mark.parametrize("seed", range(6))
def test_literal_and_directed_readings_against_common(seed):
    """Candidates N_i contain N_i ∩ N_j, so every rule that fires under "common" fires for agent
    i under "neighbours" too: literal G_sigma ⊆ common G_sigma. The literal edges are exactly the
    mutual arcs of the directed G_sigma (where they differ: the two configurations above)."""
    r, g_n = _walled_swarm(seed)
    literal = sigma_graph(r, g_n, PHI_D, "neighbours").edge_set()
    common = sigma_graph(r, g_n, PHI_D, "common").edge_set()
    arcs = sigma_graph(r, g_n, PHI_D, "directed").edge_set()
    assert literal <= common
    assert literal == {(a, b) for a, b in arcs if a < b and (b, a) in arcs}
    assert literal == set(zip(g_n.i[edge_activation(r, g_n, PHI_D)].tolist(),
                              g_n.j[edge_activation(r, g_n, PHI_D)].tolist(), strict=True))


def test_unknown_reading_and_edge_activation_of_the_directed_reading_are_refused():
    r, g = _random_swarm(0, 10)
    with pytest.raises(ValueError, match="deactivation_candidates: 'both', allowed"):
        sigma_graph(r, g, PHI_D, "both")
    with pytest.raises(ValueError, match="the directed reading has one sigma per arc"):
        edge_activation(r, g, PHI_D, "directed")
    assert DEACTIVATION_CANDIDATES[0] == "neighbours"  # the literal reading is the default


def test_g_n_is_g_s_restricted_to_d_n_eq_5_12():
    rng = np.random.default_rng(5)
    walls = list(building().walls)
    r = rng.uniform((0, 12), (10, 22), size=(100, 2))
    g_s = sensing_graph(r, walls, 2.0, D_L)
    assert restrict(g_s, r, D_N).edge_set() == neighbour_graph(r, walls, D_N, D_L).edge_set()
    assert neighbour_graph(r, walls, D_N, D_L).edge_set() < g_s.edge_set()


def test_ranks_eq_5_23_match_networkx_and_mark_lost_agents():
    r, g = _random_swarm(2, n=60)
    rho = ranks(g, leader=59)
    hops = nx.single_source_shortest_path_length(g.to_networkx(), 59)
    for i in range(60):
        assert rho[i] == hops.get(i, 60)
    assert is_connected(g) == nx.is_connected(g.to_networkx())
    chain = EdgeList.from_pairs(5, [(0, 1), (1, 2), (3, 4)])
    assert ranks(chain, leader=0).tolist() == [0, 1, 2, 5, 5]


@pytest.mark.parametrize("seed", range(10))
def test_rank_estimate_properties_5_27_to_5_29(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 80))
    r = rng.uniform(0.0, np.sqrt(n) * 0.55, size=(n, 2))
    g = sigma_graph(r, neighbour_graph(r, [], D_N, D_L), PHI_D)
    leader = int(rng.integers(n))
    rho = ranks(g, leader)
    connected = rho < n
    rho_bar = initial_rank_estimate(n, leader)
    for k in range(n + 2):
        # 5.27 / 5.28 on the leader's component: too high until step rho_i, exact from then on.
        reached = connected & (rho <= k)
        np.testing.assert_array_equal(rho_bar[reached], rho[reached])
        assert np.all(rho_bar[connected & ~reached] > rho[connected & ~reached])
        # 5.29: rho_bar_i < rho_bar_j implies rho_i < rho_j, for every pair.
        lower = rho_bar[:, None] < rho_bar[None, :]
        assert np.all((rho[:, None] < rho[None, :])[lower])
        rho_bar = rank_estimate_step(rho_bar, g, leader)
    assert np.all(rho_bar[~connected] == n)  # cut-off agents read "lost"


def test_virtual_leader_eq_5_24_5_25_averages_lowest_rank_neighbours():
    r = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [5.0, 5.0]])
    g = EdgeList.from_pairs(5, [(0, 1), (0, 2), (0, 3)])
    rho_bar = np.array([3, 1, 1, 2, 4])
    l_i, has = virtual_leader(r, g, rho_bar)
    np.testing.assert_allclose(l_i[0], [0.5, 0.5])  # mean of agents 1 and 2 (rank 1)
    np.testing.assert_allclose(l_i[3], r[0])  # its only neighbour
    assert has.tolist() == [True, True, True, True, False]
    np.testing.assert_allclose(l_i[4], r[4])


def test_max_rank_and_neighbour_min_match_networkx_on_random_graphs():
    """The per-tick shortcuts: the largest rank (eq. 5.23, N when cut off) and min over N_i."""
    from swarmscene.methods.indoor.graphs import max_rank

    rng = np.random.default_rng(11)
    for _ in range(200):
        n = int(rng.integers(1, 40))
        graph = nx.gnp_random_graph(n, rng.uniform(0.02, 0.3), seed=int(rng.integers(1 << 30)))
        edges = EdgeList.from_pairs(n, np.array(list(graph.edges()), dtype=int).reshape(-1, 2))
        leader = int(rng.integers(n))
        hops = nx.single_source_shortest_path_length(graph, leader)
        worst, reached = max_rank(edges, leader)
        assert worst == (max(hops.values()) if len(hops) == n else n)
        assert reached.tolist() == [v in hops for v in range(n)]
        values = rng.integers(0, 50, n)
        expected = [min((values[j] for j in graph.neighbors(i)), default=-1) for i in range(n)]
        assert edges.neighbour_min(values, -1).tolist() == expected
