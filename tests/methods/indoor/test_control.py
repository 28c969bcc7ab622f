"""Thesis sections 5.3.3-5.4: follower potentials (eq. 5.30-5.42), leader (Algorithm 1, eq. 5.43-5.44),
and a closed-loop corridor run with Table 5.1 parameters."""

import numpy as np
import pytest
from oracles.indoor import (
    IndoorController,
    follower_input,
    leader_direction,
    leader_input,
    random_connected_swarm,
)

from swarmscene.methods.indoor.control import (
    TABLE_5_1,
    psi_col,
    psi_com,
    psi_con,
    psi_led,
    psi_obs,
    w_col,
    w_com,
    w_con,
    w_led,
    w_obs,
)
from swarmscene.methods.indoor.graphs import (
    EdgeList,
    is_connected,
    neighbour_graph,
    sigma_graph,
    virtual_leader,
)
from swarmscene.methods.indoor.maps import in_region, straight_corridor
from swarmscene.methods.indoor.sensing import (
    nearest_obstacle,
    pairwise_min_distance,
    single_integrator_step,
)

G = TABLE_5_1


def test_table_5_1_values():
    assert (G.T_s, G.u_max, G.u_sat, G.d_c, G.d_o, G.d_s, G.d_l, G.d_n, G.phi_d) == (
        0.01, 0.025, 0.02, 0.3, 0.1, 2.0, 0.05, 1.0, 0.2)
    assert (G.K_obs, G.eps_obs, G.l_o, G.K_col, G.eps_col, G.l_c) == (200, 1e-4, 0.7, 200, 1e-4, 0.7)
    assert (G.K_con, G.eps_con, G.l_n, G.K_com, G.alpha_com, G.K_led) == (200, 1e-4, 0.7, 0.1, 0.8, 0.06)
    assert (G.alpha_lsat, G.alpha_lcon) == (0.7, 0.95)


def test_psi_obs_and_psi_col_eq_5_34_5_36():
    for psi, near in [(psi_obs, G.d_o), (psi_col, G.d_c)]:
        assert psi(near) == pytest.approx(-200.0)
        assert psi(near - 0.05) == pytest.approx(-200.0)  # held at -K below the bound
        assert psi(0.0) == pytest.approx(-200.0)
        assert psi(0.7) == pytest.approx(0.0, abs=1e-12)
        assert psi(0.71) == 0.0 and psi(5.0) == 0.0
        z = np.linspace(near, 0.7, 50)
        assert np.all(np.diff(psi(z)) > 0)  # repulsion weakens with distance
    # Mid-range value of the printed formula: x = 0.5.
    x, eps = 0.5, 1e-4
    assert psi_col(G.d_c + x * (G.l_c - G.d_c)) == pytest.approx(-200 * eps * ((1 + eps) / (x + eps) - 1))


def test_psi_con_eq_5_38_attracts():
    assert psi_con(G.d_n) == pytest.approx(200.0)
    assert psi_con(G.l_n) == pytest.approx(0.0, abs=1e-12)
    assert psi_con(0.5) == 0.0 and psi_con(1.01) == 0.0
    z = np.linspace(G.l_n, G.d_n, 50)
    assert np.all(psi_con(z) >= 0) and np.all(np.diff(psi_con(z)) > 0)


def test_psi_com_eq_5_40_and_psi_led_eq_5_42():
    assert psi_com(G.d_c) == pytest.approx(-0.1)
    assert psi_com(G.d_c + 0.8 * (G.d_n - G.d_c)) == pytest.approx(0.0, abs=1e-15)  # 0.86 m
    assert psi_com(G.d_n) == pytest.approx(0.1 * (1 / 0.8 - 1))
    assert psi_com(0.2) == 0.0 and psi_com(1.2) == 0.0
    assert psi_led(2.0) == pytest.approx(0.12)


def test_pair_terms_directions():
    r = np.array([[0.0, 0.0], [0.5, 0.0]])
    g = EdgeList.from_pairs(2, [(0, 1)])
    col = w_col(r, g)
    np.testing.assert_allclose(col[0], [psi_col(0.5), 0.0])
    assert col[0, 0] < 0 and np.allclose(col[0], -col[1])  # pushed apart, equal and opposite
    far = np.array([[0.0, 0.0], [0.0, 0.9]])
    con = w_con(far, g)
    assert con[0, 1] == pytest.approx(psi_con(0.9)) and con[0, 1] > 0  # pulled together
    np.testing.assert_allclose(w_com(far, g)[1], [0.0, -psi_com(0.9)])


def test_w_obs_pushes_away_and_ignores_undetected():
    r = np.array([[0.3, 0.0], [5.0, 5.0]])
    o = np.array([[0.0, 0.0], [np.nan, np.nan]])
    out = w_obs(r, o)
    np.testing.assert_allclose(out[0], [-psi_obs(0.3), 0.0])
    assert out[0, 0] > 0
    np.testing.assert_array_equal(out[1], [0.0, 0.0])


def test_w_led_pulls_to_virtual_leader():
    r = np.zeros((2, 2))
    l_i = np.array([[1.0, 2.0], [3.0, 3.0]])
    np.testing.assert_allclose(w_led(r, l_i, np.array([True, False])), [[0.06, 0.12], [0.0, 0.0]])


