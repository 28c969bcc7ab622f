"""The ``cem`` avoidance plugin driven directly, with a perfect-tracking kinematic loop.

Scenario numbers from papers/cem-fluid-flow-navigation.md section IV-V: eps = 0.28 m, delta = 0.40 m,
a_f = eps + delta, a_p = 1.36 m, d_min = 2.72 m, v_des = 1.0 m/s, dT = 10 ms, K = 2, n = 20, sigma = 1 mm.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError

from swarmscene.core.events import Event
from swarmscene.core.plugin import BuildContext
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.methods.cem.mode import failure_strengths
from swarmscene.plugins.avoidance import cem as cem_module
from swarmscene.plugins.avoidance.cem import CEM
from swarmscene.plugins.event.comm_loss import CommLoss
from swarmscene.plugins.event.drift import Drift
from swarmscene.plugins.event.hover import Hover
from swarmscene.plugins.event.motor_failure import MotorFailure
from swarmscene.plugins.event.stuck import Stuck

DT = 0.01
ALT = 2.0


def six_vehicle_positions(d: float = 2.72) -> np.ndarray:
    """Q1 (index 0) leads a triangle; Q2 (index 1) is right behind it (see tests/methods/cem/test_flow.py)."""
    s3 = np.sqrt(3.0)
    xy = np.array([[0, 0], [-s3 * d, 0], [-s3 / 2 * d, d / 2], [-s3 / 2 * d, -d / 2], [-s3 * d, d], [-s3 * d, -d]])
    return np.column_stack([xy, np.full(len(xy), ALT)])


def build(pos: np.ndarray, seed: int = 0, **params) -> tuple[CEM, WorldState, SimpleNamespace]:
    world = WorldState.at_rest(pos)
    ctx = BuildContext(n=world.n, guidance_period=DT, physics_step=DT, duration=60.0, separation_limit=1.36,
                       clearance_limit=0.0, comm_range=50.0, environment=None, rng=np.random.default_rng(seed),
                       initial=world)
    return CEM(CEM.Params(**params), ctx), world, SimpleNamespace(world=world)


def formation(world: WorldState, v=(1.0, 0.0)) -> Setpoints:
    """A formation flying rigidly at v (TRACK), failed vehicles holding."""
    sp = Setpoints.hold(world.pos)
    live = world.healthy
    sp.mode[live] = Mode.TRACK
    sp.vel[live, :2] = v
    sp.pos[live, :2] += np.asarray(v) * DT
    sp.pos[:, 2] = ALT
    return sp


def fly(plugin: CEM, world: WorldState, sim, ticks: int, events: dict[int, list[Event]], v=(1.0, 0.0),
        tracking_error=None, record=None) -> dict:
    """Kinematic loop: events, formation, avoidance, perfect (or perturbed) tracking, step end."""
    rng = np.random.default_rng(99)
    for k in range(ticks):
        for ev in events.get(k, []):
            ev.apply(world)
            plugin.swarmscene_event(sim=sim, event=ev)
        sp = formation(world, v)
        out = plugin.adjust(world, None, sp)
        if record is not None:
            record.append((sp, out, plugin.mode.active))
        live = world.healthy
        world.pos[live] = out.pos[live]
        world.vel[live] = out.vel[live]
        if tracking_error is not None:  # bounded tracking error, |e| <= tracking_error
            ang = rng.uniform(0, 2 * np.pi, live.sum())
            rad = tracking_error * np.sqrt(rng.uniform(0, 1, live.sum()))
            world.pos[live, 0] += rad * np.cos(ang)
            world.pos[live, 1] += rad * np.sin(ang)
        world.t += DT
        plugin.swarmscene_step_end(sim=sim)
    metrics: dict = {}
    plugin.swarmscene_run_end(sim=sim, metrics=metrics)
    return metrics


def hover(at_tick: int, *agents: int) -> Event:
    return Hover.event(at_tick * DT, tuple(agents))


# ---- params and registration ---------------------------------------------------------------------


SIGMA, A_P = 1e-3, 1.36
PRINTED_DRIFT = 2 * 5 * SIGMA  # eq. 6 as printed: |psi - psi_0| <= 2 |r_noise| (tests/methods/cem/test_flow.py)
GUARD = 1e-6 * A_P  # the branch guard moves commands deeper than this out of a_p


def test_params_defaults_are_the_papers_and_validate():
    p = CEM.Params()
    assert (p.K, p.newton_iterations, p.sigma, p.v_des, p.eps, p.delta, p.direction) == (2, 20, 1e-3, 1.0, 0.28, 0.40, "auto")
    assert (p.saddle_noise, p.multi_failure_flow) == ("printed", "ring_streamlines")  # the readings
    plugin, _, _ = build(six_vehicle_positions())
    assert plugin.mode.a_f == pytest.approx(0.68) and plugin.mode.a_p == pytest.approx(1.36)
    assert plugin.mode.hand_back.distance == pytest.approx(2.72)
    for bad in ({"K": 0}, {"newton_iterations": 0}, {"sigma": -1.0}, {"v_des": 0.0}, {"direction": "north"}, {"speed": 1.0},
                {"saddle_noise": "always"}, {"multi_failure_flow": "sum"}):
        with pytest.raises(ValidationError):
            CEM.Params(**bad)
    assert CEM.Params(direction=90).direction == 90


def test_module_registers_the_class():
    got = []
    cem_module.swarmscene_register_avoidances(register=got.append)
    assert got == [CEM] and CEM.name == "cem"


def test_inactive_passes_setpoints_through_and_comm_loss_does_not_activate():
    plugin, world, sim = build(six_vehicle_positions())
    sp = formation(world)
    assert plugin.adjust(world, None, sp) is sp
    ev = CommLoss.event(0.0, (0,))
    ev.apply(world)
    plugin.swarmscene_event(sim=sim, event=ev)
    assert not plugin.mode.active and plugin.adjust(world, None, sp) is sp


def test_motor_failure_activates_like_hover_but_moving_faults_do_not():
    """A vehicle that lost a rotor is a doublet at the point where it failed, as a hovering one;
    stuck and drifting vehicles break Assumption 3 (they move), so CEM leaves them out."""
    for kind, extra in ((Stuck, {}), (Drift, {"velocity": (0.2, 0.0, 0.0)})):
        plugin, world, sim = build(six_vehicle_positions())
        ev = kind.event(0.0, (0,), **extra)
        ev.apply(world)
        plugin.swarmscene_event(sim=sim, event=ev)
        assert not plugin.mode.active and plugin.mode.failed == {}
    plugin, world, sim = build(six_vehicle_positions())
    ev = MotorFailure.event(0.0, (0,), rotor=2, fraction=0.0)
    ev.apply(world)
    plugin.swarmscene_event(sim=sim, event=ev)
    assert plugin.mode.active and list(plugin.mode.failed) == [0]
    np.testing.assert_array_equal(plugin.mode.failed[0], world.pos[0, :2])
    hovering, hworld, hsim = build(six_vehicle_positions())
    ev = hover(0, 0)
    ev.apply(hworld)
    hovering.swarmscene_event(sim=hsim, event=ev)
    # the same flow: direction, doublet centres and every agent's (phi, psi)
    assert plugin.mode.nav.theta == hovering.mode.nav.theta
    np.testing.assert_array_equal(plugin.mode.nav.centres, hovering.mode.nav.centres)
    np.testing.assert_array_equal(plugin.mode.nav.w0, hovering.mode.nav.w0)


# ---- section V-A through the plugin --------------------------------------------------------------


@pytest.fixture(scope="module")
def six_run():
    """Gated saddle noise: the commands sit on their streamlines exactly (eq. 4), so the paper's
    invariants are asserted to rounding; the default printed reading is tested beside it."""
    plugin, world, sim = build(six_vehicle_positions(), seed=1, saddle_noise="gated")
    record: list = []
    metrics = fly(plugin, world, sim, 1700, {100: [hover(100, 0)]}, record=record)
    return plugin, world, metrics, record


def test_six_vehicle_metrics_reproduce_section_v_a(six_run):
    plugin, world, m, _ = six_run
    assert m["cem.activations"] == 1
    assert m["cem.theorem2_holds"] and m["cem.theorem2_applicable"]
    assert not m["cem.theorem1_holds"]  # conservative: p_min0^2 / lambda_max = 1.04 < 1.85
    assert m["cem.theorem1_lhs"] == pytest.approx(2.04**2 / 4) and m["cem.theorem1_rhs"] == pytest.approx(1.8496)
    assert m["cem.min_pair_distance"] >= m["cem.pair_bound"] == pytest.approx(1.36)  # Fig. 9
    assert m["cem.separation_holds"]
    assert m["cem.min_exclusion_margin"] >= -1e-12  # no command inside a_p
    assert m["cem.min_actual_clearance"] >= DELTA_BOUND - 1e-12
    assert m["cem.psi_drift_max"] < 1e-9  # eq. 4
    assert 1.0 < m["cem.max_speed"] < 1.4  # K = 2 (Fig. 10)
    assert m["cem.dphi_min"] < 0.05 * 1.0 * DT  # Fig. 8
    assert m["cem.handback_time"] is not None
    json.dumps(m)  # metrics.json-ready


DELTA_BOUND = 0.40  # perfect tracking: the vehicle keeps a_p - a_f - eps = delta in hand


def test_commands_while_active_are_track_setpoints_with_the_formations_altitude(six_run):
    plugin, world, m, record = six_run
    active = [(sp, out) for sp, out, on in record if on]
    sp, out = active[10]
    assert (out.mode[1:] == Mode.TRACK).all() and out.mode[0] == Mode.HOLD
    assert (out.pos[:, 2] == ALT).all() and (out.vel[1:, 2] == 0).all()
    prev = active[9][1]
    np.testing.assert_allclose(out.vel[1:, :2], (out.pos[1:, :2] - prev.pos[1:, :2]) / DT, atol=1e-9)
    np.testing.assert_array_equal(out.pos[0], sp.pos[0])  # the failed lead is left alone


def test_hand_back_returns_the_formations_setpoints_once_all_have_passed(six_run):
    plugin, world, m, record = six_run
    flags = [on for _, _, on in record]
    first_off = next(i for i in range(101, len(flags)) if not flags[i])
    assert all(flags[101:first_off]) and not any(flags[first_off:])
    sp, out, _ = record[first_off]
    assert out is sp
    assert m["cem.handback_time"] == pytest.approx(first_off * DT)
    healthy_x = record[first_off - 1][1].pos[1:, 0]
    assert healthy_x.min() >= 0.0 + plugin.mode.hand_back.distance - 0.02  # all past the failed lead


def test_printed_saddle_noise_through_the_plugin_keeps_theorem_2_within_its_measured_bounds():
    """The default reading (eq. 6 as printed): Fig. 9's separation holds, psi drifts by at most
    2 |r_noise| (<= 0.01), commands enter a_p by at most the guard's 1.36 um, and the seed matters."""
    runs = []
    for seed in (1, 2):
        plugin, world, sim = build(six_vehicle_positions(), seed=seed)
        runs.append(fly(plugin, world, sim, 1700, {100: [hover(100, 0)]}))
    for m in runs:
        assert m["cem.separation_holds"] and m["cem.min_pair_distance"] >= m["cem.pair_bound"]
        assert 1e-4 < m["cem.psi_drift_max"] <= PRINTED_DRIFT
        assert m["cem.min_exclusion_margin"] >= -GUARD
        assert m["cem.theorem2_holds"] and m["cem.handback_time"] is not None
    assert runs[0]["cem.max_speed"] != runs[1]["cem.max_speed"]


