"""The vector environments' worlds in worker processes (``workers=W``; swarmscene/rl/workers.py,
docs/rl.md): every answer is the one-process environment's, bit for bit, and the workers' errors,
ends and shutdown reach the environment's user as one line."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from swarmscene import api
from swarmscene import env as swarm_env
from swarmscene.rl.workers import Stepped, joined, shares

SHORT = ["swarm.start.layout=random", "clock.duration=0.5"]  # 5 ticks an episode, the start drawn from the seed
swarm_env.register_scenario("swarmscene-test/workers-short-v0", SHORT)


def failing():
    """The default scenario from a random start, 12 ticks an episode, agent 0 failing at t = 0.5 s."""
    data = api.compose(["events=lead_fails", "clock.duration=1.2", "swarm.start.layout=random"])
    data["events"][0]["at"] = 0.5
    return data


def rollout(envs, steps, seed):
    """Everything the environment answers over ``steps`` random steps after ``reset(seed=seed)``."""
    rng = np.random.default_rng(0)
    answers = [envs.reset(seed=seed)]
    for _ in range(steps):
        answers.append(envs.step(rng.uniform(-1, 1, envs.action_space.shape)))
    envs.close()
    return answers


def assert_same(a, b, where="answer"):
    """The same answers, bit for bit: arrays (values and dtypes), dicts (keys, recursively), tuples."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, tuple | list):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{k}]")
    else:
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype, where
        np.testing.assert_array_equal(a, b, err_msg=where)


def test_the_central_vector_env_on_two_workers_answers_as_in_one_process():
    """Five worlds (shares of 2 and 3) over 13 steps: two episode ends each, with their metrics,
    success masks and next-step autoresets; made through ``gym.make_vec``."""
    one = gym.make_vec("swarmscene-test/workers-short-v0", num_envs=5)
    two = gym.make_vec("swarmscene-test/workers-short-v0", num_envs=5, workers=2)
    a, b = rollout(one, 13, seed=7), rollout(two, 13, seed=7)
    assert_same(a, b)
    assert [int(step[3].sum()) for step in a[1:]].count(5) == 2  # every world truncated twice
    assert "metrics" in a[5][4] and a[5][4]["_success"].all()


@pytest.mark.parametrize("seed", [11, [3, 1, 4, 1], None], ids=["int", "per-world", "none"])
def test_the_multi_agent_vector_env_on_workers_answers_as_in_one_process(seed):
    """Four worlds on 1, 2 and 4 workers through failures (an agent leaves its world's mask),
    truncations, the ended worlds' metrics and restarts drawn from each world's own generator."""
    config = failing()
    answers = [rollout(swarm_env.SwarmMultiAgentVectorEnv(4, config, workers=w), 27, seed) for w in (1, 2, 4)]
    assert_same(answers[0], answers[1])
    assert_same(answers[0], answers[2])
    assert not answers[0][7][4]["agents"][:, 0].any()  # agent 0 failed in every world
    assert sum("metrics" in step[4] for step in answers[0][1:]) == 2  # two episode ends, 12 ticks each


def test_the_agent_mask_follows_the_workers_answers():
    envs = swarm_env.SwarmMultiAgentVectorEnv(2, failing(), workers=2)
    _, infos = envs.reset(seed=0)
    assert envs.agent_mask.all()
    zero = np.zeros(envs.action_space.shape)
    for _ in range(6):
        _, _, _, _, infos = envs.step(zero)
    np.testing.assert_array_equal(envs.agent_mask, infos["agents"])
    assert envs.agent_mask.tolist() == [[False, True, True, True, True]] * 2
    envs.close()


def test_a_spawned_worker_answers_as_a_forked_one():
    """The start method macOS and Windows use (the workers import swarmscene afresh)."""
    config = ["swarm.start.layout=random", "swarm.n=3", "clock.duration=0.3"]
    a = rollout(swarm_env.SwarmVectorEnv(2, config, workers=2, context="spawn"), 4, seed=2)
    b = rollout(swarm_env.SwarmVectorEnv(2, config), 4, seed=2)
    assert_same(a, b)


