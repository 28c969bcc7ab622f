"""APF navigation with flight levels (thesis section 4.3.3, eq. 4.21-4.28, Fig. 4.10, Table 4.3)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swarmscene.methods.outdoor.apf_navigation import (
    apf_navigation,
    arrived_on_target,
    attraction_velocity,
    close_to_target,
    collision_gain,
    flight_level_altitude,
    navigation_velocity,
    repulsion_velocity,
    saturate,
    target_gain,
)
from swarmscene.methods.outdoor.hex_pattern import assign_offsets, hex_pattern, slot_positions

# Table 4.3
D_Q, D_C, D_R, V_SAT, EPS_R, T_S = 0.55, 1.65, 5.0, 0.5, 0.5, 0.1


def test_potential_shapes_of_fig_4_10():
    d_c, v_sat = 1.5, 0.5  # the figure's values
    np.testing.assert_allclose(collision_gain([0.0, d_c, 1.5 * d_c, 2 * d_c, 5.0], d_c, v_sat),
                               [-2 * v_sat, -v_sat, -0.5 * v_sat, 0.0, 0.0])
    np.testing.assert_allclose(target_gain([0.0, 0.5 * d_c, d_c, 10.0], d_c, v_sat),
                               [0.0, 0.5 * v_sat, v_sat, v_sat])
    z = np.linspace(0, 4 * d_c, 401)
    assert np.all(np.abs(np.diff(collision_gain(z, d_c, v_sat))) < 0.01)  # continuous
    assert np.all(np.abs(np.diff(target_gain(z, d_c, v_sat))) < 0.01)
    # Repulsion inside d_c always beats the strongest attraction (the thesis' override argument).
    assert np.all(collision_gain(z[z <= d_c], d_c, v_sat) <= -target_gain(z, d_c, v_sat).max())


def test_velocity_reference_has_the_exact_gains():
    # Agent 0: target 10 m north; agent 1 on the same level 1 m east of it.
    pos = np.array([[0.0, 0.0, 5.65], [1.0, 0.0, 5.8]])
    targets = np.array([[0.0, 10.0, 4.0], [1.0, 0.0, 4.0]])
    v_col = repulsion_velocity(pos, D_C, V_SAT)
    np.testing.assert_allclose(v_col[0], [V_SAT * (1.0 / D_C - 2.0), 0.0])
    np.testing.assert_allclose(v_col[1], -v_col[0])
    np.testing.assert_allclose(attraction_velocity(pos, targets, D_C, V_SAT)[0], [0.0, V_SAT])
    v_inf = v_col[0] + np.array([0.0, V_SAT])
    expected = v_inf / np.linalg.norm(v_inf) * V_SAT  # |v_inf| > v_sat: eq. 4.21 rescales
    np.testing.assert_allclose(navigation_velocity(pos, targets, D_C, V_SAT)[0], expected)


def _reference_repulsion(pos, d_c, v_sat):
    """Eq. 4.23 written as the thesis' sum, one agent at a time (test oracle)."""
    v = np.zeros((len(pos), 2))
    for i in range(len(pos)):
        for j in range(len(pos)):
            dz = pos[j, 2] - pos[i, 2]
            dh = pos[j, :2] - pos[i, :2]
            if i != j and abs(dz) < 2 / 3 * d_c and np.linalg.norm(dh) > 0:
                z = np.linalg.norm(dh)
                v[i] += (v_sat * (z / d_c - 2) if z < 2 * d_c else 0.0) * dh / z
    return v


def test_vectorised_repulsion_matches_the_sum_of_eq_4_23_and_accepts_a_shared_tree():
    rng = np.random.default_rng(2)
    pos = np.c_[rng.uniform(0, 8, size=(60, 2)), rng.choice([4.0, 4.3, 5.65, 6.0], size=60)]
    expected = _reference_repulsion(pos, D_C, V_SAT)
    np.testing.assert_allclose(repulsion_velocity(pos, D_C, V_SAT), expected, atol=1e-12)
    np.testing.assert_allclose(repulsion_velocity(pos, D_C, V_SAT, cKDTree(pos)), expected, atol=1e-12)
    np.testing.assert_allclose(repulsion_velocity(pos, D_C, V_SAT, cKDTree(pos[:, :2])), expected, atol=1e-12)


def test_speed_never_exceeds_v_sat():
    rng = np.random.default_rng(4)
    for _ in range(20):
        pos = np.c_[rng.uniform(0, 5, size=(80, 2)), np.full(80, 5.65)]
        targets = np.c_[rng.uniform(-50, 50, size=(80, 2)), np.full(80, 4.0)]
        v = navigation_velocity(pos, targets, D_C, V_SAT)
        assert np.all(np.linalg.norm(v, axis=1) <= V_SAT * (1 + 1e-12))
    v = saturate(np.array([[3.0, 4.0], [0.3, 0.0], [0.0, 0.0]]), V_SAT)
    np.testing.assert_allclose(v, [[0.3, 0.4], [0.3, 0.0], [0.0, 0.0]])