def test_psi_drift_is_reported_per_agent(six_run):
    _, _, m, _ = six_run
    per = m["cem.psi_drift_per_agent"]
    assert len(per) == 6 and per[0] == 0.0 and max(per) == m["cem.psi_drift_max"]


# ---- direction -----------------------------------------------------------------------------------


def test_auto_direction_from_velocity_and_from_bearing():
    pos = six_vehicle_positions()
    rot = pos.copy()
    rot[:, 0], rot[:, 1] = -pos[:, 1], pos[:, 0]  # the formation turned to fly north
    plugin, world, sim = build(rot)
    ev = hover(0, 0)
    ev.apply(world)
    plugin.swarmscene_event(sim=sim, event=ev)
    assert plugin.mode.nav.theta == pytest.approx(math.pi / 2)  # at rest: towards the failure
    plugin, world, sim = build(rot)
    world.vel[:, :2] = [0.3, -0.3]
    ev.apply(world)
    plugin.swarmscene_event(sim=sim, event=ev)
    assert plugin.mode.nav.theta == pytest.approx(-math.pi / 4)  # moving: the mean velocity's heading
    plugin, world, sim = build(rot, direction=90.0)
    world.vel[:, :2] = [0.3, -0.3]
    ev.apply(world)
    plugin.swarmscene_event(sim=sim, event=ev)
    assert plugin.mode.nav.theta == pytest.approx(math.pi / 2)  # fixed by config


