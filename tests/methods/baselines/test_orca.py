"""ORCA against the reference implementation (RVO2 2.0.3, through the ``pyrvo`` bindings) and
against the paper's guarantee (van den Berg et al. 2011, Theorem: velocities chosen from the ORCA
half-planes of both agents are collision-free for tau)."""

from __future__ import annotations

import numpy as np
import pyrvo
import pytest
from scipy.spatial import cKDTree

from swarmscene.methods.baselines.halfplanes import violation
from swarmscene.methods.baselines.neighbours import neighbour_table
from swarmscene.methods.baselines.orca import agent_lines, new_velocities

NEIGHBOR_DIST, MAX_NEIGHBORS, TAU, RADIUS, V_MAX, TIME_STEP = 5.0, 6, 2.0, 0.4, 1.2, 0.1


def f32(x):
    """RVO2 computes in float: give both sides the same rounded inputs."""
    return np.asarray(x, dtype=np.float32).astype(float)


def rvo2_step(pos, vel, pref):
    """One RVO2 step: the new velocities and each agent's ORCA lines (direction, point)."""
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(TIME_STEP)
    sim.set_agent_defaults(NEIGHBOR_DIST, MAX_NEIGHBORS, TAU, TAU, RADIUS, V_MAX)
    for p, v, w in zip(pos, vel, pref, strict=True):
        a = sim.add_agent(tuple(p))
        sim.set_agent_velocity(a, tuple(v))
        sim.set_agent_pref_velocity(a, tuple(w))
    sim.do_step()
    velocity = np.array([sim.get_agent_velocity(i).to_tuple() for i in range(len(pos))])
    lines = [[sim.get_agent_orca_line(i, k) for k in range(sim.get_agent_num_orca_lines(i))]
             for i in range(len(pos))]
    return velocity, lines


def ours(pos, vel, pref):
    pairs = cKDTree(pos).query_pairs(NEIGHBOR_DIST, output_type="ndarray")
    index, valid = neighbour_table(pairs, pos, MAX_NEIGHBORS)
    v, feasible = new_velocities(pos, vel, pref, index, valid, np.zeros(len(pos), dtype=bool),
                                 2 * RADIUS, TAU, TIME_STEP, V_MAX)
    point, direction = agent_lines(pos[index] - pos[:, None], vel[:, None] - vel[index], vel, 2 * RADIUS,
                                   TAU, TIME_STEP)
    return v, feasible, point, direction, valid


def configurations(seed, count, n=12, spread=4.0):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield (f32(rng.uniform(-spread, spread, (n, 2))), f32(rng.uniform(-1, 1, (n, 2))),
               f32(rng.uniform(-1.5, 1.5, (n, 2))))


def test_lines_and_velocities_match_rvo2():
    """Same inputs, one step: every ORCA line and, where the 2-D program is feasible, every new
    velocity agree with RVO2 to its float precision."""
    compared = 0
    for pos, vel, pref in configurations(1, 60):
        ref_v, ref_lines = rvo2_step(pos, vel, pref)
        v, feasible, point, direction, valid = ours(pos, vel, pref)
        for i, lines in enumerate(ref_lines):
            assert len(lines) == valid[i].sum()
            np.testing.assert_allclose([ln[0] for ln in lines], direction[i, : len(lines)], atol=2e-5)
            np.testing.assert_allclose([ln[1] for ln in lines], point[i, : len(lines)], atol=2e-5)
        np.testing.assert_allclose(v[feasible], ref_v[feasible], atol=2e-4)
        compared += feasible.sum()
    assert compared > 500


def test_dense_fallback_penetrates_no_deeper_than_rvo2():
    """Where the half-planes are infeasible (overlapping crowds) both run linearProgram3; RVO2's
    float arithmetic can be far off in near-parallel cases, so compare the quantity it minimises:
    the largest penetration of the agent's ORCA half-planes."""
    fallbacks = 0
    for pos, vel, pref in configurations(2, 40, n=16, spread=2.5):
        ref_v, _ = rvo2_step(pos, vel, pref)
        v, feasible, point, direction, valid = ours(pos, vel, pref)
        rows = np.flatnonzero(~feasible)
        fallbacks += rows.size
        for i in rows:
            mine = violation(point[i : i + 1], direction[i : i + 1], v[i : i + 1])[0][valid[i]].max()
            theirs = violation(point[i : i + 1], direction[i : i + 1], ref_v[i : i + 1])[0][valid[i]].max()
            assert mine <= theirs + 1e-4
            assert np.linalg.norm(v[i]) <= V_MAX + 1e-9
    assert fallbacks > 20


def closest_approach(rel_pos, rel_vel, horizon):
    """min over t in [0, horizon] of |rel_pos + t rel_vel| (rows)."""
    speed2 = np.maximum(np.einsum("ij,ij->i", rel_vel, rel_vel), 1e-300)
    t = np.clip(-np.einsum("ij,ij->i", rel_pos, rel_vel) / speed2, 0.0, horizon)
    return np.linalg.norm(rel_pos + t[:, None] * rel_vel, axis=1)


@pytest.mark.parametrize("static", [False, True])
def test_reciprocal_and_static_pairs_are_collision_free_for_tau(static):
    """Two agents each choosing from their ORCA half-plane (or one avoiding a static one with
    responsibility 1) stay at least r_A + r_B apart for tau (the paper's section 4 guarantee)."""
    rng = np.random.default_rng(5)
    m = 400
    gap = rng.uniform(2 * RADIUS + 0.05, 4.0, m)
    angle = rng.uniform(0, 2 * np.pi, m)
    pos = np.zeros((m, 2, 2))
    pos[:, 1] = gap[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    vel = rng.uniform(-1, 1, (m, 2, 2))
    pref = -pos + pos[:, ::-1]  # each heads at the other: a conflict
    if static:
        vel[:, 1] = pref[:, 1] = 0.0
    checked = 0
    for k in range(m):
        v, feasible = new_velocities(pos[k], vel[k], pref[k], np.array([[1], [0]]), np.ones((2, 1), bool),
                                     np.array([False, static]), 2 * RADIUS, TAU, TIME_STEP, 5.0)
        if static:
            v[1] = 0.0
        if feasible.all():
            checked += 1
            d = closest_approach(pos[k, 1:2] - pos[k, 0:1], v[1:2] - v[0:1], TAU)
            assert d[0] >= 2 * RADIUS - 1e-9
    assert checked > 0.9 * m
