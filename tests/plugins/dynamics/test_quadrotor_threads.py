"""``dynamics.threads``: the quadrotor's physics step on numba's threads gives every agent the bits
it gets on one thread (kernels.step_swarm_parallel against kernels.step_swarm), in one world and
in a batch of worlds."""

from __future__ import annotations

import numba
import numpy as np
import pytest

import swarmscene.plugins.dynamics.quadrotor as quadrotor_plugin
from swarmscene import api
from swarmscene.core.batch import BatchSimulation
from swarmscene.core.errors import ConfigError
from swarmscene.methods.quadrotor import kernels

STATE = ("pos", "vel", "quat", "omega", "rotor_speed")


AGENTS = 150
"""Three blocks of lanes (kernels.BLOCK = 64), the last one partial."""


def flown(chunks: int | None, monkeypatch, dtype: str = "float64") -> tuple[dict[str, bytes], list[int]]:
    """A tumbling quadrotor world of ``AGENTS`` agents under wind and a force, stepped 12 physics
    steps of a tenth of a second (24 internal steps each) by the serial kernel (None) or by the
    parallel one in ``chunks`` runs, in ``dtype`` (``dynamics.dtype``); its state's bytes and the
    rows each call stepped."""
    from tests.methods.quadrotor.test_kernels import pair, random_setpoints, random_state

    rng = np.random.default_rng(11)
    (dyn, world), _ = pair(np.zeros((AGENTS, 3)), dtype=dtype)
    random_state(rng, world, tumbling=True)
    world.wind = rng.normal(0.0, 3.0, (AGENTS, 3))
    world.force = rng.normal(0.0, 1.0, (AGENTS, 3))
    rows: list[int] = []
    if chunks is not None:
        def parallel(kernels_module, threads, agents):
            rows.append(agents)
            return kernels.step_swarm_parallel, {"chunks": chunks}
        monkeypatch.setattr(quadrotor_plugin, "_stepper", parallel)
    for _ in range(12):
        dyn.control(world, random_setpoints(rng, AGENTS, "snap"))
        dyn.step(world, 0.1)
    monkeypatch.undo()
    return {name: getattr(world, name).tobytes() for name in STATE}, rows


@pytest.mark.parametrize("chunks, dtype", [(1, "float64"), (3, "float64"), (7, "float64"), (3, "float32")])
def test_the_parallel_kernel_gives_every_agent_the_serial_bits(chunks, dtype, monkeypatch):
    serial, _ = flown(None, monkeypatch, dtype)
    parallel, rows = flown(chunks, monkeypatch, dtype)
    assert rows == [AGENTS] * 12
    assert parallel == serial


SCENARIO = ["scenario=flocking", "swarm.n=48", "dynamics=quadrotor", "clock.duration=1", "output.summary=false"]


def test_a_world_on_two_threads_is_its_one_thread_run(monkeypatch):
    """48 agents, the parallel threshold set to 32: threads=2 steps them on two threads when numba
    has two (else on one), and the run is the one-thread run to the bit."""
    calls = []
    real = quadrotor_plugin._stepper
    monkeypatch.setattr(quadrotor_plugin, "PARALLEL_MIN_AGENTS", 32)
    monkeypatch.setattr(quadrotor_plugin, "_stepper",
                        lambda *a: calls.append(real(*a)[0].__name__) or real(*a))
    threaded = api.run([*SCENARIO, "dynamics.threads=2"])
    expected = "step_swarm_parallel" if numba.config.NUMBA_NUM_THREADS >= 2 else "step_swarm"
    assert calls and set(calls) == {expected}
    calls.clear()
    alone = api.run([*SCENARIO, "dynamics.threads=1"])
    assert set(calls) == {"step_swarm"}
    for key, value in alone.trajectory.items():
        assert threaded.trajectory[key].tobytes() == value.tobytes(), key


def test_a_batch_of_small_worlds_is_stepped_on_threads_as_one_swarm(monkeypatch):
    """Three worlds of 16 agents (48 rows together, above the threshold of 32, each world below
    it): the batch steps them on threads, each world its single one-thread run to the bit."""
    monkeypatch.setattr(quadrotor_plugin, "PARALLEL_MIN_AGENTS", 32)
    config = ["scenario=flocking", "swarm.n=16", "dynamics=quadrotor", "dynamics.threads=2",
              "clock.duration=1", "output.summary=false"]
    rows, kernels = [], []
    real = quadrotor_plugin._stepper

    def stepper(k, t, agents):
        rows.append(agents)
        chosen = real(k, t, agents)
        kernels.append(chosen[0].__name__)
        return chosen

    monkeypatch.setattr(quadrotor_plugin, "_stepper", stepper)
    data = api.compose(config)
    outcomes = BatchSimulation([api.build({**data, "seed": seed}) for seed in (0, 1, 2)]).run()
    assert rows and set(rows) == {48}
    assert set(kernels) == {"step_swarm_parallel" if numba.config.NUMBA_NUM_THREADS >= 2 else "step_swarm"}
    monkeypatch.undo()
    for seed, outcome in zip((0, 1, 2), outcomes, strict=True):
        alone = api.run([*config, f"seed={seed}"])
        for key, value in alone.trajectory.items():
            assert outcome.result.trajectory[key].tobytes() == value.tobytes(), (seed, key)


def test_threads_below_one_are_refused_in_one_line():
    with pytest.raises(ConfigError, match=r"dynamics.threads: must be >= 1 \(got 0\)"):
        api.build(["dynamics=quadrotor", "dynamics.threads=0"])
