"""The lean tick of small swarms (issue #25): each leaner per-tick form gives the values of the form
it replaced (tests/oracles/tick.py) bit for bit, and the monitor's batched clearance series equal
the per-tick ones. Comparisons are of the bytes, so a -0.0 for a +0.0 fails too."""

from __future__ import annotations

import copy
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse
from oracles import tick as old
from scipy.sparse.csgraph import connected_components

from swarmscene import api
from swarmscene.core import monitors
from swarmscene.core.environment import Environment
from swarmscene.core.sensing import Sensing
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.simulation import NonFiniteState
from swarmscene.core.state import WorldState
from swarmscene.core.vectors import DENSE_POINTS, clip_norm, dense_pair_dist2, pairs_within
from swarmscene.methods.quadrotor.thesis_controllers import (
    ThesisController,
    position_gains,
    sat,
    tracker_gains,
    velocity_gains,
    velocity_limiter,
)
from swarmscene.plugins.avoidance.potential import _sum_at


def same_bits(a, b) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes(), f"differ:\n{a!r}\n{b!r}"


def same_setpoints(a: Setpoints, b: Setpoints) -> None:
    for field in ("mode", "pos", "vel", "acc", "yaw"):
        same_bits(getattr(a, field), getattr(b, field))


# -- pair distances and the few-agent Sensing ---------------------------------------------------

@pytest.mark.parametrize("dim", [1, 2, 3])
def test_pair_distances_are_the_per_axis_sums(dim):
    rng = np.random.default_rng(dim)
    for n in (0, 1, 2, 3, 7, DENSE_POINTS):
        for scale, offset in ((1.0, 0.0), (1e-3, 1e6), (50.0, -3.0)):
            pts = offset + scale * rng.standard_normal((n, dim))
            for points in (pts, pts.astype(np.float32), np.round(pts).astype(int)):
                for new, ref in zip(dense_pair_dist2(points), old.dense_pair_dist2(points), strict=True):
                    same_bits(new, ref)


def _graph_connected(pos, members, radius) -> bool:
    """Oracle: connected components of the member-induced disk graph."""
    idx = np.flatnonzero(members)
    if idx.size <= 1:
        return True
    d = np.linalg.norm(pos[idx, None, :] - pos[None, idx, :], axis=2)
    return connected_components(scipy.sparse.csr_matrix(d <= radius), directed=False)[0] == 1


def test_few_agents_pairs_separation_and_connectivity_match_the_old_queries():
    rng = np.random.default_rng(25)
    env = Environment()
    outcomes = set()
    for trial in range(400):
        n = int(rng.integers(2, DENSE_POINTS + 1))
        pos = rng.uniform(0.0, 30.0, (n, 3)) * [1.0, 1.0, 0.1]
        world = WorldState.at_rest(pos)
        if trial % 2:  # some failed or radio-less agents leave the graph
            world.healthy[:] = rng.random(n) > 0.2
            world.comm_ok[:] = rng.random(n) > 0.2
        radius = float(rng.uniform(4.0, 16.0))
        s = Sensing(world, env, radius)
        i, j, d2 = old.dense_pair_dist2(pos)
        for r in (0.5 * radius, radius, 2.0 * radius):
            near = d2 <= r * r
            same_bits(s.pairs(r), np.column_stack([i[near], j[near]]))
        assert s.min_separation == float(np.sqrt(d2.min()))
        members = world.healthy & world.comm_ok
        expected = _graph_connected(pos, members, radius)
        assert s.comm_connected == expected
        outcomes.add(expected)
        # the listed pairs equal the general query's (cell list above DENSE_POINTS, same sums)
        got, got_d2 = pairs_within(pos, radius)
        same_bits(got, s.pairs(radius))
    assert outcomes == {True, False}


def test_connectivity_follows_the_members_from_snapshot_to_snapshot():
    """The members' pairs are kept from tick to tick: a failure or a lost radio in place (as events
    do it) must still be seen at the next snapshot."""
    rng = np.random.default_rng(7)
    env = Environment()
    world = WorldState.at_rest(rng.uniform(0.0, 12.0, (8, 3)))
    s = None
    seen = set()
    for tick in range(300):
        world.pos[:] = rng.uniform(0.0, 10.0 if tick % 3 else 30.0, world.pos.shape)
        if tick % 20 == 0:  # in place, as events change them
            world.healthy[:] = True
            world.comm_ok[:] = True
            if tick % 40:
                world.healthy[rng.integers(8)] = False
                world.comm_ok[rng.integers(8)] = False
        s = Sensing(world, env, 6.0, s)
        expected = _graph_connected(world.pos, world.healthy & world.comm_ok, 6.0)
        assert s.comm_connected == expected
        seen.add((expected, bool((world.healthy & world.comm_ok).all())))
    assert len(seen) == 4  # connected or not, with all or some members


