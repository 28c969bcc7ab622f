"""outdoor_mission (thesis section 4.3.1, 4.5.2): the workflow in a run, the outdoor_square mission.

The method-level checks (swarm map, catch-up rule) are tests/methods/outdoor/test_mission.py."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.methods.outdoor.mission import Task

QUIET = ["output.progress=off", "output.summary=false", "output.trajectory=false"]
D_Q, T_MSG, T_FOR, T_INI, T_LED, T_FOL, TAU = 0.55, 2.0, 40.0, 5.0, 10.0, 10.0, 0.2
T_FAIL = 40.0  # outdoor_square_failure: follower 5 hovers


def build(overrides, events=None):
    data = api.compose(overrides)
    if events is not None:
        data["events"] = events
    return api.build(data)


def run_to(sim, t_end: float) -> None:
    while sim.world.t < t_end - 1e-9:
        sim.step()


@pytest.fixture(scope="module")
def square():
    sim = api.build(["scenario=outdoor_square", *QUIET])
    return sim, sim.run()


@pytest.fixture(scope="module")
def failure():
    sim = api.build(["scenario=outdoor_square_failure", *QUIET])
    return sim, sim.run()


def test_comm_loss_agent_disappears_from_the_others_maps():
    sim = build(["scenario=outdoor_square", *QUIET],
                [{"at": 30.0, "agents": [4], "name": "comm_loss"}])
    run_to(sim, 30.0 + T_MSG - 0.3)
    others = np.arange(8) != 4
    assert sim.formation.mission.map.present[others, 4].all()  # still within T_msg
    run_to(sim, 30.0 + T_MSG + 0.2)
    assert not sim.formation.mission.map.present[others, 4].any()
    assert not sim.formation.mission.map.present[4, others].any()  # and it hears nobody
    assert sim.formation.mission.map.present[4, 4]  # it still knows itself


# -- workflow ----------------------------------------------------------------------------------


def test_followers_wait_T_ini_for_a_stable_map_then_form():
    sim = api.build(["scenario=outdoor_square", *QUIET])
    task = sim.formation.mission.task
    run_to(sim, T_INI)
    assert task[1] == Task.LEAD and np.all(np.delete(task, 1) == Task.INIT)
    run_to(sim, T_INI + 0.5)
    assert np.all(np.delete(task, 1) == Task.FORM)
    # every follower was given a distinct slot
    slots = np.delete(sim.formation.mission.slot, 1)
    assert len(set(slots.tolist())) == 7 and slots.min() >= 0


def test_one_assignment_per_tick_when_every_map_holds_the_same_messages(square):
    # d_com covers the swarm: every follower's map is the same snapshot (one hop), so the seven
    # FORM followers share one solve per tick (fewer when the rounded view repeats)
    m = square[1].metrics
    forming_ticks = (m["outdoor.formed_at"] - T_INI) / 0.1 + 1
    assert 0 < m["outdoor.assignment_solves"] <= forming_ticks


def test_multi_hop_maps_still_complete_the_mission_safely():
    # d_com = 6 m > d_r: the line start and the formation are multi-hop (maps differ by hops)
    sim = api.build(["scenario=outdoor_square", "comm.range=6.0", *QUIET])
    result = sim.run()
    hops = sim.formation.mission._hops
    assert np.nanmax(hops[np.isfinite(hops)]) >= 2
    m = result.metrics
    assert m["outdoor.mission_complete"] is True and m["outdoor.ignored"] == []
    assert m["collisions"] == 0 and m["min_separation"] >= D_Q
    assert 4.2 <= m["outdoor.neighbour_distance_min"] <= m["outdoor.neighbour_distance_max"] <= 5.8


def test_a_lone_leader_aborts_after_T_led_and_the_cut_off_follower_stops_after_T_fol():
    sim = build(["scenario=outdoor_square", "swarm.n=2", "swarm.leader=0", *QUIET, "clock.duration=30"],
                [{"at": 0.0, "agents": [1], "name": "comm_loss"}])
    run_to(sim, T_LED - 0.2)
    assert sim.formation.mission.task[0] == Task.LEAD and not sim.formation.mission.leader.aborted
    run_to(sim, T_LED + 0.2)
    assert sim.formation.mission.leader.aborted and sim.formation.mission.task[0] == Task.STOP
    assert sim.formation.mission.task[1] == Task.STOP  # no leader after T_fol: stop sequence (home)
    result = sim.run()
    assert result.metrics["outdoor.mission_complete"] is False


# -- the outdoor_square mission (thesis 4.5.2-4.5.3) ----------------------------------------------


def test_outdoor_square_mission_completes(square):
    sim, result = square
    m = result.metrics
    assert result.stop_reason == "complete" and m["outdoor.mission_complete"] is True
    assert m["outdoor.waypoints_visited"] == 5 and m["outdoor.ignored"] == []
    assert m["outdoor.followers_home"] == 7
    assert m["outdoor.formed_at"] is not None
    assert m["outdoor.formed_at"] < m["outdoor.path_done_at"] < m["outdoor.last_home_at"]
    # the 53 m square at 1 m/s: 53 s, as the thesis' leader (waypoint 1 at 34 s, 5 at 87 s)
    assert m["outdoor.path_done_at"] - m["outdoor.departed_at"] == pytest.approx(53.0, abs=1.0)
    form = sim.formation.mission
    followers = np.arange(8) != 1
    home_error = np.linalg.norm(sim.world.pos[followers] - form.home[followers], axis=1)
    assert np.all(home_error < 0.5)
    assert np.linalg.norm(sim.world.pos[1] - form.home[1]) < 0.5  # last waypoint = home


def test_outdoor_square_neighbour_distance_and_tracking_error(square):
    m = square[1].metrics
    # Fig. 4.21: mean neighbour distance ~ d_r = 5 m, always within [4.2, 5.8] m
    assert m["outdoor.mean_neighbour_distance"] == pytest.approx(5.0, abs=0.2)
    assert m["outdoor.neighbour_distance_min"] >= 4.2
    assert m["outdoor.neighbour_distance_max"] <= 5.8
    # Fig. 4.24 / section 4.5.3: "the average tracking error [the mean over the followers of the
    # distance to their slot] remains below 0.8 m", a bound throughout the following sequence: the
    # largest per-tick mean (outdoor.tracking_error_max), not its time average, must stay below it.
    assert m["outdoor.tracking_error_max"] < 0.8
    assert m["outdoor.tracking_error_mean"] <= m["outdoor.tracking_error_max"]


def test_outdoor_square_no_two_agents_closer_than_d_q_including_forming(square):
    sim, result = square
    assert result.metrics["collisions"] == 0
    assert result.metrics["min_separation"] >= D_Q
    start = sim.formation.mission.home
    assert np.linalg.norm(start[1] - start[2]) < 1.65  # the hard start: closer than d_c


def test_failed_follower_is_ignored_after_T_msg_and_T_for_and_the_mission_completes(square, failure):
    sim, result = failure
    m = result.metrics
    assert result.stop_reason == "complete" and m["outdoor.mission_complete"] is True
    assert m["outdoor.ignored"] == [5]
    (t_ignored, ids), = m["outdoor.ignored_at"]
    assert ids == [5]
    # fails at 40 s: its entry expires after T_msg (its last messages in flight are lost, up to
    # one hop), then the leader waits T_for for it to be back in FLOW
    assert T_FAIL + T_MSG - TAU + T_FOR - 1e-6 <= t_ignored <= T_FAIL + T_MSG + T_FOR + 0.1
    # the leader stood still from the expiry to the ignore: the path took T_for longer
    nominal = square[1].metrics
    extra = (m["outdoor.path_done_at"] - m["outdoor.departed_at"]) - (
        nominal["outdoor.path_done_at"] - nominal["outdoor.departed_at"])
    assert extra == pytest.approx(T_FOR, abs=0.5)
    assert m["outdoor.followers_home"] == 6 and m["healthy_at_end"] == 7
    assert m["outdoor.mean_neighbour_distance"] == pytest.approx(5.0, abs=0.2)
    assert m["collisions"] == 0
