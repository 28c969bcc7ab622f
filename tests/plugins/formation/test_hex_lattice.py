"""hex_lattice formation (thesis chapter 4): unit behaviour and a mission through swarmscene.api."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core.environment import Environment
from swarmscene.core.plugin import BuildContext
from swarmscene.core.registry import make_plugin_manager
from swarmscene.core.setpoint import Mode
from swarmscene.core.simulation import Simulation
from swarmscene.core.state import WorldState
from swarmscene.methods.outdoor.hex_pattern import formation_graph
from swarmscene.plugins.formation.hex_lattice import HexLattice

# Listed here as well until swarmscene/builtins.py registers them (a no-op afterwards).
MODULES = ("swarmscene.plugins.formation.hex_lattice", "swarmscene.plugins.avoidance.apf_navigation")

# Table 4.3 / section 4.5.2: N = 8 on a line d_i = 1.5 m apart, leader second in line.
THESIS_LINE_START = [
    "formation=hex_lattice", "avoidance=apf_navigation", "environment=open",
    "dynamics=double_integrator", "dynamics.u_sat=2.0", "dynamics.v_max=0.5",
    "swarm.n=8", "swarm.leader=1", "swarm.start.layout=line", "swarm.start.spacing=1.5",
    "swarm.start.center=[0.0,0.0,4.0]", "safety.separation_limit=0.55", "safety.start_overlap=warn",
    "clock.duration=250", "output.progress=off",
]
D_Q, D_R = 0.55, 5.0


def simulation(overrides) -> Simulation:
    pm, registry = make_plugin_manager(tuple(dict.fromkeys((*BUILTIN_PLUGINS, *MODULES))))
    return Simulation(api.load(overrides, registry), pm, registry.observers)


def _context(pos, leader=1):
    world = WorldState.at_rest(np.asarray(pos, dtype=float), leader=leader)
    ctx = BuildContext(
        n=world.n, guidance_period=0.1, physics_step=0.1, duration=10.0, separation_limit=0.55,
        clearance_limit=0.0, comm_range=50.0, environment=Environment(),
        rng=np.random.default_rng(0), initial=world,
    )
    return ctx, world


def test_followers_track_distinct_slots_and_the_leader_waits():
    pos = [[1.5 * i, 0.0, 4.0] for i in range(8)]
    ctx, world = _context(pos)
    form = HexLattice(HexLattice.Params(waypoints=[(0.0, 10.0, 0.0)]), ctx)
    world.vel[1] = [0.2, 0.0, 0.0]
    sp = form.setpoints(world, None)
    followers = np.array([0, 2, 3, 4, 5, 6, 7])
    assert np.all(sp.mode == Mode.TRACK)
    assert len(set(form.slot_of[followers].tolist())) == 7 and form.slot_of[1] == -1
    # Slots are r_N + h_j at the leader's altitude, with the leader's velocity as feed-forward.
    expected = world.pos[1, :2] + form.pattern.offsets_xy[form.slot_of[followers]]
    np.testing.assert_allclose(sp.pos[followers, :2], expected)
    np.testing.assert_allclose(sp.pos[followers, 2], 4.0)
    np.testing.assert_allclose(sp.vel[followers], np.tile([0.2, 0.0, 0.0], (7, 1)))
    # Not formed: the leader holds its home.
    np.testing.assert_allclose(sp.pos[1], pos[1])
    np.testing.assert_allclose(sp.vel[1], 0.0)
    assert form.t_start is None


def test_leader_sets_off_once_formed_along_its_waypoint_offsets():
    ctx, world = _context(np.tile([0.0, 0.0, 4.0], (3, 1)), leader=0)
    form = HexLattice(HexLattice.Params(waypoints=[(0.0, 11.0, 0.0)], leader_speed=0.5), ctx)
    world.pos[1:] = form.slot_targets(world)[1:]  # followers already on their slots
    form.setpoints(world, None)
    assert form.formed_at == 0.0 and form.t_start == 0.0
    world.t = 4.0
    sp = form.setpoints(world, None)
    np.testing.assert_allclose(sp.pos[0], [0.0, 2.0, 4.0])  # 0.5 m/s north (+y) for 4 s
    np.testing.assert_allclose(sp.vel[0], [0.0, 0.5, 0.0])


def test_failed_follower_loses_its_slot_and_the_rest_are_reassigned():
    pos = [[1.5 * i, 0.0, 4.0] for i in range(8)]
    ctx, world = _context(pos)
    form = HexLattice(HexLattice.Params(reassign="on_failure"), ctx)
    form.setpoints(world, None)
    world.healthy[4] = False
    sp = form.setpoints(world, None)
    assert form.slot_of[4] == -1 and sp.mode[4] == Mode.HOLD
    live = [0, 2, 3, 5, 6, 7]
    assert len(set(form.slot_of[live].tolist())) == len(live)


def test_a_leader_is_required():
    from swarmscene.core.errors import ConfigError

    assert HexLattice.requires_leader
    with pytest.raises(ConfigError) as info:
        api.load(["formation=hex_lattice", "swarm.leader=null"])
    assert info.value.lines == ["swarm.leader: formation 'hex_lattice' needs a leader (an agent index 0..4)"]


def test_thesis_line_start_forms_then_flies_the_square_in_formation():
    sim = simulation(THESIS_LINE_START)
    result = sim.run()
    m = result.metrics
    assert result.stop_reason == "complete" and m["hex.path_done"]
    assert m["collisions"] == 0 and m["min_separation"] > D_Q  # forming included
    assert m["hex.formed_at"] is not None and m["hex.formed_at"] < 60.0
    assert (m["hex.m"], m["hex.m_max"]) == (12, 18)

    # Following phase: neighbours on the formation graph about d_r apart, slots tracked closely.
    form = sim.formation
    t, pos = result.trajectory["t"], result.trajectory["pos"]
    flow = pos[t >= m["hex.formed_at"] + 1.0]
    node_agent = {0: form.leader, **{int(s) + 1: a for a, s in enumerate(form.slot_of) if s >= 0}}
    edges = [(node_agent[i], node_agent[j]) for i, j in formation_graph(form.pattern).edges
             if i in node_agent and j in node_agent]
    gaps = np.array([np.linalg.norm(flow[:, i] - flow[:, j], axis=1) for i, j in edges])
    assert gaps.mean() == pytest.approx(D_R, abs=0.2)
    assert 4.2 <= gaps.min() and gaps.max() <= 5.8
    followers = np.flatnonzero(form.slot_of >= 0)
    slots = flow[:, [form.leader]].repeat(len(followers), axis=1)
    slots[:, :, :2] += form.pattern.offsets_xy[form.slot_of[followers]]
    assert np.linalg.norm(flow[:, followers] - slots, axis=2).mean() < 0.8


def test_slots_are_kept_once_the_leader_has_set_off():
    ctx, world = _context(np.tile([0.0, 0.0, 4.0], (8, 1)) + np.c_[np.arange(8) * 1.5, np.zeros((8, 2))])
    form = HexLattice(HexLattice.Params(formation_timeout=1.0, switch_margin=0.0), ctx)
    form.setpoints(world, None)
    world.t = 1.0
    form.setpoints(world, None)  # timeout: the leader sets off without the formation
    assert form.t_start == 1.0 and form.formed_at is None
    held = form.slot_of.copy()
    world.pos[[0, 2]] = world.pos[[2, 0]]  # two followers swap places
    world.t = 1.1
    form.setpoints(world, None)
    np.testing.assert_array_equal(form.slot_of, held)
