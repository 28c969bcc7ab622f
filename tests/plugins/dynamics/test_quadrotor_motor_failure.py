"""Motor failure on the 6-DOF quadrotor (#18): the vehicle falls and spins as its physics says."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.setpoint import Setpoints
from swarmscene.methods.quadrotor.model import GRAVITY
from swarmscene.plugins.event.comm_loss import CommLoss


def hover(data: dict, events: list, duration: float = 3.0, **clock):
    data["swarm"] = {"n": 2, "leader": None, "start": {"layout": "line", "spacing": 3.0, "center": [0, 0, 20]}}
    data["environment"] = {"name": "open", "obstacles": []}
    data["avoidance"] = {"name": "none"}
    data["dynamics"] = {"name": "quadrotor"}
    data["events"] = events
    data["clock"].update(duration=duration, **clock)
    data["termination"]["on_complete"] = False
    sim = api.build(data)
    target = sim.world.pos.copy()
    sim.formation.setpoints = lambda world, sensing: Setpoints.hold(target)
    return sim, target


def test_all_rotors_dead_is_free_fall(data):
    """Four motor failures at t_f = 1 s: no thrust, no torque; from hover at rest
    z(t) = z(t_f) - g (t - t_f)^2 / 2 exactly (RK4 is exact for constant acceleration)."""
    events = [{"at": 1.0, "agents": [0], "name": "motor_failure", "rotor": r} for r in range(4)]
    sim, target = hover(data, events, duration=3.0)
    zs, ts = [], []
    while sim.step_count < sim.total_steps:
        sim.step()
        zs.append(sim.world.pos[0, 2])
        ts.append(sim.world.t)
    zs, ts = np.array(zs), np.array(ts)
    after = ts >= 1.0
    t_f = 1.0
    np.testing.assert_allclose(zs[after], target[0, 2] - 0.5 * GRAVITY * (ts[after] - t_f) ** 2, atol=1e-9)
    assert not sim.world.healthy[0] and sim.world.healthy[1]  # the avoidance sees it failed
    np.testing.assert_allclose(sim.world.pos[1], target[1], atol=1e-9)  # the other one hovers on


@pytest.mark.parametrize("fraction", [0.0, 0.5])
def test_first_instant_after_a_rotor_failure(data, fraction):
    """Rotor 0 keeping fraction f of its thrust, at hover: in the first instant the thrust is
    (3 + f)/4 m g, so z'' = -(1 - f) g / 4, and the yaw drag torques leave (1 - f) k_D w_h^2 about
    +z (rotor 0 turns against +z in the FLU frame): omega_z' = (1 - f) k_D w_h^2 / J_z."""
    sim, _ = hover(data, [{"at": 0.0, "agents": [0], "name": "motor_failure", "rotor": 0,
                           "fraction": fraction}])
    af = sim.dynamics.airframe
    h = sim.dynamics.params.max_step
    sim._apply_due_events()  # the event at t = 0, through the kernel's events phase and the hook
    world = sim.world
    sim.dynamics.control(world, Setpoints.hold(world.pos))
    sim.dynamics.step(world, h)  # one internal step
    assert world.vel[0, 2] / h == pytest.approx(-(1 - fraction) * GRAVITY / 4, rel=0.01)
    alpha = (1 - fraction) * af.k_D * af.hover_rotor_speed**2 / af.inertia[2]
    assert world.omega[0, 2] / h == pytest.approx(alpha, rel=0.05)
    assert world.vel[1, 2] == pytest.approx(0.0, abs=1e-12)  # the healthy one hovers


def test_a_dead_rotor_makes_it_spin_and_fall(data):
    """The controller, unaware, keeps its four-rotor allocation: without rotor 0 the yaw torque
    cannot be balanced and the lift not held level: the vehicle spins up and falls."""
    sim, target = hover(data, [{"at": 0.5, "agents": [0], "name": "motor_failure", "rotor": 0}])
    sim.run()
    assert abs(sim.world.omega[0, 2]) > 10.0  # rad/s
    assert sim.world.pos[0, 2] < target[0, 2] - 1.0
    assert not sim.world.healthy[0]  # formations and avoidance see it failed


@pytest.mark.parametrize("dynamics, event, line", [
    ("single_integrator", {"rotor": 0}, "events.0.name: motor_failure needs a dynamics model with rotors "
                                        "(dynamics 'single_integrator' has none; e.g. dynamics=quadrotor)"),
    ("quadrotor", {"rotor": 4}, "events.0.rotor: must be < 4, the rotors of dynamics 'quadrotor' (got 4)"),
])
def test_motor_failure_needs_a_rotor_the_dynamics_has(data, dynamics, event, line):
    data["dynamics"] = {"name": dynamics}
    data["events"] = [{"at": 1.0, "agents": [0], "name": "motor_failure", **event}]
    with pytest.raises(ConfigError) as exc:
        api.load(data)
    assert exc.value.lines == [line]


def test_other_events_leave_the_rotors_alone(data):
    sim, _ = hover(data, [], duration=0.5)
    sim.dynamics.swarmscene_event(sim=sim, event=CommLoss.event(0.0, (0,)))
    assert sim.dynamics.rotor_health is None
