"""The five physics effects of issue #37 as disturbance models in runs: composed and swept from the
command line, listed, applied by the kernel's force phase (added to point masses, integrated by the
quadrotor), a dead battery's event, the radio on the engine's link layer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.setpoint import Setpoints
from swarmscene.methods.physics import crazyflie, downwash
from swarmscene.testing import check_disturbance

EFFECTS = ("downwash", "ground_effect", "drag", "battery", "radio")


def stacked(data: dict, dynamics: dict, gap: float, disturbances: dict, duration: float = 0.1,
            floor=None) -> tuple:
    """Two vehicles told to hold, one ``gap`` m straight above the other (at 1 m), built."""
    data["swarm"] = {"n": 2, "leader": None,
                     "start": {"layout": "explicit", "positions": [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0 + gap]]}}
    data["safety"]["start_overlap"] = "warn"
    data["environment"]["floor"] = floor
    data["clock"].update(duration=duration, guidance_period=0.1, physics_step=0.02)
    data["avoidance"] = {"name": "none"}
    data["dynamics"] = dynamics
    data["termination"]["on_complete"] = False
    data["disturbances"] = disturbances
    data["events"] = []
    sim = api.build(data)
    target = sim.world.pos.copy()
    sim.formation.setpoints = lambda world, sensing: Setpoints.hold(target)
    return sim, target


def test_every_effect_is_a_registered_model_that_passes_the_contract():
    registry = api.plugins()[1]
    assert set(EFFECTS) <= set(registry.names("disturbance"))
    for name in EFFECTS:
        check_disturbance(registry.classes["disturbance"][name])


def test_effects_compose_and_sweep_from_the_command_line():
    data = api.compose(["scenario=cem_six_vehicle", "disturbances=[downwash,ground_effect]",
                        "disturbances.downwash.scale=0.5", "environment.floor=0"])
    scenario = api.load(data)
    assert list(scenario.disturbances) == ["downwash", "ground_effect"]
    assert scenario.data["disturbances"]["downwash"]["scale"] == 0.5
    assert scenario.data["disturbances"]["downwash"]["c1"] == 2267.18  # defaults recorded
    assert scenario.config.environment.floor == 0.0


def test_ground_effect_without_a_floor_is_refused_in_one_line(data):
    data["disturbances"] = {"ground_effect": {}}
    with pytest.raises(ConfigError) as err:
        api.build(data)
    assert err.value.lines == ["disturbances.ground_effect: needs a ground: set environment.floor "
                               "(e.g. environment.floor=0)"]


def test_downwash_is_added_exactly_to_a_point_mass(data):
    gap, dt = 0.5, 0.02
    sims = [stacked(data, {"name": "double_integrator"}, gap, d)[0] for d in ({}, {"downwash": {}})]
    for sim in sims:  # one physics step, the kernel's phases in order
        sim.dynamics.control(sim.world, Setpoints.hold(sim.world.pos.copy()))
        sim.disturbances.blow(sim.world, 0.0)
        sim.dynamics.step(sim.world, dt)
        sim.disturbances.push(sim.world, dt)
    plain, pushed = (sim.world for sim in sims)
    a = -downwash.downwash_force(gap, 0.0, *crazyflie.DOWNWASH_COEFFICIENTS, crazyflie.ROTOR_RADIUS,
                                 2 * crazyflie.ROTOR_RADIUS, 0.1) / crazyflie.MASS
    assert pushed.vel[0, 2] - plain.vel[0, 2] == pytest.approx(dt * a, rel=1e-12)
    assert pushed.pos[0, 2] - plain.pos[0, 2] == pytest.approx(0.5 * dt * dt * a, rel=1e-9)
    assert pushed.vel[1].tolist() == plain.vel[1].tolist()  # nobody above the upper vehicle


def test_downwash_makes_the_lower_quadrotor_sag_and_reports_the_keep_out(data):
    sim, target = stacked(data, {"name": "quadrotor"}, 0.6, {"downwash": {}}, duration=3.0)
    result = sim.run()
    sag = target[0, 2] - sim.world.pos[0, 2]
    assert sag > 0.1  # well beyond its free-air tracking error
    assert abs(sim.world.pos[1, 2] - target[1, 2]) < 1e-3
    m = result.metrics
    assert m["disturbances.downwash.peak_acceleration"] > 5.0
    assert m["disturbances.downwash.min_keep_out"] == pytest.approx(0.6 / 0.3, rel=1e-12)  # at t = 0
    assert m["disturbances.downwash.keep_out_conflicts"] == 0  # 0.6 m apart vertically: outside 0.3 m


def test_keep_out_conflicts_are_reported_with_their_first_time(data):
    sim, _ = stacked(data, {"name": "double_integrator"}, 0.2, {"downwash": {"scale": 0.0}}, duration=0.3)
    m = sim.run().metrics
    assert m["disturbances.downwash.keep_out_conflicts"] == 1
    assert m["disturbances.downwash.keep_out_agents"] == [0, 1]
    assert m["disturbances.downwash.keep_out_first_time"] == 0.0
    assert m["disturbances.downwash.min_keep_out"] == pytest.approx(0.2 / 0.3, rel=1e-9)


def test_drag_slows_a_coasting_point_mass_at_foersters_rate(data):
    sim, _ = stacked(data, {"name": "double_integrator"}, 2.0, {"drag": {"body": 0.0}})
    sim.world.vel[:] = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    sim.disturbances.blow(sim.world, 0.0)
    k = 4 * crazyflie.HOVER_ROTOR_SPEED / crazyflie.MASS * np.array(crazyflie.K_AERO)
    np.testing.assert_allclose(sim.world.force, [[-k[0] * 2.0, 0, 0], [0, -k[1] * 1.0, 0]], rtol=1e-12)


def test_ground_effect_lifts_a_vehicle_near_the_floor(data):
    sim, _ = stacked(data, {"name": "single_integrator"}, 2.0, {"ground_effect": {}}, floor=0.98)
    sim.disturbances.blow(sim.world, 0.0)
    for agent, z in ((0, 1.0 - 0.98), (1, 3.0 - 0.98)):  # heights above the floor
        ratio = 1 / (1 - (crazyflie.ROTOR_RADIUS / (4 * z)) ** 2)
        assert sim.world.force[agent, 2] == pytest.approx((ratio - 1) * crazyflie.GRAVITY, rel=1e-9)
    assert sim.world.force[0, 2] > 0.1 and sim.world.force[1, 2] < 1e-4


def test_a_dead_battery_is_an_event_and_the_vehicle_falls_onto_the_floor(data):
    sim, _ = stacked(data, {"name": "quadrotor"}, 1.0, {"battery": {"charge": 0.0005}}, duration=4.0, floor=0.0)
    events = []

    class Seen:
        @hookimpl
        def swarmscene_event(self, sim, event):
            events.append(event)

    sim.pm.register(Seen(), name="seen")
    m = sim.run().metrics
    kinds = [(e.name, e.agents) for e in events]
    assert kinds[0] == ("battery_depleted", (0, 1))
    assert m["disturbances.battery.depleted"] == 2
    assert m["disturbances.battery.min_charge"] == 0.0  # drawn to empty, the terminal voltage held
    assert m["disturbances.battery.min_voltage"] == pytest.approx(2.8, rel=1e-12)  # at the cut-off
    assert 0 < m["disturbances.battery.first_depleted_time"] < 1.0
    assert ("crash", (0,)) in kinds or ("crash", (0, 1)) in kinds  # ~1 m of free fall: > 0.5 m/s
    assert sim.world.pos[:, 2].tolist() == [0.0, 0.0]
    assert m["floor.crashes"] == 2 and m["success"] is False


def test_a_low_battery_caps_the_thrust(data):
    sim, _ = stacked(data, {"name": "double_integrator"}, 2.0, {"battery": {"charge": 0.5}})
    sim.world.acc[:] = [[0.0, 0.0, 20.0], [0.0, 0.0, 0.0]]  # 3 g asked of the first, hover of the second
    sim.disturbances.blow(sim.world, 0.0)
    battery = sim.disturbances.models["battery"]
    g, w, v_oc = crazyflie.GRAVITY, crazyflie.MASS * crazyflie.GRAVITY, 3.0 + 1.2 * 0.5
    p_cap = 2.8 * (v_oc - 2.8) / 0.2  # the power at the cut-off voltage: the most the cell gives
    assert battery.voltage[0] == pytest.approx(2.8, rel=1e-12)  # 3 g asks more: held at the cut-off
    t_cap = w * (p_cap / 5.88) ** (2 / 3)
    t_max = 2.25 * w * (2.8 / 4.2) ** 2
    assert sim.world.force[0, 2] == pytest.approx(min(t_cap, t_max) / crazyflie.MASS - (20.0 + g), rel=1e-9)
    assert sim.world.force[1, 2] == 0.0  # hover is within what a half-charged cell gives
    assert not battery.depleted.any()


def test_the_radio_drops_what_is_out_of_range_and_feeds_the_link_layer(data):
    data["swarm"]["start"] = {"layout": "line", "spacing": 10.0, "center": [0.0, 0.0, 2.0]}
    data["clock"]["duration"] = 1.0
    data["disturbances"] = {"radio": {"range": 5.0, "budget": 20}}
    sim = api.build(data)
    assert sim.formation.ctx.link_loss is not None and sim.formation.ctx.link_delay is not None
    lost = sim.formation.ctx.link_loss(sim.world, sim.sensing)
    assert lost.tolist() == (~np.eye(5, dtype=bool)).tolist()  # every pair 10 m > 5 m apart
    m = sim.run().metrics
    assert m["disturbances.comm.loss_rate"] == 1.0
    assert m["disturbances.radio.mean_reception"] is None  # no link within range


def test_the_radio_reception_in_range_follows_the_link_model(data):
    data["swarm"]["start"] = {"layout": "line", "spacing": 120.0, "center": [0.0, 0.0, 2.0]}
    data["clock"]["duration"] = 20.0
    data["comm"]["range"] = 500.0
    data["termination"]["on_complete"] = False
    data["avoidance"] = {"name": "none"}
    data["disturbances"] = {"radio": {"p_gb": 0.0}}
    sim = api.build(data)
    prr0 = (1 - 0.5 * math.exp(-0.5 * 10 ** ((0 - 40.05 - 20 * math.log10(120) + 93) / 10))) ** 256
    lost = [sim.disturbances.models["radio"].lost(sim.world, sim.sensing) for _ in range(2000)]
    assert np.mean(lost) == pytest.approx(1 - prr0, abs=0.02)  # 120 m to the nearest: PRR 0.873
    m = api.build(data).run().metrics  # the swarm flies its waypoints: the loss follows the distances
    assert m["disturbances.comm.loss_rate"] == pytest.approx(1 - m["disturbances.radio.mean_reception"], abs=0.03)


def test_the_downwash_scale_sweeps_as_a_multirun(tmp_path):
    """``swarmscene -m ... disturbances.downwash.scale=0,1`` through the API: a stacked pair swapping
    heights (the antipodal swap of two vehicles 0.5 m one above the other), two jobs, the push each
    recorded: none at scale 0, the fit's 0.30 N on 27 g at scale 1."""
    result = api.sweep({"disturbances.downwash.scale": [0.0, 1.0]},
                       ["scenario=swap", "swarm.n=2", "swarm.start.layout=explicit",
                        "swarm.start.positions=[[0,0,1],[0,0,1.5]]", "safety.start_overlap=warn",
                        "dynamics=quadrotor", "avoidance=none", "disturbances=[downwash]", "environment.floor=0",
                        "clock.duration=0.3", "output.trajectory=false"],
                       sweep_dir=tmp_path / "sweep", allow_failed=False)
    peaks = sorted(float(row["disturbances.downwash.peak_acceleration"]) for row in result.rows)
    assert [row["status"] for row in result.rows] == ["complete", "complete"]
    assert peaks[0] == 0.0
    push = downwash.downwash_force(0.5, 0.0, *crazyflie.DOWNWASH_COEFFICIENTS, crazyflie.ROTOR_RADIUS,
                                   2 * crazyflie.ROTOR_RADIUS, 0.1) / crazyflie.MASS
    assert peaks[1] == pytest.approx(push, rel=0.05)  # at the start, before the two move apart
