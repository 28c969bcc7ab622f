"""Take-off and landing (swarm.takeoff, swarm.land; issue #37): the flights from and to the floor.

The mission's clock is the same with a take-off (the formation is first asked at t = 0, events
fire at their mission times); the climb and the descent follow the minimum-jerk profile; a landing
ends with every healthy vehicle resting on the floor, or counts the ones that did not make it."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.phases import LAND_PRESS, min_jerk

FLOOR = 0.0


def phased(data: dict, takeoff=None, land=None, floor=FLOOR) -> dict:
    data["environment"]["floor"] = floor
    data["swarm"]["takeoff"] = takeoff
    data["swarm"]["land"] = land
    return data


def test_the_minimum_jerk_profile_rises_from_rest_to_rest_and_its_rates_are_its_derivatives():
    # the quintic of Flash & Hogan (1985), written out: s = 10 u^3 - 15 u^4 + 6 u^5
    u = np.linspace(0.0, 1.0, 101)
    expected = 10 * u**3 - 15 * u**4 + 6 * u**5
    s, ds, dds = np.array([min_jerk(x) for x in u]).T
    np.testing.assert_allclose(s, expected, atol=1e-15)
    h = 1e-6
    inner = u[1:-1]
    numeric = [(min_jerk(x + h)[0] - min_jerk(x - h)[0]) / (2 * h) for x in inner]
    np.testing.assert_allclose(ds[1:-1], numeric, atol=1e-8)
    numeric2 = [(min_jerk(x + h)[1] - min_jerk(x - h)[1]) / (2 * h) for x in inner]
    np.testing.assert_allclose(dds[1:-1], numeric2, atol=1e-7)
    assert (s[0], ds[0], dds[0], s[-1], ds[-1], dds[-1]) == (0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    assert min_jerk(-0.5) == (0.0, 0.0, 0.0) and min_jerk(1.5) == (1.0, 0.0, 0.0)  # at rest outside


def test_a_takeoff_starts_on_the_floor_below_the_start_and_the_mission_clock_is_unchanged(data, monkeypatch):
    sim = api.build(phased(data, takeoff=3.0))
    targets = sim.phases.targets.copy()
    asked: list[float] = []
    setpoints = type(sim.formation).setpoints

    def recorded(self, world, sensing):
        asked.append(world.t)
        return setpoints(self, world, sensing)

    monkeypatch.setattr(type(sim.formation), "setpoints", recorded)
    result = sim.run()
    t, pos = np.asarray(result.trajectory["t"]), np.asarray(result.trajectory["pos"])
    assert t[0] == -3.0
    np.testing.assert_array_equal(pos[0, :, :2], targets[:, :2])
    assert np.all(pos[0, :, 2] == FLOOR)
    assert asked[0] == 0.0  # the formation rests during the climb, and starts at mission time 0
    at_zero = int(np.flatnonzero(np.isclose(t, 0.0))[0])
    np.testing.assert_allclose(pos[at_zero], targets, atol=0.05)  # arrived, at rest
    assert np.abs(np.asarray(result.trajectory["vel"])[at_zero]).max() < 0.1  # nearly still: the tracker lags
    climbing = pos[1:at_zero]
    np.testing.assert_allclose(climbing[:, :, :2], np.broadcast_to(targets[:, :2], climbing[:, :, :2].shape), atol=1e-9)
    m = result.metrics
    assert m["phases.takeoff"] == 3.0 and "phases.landed" not in m
    assert m["duration"] == pytest.approx(m["steps"] * 0.1) and m["duration"] == pytest.approx(t[-1] + 3.0)
    assert m["floor.crashes"] == 0 and m["success"] is True


def test_events_fire_at_their_mission_times_after_a_takeoff(data):
    """A drift straight down from t = 0.5 s, 1 m/s, from 2 m: under the floor in the tick ending at
    2.5 s with a take-off as without one (tests/core/test_floor.py)."""
    data = phased(data, takeoff=2.0)
    data["events"] = [{"at": 0.5, "agents": [0], "name": "drift", "velocity": [0.0, 0.0, -1.0]}]
    data["termination"]["on_complete"] = False
    data["clock"]["duration"] = 4.0
    m = api.run(data).metrics
    assert m["violations.floor.first_time"] == pytest.approx(2.5) and m["violations.floor.agents"] == [0]


def test_a_landing_brings_every_healthy_vehicle_down_to_rest_on_the_floor(data):
    data = phased(data, takeoff=2.0, land=4.0)
    data["termination"]["on_complete"] = False
    data["clock"]["duration"] = 6.0
    sim = api.build(data)
    result = sim.run()
    m = result.metrics
    assert m["phases.land_start"] == pytest.approx(6.0)  # the mission's end
    assert (m["phases.landed"], m["phases.airborne"]) == (data["swarm"]["n"], 0)
    assert m["floor.landings"] == data["swarm"]["n"] and m["floor.crashes"] == 0  # each slowly, once
    assert np.all(sim.world.pos[:, 2] == FLOOR) and np.all(sim.world.vel == 0.0)
    assert m["stop_reason"] == "duration"
    t, pos = np.asarray(result.trajectory["t"]), np.asarray(result.trajectory["pos"])
    # down below where each vehicle was when the mission ended (it was flying at ~0.7 m/s: braking
    # to that point carries it on a little first)
    start = pos[int(np.flatnonzero(np.isclose(t, 6.0))[0])]
    np.testing.assert_allclose(pos[-1, :, :2], start[:, :2], atol=0.1)
    assert t[-1] <= 6.0 + 2 * 4.0 + 1e-9


def test_the_landing_reference_ends_below_the_floor_so_an_exact_tracker_touches_it(data):
    sim = api.build(phased(data, land=2.0))
    sim.phases.begin_landing(sim.world, True, completed=True)
    end = sim.phases.setpoints(sim.world.t + 2.0)
    np.testing.assert_allclose(end.pos[:, 2], FLOOR - LAND_PRESS, atol=1e-12)
    assert np.all(end.vel == 0.0) and np.all(end.acc == 0.0)
    half = sim.phases.setpoints(sim.world.t + 1.0)  # s(1/2) = 1/2
    np.testing.assert_allclose(half.pos[:, 2], (sim.world.pos[:, 2] + FLOOR - LAND_PRESS) / 2, atol=1e-12)


def test_a_landing_too_short_to_end_on_the_floor_counts_the_vehicles_left_in_the_air(data):
    data = phased(data, land=0.1)  # one tick to come down from 2 m (and one more to wait)
    data["termination"]["on_complete"] = False
    data["clock"]["duration"] = 2.0
    m = api.run(data).metrics
    assert m["phases.airborne"] == data["swarm"]["n"] and m["phases.landed"] == 0
    assert m["success"] is False
    assert m["steps"] == 20 + 2  # the mission, the landing's tick, its one tick of waiting


def test_a_mission_that_completes_lands_and_keeps_its_verdict(data):
    result = api.run(phased(data, land=3.0))
    m = result.metrics
    assert m["stop_reason"] == "complete" and m["phases.airborne"] == 0
    assert m["phases.land_start"] < data["clock"]["duration"]
    assert m["success"] is True  # the formation's verdict when the mission ended, not after the descent


@pytest.mark.parametrize(("key", "floor", "seconds", "message"), [
    ("takeoff", None, 2.0, "swarm.takeoff: needs a ground: set environment.floor"),
    ("land", None, 2.0, "swarm.land: needs a ground: set environment.floor"),
    ("land", 0.0, 0.05, "swarm.land: 0.05 s is shorter than one guidance tick"),
    ("takeoff", 0.0, -1.0, "swarm.takeoff"),
])
def test_a_phase_without_a_ground_or_shorter_than_a_tick_is_refused_in_one_line(data, key, floor, seconds, message):
    data["environment"]["floor"] = floor
    data["swarm"][key] = seconds
    with pytest.raises(ConfigError) as info:
        api.build(data)
    assert message in str(info.value) and "\n" not in str(info.value).strip()


def test_a_run_without_phases_records_no_phase_keys(data):
    assert "takeoff" not in api.compose([])["swarm"]
    record = api.build(data).config.model_dump(mode="json")
    assert "takeoff" not in record["swarm"] and "land" not in record["swarm"]


def test_a_batch_of_phased_worlds_is_its_single_runs():
    config = ["environment.floor=0", "swarm.takeoff=1", "swarm.land=2", "clock.duration=3", "output.summary=false"]
    for seed, batched in zip([0, 1], api.run_batch(config, [0, 1]), strict=True):
        alone = api.run([*config, f"seed={seed}"])
        np.testing.assert_array_equal(batched.trajectory["pos"], alone.trajectory["pos"])
        assert batched.metrics["phases.landed"] == alone.metrics["phases.landed"]


def test_the_summary_judges_the_mission_when_it_ended_and_the_landing_by_the_vehicles_left_aloft(data):
    from swarmscene.views.summary import FAIL, OK, verdicts

    data = phased(data, land=0.1)
    data["termination"]["on_complete"] = False
    data["clock"]["duration"] = 2.0
    sim = api.build(data)
    lines = {name: (status, detail) for name, status, detail in verdicts(sim, sim.run().metrics)}
    assert lines["landing"][0] == FAIL and lines["landing"][1].startswith("0 healthy vehicle(s) on the floor")
    assert "not complete when the run stopped at 2 s (then the landing)" in lines["mission"][1]
    landed = api.build(phased(api.compose([]), land=3.0))
    lines = {name: (status, detail) for name, status, detail in verdicts(landed, landed.run().metrics)}
    assert lines["landing"][0] == OK and lines["mission"][0] == OK


def test_a_takeoff_that_is_not_whole_ticks_still_starts_its_climb_on_the_floor(data):
    """1.04 s at T_s = 0.1 s is 10 ticks: the climb's profile spans those 1.0 s, so its first
    reference is the floor (over 1.04 s it would start 4 cm up)."""
    sim = api.build(phased(data, takeoff=1.04))
    assert sim.world.t == pytest.approx(-1.0)
    first = sim.phases.setpoints(sim.world.t)
    np.testing.assert_array_equal(first.pos[:, 2], np.full(sim.world.n, FLOOR))
    np.testing.assert_allclose(sim.phases.setpoints(0.0).pos, sim.phases.targets, atol=1e-12)