def test_bad_workers_and_contexts_are_one_line_before_a_process_starts():
    config = ["scenario=swap"]
    for workers in (0, 3, True, 1.5):
        with pytest.raises(ValueError, match=r"^workers: must be an integer from 1 to num_envs = 2 \(got "):
            swarm_env.SwarmVectorEnv(2, config, workers=workers)
    with pytest.raises(ValueError, match=r"^context: must be one of \[.*\] or None \(got 'threads'\)$"):
        swarm_env.SwarmMultiAgentVectorEnv(2, config, workers=2, context="threads")
    with pytest.raises(ValueError, match=r"^num_envs: must be an integer >= 1 \(got 0\)$"):
        swarm_env.SwarmVectorEnv(0, config, workers=2)


def test_a_bad_scenario_is_the_same_error_with_workers():
    """The scenario is composed and validated in the environment's process first."""
    errors = []
    for workers in (1, 2):
        with pytest.raises(Exception) as caught:  # noqa: PT011 - the two errors are compared below
            swarm_env.SwarmVectorEnv(2, ["swarm.n=-1"], workers=workers)
        errors.append(caught.value)
    assert type(errors[0]) is type(errors[1]) and str(errors[0]) == str(errors[1])


def test_a_workers_error_is_raised_in_the_environment_and_the_workers_stay_usable():
    envs = swarm_env.SwarmMultiAgentVectorEnv(3, ["scenario=swap", "clock.duration=0.3"], workers=2)
    zero = np.zeros(envs.action_space.shape)
    with pytest.raises(RuntimeError, match=r"^step\(\) called before reset\(\)$"):  # raised in both workers
        envs.step(zero)
    with pytest.raises(ValueError, match=r"^actions: "):  # checked here, before any worker
        envs.step(np.zeros((3, envs.num_agents)))
    envs.reset(seed=0)
    assert envs.step(zero)[0].shape == envs.observation_space.shape
    envs.close()


def test_the_simulations_are_not_read_across_processes():
    envs = swarm_env.SwarmMultiAgentVectorEnv(2, ["scenario=swap"], workers=2)
    envs.reset(seed=0)
    message = r"^the worlds are stepped by 2 worker processes \(workers=2\): make the environment with workers=1"
    with pytest.raises(RuntimeError, match=message):
        envs.sims  # noqa: B018 - the property raises
    central = swarm_env.SwarmVectorEnv(2, ["scenario=swap"], workers=2)
    with pytest.raises(RuntimeError, match=message):
        central.drivers  # noqa: B018
    envs.close()
    central.close()


def test_close_ends_the_workers_and_a_closed_environment_says_so():
    envs = swarm_env.SwarmVectorEnv(2, ["scenario=swap"], workers=2)
    processes = envs._worlds._processes
    assert all(p.is_alive() for p in processes)
    envs.close()
    envs.close()  # idempotent
    assert not any(p.is_alive() for p in processes)
    assert [p.exitcode for p in processes] == [0, 0]  # each ended on its own, at the close command
    with pytest.raises(RuntimeError, match=r"^the vector environment is closed$"):
        envs.reset(seed=0)


def test_a_worker_that_dies_is_named():
    envs = swarm_env.SwarmVectorEnv(2, ["scenario=swap"], workers=2)
    envs.reset(seed=0)
    dead = envs._worlds._processes[1]
    dead.kill()
    dead.join()
    with pytest.raises(RuntimeError, match=r"^worker 1 of the vector environment ended unexpectedly \(exit code -9\)$"):
        envs.step(np.zeros(envs.action_space.shape))
    envs.close()


@pytest.mark.parametrize("num_envs", range(1, 12))
def test_the_shares_are_contiguous_and_even(num_envs):
    for workers in range(1, num_envs + 1):
        parts = shares(num_envs, workers)
        assert [b for part in parts for b in part] == list(range(num_envs))
        sizes = [len(part) for part in parts]
        assert len(sizes) == workers and min(sizes) >= 1 and max(sizes) - min(sizes) <= 1


def test_joined_offsets_the_ended_worlds_and_joins_the_arrays():
    def part(b, ended):
        return Stepped(np.full((b, 2, 4), b, np.float32), np.arange(b), np.zeros(b, bool), np.ones(b, bool),
                       ended, {"acted": np.full((b, 2), b == 2)})

    both = joined([part(2, [(1, {"success": True})]), part(3, [(0, {"success": False}), (2, {"success": True})])],
                  [0, 2])
    assert both.observations.shape == (5, 2, 4) and both.observations.dtype == np.float32
    assert both.rewards.tolist() == [0, 1, 0, 1, 2]
    assert [b for b, _ in both.ended] == [1, 2, 4]
    assert both.arrays["acted"][:, 0].tolist() == [True, True, False, False, False]