def test_northbound_formation_avoids_its_failed_lead():
    pos = six_vehicle_positions()
    rot = pos.copy()
    rot[:, 0], rot[:, 1] = -pos[:, 1], pos[:, 0]
    plugin, world, sim = build(rot, seed=3)
    m = fly(plugin, world, sim, 1500, {50: [hover(50, 0)]}, v=(0.0, 1.0))
    assert m["cem.separation_holds"] and m["cem.min_exclusion_margin"] >= -GUARD  # printed eq. 6
    assert m["cem.psi_drift_max"] <= PRINTED_DRIFT and m["cem.handback_time"] is not None


# ---- tracking error bounded by delta (section V-B in miniature) -----------------------------------


def test_two_vehicles_with_tracking_error_stay_clear_of_a_f():
    pos = six_vehicle_positions()[:2]
    plugin, world, sim = build(pos, seed=2)
    m = fly(plugin, world, sim, 1300, {50: [hover(50, 0)]}, tracking_error=DELTA_BOUND)
    assert 0 < m["cem.tracking_error_max"] <= DELTA_BOUND
    assert m["cem.min_actual_clearance"] >= 0.0  # the body never touches the a_f cylinder
    assert m["cem.min_exclusion_margin"] >= -GUARD  # printed eq. 6: the guard's tolerance
    assert m["cem.theorem1_holds"] and m["cem.theorem2_holds"]  # one healthy agent: nothing to collide


