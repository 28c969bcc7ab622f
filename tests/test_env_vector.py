"""The native vector environment (issue #34; docs/rl.md, docs/batched.md): ``gym.make_vec`` on a
swarmscene id steps B worlds as one batch, and each world is Gymnasium's ``SyncVectorEnv`` of the
single environment, step for step: observations, rewards, ends, infos and the next-step autoreset."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from swarmscene import api
from swarmscene import env as swarm_env
from swarmscene.core.setpoint import Mode
from swarmscene.rl import episode as rl_episode

SHORT = "swarmscene-test/default-short-v0"
# 5 ticks an episode, from a random start: a world's seed decides its start, so seeding is checked
swarm_env.register_scenario(SHORT, ["swarm.start.layout=random", "clock.duration=0.5"])


def rollout(envs, steps, seed=7):
    rng = np.random.default_rng(0)
    record, ends = [envs.reset(seed=seed)[0]], []
    assert not np.array_equal(record[0][0], record[0][1])  # the worlds' seeds differ, and so do their starts
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


LIMITED = "swarmscene-test/collide-limited-v0"
# random starts 6 m wide with a 1.8 m separation limit: some worlds collide (terminate) by step 7
swarm_env.register_scenario(LIMITED, ["swarm.start.layout=random", "swarm.start.extent=6", "clock.duration=2",
                                      "termination.on_collision=true", "safety.separation_limit=1.8"],
                            max_episode_steps=7)


def test_with_max_episode_steps_the_batch_still_equals_the_sync_vector_env():
    """Gymnasium's TimeLimit truncates at the limit also where the episode terminated at that step,
    and gives no metrics for an episode it cuts short; the batch truncated only the worlds still
    going and gave their metrics. Four worlds over nine steps, each step compared."""
    runs = {}
    for mode in ("batch", "sync"):
        envs = gym.make_vec(LIMITED, num_envs=4, **({"vectorization_mode": "sync"} if mode == "sync" else {}))
        rng = np.random.default_rng(0)
        envs.reset(seed=3)
        runs[mode] = [envs.step(rng.uniform(-1, 1, envs.action_space.shape)) for _ in range(9)]
        envs.close()
    for step, (a, b) in enumerate(zip(runs["batch"], runs["sync"], strict=True), 1):
        for x, y in zip(a[:4], b[:4], strict=True):
            np.testing.assert_array_equal(x, y, err_msg=f"step {step}")
        assert a[4].keys() == b[4].keys(), step
        for key in a[4]:
            if key != "metrics":
                np.testing.assert_array_equal(a[4][key], b[4][key], err_msg=f"step {step} {key}")
    _, _, terminated, truncated, infos = runs["batch"][6]
    assert truncated.all() and terminated.any() and not terminated.all()  # the case: both at the limit
    assert (infos["_metrics"] == terminated).all()  # the metrics of the episodes that ended themselves only


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
    """The default scenario from a random start (so that a world's seed matters), 12 ticks an
    episode, agent 0 failing at its sixth tick (t = 0.5 s)."""
    data = api.compose(["events=lead_fails", "clock.duration=1.2", "swarm.start.layout=random"])
    data["events"][0]["at"] = 0.5
    return data


def colliding():
    """Five vehicles from a random start in a 6 m square, an episode ending at the first pair closer
    than 1.8 m (random actions end most episodes so within the 2 s), agent 0 failing at t = 0.3 s:
    a terminated world's failed agent did not act, so its ends stay False."""
    data = api.compose(["events=lead_fails", "swarm.start.layout=random", "swarm.start.extent=6",
                        "termination.on_collision=true", "safety.separation_limit=1.8", "clock.duration=2"])
    data["events"][0]["at"] = 0.3
    return data


@pytest.mark.parametrize(("config", "steps", "ends"), [(failing_short(), 27, "truncated"), (colliding(), 80, "terminated")],
                         ids=["failures-truncation", "collisions"])
def test_the_multi_agent_vector_env_is_the_parallel_env_world_by_world(config, steps, ends):
    """Three worlds against three PettingZoo parallel environments seeded as the worlds: every
    entry of the observations, rewards and ends (the agents that did not act: 0 and False), the
    live agents and the ended worlds' metrics, through failures, ends and restarts."""
    b_worlds = 3
    envs = swarm_env.SwarmMultiAgentVectorEnv(b_worlds, config)
    singles = [swarm_env.make_env(config) for _ in range(b_worlds)]
    obs, infos = envs.reset(seed=11)
    assert obs.shape == (b_worlds, 5, envs.single_agent_observation_space.shape[0])
    assert not np.array_equal(obs[0], obs[1])  # the worlds' seeds differ, and so do their starts
    for b, env in enumerate(singles):
        expect(obs[b], infos["agents"][b], env, env.reset(seed=11 + b)[0])
    rng = np.random.default_rng(0)
    counted = {"restarts": 0, "failures": 0, "terminated": 0, "truncated": 0}
    for _ in range(steps):
        actions = rng.uniform(-1, 1, envs.action_space.shape)
        obs, rewards, terminated, truncated, infos = envs.step(actions)
        for b, env in enumerate(singles):
            if not env.agents:  # the world restarted at this step: its first observation, nothing acted
                counted["restarts"] += 1
                expect(obs[b], infos["agents"][b], env, env.reset()[0])
                assert not infos["acted"][b].any() and not rewards[b].any()
                assert not (terminated[b] | truncated[b]).any()
                continue
            acting = list(env.agents)
            assert infos["acted"][b].tolist() == [a in acting for a in env.possible_agents]
            index = {a: i for i, a in enumerate(env.possible_agents)}
            o, r, te, tr, inf = env.step({a: actions[b, index[a]] for a in acting})
            own = np.zeros(5), np.zeros(5, bool), np.zeros(5, bool)
            for a in acting:
                own[0][index[a]], own[1][index[a]], own[2][index[a]] = r[a], te[a], tr[a]
            for mine, theirs in zip((rewards[b], terminated[b], truncated[b]), own, strict=True):
                np.testing.assert_array_equal(mine, theirs)  # every entry: the others 0 and False
            expect(obs[b], infos["agents"][b], env, o)
            ended = not env.agents
            assert infos.get("_metrics", np.zeros(b_worlds, bool))[b] == ended
            if ended:
                counted["terminated" if any(te.values()) else "truncated"] += 1
                assert infos["metrics"]["steps"][b] == inf[acting[0]]["metrics"]["steps"]
                assert infos["success"][b] == inf[acting[0]]["metrics"]["success"]
            else:
                counted["failures"] += sum(te.values())  # the world goes on: an agent failed alone
    # what the comparison covered
    assert counted["restarts"] >= b_worlds and counted[ends] >= b_worlds
    if ends == "truncated":
        assert counted["failures"] == 2 * b_worlds


def expect(rows, live, env, observed):
    """A world's rows and live-agent mask are the parallel environment's (its observations of
    the agents it reports, its ``agents``)."""
    assert live.tolist() == [a in env.agents for a in env.possible_agents]
    for a, row in observed.items():
        np.testing.assert_array_equal(rows[env.possible_agents.index(a)], row)


def test_a_world_starting_with_no_healthy_agent_ends_at_once_and_restarts_next(monkeypatch):
    """Stock scenarios start healthy; a plugin's ``run_start`` could fail every agent. The parallel
    environment then has no agents; the world is over before it acts, without a tick or metrics."""
    start = rl_episode.Episode.__init__

    def no_one_healthy(self, scenario, options):
        start(self, scenario, options)
        self.sim.world.healthy[:] = False

    monkeypatch.setattr(rl_episode.Episode, "__init__", no_one_healthy)
    config = ["scenario=swap", "swarm.n=4", "clock.duration=0.4"]
    single = swarm_env.make_env(config)
    single.reset(seed=0)
    assert single.agents == []
    envs = swarm_env.SwarmMultiAgentVectorEnv(1, config)
    _, infos = envs.reset(seed=0)
    assert not infos["agents"].any()
    _, rewards, terminated, truncated, infos = envs.step(np.zeros(envs.action_space.shape))
    assert not infos["acted"].any() and "_metrics" not in infos and not rewards.any()
    assert envs.worlds.drivers[0].episode.sim.step_count == 0  # restarted, not ticked


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


def test_the_rewards_of_stacked_worlds_are_each_worlds_own_with_every_term_weighted():
    """``_rewards`` over B stacked worlds (the vector environments' judge) against each world's own
    call, every weight non-zero, some worlds complete: the same bits; and one world against the
    reward's definition (RewardOptions), term by term."""
    rng = np.random.default_rng(8)
    weights = swarm_env.RewardOptions(progress=1.5, separation=10.0, clearance=7.0, effort=0.3, complete=2.5)
    b_worlds, n = 9, 6
    action, before, pos, ref_pos = (rng.uniform(-3, 3, (b_worlds, n, 3)) for _ in range(4))
    healthy, near, close = (rng.random((b_worlds, n)) < share for share in (0.8, 0.3, 0.3))
    mode = rng.integers(0, 4, (b_worlds, n)).astype(np.int8)
    complete = np.arange(b_worlds) % 2 == 0
    stacked = rl_episode._rewards(weights, action, before, pos, healthy, mode, ref_pos, near, close, complete)
    for b in range(b_worlds):
        own = rl_episode._rewards(weights, action[b], before[b], pos[b], healthy[b], mode[b], ref_pos[b], near[b],
                                 close[b], np.array(complete[b]))
        assert stacked[b].tobytes() == own.tobytes()
        assert own.tobytes() == rewards_084(weights, action[b], before[b], pos[b], healthy[b], mode[b], ref_pos[b],
                                            near[b], close[b], complete[b]).tobytes()
        for i in range(n):
            has = healthy[b, i] and mode[b, i] in (Mode.POSITION, Mode.TRACK)
            gained = np.hypot.reduce(ref_pos[b, i] - before[b, i]) - np.hypot.reduce(ref_pos[b, i] - pos[b, i])
            want = (1.5 * gained * has - 0.3 * float(action[b, i] @ action[b, i]) - 10.0 * near[b, i] - 7.0 * close[b, i]
                    + 2.5 * complete[b])
            assert own[i] == pytest.approx(want, rel=1e-12, abs=1e-12)


def rewards_084(weights, action, before, pos, healthy, mode, ref_pos, near, close, complete):
    """swarmscene 0.8.4's ``_Episode.judge`` reward arithmetic for one world, transcribed (its
    ``_progress``, the einsum, the in-place penalties and bonus): the bits the refactor must keep."""
    has = (mode == int(Mode.POSITION)) | (mode == int(Mode.TRACK))
    gained = np.linalg.norm(ref_pos - before, axis=1) - np.linalg.norm(ref_pos - pos, axis=1)
    reward = weights.progress * np.where(has & healthy, gained, 0.0) - weights.effort * np.einsum(
        "ij,ij->i", action, action)
    if weights.separation:
        reward -= weights.separation * near
    if weights.clearance:
        reward -= weights.clearance * close
    if complete:
        reward += weights.complete
    return reward
