"""The kernel: phase order, clock, determinism, events, termination."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.plugin import Avoidance, Dynamics, Formation
from swarmscene.core.setpoint import Setpoints
from swarmscene.core.simulation import Simulation


def short(data: dict, duration: float = 3.0) -> dict:
    data["clock"]["duration"] = duration
    return data


def test_same_config_and_seed_give_bit_identical_results(data):
    data["swarm"]["start"] = {"layout": "random", "spacing": 1.0, "extent": 8.0, "center": [0, 0, 2]}
    data["seed"] = 7
    a = api.run(short(data, 5.0))
    b = api.run(short(data, 5.0))
    assert np.array_equal(a.trajectory["pos"], b.trajectory["pos"])
    timing = {"wall_time", "realtime_factor", "step_ms_median"}
    assert {k: v for k, v in a.metrics.items() if k not in timing} == {
        k: v for k, v in b.metrics.items() if k not in timing
    }
    data["seed"] = 8
    c = api.run(short(data, 5.0))
    assert not np.array_equal(a.trajectory["pos"][0], c.trajectory["pos"][0])


class Probe:
    """Records the order in which the kernel calls the phases and hooks."""

    def __init__(self):
        self.calls: list[str] = []


def test_phases_run_in_order_and_physics_substeps(data):
    sim = api.build(short(data, 0.2))
    probe = Probe()
    for kind in ("formation", "avoidance"):
        obj = getattr(sim, kind)
        method = "setpoints" if kind == "formation" else "adjust"
        original = getattr(obj, method)

        def wrapped(*args, _o=original, _k=kind):
            probe.calls.append(_k)
            return _o(*args)

        setattr(obj, method, wrapped)
    control, step = sim.dynamics.control, sim.dynamics.step
    sim.dynamics.control = lambda *a: (probe.calls.append("control"), control(*a))[1]
    sim.dynamics.step = lambda *a: (probe.calls.append("physics"), step(*a))[1]

    class Observer:
        @hookimpl
        def swarmscene_step_end(self, sim):
            probe.calls.append("observers")

    sim.pm.register(Observer())
    sim.step()
    assert sim.substeps == 5  # 0.1 s guidance / 0.02 s physics
    assert probe.calls == ["formation", "avoidance", "control"] + ["physics"] * 5 + ["observers"]
    assert sim.world.t == pytest.approx(0.1)


def test_clock_does_not_drift(data):
    data["termination"]["on_complete"] = False
    result = api.run(short(data, 10.0))
    t = result.trajectory["t"]
    assert len(t) == 101
    assert np.array_equal(t, np.arange(101) * 0.1)


def test_hover_failure_holds_position_and_is_seen_by_plugins(data):
    data["events"] = [{"at": 1.0, "agents": [2], "name": "hover"}]
    data["termination"]["on_complete"] = False
    seen = []
    sim = api.build(short(data, 4.0))

    class Listener:
        @hookimpl
        def swarmscene_event(self, sim, event):
            seen.append((round(sim.world.t, 6), event.agents, event.name, bool(sim.world.healthy[2])))

    sim.pm.register(Listener())
    result = sim.run()
    assert seen == [(1.0, (2,), "hover", False)]
    traj = result.trajectory
    after = traj["t"] >= 1.0
    frozen = traj["pos"][after, 2]
    assert np.all(frozen == frozen[0])
    assert np.all(traj["vel"][traj["t"] > 1.0, 2] == 0.0)
    assert not traj["healthy"][-1, 2] and traj["healthy"][-1, [0, 1, 3, 4]].all()
    assert result.metrics["healthy_at_end"] == 4


def test_comm_loss_removes_agent_from_graph(data):
    data["events"] = [{"at": 0.5, "agents": [1], "name": "comm_loss"}]
    sim = api.build(short(data, 1.0))
    sim.run()
    assert not sim.world.comm_ok[1] and sim.world.healthy[1]
    assert 1 not in sim.sensing.comm_graph.nodes


def test_disconnection_is_reported_with_time_and_agents(data):
    data["comm"]["range"] = 2.5  # grid spacing 2 m: connected at start
    data["swarm"]["start"]["kind"] = "line"
    data["events"] = [{"at": 0.5, "agents": [2], "name": "comm_loss"}]  # the middle of the line
    data["formation"]["shape"] = "line"
    result = api.run(short(data, 1.0))
    assert result.metrics["connected"] is False
    assert result.metrics["violations.connectivity.first_time"] == pytest.approx(0.5)
    assert result.metrics["violations.connectivity.agents"] == [0, 1, 3, 4]


def test_collision_termination_and_first_violation(data):
    # Two agents start 0.6 m apart and are sent to the same point: they collide.
    data["swarm"].update(n=2, start={"layout": "explicit", "positions": [[0, 0, 2], [0.6, 0, 2]]})
    data["avoidance"] = {"name": "none"}
    data["environment"]["obstacles"] = []
    data["formation"].update(shape="line", spacing=0.01, waypoints=[[0.3, 0, 2]])
    data["termination"].update(on_collision=True, on_complete=False)
    result = api.run(short(data, 10.0))
    assert result.stop_reason == "collision"
    assert result.metrics["collisions"] == 1
    assert result.metrics["violations.separation.agents"] == [0, 1]
    assert 0 < result.metrics["violations.separation.first_time"] < 10.0
    assert result.metrics["success"] is False


def test_mission_complete_terminates(data):
    result = api.run(data)
    assert result.stop_reason == "complete"
    assert result.metrics["duration"] < data["clock"]["duration"]
    assert result.metrics["success"] is True


def test_interrupt_returns_incomplete_result(data):
    sim = api.build(short(data, 5.0))
    original = sim.dynamics.step

    def interrupt(world, dt):
        if sim.step_count == 3:
            raise KeyboardInterrupt
        original(world, dt)

    sim.dynamics.step = interrupt
    result = sim.run()
    assert result.stop_reason == "interrupted" and not result.complete
    assert result.metrics["steps"] == 3
    assert len(result.trajectory["t"]) == 4


def test_kernel_names_no_plugin():
    """The kernel calls plugins through the base classes only."""
    import inspect

    import swarmscene.core.simulation as kernel

    source = inspect.getsource(kernel)
    for name in ("static_shape", "potential", "cem", "double_integrator", "plugins."):
        assert name not in source
    assert issubclass(Simulation, object) and Formation and Avoidance and Dynamics and Setpoints


def test_plugin_refusing_the_scenario_is_a_config_error(data):
    from swarmscene.core.errors import ConfigError

    data["swarm"].update(n=1, leader=0)
    data["formation"] = {"name": "hex_lattice"}
    with pytest.raises(ConfigError) as info:
        api.build(data)  # valid config, but the plugin's constructor refuses a lone leader
    (line,) = info.value.lines
    assert line == "formation: hex_lattice needs at least one follower"


def test_plugin_without_its_kinds_methods_cannot_be_built():
    class Incomplete(Formation):
        name = "incomplete"

    with pytest.raises(TypeError, match="abstract method"):
        Incomplete(Incomplete.Params(), None)


def test_a_non_finite_state_stops_the_run_naming_the_agent_and_tick():
    """Agent 2's velocity turns NaN during tick 3: the run stops there, says so in one line, is not
    a success, and every recorded frame (t = 0 and ticks 1-2) is finite."""
    sim = api.build(["clock.duration=2", "clock.guidance_period=0.1", "clock.physics_step=0.1"])
    step = sim.dynamics.step

    def failing_step(world, dt):
        step(world, dt)
        if sim.step_count == 2:  # during the third tick
            world.vel[2, 1] = np.nan

    sim.dynamics.step = failing_step
    result = sim.run()
    assert result.stop_reason == "non_finite" and result.metrics["stop_reason"] == "non_finite"
    assert result.error.startswith("non-finite state of agent 2 at tick 3 (t = 0.3 s; 1 agents)")
    assert "\n" not in result.error
    assert result.metrics["success"] is False
    assert result.metrics["steps"] == 2
    traj = result.trajectory
    assert traj["pos"].shape[0] == 3 and np.isfinite(traj["pos"]).all() and np.isfinite(traj["vel"]).all()


def test_random_events_are_drawn_by_the_kernel_and_reported(data):
    """The kernel builds its queue from the scenario (EventQueue.from_scenario): a random event's
    drawn time and agents are applied and reported as events.<k>.* metrics."""
    data["events"] = [{"at": {"uniform": [0.5, 1.5]}, "agents": {"sample": 2}, "name": "hover"}]
    result = api.run(short(data, 2.0))
    at, agents = result.metrics["events.0.at"], result.metrics["events.0.agents"]
    assert 0.5 <= at <= 1.5 and len(agents) == 2
    assert result.metrics["healthy_at_end"] == data["swarm"]["n"] - 2
    again = api.run(short(data, 2.0))
    assert (again.metrics["events.0.at"], again.metrics["events.0.agents"]) == (at, agents)