def test_no_obstacle_in_reach_answers_without_a_geometry_query():
    env = Environment([__import__("shapely").Point(100.0, 0.0).buffer(1.0)])
    world = WorldState.at_rest(np.array([[0.0, 0.0, 2.0], [3.0, 1.0, 2.0]]))
    s = Sensing(world, env, 20.0)
    index, clearance = s.obstacle_nearest(5.0)
    ref_index, ref_clearance = env.nearest_obstacle(world.pos, 5.0)
    same_bits(index, ref_index)
    same_bits(clearance, ref_clearance)
    assert s.clearance_within(2.0).tolist() == [np.inf, np.inf]
    # within a wider range the obstacle is found, exactly as the environment finds it
    far = Sensing(world, env, 20.0)
    same_bits(far.clearance_within(150.0), env.clearance(world.pos, 150.0))


# -- the safety monitor's batched distances -----------------------------------------------------

def _clearance_series(result, env, horizon):
    """Oracle: each recorded frame's min_clearance as the monitor computed it tick by tick."""
    out = []
    for pos in result.trajectory["pos"]:
        bounded = env.clearance(pos, horizon)
        out.append(bounded.min() if np.isfinite(bounded).any() else env.distance(pos))
    return np.array(out)


def test_far_ticks_get_the_distance_the_monitor_used_to_compute_each_tick(data, monkeypatch):
    data["termination"]["on_complete"] = False
    data["clock"]["duration"] = 30.0
    data["environment"]["obstacles"] = [{"type": "circle", "center": [12.0, -5.0], "radius": 0.6}]  # on the path
    sim = api.build(copy.deepcopy(data))
    result = sim.run()
    series = result.series["min_clearance"]
    horizon = result.monitor.horizon
    assert (series > horizon).any() and (series <= horizon).any()  # both branches ran
    same_bits(series, _clearance_series(result, sim.environment, horizon))
    assert result.metrics["min_clearance"] == float(series.min())
    # in batches of a few ticks: the same series
    monkeypatch.setattr(monitors, "FAR_BATCH", 7 * sim.world.n)
    again = api.build(copy.deepcopy(data)).run()
    same_bits(again.series["min_clearance"], series)


# -- controllers and dynamics -------------------------------------------------------------------

def _controller(n: int, u_sat=3.4, eps_lim=0.0) -> ThesisController:
    return ThesisController(n, velocity_gains(0.3, 0.8, 0.1), position_gains(0.23, 0.71, 0.1),
                            tracker_gains(1.5, 0.71, 0.1), u_sat, 2.5, eps_lim)


