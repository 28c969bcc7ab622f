"""antipodal_swap: goals through the ring centre, the RVO2 examples' preferred velocity, completion,
and the scenario as the stress test it is meant to be (without avoidance every pair collides)."""

from __future__ import annotations

import numpy as np

from swarmscene import api
from swarmscene.core.setpoint import Mode

QUIET = ["output.progress=off", "output.trajectory=false"]


def test_goal_is_the_antipode_and_velocity_points_at_it():
    sim = api.build(["scenario=swap", "swarm.n=6", "swarm.start.radius=5", *QUIET])
    formation, world = sim.formation, sim.world
    np.testing.assert_allclose(np.linalg.norm(world.pos[:, :2], axis=1), 5.0)  # the ring of R = 5 m
    np.testing.assert_allclose(formation.goal, 2 * np.array([0.0, 0.0, 2.0]) - world.pos, atol=1e-12)
    sp = formation.setpoints(world, sim.sensing)
    np.testing.assert_array_equal(sp.mode, Mode.VELOCITY)
    np.testing.assert_allclose(sp.vel, -world.pos * [1, 1, 0] / 5.0, atol=1e-12)  # 1 m/s to the centre
    # within speed / gain of the goal the agent slows down in proportion (gain 1/s)
    world.pos[0] = formation.goal[0] + [0.3, -0.4, 0.0]
    sp = formation.setpoints(world, sim.sensing)
    np.testing.assert_allclose(sp.vel[0], [-0.3, 0.4, 0.0], atol=1e-12)


def test_complete_when_every_healthy_agent_is_within_tolerance():
    sim = api.build(["scenario=swap", "swarm.n=4", *QUIET])
    formation, world = sim.formation, sim.world
    assert formation.complete(world) is False
    world.pos[:] = formation.goal + [0.05, 0.0, 0.0]
    assert formation.complete(world) is True
    world.pos[2] = [0.0, 0.0, 2.0]  # agent 2 stuck at the centre...
    assert formation.complete(world) is False
    world.healthy[2] = False  # ...but failed: it no longer counts, and it holds
    assert formation.complete(world) is True
    assert formation.setpoints(world, sim.sensing).mode[2] == Mode.HOLD


def test_without_avoidance_every_pair_meets_in_the_centre():
    """Straight lines at equal speed through one point: all C(8, 2) = 28 pairs collide (the issue's
    measurement), and they do so at the same instant."""
    metrics = api.run(["scenario=swap", "avoidance=none", *QUIET]).metrics
    assert metrics["collisions"] == 28
    assert metrics["min_separation"] < 1e-9
    assert sorted(metrics["violations.separation.agents"]) == list(range(8))