def test_follower_input_saturates_at_u_sat_eq_5_30():
    # A near-rest triangular lattice (small inputs) with one pair pushed close (saturated inputs).
    rng = np.random.default_rng(0)
    a, b = np.meshgrid(np.arange(6), np.arange(6))
    r = 0.86 * np.column_stack([a.ravel() + 0.5 * (b.ravel() % 2), b.ravel() * np.sqrt(3) / 2])
    r += rng.normal(0.0, 0.01, size=r.shape)
    r[0] = r[1] + [-0.35, 0.0]
    g = sigma_graph(r, neighbour_graph(r, [], G.d_n, G.d_l), G.phi_d)
    l_i, has = virtual_leader(r, g, np.zeros(36, dtype=int))
    u = follower_input(r, g, np.full((36, 2), np.nan), l_i, has)
    w = w_col(r, g) + w_con(r, g) + w_com(r, g) + w_led(r, l_i, has)
    norm_u, norm_w = np.linalg.norm(u, axis=1), np.linalg.norm(w, axis=1)
    assert np.all(norm_u <= G.u_sat + 1e-15)
    big = norm_w > G.u_sat
    assert big.any() and (~big).any()
    np.testing.assert_allclose(norm_u[big], G.u_sat)
    np.testing.assert_allclose(u[~big], w[~big])
    np.testing.assert_allclose(u[big] / norm_u[big, None], w[big] / norm_w[big, None])


def test_algorithm_1_next_waypoint():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    d, m = leader_direction(np.array([-1.0, 0.0]), p, 0)
    assert m == 0 and np.allclose(d, [1.0, 0.0])
    d, m = leader_direction(np.array([0.5, -0.1]), p, 0)  # passed p_0 along p_0 -> p_1
    assert m == 1 and np.allclose(d, np.array([0.5, 0.1]) / np.hypot(0.5, 0.1))
    _, m = leader_direction(np.array([0.5, 0.0]), p, 0)  # level with p_1 across p_1 -> p_2: ">="
    assert m == 2
    d, m = leader_direction(np.array([1.0, -0.2]), p, 1)  # before p_1 across p_1 -> p_2
    assert m == 1 and np.allclose(d, [0.0, 1.0])
    d, m = leader_direction(np.array([1.1, 0.1]), p, 1)
    assert m == 2 and np.allclose(d, np.array([-0.1, 0.9]) / np.hypot(0.1, 0.9))
    d, m = leader_direction(np.array([1.0, 1.0]), p, 2)  # on the last way-point
    assert m == 2 and np.allclose(d, 0.0)


@pytest.mark.parametrize(
    "nearest, expect",
    [(0.5, 0.7 * 0.02), (0.94, 0.95 - 0.94), (0.96, 0.0)],  # u_lsat = 0.014, u_lcon = 0.95 d_n - d
)
def test_leader_magnitude_eq_5_43_5_44(nearest, expect):
    r = np.array([[0.0, 0.0], [-nearest, 0.0], [0.0, -0.99]])
    g = EdgeList.from_pairs(3, [(0, 1), (0, 2)])
    p = np.array([[0.0, 0.0], [5.0, 0.0]])
    u, m = leader_input(r, 0, g, p, 0)
    assert m == 1
    np.testing.assert_allclose(u, [expect, 0.0], atol=1e-15)


def test_leader_waits_without_neighbours_and_stops_on_final_waypoint():
    p = np.array([[0.0, 0.0], [5.0, 0.0]])
    alone = EdgeList.from_pairs(2, np.empty((0, 2)))
    u, _ = leader_input(np.array([[1.0, 0.0], [3.0, 0.0]]), 0, alone, p, 0)
    np.testing.assert_array_equal(u, [0.0, 0.0])
    g = EdgeList.from_pairs(2, [(0, 1)])
    u, m = leader_input(np.array([[4.995, 0.0], [4.5, 0.0]]), 0, g, p, 1)
    assert m == 1
    np.testing.assert_allclose(u, [0.005, 0.0])


def _corridor_run(width, seed, n=30, length=10.0, max_steps=4000):
    """Single-integrator loop of eq. 5.1 with the full step; returns what the thesis measures."""
    mp = straight_corridor(width, length)
    r = random_connected_swarm(mp.start_region, n, np.random.default_rng(seed))
    swarm = IndoorController(n, n - 1, mp.waypoints, mp.walls)
    connected, min_sep, min_obs = True, np.inf, np.inf
    for _ in range(max_steps):
        u = swarm.input(r)
        connected &= is_connected(swarm.g_n)
        min_sep = min(min_sep, pairwise_min_distance(r))
        min_obs = min(min_obs, nearest_obstacle(r, swarm.obstacles, 1.0)[1].min())
        r = single_integrator_step(r, u, G.u_max)
        if in_region(r, mp.end_region).all():
            break
    return in_region(r, mp.end_region).all(), connected, min_sep, min_obs


def test_closed_loop_straight_corridor_w_0_8():
    """N = 30 through a 0.8 m corridor (section 5.4, shortened to 4 m to stay fast): G_n stays
    connected, eq. 5.2 and 5.3 hold, every agent reaches the exit room."""
    arrived, connected, min_sep, min_obs = _corridor_run(0.8, seed=0, length=4.0)
    assert arrived and connected
    assert min_sep >= G.d_c
    assert min_obs >= G.d_o


def test_closed_loop_narrow_corridor_keeps_safety():
    """At w = 0.5 m the thesis loses connectivity, but collision and obstacle conditions still hold."""
    _, _, min_sep, min_obs = _corridor_run(0.5, seed=1, length=4.0, max_steps=600)
    assert min_sep >= G.d_c and min_obs >= G.d_o


@pytest.mark.slow
@pytest.mark.parametrize("width", [0.7, 0.8, 0.9])
def test_closed_loop_corridor_success_rate(width):
    """Full 10 m corridor, 10 seeds: the thesis' success for w >= 0.7 m (Fig. 5.13)."""
    runs = [_corridor_run(width, seed) for seed in range(10)]
    assert sum(a and c for a, c, _, _ in runs) >= 8
    assert all(s >= G.d_c and o >= G.d_o for _, _, s, o in runs)
