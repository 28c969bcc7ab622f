"""The native vector environment (issue #34; docs/rl.md, docs/batched.md): ``gym.make_vec`` on a
swarmscene id steps B worlds as one batch, and each world is Gymnasium's ``SyncVectorEnv`` of the
single environment, step for step: observations, rewards, ends, infos and the next-step autoreset."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from swarmscene import env as swarm_env

SHORT = "swarmscene-test/swap-short-v0"
swarm_env.register_scenario(SHORT, ["scenario=swap", "clock.duration=0.5"])  # 5 ticks an episode


def rollout(envs, steps, seed=7):
    rng = np.random.default_rng(0)
    record, ends = [envs.reset(seed=seed)[0]], []
    for _ in range(steps):
        actions = rng.uniform(-1, 1, envs.action_space.shape)
        obs, rewards, terminated, truncated, infos = envs.step(actions)
        record += [obs, rewards, terminated, truncated, {k: v for k, v in infos.items() if k != "metrics"}]
        ends.append(terminated | truncated)
        if "metrics" in infos:
            record.append(infos["metrics"])
    envs.close()
    return record, ends


def test_make_vec_defaults_to_the_batch_and_equals_the_sync_vector_env():
    """Three worlds over 13 steps: two episode ends (5 ticks, truncated) and their autoresets."""
    batched = gym.make_vec(SHORT, num_envs=3)
    assert isinstance(batched.unwrapped, swarm_env.SwarmVectorEnv)
    sync = gym.make_vec(SHORT, num_envs=3, vectorization_mode="sync")
    (a, ends), (b, _) = rollout(batched, 13), rollout(sync, 13)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        if isinstance(x, dict):
            assert x.keys() == y.keys()
            for key in x:
                np.testing.assert_array_equal(x[key], y[key], err_msg=key)
        else:
            np.testing.assert_array_equal(x, y)
    assert [step for step, end in enumerate(ends, 1) if end.all()] == [5, 11]  # 5 ticks, autoreset, 5 ticks


def test_an_ended_world_reports_its_success_and_restarts_at_its_next_step():
    envs = gym.make_vec(SHORT, num_envs=2)
    envs.reset(seed=1)
    zero = np.zeros(envs.action_space.shape)
    for _ in range(4):
        assert not envs.step(zero)[3].any()
    obs, rewards, terminated, truncated, infos = envs.step(zero)
    assert truncated.all() and not terminated.any()
    assert infos["_success"].all() and infos["success"].dtype == bool
    assert list(infos["metrics"]["steps"]) == [5, 5]
    first, rewards, _, truncated, infos = envs.step(zero)  # the autoreset step
    assert not truncated.any() and (rewards == 0).all() and infos == {}


def test_a_bad_world_count_or_render_mode_is_one_line():
    with pytest.raises(ValueError, match=r"^num_envs: must be an integer >= 1 \(got 0\)$"):
        swarm_env.SwarmVectorEnv(0, ["scenario=swap"])
    with pytest.raises(ValueError, match=r"^render_mode: the vector environment does not render"):
        swarm_env.SwarmVectorEnv(2, ["scenario=swap"], render_mode="human")
