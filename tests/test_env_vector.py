"""The native vector environment (issue #34; docs/rl.md, docs/batched.md): ``gym.make_vec`` on a
swarmscene id steps B worlds as one batch, and each world is Gymnasium's ``SyncVectorEnv`` of the
single environment, step for step: observations, rewards, ends, infos and the next-step autoreset."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from swarmscene import api
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


# --------------------------------------------------------------------------- the multi-agent form

def failing_short():
    """The default scenario, 12 ticks an episode, agent 0 failing at its sixth tick (t = 0.5 s)."""
    data = api.compose(["events=lead_fails", "clock.duration=1.2"])
    data["events"][0]["at"] = 0.5
    return data


def test_the_multi_agent_vector_env_is_the_parallel_env_world_by_world():
    """Three worlds over 27 steps, two episodes each (a failure in each, ends and autoresets),
    against three PettingZoo parallel environments seeded as the worlds: every acting agent's
    observation, reward and ends, the live agents, and the ended worlds' metrics."""
    config, b_worlds, steps = failing_short(), 3, 27
    envs = swarm_env.SwarmMultiAgentVectorEnv(b_worlds, config)
    singles = [swarm_env.make_env(config) for _ in range(b_worlds)]
    obs, infos = envs.reset(seed=11)
    assert obs.shape == (b_worlds, 5, envs.single_agent_observation_space.shape[0])
    for b, env in enumerate(singles):
        first, _ = env.reset(seed=11 + b)
        assert infos["agents"][b].tolist() == [a in first for a in env.possible_agents]
        for a, row in first.items():
            np.testing.assert_array_equal(obs[b, env.possible_agents.index(a)], row)
    rng = np.random.default_rng(0)
    restarts, failures = 0, 0
    for _ in range(steps):
        actions = rng.uniform(-1, 1, envs.action_space.shape)
        obs, rewards, terminated, truncated, infos = envs.step(actions)
        for b, env in enumerate(singles):
            if not env.agents:  # the world restarted at this step: its first observation, nothing acted
                first, _ = env.reset()
                restarts += 1
                assert not infos["acted"][b].any() and not rewards[b].any() and not terminated[b].any()
                for a, row in first.items():
                    np.testing.assert_array_equal(obs[b, env.possible_agents.index(a)], row)
                continue
            index = {a: i for i, a in enumerate(env.possible_agents)}
            acting = list(env.agents)
            assert infos["acted"][b].tolist() == [a in acting for a in env.possible_agents]
            o, r, te, tr, inf = env.step({a: actions[b, index[a]] for a in acting})
            for a in acting:
                i = index[a]
                np.testing.assert_array_equal(obs[b, i], o[a])
                assert (rewards[b, i], terminated[b, i], truncated[b, i]) == (r[a], te[a], tr[a])
            if env.agents:  # the world goes on: an agent that ended failed alone
                failures += sum(te[a] for a in acting)
            assert infos["agents"][b].tolist() == [a in env.agents for a in env.possible_agents]
            ended = any(tr.values()) or not env.agents
            assert infos.get("_metrics", np.zeros(b_worlds, bool))[b] == ended
            if ended:
                assert infos["metrics"]["steps"][b] == inf[acting[0]]["metrics"]["steps"]
                assert infos["success"][b] == inf[acting[0]]["metrics"]["success"]
    assert restarts == 2 * b_worlds and failures == 2 * b_worlds  # what the comparison covered


def test_the_multi_agent_vector_env_refuses_bad_actions_and_worlds_in_one_line():
    envs = swarm_env.SwarmMultiAgentVectorEnv(2, ["scenario=swap", "clock.duration=0.3"])
    with pytest.raises(RuntimeError, match=r"^step\(\) called before reset\(\)$"):
        envs.step(np.zeros((2, envs.num_agents, 3)))
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"^actions: "):
        envs.step(np.zeros((2, envs.num_agents)))
    with pytest.raises(ValueError, match=r"^num_envs: must be an integer >= 1 \(got 0\)$"):
        swarm_env.SwarmMultiAgentVectorEnv(0, ["scenario=swap"])


def test_the_multi_agent_vector_env_truncates_at_max_episode_steps_and_restarts_next():
    envs = swarm_env.SwarmMultiAgentVectorEnv(2, ["scenario=swap"], max_episode_steps=3)
    with pytest.raises(ValueError, match=r"^seed: 3 seeds for 2 worlds$"):
        envs.reset(seed=[1, 2, 3])
    obs, infos = envs.reset(seed=[5, 5])
    np.testing.assert_array_equal(obs[0], obs[1])  # one seed, one start
    zero = np.zeros(envs.action_space.shape)
    for _ in range(2):
        _, _, terminated, truncated, infos = envs.step(zero)
        assert not (terminated | truncated).any() and "_metrics" not in infos
    _, _, terminated, truncated, infos = envs.step(zero)
    assert truncated.all() and not terminated.any() and not infos["agents"].any()
    assert list(infos["metrics"]["steps"]) == [3, 3] and infos["_success"].all()
    _, rewards, _, truncated, infos = envs.step(zero)  # the autoreset step
    assert infos["agents"].all() and not infos["acted"].any() and not rewards.any() and not truncated.any()
