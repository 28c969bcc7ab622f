"""Faults and random events: each fault's motion exactly, the draws' distributions over many seeds,
reproducibility from the seed, independence from the run's generator, one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from swarmscene import api
from swarmscene.core.config import ScenarioConfig
from swarmscene.core.errors import ConfigError
from swarmscene.core.events import Event, EventConfig, EventQueue, check_events, draw_event
from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.registry import installed_registry
from swarmscene.core.state import WorldState
from swarmscene.plugins.event.drift import Drift
from swarmscene.plugins.event.hover import Hover
from swarmscene.plugins.event.motor_failure import MotorFailure
from swarmscene.plugins.event.stuck import Stuck

INSTALLED = {"registry": installed_registry()}
"""The context a scenario validates in (the installed plugins' event kinds)."""


def scenario(data: dict, events: list[dict], duration: float = 3.0) -> dict:
    data["events"] = events
    data["clock"]["duration"] = duration
    data["termination"]["on_complete"] = False
    data["output"]["trajectory"] = True
    return data


def simulate(data: dict):
    """A run whose queue is built by ``EventQueue.from_scenario`` from the scenario's config (what
    the kernel is to call), with a listener recording every event the hook announces and the
    agents' flags at that moment."""
    config = api.load(data).config
    sim = api.build({**data, "events": []})
    sim.events = EventQueue.from_scenario(config)
    seen = []

    class Listener:
        @hookimpl
        def swarmscene_event(self, sim, event):
            seen.append((round(sim.world.t, 9), event, sim.world.healthy.copy()))

    sim.pm.register(Listener())
    return sim, sim.run(), seen


def tick_of(traj, t: float) -> int:
    return int(np.flatnonzero(np.isclose(traj["t"], t))[0])


# -- each fault's motion --------------------------------------------------------------------------
def test_stuck_vehicle_flies_on_at_its_last_velocity(data):
    """p(t) = p(t_f) + v(t_f) (t - t_f) for every t after the fault, v(t) = v(t_f)."""
    sim, result, seen = simulate(scenario(data, [{"at": 1.0, "agents": [2], "name": "stuck"}]))
    traj = result.trajectory
    k = tick_of(traj, 1.0)
    p_f, v_f = traj["pos"][k, 2], traj["vel"][k, 2]
    assert np.linalg.norm(v_f) > 0.1  # it was moving: the test would not see a frozen vehicle
    later = traj["t"] > 1.0
    expected = p_f + v_f * (traj["t"][later] - 1.0)[:, None]
    np.testing.assert_allclose(traj["pos"][later, 2], expected, rtol=0, atol=1e-12)
    assert np.all(traj["vel"][later, 2] == v_f)
    assert [(t, e.name, e.agents, bool(h[2])) for t, e, h in seen] == [(1.0, "stuck", (2,), False)]
    assert not traj["healthy"][-1, 2] and result.metrics["healthy_at_end"] == 4


def test_drift_vehicle_moves_at_the_drift_velocity(data):
    v_d = [0.2, -0.1, 0.05]
    sim, result, seen = simulate(
        scenario(data, [{"at": 0.5, "agents": [1], "name": "drift", "velocity": v_d}])
    )
    traj = result.trajectory
    p_f = traj["pos"][tick_of(traj, 0.5), 1]
    later = traj["t"] > 0.5
    np.testing.assert_allclose(traj["pos"][later, 1], p_f + np.outer(traj["t"][later] - 0.5, v_d),
                               rtol=0, atol=1e-12)
    assert np.all(traj["vel"][later, 1] == v_d)
    assert seen[0][1].name == "drift" and not seen[0][2][1]


def test_hover_holds_only_its_agents_and_motor_failure_is_left_to_the_dynamics(data):
    """Two failures at once: the hover agent is frozen exactly, the motor-failed one is marked
    failed (hook fired, healthy False) but moves as its dynamics model says (not held)."""
    events = [{"at": 1.0, "agents": [0], "name": "hover"},
              {"at": 1.0, "agents": [3], "name": "motor_failure", "rotor": 2, "fraction": 0.5}]
    data["dynamics"] = {"name": "quadrotor"}  # motor_failure needs a dynamics model with rotors
    sim, result, seen = simulate(scenario(data, events))
    traj = result.trajectory
    k = tick_of(traj, 1.0)
    assert np.all(traj["pos"][k:, 0] == traj["pos"][k, 0]) and np.all(traj["vel"][k + 1:, 0] == 0)
    moved = np.linalg.norm(traj["pos"][k + 1:, 3] - traj["pos"][k, 3], axis=1)
    assert moved.max() > 1e-3  # the quadrotor loses thrust: it is not frozen by the queue
    motor = [e for _, e, h in seen if e.name == "motor_failure"]
    assert motor == [MotorFailure.event(1.0, (3,), rotor=2, fraction=0.5)]
    assert all(not h[3] for _, e, h in seen if e.name == "motor_failure")
    assert not traj["healthy"][-1, [0, 3]].any()


def test_motor_failure_without_fraction_kills_the_rotor():
    config = EventConfig.model_validate({"at": 2.0, "agents": [1], "name": "motor_failure", "rotor": 0},
                                        context=INSTALLED)
    expected = MotorFailure.event(2.0, (1,), rotor=0, fraction=0.0)
    assert draw_event(config, 0, 4, seed=0) == expected


def test_the_last_fault_of_an_agent_decides_its_motion():
    """A hovering agent that then drifts leaves its hover point; the hold is per agent."""
    world = WorldState.at_rest(np.zeros((2, 3)))
    queue = EventQueue([Hover.event(0.0, (0, 1)), Drift.event(0.2, (1,), velocity=(1.0, 0.0, 0.0))],
                       guidance_period=0.1)
    for k in range(5):
        world.t = k * 0.1
        queue.apply_due(world)
        world.pos += 0.3  # whatever the dynamics did
        queue.hold(world)
    np.testing.assert_array_equal(world.pos[0], [0.0, 0.0, 0.0])
    # held at the origin until 0.2 s, then 1 m/s east until the end of the last tick (0.5 s)
    np.testing.assert_allclose(world.pos[1], [1.0 * (0.5 - 0.2), 0.0, 0.0], atol=1e-12)


def test_coasting_needs_the_guidance_period():
    with pytest.raises(ValueError, match="guidance period"):
        EventQueue([Stuck.event(1.0, (0,))])


# -- random events -------------------------------------------------------------------------------
def draws(event: dict, seeds, n: int = 6) -> list[Event]:
    config = EventConfig.model_validate(event, context=INSTALLED)
    return [draw_event(config, 0, n, seed) for seed in seeds]


def test_uniform_times_and_sampled_agents_are_uniform_over_seeds():
    """2,000 seeds: the times pass a KS test against U(2, 20); each of 6 agents is drawn ~1/6."""
    out = draws({"at": {"uniform": [2, 20]}, "agents": {"sample": 1}, "name": "hover"}, range(2000))
    times = np.array([e.at for e in out])
    assert stats.kstest(times, stats.uniform(2, 18).cdf).pvalue > 0.01
    assert times.min() >= 2 and times.max() <= 20
    counts = np.bincount([e.agents[0] for e in out], minlength=6)
    assert stats.chisquare(counts).pvalue > 0.01


@pytest.mark.parametrize("spec, reference", [
    ({"exponential": 8.0}, stats.expon(scale=8.0)),
    ({"normal": [10.0, 2.0]}, stats.norm(10.0, 2.0)),
    ({"lognormal": [1.0, 0.5]}, stats.lognorm(0.5, scale=np.e)),
])
def test_other_time_distributions_match_their_reference(spec, reference):
    times = [e.at for e in draws({"at": spec, "agents": [0], "name": "hover"}, range(2000))]
    assert stats.kstest(times, reference.cdf).pvalue > 0.01


def test_choice_and_a_sample_among_given_agents():
    out = draws({"at": {"choice": [1, 5]}, "agents": {"sample": 2, "among": [1, 3, 5]},
                 "name": "comm_loss"}, range(600))
    assert {e.at for e in out} == {1.0, 5.0}
    pairs = [e.agents for e in out]
    assert set(pairs) == {(1, 3), (1, 5), (3, 5)}  # distinct, sorted, from the pool only
    assert stats.chisquare(np.unique(pairs, axis=0, return_counts=True)[1]).pvalue > 0.01


def test_a_draw_below_zero_happens_at_zero():
    assert min(e.at for e in draws({"at": {"normal": [0.0, 1.0]}, "agents": [0], "name": "hover"},
                                    range(50))) == 0.0


def test_same_seed_same_draw_and_each_event_its_own_stream():
    event = {"at": {"uniform": [0, 100]}, "agents": {"sample": 3}, "name": "stuck"}
    a, b = draws(event, [7, 7], n=50)
    assert a == b
    assert draws(event, [8], n=50)[0] != a
    config = EventConfig.model_validate(event, context=INSTALLED)
    # The event's draw depends on its own index, not on the events before it.
    assert draw_event(config, 1, 50, 7) != a and draw_event(config, 0, 50, 7) == a


def test_random_events_leave_the_run_generator_and_trajectories_untouched(data):
    """An event drawn after the run ends changes nothing: same start, same generator state, the
    same trajectory bit for bit; the draw is reported so it can be replayed as a fixed event."""
    data["swarm"]["start"] = {"layout": "random", "spacing": 1.0, "extent": 8.0, "center": [0, 0, 2]}
    plain = scenario(data, [], duration=2.0)
    _, a, _ = simulate(plain)
    late = {"at": {"uniform": [50, 60]}, "agents": {"sample": 2}, "name": "hover"}
    sim, b, _ = simulate(scenario(dict(plain), [late], duration=2.0))
    assert np.array_equal(a.trajectory["pos"], b.trajectory["pos"])
    assert api.load(plain).rng_state == api.load(scenario(dict(plain), [late])).rng_state
    drawn = sim.events.drawn[0][1]
    assert sim.events.metrics() == {"events.0.at": drawn.at, "events.0.agents": list(drawn.agents)}
    assert 50 <= drawn.at <= 60 and len(set(drawn.agents)) == 2


def test_only_drawn_events_are_reported():
    config = ScenarioConfig.model_validate({
        "swarm": {"n": 4}, "formation": {"name": "a"}, "avoidance": {"name": "b"}, "dynamics": {"name": "c"},
        "events": [{"at": 1.0, "agents": [0], "name": "hover"},
                   {"at": 2.0, "agents": {"sample": 1, "among": [2]}, "name": "hover"}],
    }, context=INSTALLED)
    assert EventQueue.from_scenario(config).metrics() == {"events.1.at": 2.0, "events.1.agents": [2]}


def test_a_drawn_run_replays_as_fixed_events(data):
    random_event = {"at": {"uniform": [0.5, 1.5]}, "agents": {"sample": 1}, "name": "stuck"}
    sim, a, _ = simulate(scenario(data, [random_event], duration=2.0))
    m = sim.events.metrics()
    fixed = {"at": m["events.0.at"], "agents": m["events.0.agents"], "name": "stuck"}
    _, b, _ = simulate(scenario(data, [fixed], duration=2.0))
    assert np.array_equal(a.trajectory["pos"], b.trajectory["pos"])


def test_event_records_keep_only_the_keys_written(data):
    data = scenario(data, [{"at": 1.0, "agents": [0], "name": "hover"},
                           {"at": {"uniform": [1, 2]}, "agents": {"sample": 1}, "name": "drift",
                            "velocity": [0.1, 0, 0]}])
    recorded = api.load(data).data["events"]
    assert recorded == [{"at": 1.0, "agents": [0], "name": "hover"},
                        {"at": {"uniform": [1.0, 2.0]}, "agents": {"sample": 1}, "name": "drift",
                         "velocity": [0.1, 0.0, 0.0]}]


# -- bad input: one line naming the key -----------------------------------------------------------
@pytest.mark.parametrize("event, line", [
    ({"at": {"uniform": [20, 2]}, "agents": [0], "name": "hover"},
     "events.0.at.uniform: must be [low, high] with low <= high (got [20.0, 2.0])"),
    ({"at": {"uniform": [2, "x"]}, "agents": [0], "name": "hover"},
     "events.0.at.uniform.1: must be a number (got 'x')"),
    ({"at": {"unifrom": [2, 20]}, "agents": [0], "name": "hover"},
     "events.0.at.unifrom: unknown key (valid keys: uniform, normal, lognormal, exponential, choice)"
     " (got [2, 20])"),
    ({"at": {"uniform": [2, 20], "exponential": 3}, "agents": [0], "name": "hover"},
     "events.0.at: give exactly one distribution, one of uniform, normal, lognormal, exponential, "
     "choice (got {'uniform': [2, 20], 'exponential': 3})"),
    ({"at": {"normal": [5, -1]}, "agents": [0], "name": "hover"},
     "events.0.at.normal: must be [mean, std] with std >= 0 (got [5.0, -1.0])"),
    ({"at": {"exponential": 0}, "agents": [0], "name": "hover"},
     "events.0.at.exponential: must be > 0.0 (got 0)"),
    ({"at": -1.0, "agents": [0], "name": "hover"}, "events.0.at: must be >= 0.0 (got -1.0)"),
    ({"at": True, "agents": [0], "name": "hover"},
     "events.0.at: must be a number, not true/false (got True)"),
    ({"at": 1.0, "agents": {"sample": 0}, "name": "hover"}, "events.0.agents.sample: must be >= 1 (got 0)"),
    ({"at": 1.0, "agents": {"sample": 7}, "name": "hover"},
     "events.0.agents.sample: at most 5 distinct agents to draw from (got 7)"),
    ({"at": 1.0, "agents": {"sample": 1, "among": [2, 9]}, "name": "hover"},
     "events.0.agents.among: agents are 0..4 (got [9])"),
    ({"at": 1.0, "agents": [], "name": "hover"}, "events.0.agents: must have at least 1 item(s) (got [])"),
    ({"at": 1.0, "agents": [0], "name": "drift"},
     "events.0.velocity: a drift event needs its drift velocity [vx, vy, vz], m/s (got None)"),
    ({"at": 1.0, "agents": [0], "name": "stuck", "velocity": [1, 0, 0]},
     "events.0.velocity: only a drift event takes it (this event is stuck) (got (1.0, 0.0, 0.0))"),
    ({"at": 1.0, "agents": [0], "name": "motor_failure"},
     "events.0.rotor: a motor_failure event needs the index of the failed rotor (got None)"),
    ({"at": 1.0, "agents": [0], "name": "hover", "rotor": 1},
     "events.0.rotor: only a motor_failure event takes it (this event is hover) (got 1)"),
    ({"at": 1.0, "agents": [0], "name": "motor_failure", "rotor": 0, "fraction": 1.5},
     "events.0.fraction: must be <= 1.0 (got 1.5)"),
])
def test_bad_events_give_one_line_naming_the_key(data, event, line):
    data["events"] = [event]
    with pytest.raises(ConfigError) as exc:
        api.load(data)
    assert exc.value.lines == [line]


def test_check_events_accepts_a_pool_with_repeats():
    pool = {"sample": 2, "among": [1, 1, 2]}
    config = EventConfig.model_validate({"at": 1, "agents": pool, "name": "hover"}, context=INSTALLED)
    assert check_events([config], 3) == []
    assert draw_event(config, 0, 3, 0).agents == (1, 2)