@pytest.mark.parametrize("modes", ["position", "velocity", "track", "hold", "mixed", "switching", "position_hold"])
@pytest.mark.parametrize("v_lim", [None, 2.0, 0.0])
def test_controller_running_one_law_gives_the_three_law_selection(modes, v_lim):
    rng = np.random.default_rng(len(modes))
    n = 6
    new, ref = _controller(n), _controller(n)
    for tick in range(12):
        if modes == "mixed":
            mode = np.arange(n, dtype=np.int8) % 4
        elif modes == "switching":  # all in one law, then another: the integrals restart
            mode = np.full(n, [0, 1, 2, 3][tick // 3], dtype=np.int8)
        elif modes == "position_hold":  # one law under two modes, then a mixed tick of both
            mode = np.full(n, 0 if tick < 4 else 3, dtype=np.int8)
            if tick == 7:
                mode[::2] = 0
        else:
            mode = np.full(n, int(Mode[modes.upper()]), dtype=np.int8)
        r, v, r_ref, v_ref, u_ref = (rng.standard_normal((n, 3)) * 4.0 for _ in range(5))
        v[0, 2] = -0.0
        same_bits(new.step(mode, r, v, r_ref, v_ref, u_ref, v_lim),
                  old.thesis_step(ref, mode, r, v, r_ref, v_ref, u_ref, v_lim))
        # the integrals of the laws in use agree (an idle law's restarts when an agent enters it)
        for law in ("velocity", "position", "tracker"):
            used = {"velocity": [1], "position": [0, 3], "tracker": [2]}[law]
            active = np.isin(mode, used)
            same_bits(getattr(new, law).x_I[active], getattr(ref, law).x_I[active])


def test_saturation_and_scalar_limiter_are_the_old_forms():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((8, 3)) * 5.0
    a[0] = [np.nan, -0.0, 0.0]
    for u_sat in (3.4, np.array([1.0, 2.0, 3.0])):
        same_bits(sat(a, u_sat), old.sat(a, u_sat))
    v = rng.standard_normal((8, 3))
    for v_lim, eps in ((2.0, 0.0), (0.1, 0.1), (np.full(8, 1.5), 0.0), (np.full((8, 3), 0.5), 1.0)):
        same_bits(velocity_limiter(a, v, v_lim, 2.5, eps), old.velocity_limiter(a, v, v_lim, 2.5, eps))


def test_double_integrator_is_the_old_law_and_integration(data):
    data["clock"]["duration"] = 5.0
    sim = api.build(data)
    dyn, world = sim.dynamics, sim.world
    ref_dyn, ref_world = copy.deepcopy(dyn), copy.deepcopy(world)
    rng = np.random.default_rng(1)
    for tick in range(8):
        if tick == 4:  # a failed agent is switched to HOLD where it is
            world.healthy[1] = ref_world.healthy[1] = False
        sp = Setpoints.hold(world.pos + rng.standard_normal(world.pos.shape))
        sp.mode[:] = Mode.TRACK if tick % 2 else Mode.POSITION
        sp.vel[:] = rng.standard_normal(sp.vel.shape) * 3.0
        dyn.control(world, sp)
        u = old.double_integrator_control(ref_dyn, ref_world, sp)
        same_bits(dyn.u, u)
        for _ in range(sim.substeps):  # u held over the sub-steps
            dyn.step(world, sim.physics_step)
            old.double_integrator_step(ref_world.pos, ref_world.vel, u, sim.physics_step)
        same_bits(world.pos, ref_world.pos)
        same_bits(world.vel, ref_world.vel)


def test_single_integrator_command_is_the_old_selection():
    sim = api.build(["scenario=cem_six_vehicle", "clock.duration=1"])
    dyn, world = sim.dynamics, sim.world
    rng = np.random.default_rng(2)
    for modes in ([2] * 6, [1, 2, 3, 0, 2, 2], [3] * 6, [1] * 6):
        sp = Setpoints.hold(world.pos + rng.standard_normal(world.pos.shape))
        sp.mode[:] = modes
        sp.vel[:] = rng.standard_normal(sp.vel.shape)
        dyn.control(world, sp)
        same_bits(dyn.u, old.single_integrator_u(dyn.params, world, sp))


# -- formation and avoidance --------------------------------------------------------------------

@pytest.mark.parametrize("reassign", [True, False])
def test_static_shape_setpoints_are_the_old_ones_before_and_after_a_failure(data, reassign):
    data["formation"]["reassign_on_failure"] = reassign
    data["clock"]["duration"] = 40.0
    sim = api.build(data)
    formation, world = sim.formation, sim.world
    for tick in range(0, 400, 7):  # across the legs and to the end of the path
        world.t = tick * 0.1
        if tick == 140:
            world.healthy[3] = False
        if tick == 210:  # two agents out of their slots, not consecutive
            world.healthy[1] = False
        sp = formation.setpoints(world, sim.sensing)
        same_setpoints(sp, old.static_shape_setpoints(formation, world))
        assert formation._last_slots is sp.pos
    assert (formation.slot_of < 0).any() == reassign


def test_potential_repulsion_is_the_old_sum(data):
    sim = api.build(data)
    world, potential = sim.world, sim.avoidance
    rng = np.random.default_rng(4)
    pillar = np.array(sim.environment.obstacles[0].centroid.coords[0])
    for trial in range(20):
        # a tight cluster beside the pillar: agent pairs and the obstacle both in range
        world.pos[:, :2] = pillar + [1.2, 0.0] + rng.uniform(-0.6, 0.6, (world.n, 2))
        world.healthy[:] = True
        if trial % 3 == 0:
            world.healthy[trial % world.n] = False
        sp = Setpoints.hold(world.pos + rng.standard_normal(world.pos.shape))
        sp.mode[::2] = Mode.VELOCITY
        if trial % 2:
            sp.mode[:] = Mode.TRACK
        new = potential.adjust(world, Sensing(world, sim.environment, 20.0), sp)
        ref = old.potential_adjust(potential, world, Sensing(world, sim.environment, 20.0), sp)
        same_setpoints(new, ref)
        assert not np.array_equal(new.vel, sp.vel)  # something pushed


def test_clip_norm_is_the_old_scaling():
    rng = np.random.default_rng(6)
    v = rng.standard_normal((40, 3)) * 2.0
    v[0] = [3.0, 4.0, 0.0]  # exactly at the limit 5
    v[1] = [-0.0, 0.0, -0.0]
    v[2] = [np.nan, 1.0, 0.0]
    for limit in (5.0, 100.0, 0.5, 0.0, 1e-301, np.float64(2.0), 3):
        for rows in (v, v[3:], v[:0], v[3:].astype(np.float32), v[:2]):
            same_bits(clip_norm(rows, limit), old.clip_norm(rows, limit))
    same_bits(clip_norm(np.arange(6).reshape(2, 3), 100.0), old.clip_norm(np.arange(6).reshape(2, 3), 100.0))


@pytest.mark.parametrize("velocity_mode", [False, True])
def test_potential_without_anything_in_range_is_the_old_zero_sum(data, velocity_mode):
    """Nothing in range: sp + 0.0 as the old sums gave it (a -0.0 reference turns +0.0)."""
    sim = api.build(data)
    world, potential = sim.world, sim.avoidance
    world.pos[:] = [[-40.0 - 5.0 * k, 30.0, 2.0] for k in range(world.n)]  # apart, far from the pillar
    sp = Setpoints.hold(world.pos)
    sp.pos[0] = [-0.0, 0.0, -0.0]
    sp.vel[:] = -0.0
    sp.vel[1] = [1.0, -2.0, 0.0]
    if velocity_mode:
        sp.mode[1::2] = Mode.VELOCITY
    new = potential.adjust(world, Sensing(world, sim.environment, 20.0), sp)
    ref = old.potential_adjust(potential, world, Sensing(world, sim.environment, 20.0), sp)
    same_setpoints(new, ref)
    assert np.signbit(ref.vel).sum() == 1 and not np.signbit(ref.pos[0]).any()  # only the -2.0 left


def test_sum_at_is_add_at():
    rng = np.random.default_rng(5)
    for n, m in ((1, 0), (5, 10), (32, 200)):
        rows = rng.integers(0, n, m)
        values = rng.standard_normal((m, 3)) * 10.0 ** rng.integers(-8, 8, (m, 1))
        ref = np.zeros((n, 3))
        np.add.at(ref, rows, values)
        same_bits(_sum_at(rows, values, (n, 3)), ref)


# -- events --------------------------------------------------------------------------------------

@pytest.mark.parametrize("agents", [[1, 2], [0, 3], [4]])
def test_held_agents_stay_where_they_failed_whether_their_rows_are_a_run_or_not(data, agents):
    data["events"] = [{"at": 1.0, "agents": agents, "name": "hover"}]
    data["termination"]["on_complete"] = False
    data["clock"]["duration"] = 3.0
    result = api.build(data).run()
    traj = result.trajectory
    after = traj["t"] >= 1.0
    held = traj["pos"][after][:, agents]
    assert np.array_equal(held, np.broadcast_to(held[0], held.shape))
    assert not traj["vel"][traj["t"] > 1.0][:, agents].any()
    others = [k for k in range(5) if k not in agents]
    assert not np.array_equal(traj["pos"][-1, others], traj["pos"][np.flatnonzero(after)[0], others])


# -- the kernel's finite check ------------------------------------------------------------------

def test_finite_check_tolerates_an_overflowing_sum_and_names_a_non_finite_agent():
    sim = api.build(["clock.duration=1"])
    sim.world.pos[:] = sim.world.vel[:] = 1e200  # finite, though pos . vel overflows (numpy warns)
    with np.errstate(over="ignore"):
        sim._check_finite()
    for bad in (np.nan, np.inf, -np.inf):
        for field, other in (("vel", "pos"), ("pos", "vel")):
            sim.world.pos[:] = sim.world.vel[:] = 0.0  # an infinity times 0 is caught too
            getattr(sim.world, other)[:] = 1.0 if bad == np.inf else 0.0
            getattr(sim.world, field)[3, 1] = bad
            with np.errstate(invalid="ignore"), pytest.raises(
                    NonFiniteState, match=r"^non-finite state of agent 3 at tick 1 "):
                sim._check_finite()
    sim.world.pos[:] = sim.world.vel[:] = 0.0
    sim._check_finite()


def test_the_default_scenario_runs_without_numba_or_scipy_spatial():
    """The lean tick keeps the command line's start-up light: a small swarm's run imports neither
    numba (compiled paths are for swarms over DENSE_POINTS agents) nor scipy.spatial."""
    code = ("import sys; from swarmscene import api; api.run(['clock.duration=2', 'output.summary=false']); "
            "print(sorted(m for m in ('numba', 'scipy.spatial') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"
