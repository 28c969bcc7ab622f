"""The disturbances group: composition, validation, the kernel's phases, wind on each dynamics model
(analytic steady states), and that a run without disturbances keeps its random stream."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.setpoint import Setpoints

TIMING = {"wall_time", "realtime_factor", "step_ms_median"}


def hovering(data: dict, dynamics: str, duration: float, disturbances: dict, **dyn) -> object:
    """A swarm told to hold its start positions (avoidance none, no events), built."""
    data["clock"]["duration"] = duration
    data["avoidance"] = {"name": "none"}
    data["dynamics"] = {"name": dynamics, **dyn}
    data["termination"]["on_complete"] = False
    data["disturbances"] = disturbances
    sim = api.build(data)
    target = sim.world.pos.copy()
    sim.formation.setpoints = lambda world, sensing: Setpoints.hold(target)
    return sim, target


# -- composition and validation -----------------------------------------------------------------


def test_several_models_compose_from_the_command_line():
    data = api.compose(["scenario=cem_six_vehicle", "disturbances=[dryden,packet_loss]",
                        "disturbances.dryden.speed=8"])
    assert data["disturbances"] == {"dryden": {"name": "dryden", "speed": 8}, "packet_loss": {"name": "packet_loss"}}
    scenario = api.load(data)
    assert scenario.data["disturbances"]["dryden"]["speed"] == 8.0
    assert scenario.data["disturbances"]["dryden"]["field"] == "shared"  # defaults recorded
    assert list(scenario.disturbances) == ["dryden", "packet_loss"]


def test_none_declared_leaves_the_record_as_it_was():
    data = api.compose(["scenario=cem_six_vehicle"])
    assert "disturbances" not in data
    assert "disturbances" not in api.load(data).data


@pytest.mark.parametrize("node, line", [
    ({"dryden": {"speed": 1000}}, "disturbances.dryden.speed: must be <= 100.0 (got 1000)"),
    ({"dryden": {"sped": 1}}, "disturbances.dryden.sped: unknown key (valid keys: heading, moment_arm, "
                              "speed, mean, intensity, field) (got 1)"),
    ({"windy": {}}, "disturbances.windy: unknown disturbance model 'windy' (valid: battery, comm_delay, "
                    "constant_wind, downwash, drag, dryden, ground_effect, gust, packet_loss, radio, "
                    "sensing_noise)"),
    ({"w": {"name": "breeze"}}, "disturbances.w.name: unknown disturbance model 'breeze'"),
    ({"gps": {"name": "sensing_noise", "pos_std": [1, -1, 1]}},
     "disturbances.gps.pos_std: each must be in [0, 1000] (got [1.0, -1.0, 1.0])"),
    ({"packet_loss": {"p": 1.5}}, "disturbances.packet_loss.p: must be <= 1.0 (got 1.5)"),
    ({"dryden": 3}, "disturbances.dryden: must be a mapping of options (got 3)"),
])
def test_bad_options_are_one_line_naming_the_key(data, node, line):
    data["disturbances"] = node
    with pytest.raises(ConfigError) as exc:
        api.load(data)
    assert len(exc.value.lines) == 1
    assert exc.value.lines[0].startswith(line), exc.value.lines[0]


# -- bit-identical without disturbances ----------------------------------------------------------


def test_models_that_change_nothing_leave_the_run_bit_identical():
    """Zero wind and zero noise draw only from their own streams: a CEM run (which draws from the
    run's generator each tick) is unchanged to the bit, trajectory and metrics."""
    base = ["scenario=cem_six_vehicle", "clock.duration=6", "output.summary=false"]
    a = api.run(base)
    b = api.run([*base, "disturbances=[constant_wind,sensing_noise,dryden]",
                 "disturbances.constant_wind.speed=0", "disturbances.dryden.speed=0",
                 "disturbances.sensing_noise.pos_std=[0,0,0]", "disturbances.sensing_noise.vel_std=[0,0,0]"])
    assert np.array_equal(a.trajectory["pos"], b.trajectory["pos"])
    def strip(m):
        return {k: v for k, v in m.items()
                if k not in TIMING and "_ms" not in k and not k.startswith("disturbances.")}
    assert strip(a.metrics) == strip(b.metrics)
    assert b.metrics["disturbances.models"] == ["constant_wind", "dryden", "sensing_noise"]


def test_the_disturbance_stream_is_seeded_from_the_run_seed():
    base = ["scenario=cem_six_vehicle", "clock.duration=2", "output.summary=false", "disturbances=[dryden]",
            "disturbances.dryden.field=independent"]
    a, b, c = api.run(base), api.run(base), api.run([*base, "seed=1"])
    assert np.array_equal(a.trajectory["pos"], b.trajectory["pos"])
    assert not np.array_equal(a.trajectory["pos"], c.trajectory["pos"])


# -- wind: analytic steady states ------------------------------------------------------------------


def test_single_integrator_holding_in_constant_wind_settles_at_w_over_k(data):
    """Carried by the air: r(k+1) = r(k) + T (k (p - r(k)) + w), fixed point p + w / k."""
    sim, target = hovering(data, "single_integrator", 40.0,
                           {"constant_wind": {"speed": 0.5, "heading": 90.0, "vertical": 0.1}}, gain=0.8)
    sim.run()
    w = np.array([0.0, 0.5, 0.1])
    np.testing.assert_allclose(sim.world.pos - target, np.tile(w / 0.8, (sim.world.n, 1)), atol=1e-9)


def test_double_integrator_integral_action_cancels_constant_wind(data):
    """Force D w on the point mass; the position PID's integral state settles at u = -D w, zero error."""
    sim, target = hovering(data, "double_integrator", 300.0, {"constant_wind": {"speed": 4.0, "heading": 30.0}})
    sim.run()
    D = sim.dynamics.drag_coefficient
    w = 4.0 * np.array([np.cos(np.pi / 6), np.sin(np.pi / 6), 0.0])
    np.testing.assert_allclose(sim.world.acc, np.tile(-D * w, (sim.world.n, 1)), atol=1e-4)
    np.testing.assert_allclose(sim.world.pos, target, atol=1e-3)


def test_double_integrator_open_loop_drift_is_exact(data):
    """With the controller's output held at zero, the wind's acceleration integrates exactly:
    p(t) = p0 + D w t^2 / 2 at any physics step (the kernel's split is exact for a point mass)."""
    sim, target = hovering(data, "double_integrator", 2.0, {"constant_wind": {"speed": 3.0}})
    sim.dynamics.control = lambda world, sp: None  # u stays 0
    sim.run()
    D = sim.dynamics.drag_coefficient
    np.testing.assert_allclose(sim.world.pos[:, 0] - target[:, 0], 0.5 * D * 3.0 * 2.0**2, rtol=1e-12)


def test_quadrotor_hover_offset_in_constant_wind(data):
    """SE(3) control has no integral: at rest k_x e = m a_wind, so e = R D R^T w / omega_x^2."""
    sim, target = hovering(data, "quadrotor", 12.0, {"constant_wind": {"speed": 3.0}})
    sim.run()
    from swarmscene.core.disturbances import Disturbances  # noqa: F401 (documented path)

    a = sim.dynamics.wind_acceleration(sim.world)  # at the final attitude
    omega = sim.dynamics.params.position_omega
    np.testing.assert_allclose(sim.world.pos - target, a / omega**2, rtol=2e-3, atol=1e-6)
    assert a[0, 0] == pytest.approx(0.206 * 3.0, rel=2e-3)  # tilt ~ 0.06 rad barely mixes in D_z
    np.testing.assert_allclose(sim.world.vel, 0.0, atol=1e-6)


def test_quadrotor_moment_arm_shifts_its_hover_offset(data):
    """A centre of pressure h above the CoG: the drag's moment M_y = h m D w (FLU, (0, 0, h) x F)
    leaves a steady attitude error delta = M_y / k_R (no integral in the SE(3) loop). The force
    balance fixes the actual tilt, so the desired one differs by delta, which the position loop
    asks for with a further offset g delta / omega_x^2 downwind (the moment tilts it downwind: the
    desired tilt must lean further upwind)."""
    offsets = []
    for arm in (0.0, 0.05):
        sim, target = hovering(data, "quadrotor", 8.0, {"constant_wind": {"speed": 3.0, "moment_arm": arm}})
        sim.run()
        offsets.append(sim.world.pos[0, 0] - target[0, 0])
    gains, m = sim.dynamics.gains, sim.dynamics.airframe.mass
    delta = 0.05 * m * 0.206 * 3.0 / gains.k_R[1]
    omega = sim.dynamics.params.position_omega
    assert offsets[1] - offsets[0] == pytest.approx(9.81 * delta / omega**2, rel=0.02)


def test_gust_reaches_the_plant_with_its_exact_shape(data):
    """The single integrator holding at gain k sees the gust as a ground-velocity input: its
    recorded velocity minus the hold command is the gust shape at each physics step."""
    sim, target = hovering(data, "single_integrator", 6.0,
                           {"gust": {"amplitude": 2.0, "start": 1.0, "rise": 1.5, "hold": 0.0}})
    winds = []
    step = sim.dynamics.step

    def spy(world, dt):
        winds.append(world.wind[0].copy())
        step(world, dt)

    sim.dynamics.step = spy
    sim.run()
    t = np.arange(len(winds)) * sim.physics_step
    tau = t - 1.0
    shape = np.where((tau >= 0) & (tau <= 3.0), 0.5 * (1 - np.cos(np.pi * tau / 1.5)), 0.0)
    np.testing.assert_allclose(np.array(winds)[:, 0], 2.0 * shape, atol=1e-12)
    assert sim.run is not None


def test_wind_metrics_record_what_was_applied(data):
    sim, _ = hovering(data, "single_integrator", 3.0, {"constant_wind": {"speed": 2.0}})
    result = sim.run()
    assert result.metrics["disturbances.wind.peak_speed"] == pytest.approx(2.0)
    assert result.metrics["disturbances.wind.mean_speed"] == pytest.approx(2.0)


def test_every_model_option_is_documented():
    """docs/disturbances.md carries each model's option table as the docgen renders it."""
    from pathlib import Path

    from swarmscene.tools.docgen import model_table

    doc = (Path(__file__).parents[2] / "docs" / "disturbances.md").read_text()
    registry = api.plugins()[1]  # every built-in model, core/disturbances' and plugins/disturbance's
    for kind, cls in registry.classes["disturbance"].items():
        assert f"### `{kind}`" in doc
        for row in model_table(cls.Params, "disturbances.<name>."):
            assert row in doc, f"docs/disturbances.md: {kind}'s table is out of date ({row})"
