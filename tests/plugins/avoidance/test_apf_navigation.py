"""apf_navigation avoidance (thesis section 4.3.3): unit behaviour and runs through swarmscene.api."""

from __future__ import annotations

import numpy as np

from swarmscene import api
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core.environment import Environment
from swarmscene.core.plugin import BuildContext
from swarmscene.core.registry import make_plugin_manager
from swarmscene.core.sensing import Sensing
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.simulation import Simulation
from swarmscene.core.state import WorldState
from swarmscene.plugins.avoidance.apf_navigation import ApfNavigation

# Listed here as well until swarmscene/builtins.py registers them (a no-op afterwards).
MODULES = ("swarmscene.plugins.formation.hex_lattice", "swarmscene.plugins.avoidance.apf_navigation")
D_C, V_SAT, EPS_R = 1.65, 0.5, 0.5


def _setup(pos, targets, leader=0):
    world = WorldState.at_rest(np.asarray(pos, dtype=float), leader=leader)
    env = Environment()
    ctx = BuildContext(
        n=world.n, guidance_period=0.1, physics_step=0.1, duration=10.0, separation_limit=0.55,
        clearance_limit=0.0, comm_range=50.0, environment=env, rng=np.random.default_rng(0),
        initial=world,
    )
    sp = Setpoints.hold(np.asarray(targets, dtype=float))
    sp.mode[:] = Mode.TRACK
    return ApfNavigation(ApfNavigation.Params(), ctx), world, Sensing(world, env, 50.0), sp


def test_far_agents_navigate_at_the_flight_level_and_the_leader_is_left_alone():
    pos = [[0.0, 0.0, 4.0], [10.0, 0.0, 4.0], [11.0, 0.0, 4.0]]
    targets = [[0.0, 5.0, 4.0], [20.0, 0.0, 4.0], [30.0, 0.0, 4.0]]  # both heading +x
    apf, world, sensing, sp = _setup(pos, targets)
    out = apf.adjust(world, sensing, sp)
    assert out.mode[0] == Mode.TRACK and np.array_equal(out.pos[0], sp.pos[0])  # leader
    assert np.all(out.mode[1:] == Mode.VELOCITY)
    assert np.all(np.linalg.norm(out.vel[1:, :2], axis=1) <= V_SAT + 1e-12)
    # Agents 1 and 2 are 1 m apart on one level: for agent 1 (behind) the repulsion, -0.70 m/s,
    # beats the +0.5 m/s attraction: it backs off (eq. 4.22) while agent 2 goes at v_sat.
    np.testing.assert_allclose(out.vel[1, :2], [0.5 + 0.5 * (1.0 / D_C - 2.0), 0.0])
    np.testing.assert_allclose(out.vel[2, :2], [V_SAT, 0.0])
    # Climbing towards t_z + d_c (the thesis' NED -d_c), capped at v_sat.
    np.testing.assert_allclose(out.vel[1:, 2], V_SAT)
    assert sp.mode[1] == Mode.TRACK  # the formation's record is not edited


def test_hand_over_within_half_d_c_and_release_on_arrival():
    pos = [[0.0, 0.0, 4.0], [5.0, 0.0, 4.0 + D_C]]
    targets = [[0.0, 0.0, 4.0], [8.0, 0.0, 4.0]]
    apf, world, sensing, sp = _setup(pos, targets)
    assert apf.adjust(world, sensing, sp).mode[1] == Mode.VELOCITY and apf.engaged[1]
    world.pos[1] = [7.5, 0.0, 4.0 + D_C]  # 0.5 m < d_c / 2 horizontally: position control
    out = apf.adjust(world, sensing, sp)
    assert out.mode[1] == Mode.TRACK and np.array_equal(out.pos[1], sp.pos[1]) and apf.engaged[1]
    world.pos[1] = [7.9, 0.0, 4.2]  # within eps_r: arrived, released
    apf.adjust(world, sensing, sp)
    assert not apf.engaged[1] and apf.arrival_time[1] == 0.0
    # A tracking error below engage_distance (d_c) no longer triggers navigation.
    world.pos[1] = [6.8, 0.0, 4.0]
    assert apf.adjust(world, sensing, sp).mode[1] == Mode.TRACK and not apf.engaged[1]


def test_failed_agents_never_navigate_but_still_repel():
    pos = [[0.0, 0.0, 4.0], [5.0, 0.0, 5.65], [6.0, 0.0, 5.65]]
    targets = [[0.0, 0.0, 4.0], [20.0, 0.0, 4.0], [-20.0, 0.0, 4.0]]
    apf, world, sensing, sp = _setup(pos, targets)
    world.healthy[2] = False
    out = apf.adjust(world, sensing, sp)
    assert out.mode[2] == Mode.TRACK and not apf.engaged[2]
    attraction_only = V_SAT
    assert out.vel[1, 0] < attraction_only  # slowed by the failed agent 1 m ahead on its level


def _simulation(overrides):
    pm, registry = make_plugin_manager(tuple(dict.fromkeys((*BUILTIN_PLUGINS, *MODULES))))
    return Simulation(api.load(overrides, registry), pm, registry.observers)


def test_serves_another_formation_tight_grid_to_circle_without_collisions():
    # static_shape asks nine agents packed 1.5 m apart (< d_c) for a circle 4 m between slots.
    sim = _simulation([
        "formation=static_shape", "avoidance=apf_navigation", "environment=open", "swarm=grid",
        "swarm.n=9", "swarm.start.spacing=1.5", "formation.shape=circle", "formation.spacing=4.0",
        "formation.waypoints=[[0.0,0.0,2.0]]", "formation.rotate_with_heading=false",
        "dynamics=double_integrator", "safety.separation_limit=0.55", "clock.duration=120",
        "output.progress=off",
    ])
    result = sim.run()
    m = result.metrics
    assert result.stop_reason == "complete"
    assert m["collisions"] == 0 and m["min_separation"] > 0.55
    assert m["apf.max_horizontal_command"] <= V_SAT + 1e-12
    assert m["apf.last_arrival_time"] is not None
