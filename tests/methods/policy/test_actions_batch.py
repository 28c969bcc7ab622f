"""The ``policy`` avoidance's batched form (an environment's commanded actions of B worlds turned
into setpoints in one pass) against each world's own ``adjust``, to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.rl.episode import Driver

FIELDS = ("mode", "pos", "vel", "acc", "yaw")


def policies(command: str, seeds: range) -> list:
    """One built policy avoidance per seed (the default scenario from a random start, the
    environment's actions), agent 1 of the first world failed."""
    config = ["swarm.start.layout=random", "avoidance=policy", f"avoidance.action={command}"]
    driver = Driver(config, None)
    out = [driver.reset(seed).sim for seed in seeds]
    out[0].world.healthy[1] = False
    out[0].world.vel[:] = np.random.default_rng(0).normal(size=out[0].world.vel.shape)
    return out


@pytest.mark.parametrize("command", ["velocity", "acceleration"])
def test_the_batched_actions_give_each_world_its_own_setpoints_and_state(command):
    rng = np.random.default_rng(3)
    alone, together = policies(command, range(4)), policies(command, range(4))
    n = alone[0].world.n
    for _ in range(3):
        actions = rng.uniform(-1.5, 1.5, (4, n, 3))
        actions[2, 0] = [np.nan, np.inf, -np.inf]
        active = rng.random((4, n)) < 0.7
        active[2, 0] = True
        formation = [Setpoints.hold(sim.world.pos + 1.0) for sim in together]
        for sims in (alone, together):
            for sim, a, on in zip(sims, actions, active, strict=True):
                sim.avoidance.command(a, on)
        own = [sim.avoidance.adjust(sim.world, None, sp) for sim, sp in zip(alone, formation, strict=True)]
        batched = type(together[0].avoidance).adjust_batch([sim.avoidance for sim in together],
                                                           [sim.world for sim in together], [None] * 4, formation)
        for b, (mine, theirs) in enumerate(zip(own, batched, strict=True)):
            for key in FIELDS:
                a, c = getattr(mine, key), getattr(theirs, key)
                assert a.dtype == c.dtype and a.shape == c.shape and a.tobytes() == c.tobytes(), (b, key)
            assert together[b].avoidance.reference is formation[b] and together[b].avoidance._action is None
        assert not batched[0].vel[1].any()  # the failed agent holds
        assert batched[2].mode[0] == Mode.VELOCITY and np.isfinite(batched[2].vel).all()  # NaN 0, infinities clipped


def test_the_batch_is_declined_untouched_where_a_world_was_commanded_nothing():
    sims = policies("velocity", range(3))
    n = sims[0].world.n
    for sim in sims[:2]:
        sim.avoidance.command(np.zeros((n, 3)), np.ones(n, dtype=bool))
    formation = [Setpoints.hold(sim.world.pos) for sim in sims]
    avoidances = [sim.avoidance for sim in sims]
    assert type(avoidances[0]).adjust_batch(avoidances, [sim.world for sim in sims], [None] * 3,
                                            formation) is NotImplemented
    assert all(a.reference is None for a in avoidances) and avoidances[0]._action is not None