# ---- several failures at different times (Theorem 1) ---------------------------------------------


def grid(spacing: float = 6.0) -> np.ndarray:
    xy = np.array([[x, y] for x in (0.0, -spacing, -2 * spacing) for y in (-1.5, -0.5, 0.5, 1.5)]) * [1, spacing]
    return np.column_stack([xy, np.full(len(xy), ALT)])


@pytest.fixture(scope="module")
def multi_run():
    plugin, world, sim = build(grid(), seed=4)
    events = {50: [hover(50, 0, 3)], 350: [hover(350, 6)]}  # two front corners, then a middle agent
    m = fly(plugin, world, sim, 4000, events)
    return plugin, m


def test_three_failures_one_later_keep_theorem_1(multi_run):
    plugin, m = multi_run
    assert m["cem.activations"] == 2 and plugin.mode.nav.centres.size == 3
    assert m["cem.theorem1_holds"]  # precondition at both activations
    assert not m["cem.theorem2_applicable"] and not m["cem.theorem2_holds"]
    assert m["cem.min_pair_distance"] >= m["cem.pair_bound"]  # and its conclusion
    assert m["cem.min_exclusion_margin"] >= -GUARD  # printed eq. 6: the guard's tolerance
    assert m["cem.psi_drift_max"] < 0.02  # several doublets: circles are streamlines to first order
    assert m["cem.max_speed"] < 1.5
    assert m["cem.handback_time"] is not None


def test_agent_starting_inside_a_p_is_counted_and_commanded_out():
    pos = np.array([[0.0, 0.0, ALT], [-1.0, 0.3, ALT], [-5.0, 3.0, ALT]])  # agent 1 is 1.04 m from agent 0
    plugin, world, sim = build(pos, seed=5)
    m = fly(plugin, world, sim, 200, {0: [hover(0, 0)]})
    assert m["cem.start_inside_exclusion"] == 1
    assert m["cem.min_exclusion_margin"] >= -1e-12  # every command is outside a_p nonetheless


def test_multi_failure_activations_start_outside(multi_run):
    _, m = multi_run
    assert m["cem.start_inside_exclusion"] == 0


def test_newton_iterations_is_named_apart_from_swarm_n_and_the_old_key_still_works():
    """CEM's Newton iteration count n (Alg. 2) reads avoidance.newton_iterations; avoidance.n, easily
    read as swarm.n, is accepted for one release with a deprecation warning."""
    from swarmscene import api

    assert api.load(["scenario=cem_six_vehicle"]).plugin_params["avoidance"].newton_iterations == 20
    with pytest.warns(DeprecationWarning, match="avoidance.n is deprecated: write avoidance.newton_iterations"):
        scenario = api.load(["scenario=cem_six_vehicle", "avoidance.n=5"])
    assert scenario.plugin_params["avoidance"].newton_iterations == 5
    assert "n" not in scenario.data["avoidance"]


def strengths(plugin: CEM, n_failures: int) -> np.ndarray | None:
    """The doublet strengths mu_f the plugin's ``multi_failure_flow`` gives ``n_failures`` failures."""
    return failure_strengths(plugin.mode.settings.multi_failure_flow, plugin.mode.a_p, n_failures)


