"""The virtual_rigid_body formation end to end through swarmscene.api (papers/virtual-rigid-bodies.md).

Fast tests fly the part of the air show that matters (take-off and Phi^1_2, the transformation of
Fig. 8) with the 6-DOF quadrotor; the whole 71 s show is marked slow.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarmscene import api
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core.errors import ConfigError
from swarmscene.core.registry import make_plugin_manager
from swarmscene.core.setpoint import Mode
from swarmscene.core.simulation import Simulation

VRB_MODULE = "swarmscene.plugins.formation.virtual_rigid_body"
QUADROTOR_MODULE = "swarmscene.plugins.dynamics.quadrotor"
S_IJ = 0.6  # s_i + s_j, m
KEYS = ("vrb.min_transformation_distance", "vrb.max_switch_discontinuity", "vrb.tracking_rms")


def registry_and_pm():
    modules = tuple(dict.fromkeys((*BUILTIN_PLUGINS, VRB_MODULE, QUADROTOR_MODULE)))
    return make_plugin_manager(modules, load_entry_points=False)


def build(overrides: list[str]) -> Simulation:
    pm, registry = registry_and_pm()
    return Simulation(api.load(overrides, registry), pm, registry.observers)


def test_airshow_take_off_and_first_transformation_with_quadrotors(tmp_path):
    sim = build(["scenario=vrb_airshow", "clock.duration=5.2"])  # Phi^1_2 is 2-5 s
    result = sim.run()
    m = result.metrics
    assert m["vrb.min_transformation_distance"] >= S_IJ and m["vrb.safety_holds"]
    assert m["vrb.min_transformation_distance"] == pytest.approx(0.65, abs=0.01)  # Fig. 8
    assert m["vrb.max_switch_discontinuity"] < 1e-6
    assert m["vrb.tracking_rms"] < 0.05  # m, the bound for the whole show
    assert m["collisions"] == 0 and m["min_separation"] >= S_IJ
    api.write_outputs(sim, result, tmp_path / "run")
    written = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert all(key in written for key in KEYS)


def test_setpoints_carry_flat_outputs_and_body_yaw():
    sim = build(["scenario=vrb_airshow", "clock.duration=0.1"])
    vrb = sim.formation
    sim.world.t = 12.0  # inside Pi_2, the body circling
    sp = vrb.setpoints(sim.world, sim.sensing)
    assert np.all(sp.mode == Mode.TRACK)
    body = vrb.trajectory.evaluate(12.0)
    r = vrb.flight.formations[1]
    np.testing.assert_allclose(sp.pos, body.p[0, 0] + r @ body.R[0, 0].T, atol=1e-12)  # eq. 1
    np.testing.assert_allclose(sp.snap, body.p[4, 0] + r @ body.R[4, 0].T, atol=1e-9)  # eq. 2
    np.testing.assert_allclose(sp.yaw, body.euler[0, 0, 2])


def test_field_off_plan_violates_the_safety_distance():
    """Fig. 8 through the plugin: 0.55 m without the repelling field, 0.65 m with it."""
    on = build(["scenario=vrb_airshow", "clock.duration=0.1"]).formation.flight
    off = build(["scenario=vrb_airshow", "clock.duration=0.1", "formation.repel_gain=0"]).formation.flight
    assert off.transformations[0].min_distance() == pytest.approx(0.55, abs=0.005)
    assert off.min_transformation_distance() < S_IJ <= on.min_transformation_distance()


def test_agents_are_matched_to_slots_whatever_their_order():
    sim = build(["scenario=vrb_airshow", "clock.duration=1.0",
                 "swarm.start.positions=[[0.7,0.0,0.0],[-0.7,0.0,0.0],[0.0,0.0,0.0]]"])
    m = sim.run().metrics
    assert m["vrb.tracking_rms"] < 0.01


def test_generic_show_any_swarm_with_simple_dynamics():
    """The group default: named shapes in the body frame, five agents, a double integrator."""
    sim = build(["formation=virtual_rigid_body", "environment=open", "avoidance=none",
                 "clock.duration=12.0"])
    m = sim.run().metrics
    assert m["vrb.max_switch_discontinuity"] < 1e-6
    assert m["vrb.min_transformation_distance"] >= S_IJ
    assert m["collisions"] == 0


def test_config_errors_name_the_key():
    pm, registry = registry_and_pm()
    with pytest.raises(ConfigError, match="formation"):
        api.load(["formation=virtual_rigid_body", "formation.preset=airshow"], registry)
    with pytest.raises(ConfigError, match="threshold"):
        api.load(["scenario=vrb_airshow", "formation.threshold=0.5"], registry)
    with pytest.raises(ValueError, match="3 agents"):
        build(["scenario=vrb_airshow", "swarm.n=4", "swarm.start.layout=grid"])


@pytest.mark.slow
def test_full_airshow_with_quadrotors():
    """Section IV, all 71 s: every transformation safe, switches smooth, RMS tracking < 5 cm."""
    result = build(["scenario=vrb_airshow"]).run()
    m = result.metrics
    assert m["vrb.min_transformation_distance"] >= S_IJ
    assert m["vrb.max_switch_discontinuity"] < 1e-6
    assert m["vrb.tracking_rms"] < 0.05
    assert m["collisions"] == 0 and m["success"] and result.stop_reason == "complete"


def test_params_start_shape_only_first():
    from swarmscene.plugins.formation.virtual_rigid_body import VirtualRigidBody

    kf = [{"t": 0.0, "pos": [0, 0, 2]}, {"t": 10.0, "pos": [5, 0, 2]}]
    ok = {"preset": "custom", "keyframes": kf,
          "formations": [{"shape": "start", "duration": 2.0}, {"shape": "line", "duration": 5.0}]}
    VirtualRigidBody.Params.model_validate(ok)
    bad = dict(ok, formations=ok["formations"][::-1])
    with pytest.raises(ValueError, match="start"):
        VirtualRigidBody.Params.model_validate(bad)


def test_generic_show_starts_from_where_the_agents_are():
    sim = build(["formation=virtual_rigid_body", "environment=open", "avoidance=none",
                 "clock.duration=0.1"])
    sp = sim.formation.setpoints(sim.world, sim.sensing)
    np.testing.assert_allclose(sp.pos, sim.world.pos, atol=1e-12)  # Pi_1 = shape 'start'
    np.testing.assert_allclose(sp.vel, 0.0, atol=1e-12)