def test_only_agents_on_the_same_flight_level_repel():
    base = np.array([0.0, 0.0, 5.65])
    for dz, repelled in [(0.6 * D_C, True), (0.7 * D_C, False), (-D_C, False), (0.0, True)]:
        pos = np.vstack([base, base + [1.0, 0.0, dz]])
        v = repulsion_velocity(pos, D_C, V_SAT)
        assert (np.linalg.norm(v[0]) > 0) == repelled, dz


def test_navigating_agents_fly_one_level_above_the_target_level():
    # NED r_z = t^T z_o - d_c is d_c higher: world z_ref = t_z + d_c; the leader/formed agents
    # at t_z are then on another level and are not avoided.
    pos = np.array([[0.0, 0.0, 4.0], [20.0, 0.0, 4.0]])
    targets = np.array([[0.0, 0.0, 4.0], [0.0, 3.0, 4.0]])  # agent 1 navigates, agent 0 is home
    cmd = apf_navigation(pos, targets, D_C, V_SAT, EPS_R)
    assert not cmd.position_mode[1]
    assert cmd.z_ref[1] == pytest.approx(4.0 + D_C)
    np.testing.assert_allclose(flight_level_altitude(4.0, D_C, level_offset=-1.0), 4.0 - D_C)
    # At the flight level it passes right over an agent standing on the target level.
    above = np.array([[0.0, 0.0, 4.0], [0.5, 0.0, 4.0 + D_C]])
    np.testing.assert_allclose(repulsion_velocity(above, D_C, V_SAT), 0.0)


def test_switch_to_position_control_within_half_d_c_and_arrival_within_eps_r():
    targets = np.tile([10.0, 10.0, 4.0], (4, 1))
    pos = targets + np.array(
        [[0.49 * D_C, 0.0, D_C], [0.51 * D_C, 0.0, D_C], [0.3, 0.0, 0.3], [0.3, 0.0, 0.45]]
    )
    cmd = apf_navigation(pos, targets, D_C, V_SAT, EPS_R)
    np.testing.assert_array_equal(cmd.position_mode, [True, False, True, True])
    np.testing.assert_allclose(cmd.z_ref, [4.0, 4.0 + D_C, 4.0, 4.0])
    np.testing.assert_allclose(cmd.vel_xy[cmd.position_mode], 0.0)
    np.testing.assert_array_equal(cmd.arrived, [False, False, True, False])  # 0.42 m vs 0.54 m
    np.testing.assert_array_equal(close_to_target(pos, targets, D_C), cmd.position_mode)
    np.testing.assert_array_equal(arrived_on_target(pos, targets, EPS_R), cmd.arrived)


def _fly(pos, targets, steps, hold=()):
    """Kinematic agents under APF navigation (position mode: saturated P control), T_s steps."""
    pos = pos.astype(float).copy()
    min_sep = np.inf
    for step in range(steps):
        cmd = apf_navigation(pos, targets, D_C, V_SAT, EPS_R)
        v = np.zeros_like(pos)
        v[:, :2] = cmd.vel_xy
        v[:, 2] = np.clip(cmd.z_ref - pos[:, 2], -V_SAT, V_SAT)
        pm = cmd.position_mode.copy()
        pm[list(hold)] = True
        v[pm] = saturate(targets[pm] - pos[pm], V_SAT)
        pos += v * T_S
        gap = np.linalg.norm(pos[:, None] - pos[None], axis=2) + np.diag(np.full(len(pos), np.inf))
        min_sep = min(min_sep, gap.min())
        if cmd.arrived.all():
            return True, step * T_S, min_sep
    return False, steps * T_S, min_sep


def test_head_on_crossing_keeps_agents_apart():
    # Two navigating agents swap places on the same level, slightly offset sideways.
    pos = np.array([[0.0, 0.0, 4.0 + D_C], [10.0, 0.1, 4.0 + D_C]])
    targets = np.array([[10.0, 0.0, 4.0], [0.0, 0.1, 4.0]])
    arrived, _, min_sep = _fly(pos, targets, steps=600)
    assert arrived
    assert min_sep >= D_C  # they slide round each other outside d_c


def test_exactly_opposed_agents_stop_at_d_c_rather_than_collide():
    # Perfect symmetry is the APF local minimum: equilibrium where psi_col = -v_sat, i.e. d_c apart.
    pos = np.array([[0.0, 0.0, 4.0 + D_C], [10.0, 0.0, 4.0 + D_C]])
    targets = np.array([[10.0, 0.0, 4.0], [0.0, 0.0, 4.0]])
    arrived, _, min_sep = _fly(pos, targets, steps=400)
    assert not arrived
    assert min_sep == pytest.approx(D_C, abs=1e-6)


def test_forming_from_the_thesis_line_start_is_collision_free():
    # Section 4.5.2: N = 8 on a line d_i = 1.5 m apart (closer than d_c), leader second in line.
    n, leader = 8, 1
    home = np.c_[np.arange(n) * 1.5, np.zeros(n), np.full(n, 4.0)]
    followers = np.array([i for i in range(n) if i != leader])
    pattern = hex_pattern(n, D_R)
    slots = assign_offsets(pattern, followers, home[followers], home[leader])
    targets = home.copy()
    targets[followers] = slot_positions(pattern, slots, home[leader])
    arrived, t_form, min_sep = _fly(home, targets, steps=1000, hold=[leader])
    assert arrived and t_form < 60.0
    assert min_sep > D_Q