def test_multi_failure_flow_readings_are_eq_1_for_one_failure_and_differ_for_several():
    """multi_failure_flow: 'summed' is eq. 1 as printed (N_f uniform terms = mu_f a_p^2 / N_f after
    dividing f by N_f), 'unit_doublets' mu_f = a_p^2, 'ring_streamlines' the solved strengths."""
    from swarmscene.methods.cem.flow import doublet_strengths

    a2 = A_P**2
    got = {rule: build(grid(), multi_failure_flow=rule)[0] for rule in ("ring_streamlines", "unit_doublets", "summed")}
    assert strengths(got["ring_streamlines"], 3) is None  # the navigator solves them
    np.testing.assert_allclose(strengths(got["unit_doublets"], 3), a2)
    np.testing.assert_allclose(strengths(got["summed"], 3), a2 / 3)
    for plugin in got.values():  # one failure: every reading is eq. 1 exactly
        mu = strengths(plugin, 1)
        np.testing.assert_allclose(doublet_strengths(np.array([0j]), A_P) if mu is None else mu, a2)
    for rule, plugin in got.items():  # and the navigator flies the reading's strengths
        world = WorldState.at_rest(grid())
        world.healthy[[0, 3, 6]] = False
        plugin.mode.failed = {0: world.pos[0, :2].copy(), 3: world.pos[3, :2].copy(), 6: world.pos[6, :2].copy()}
        plugin.mode.activate(world)
        expected = doublet_strengths(plugin.mode.nav.centres, A_P) if rule == "ring_streamlines" else strengths(plugin, 3)
        np.testing.assert_allclose(plugin.mode.nav.strengths, expected)


# ---- hand-back test of the formation's setpoints (issue #26) -------------------------------------


def test_segment_clearance_is_the_distance_to_the_closest_point_of_each_path():
    from swarmscene.methods.cem.flow import segment_clearance

    start = np.array([[-3.0, 1.0], [2.0, 0.0], [0.0, 5.0]])
    end = np.array([[3.0, 1.0], [4.0, 0.0], [0.0, 5.0]])  # crossing above, pointing away, zero length
    got = segment_clearance(start, end, np.array([[0.0, 0.0], [10.0, 0.0]]))
    np.testing.assert_allclose(got, [1.0, 2.0, 5.0])
    assert segment_clearance(start, end, np.zeros((0, 2))).tolist() == [np.inf] * 3


def fly_back(rule: str, ticks: int = 1700):
    """Section V-A, but after t = 12 s the formation turns round (-x at 1 m/s) into the failed lead."""
    plugin, world, sim = build(six_vehicle_positions(), seed=1, saddle_noise="gated", hand_back_rule=rule)
    events, flags, closest = {100: [hover(100, 0)]}, [], math.inf
    for k in range(ticks):
        for ev in events.get(k, []):
            ev.apply(world)
            plugin.swarmscene_event(sim=sim, event=ev)
        sp = formation(world, (1.0, 0.0) if k < 1200 else (-1.0, 0.0))
        out = plugin.adjust(world, None, sp)
        flags.append(plugin.mode.active)
        live = world.healthy
        world.pos[live], world.vel[live] = out.pos[live], out.vel[live]
        world.t += DT
        plugin.swarmscene_step_end(sim=sim)
        closest = min(closest, float(np.linalg.norm(world.pos[1:, :2] - world.pos[0, :2], axis=1).min()))
    metrics: dict = {}
    plugin.swarmscene_run_end(sim=sim, metrics=metrics)
    return metrics, flags, closest


def test_clear_path_reactivates_cem_when_a_setpoint_heads_back_into_a_failed_vehicle():
    m, flags, closest = fly_back("clear_path")
    off = flags.index(False, 101)  # handed back: every setpoint 1 cm ahead of its agent, clear of a_p
    assert not all(flags[off:]) and any(flags[off:])  # and activated again once the paths turned back
    assert m["cem.activations"] == 2
    assert closest >= A_P - 1e-6 and m["cem.clearance_holds"] and m["cem.min_actual_clearance"] >= DELTA_BOUND - 1e-6
    old, _, old_closest = fly_back("passed")
    assert old["cem.activations"] == 1 and old_closest < A_P - DELTA_BOUND  # the old rule flies into it
    assert not old["cem.clearance_holds"] and old["cem.violations.clearance.agents"][-1] == 0
