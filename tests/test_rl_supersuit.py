"""The SuperSuit recipe of docs/rl.md (docs/examples/supersuit_recipe.py): parallel env ->
black_death_v3 -> one vector-env row per agent -> concatenated copies -> Stable-Baselines3.

The scenario: the default one with ``events=lead_fails`` (agent_0 fails at 10 s, applied in the
tick ending at 10.1 s, the 101st step) cut to 12 s (120 steps, then truncation)."""

from __future__ import annotations

from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest
import script_modules
from packaging.version import Version

ss = pytest.importorskip("supersuit")
from stable_baselines3 import PPO  # noqa: E402

from swarmscene.env import make_env  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "supersuit_recipe.py"
FAILING = ["scenario=default", "events=lead_fails", "clock.duration=12"]
N, D = 5, 47
FAILURE_STEP, LAST_STEP = 101, 120


@pytest.fixture(scope="module")
def recipe():
    return script_modules.load("supersuit_recipe", EXAMPLE)


def test_without_black_death_the_vectoriser_fails_at_the_first_failure():
    rows = ss.pettingzoo_env_to_vec_env_v1(make_env(FAILING))
    rows.reset(seed=0)
    zeros = np.zeros((N, 3), dtype=np.float32)
    for _ in range(FAILURE_STEP - 1):
        rows.step(zeros)
    with pytest.raises(AssertionError, match="^MarkovVectorEnv does not support environments with varying "
                                             "numbers of active agents unless black_death is set to True$"):
        rows.step(zeros)
    assert rows.par_env.agents == ["agent_1", "agent_2", "agent_3", "agent_4"]


def test_the_recipe_keeps_a_failed_agents_row_with_zeros_until_the_end(recipe):
    venv = recipe.shared_policy_vec_env(FAILING, copies=2, seed=7)
    copies = [rows.par_env.unwrapped for rows in venv.venv.vec_envs]
    assert [env.sim.config.seed for env in copies] == [7, 8]  # seeded one by one, under SB3's wrapper
    assert venv.num_envs == 2 * N
    assert venv.observation_space.shape == (D,) and venv.action_space.shape == (3,)
    obs = venv.reset()
    assert obs.shape == (2 * N, D) and obs.dtype == np.float32
    rng = np.random.default_rng(0)
    led = [0, N]  # agent_0's row in each copy
    for step in range(1, LAST_STEP + 1):
        obs, rewards, dones, infos = venv.step(rng.uniform(-1, 1, (2 * N, 3)).astype(np.float32))
        assert obs.shape == (2 * N, D) and rewards.shape == dones.shape == (2 * N,)
        if step < FAILURE_STEP:
            assert np.all(obs[led, 6] == 1.0)  # the healthy flag
        elif step == FAILURE_STEP:
            assert np.all(obs[led, 6] == 0.0) and np.all(obs[led, :3] != 0)  # its last real observation
        elif step < LAST_STEP:  # black death: zeros and no reward, while the others fly on
            assert np.all(obs[led] == 0.0) and np.all(rewards[led] == 0.0)
            others = [i for i in range(2 * N) if i not in led]
            assert np.all(obs[others, 6] == 1.0) and np.any(rewards[others] != 0.0)
        if step < LAST_STEP:
            assert not dones.any()
    assert dones.all()  # every row of both copies ends at the truncation, then resets
    assert len({env.sim.config.seed for env in copies}) == 2  # the next seeds, drawn per copy
    assert np.all(obs[:, 6] == 1.0)  # the next episode's first observation: every agent flies again
    assert "terminal_observation" in infos[0] and np.all(infos[0]["terminal_observation"] == 0.0)
    assert infos[1]["metrics"]["healthy_at_end"] == N - 1 and infos[1]["metrics"]["steps"] == LAST_STEP
    venv.close()


def test_black_death_alone_ends_no_episode_in_supersuit_3_11(recipe):
    """SuperSuit <= 3.11.0 ends a black-death episode only when every agent is terminated and
    truncated at once; EndBothWays (the recipe's) makes the end reach it, with any version."""
    env = ss.black_death_v3(make_env(FAILING))
    env.reset(seed=0)
    zeros = {a: np.zeros(3, dtype=np.float32) for a in env.possible_agents}
    for _ in range(LAST_STEP):
        _, _, terminations, truncations, _ = env.step(zeros)
    if Version(version("supersuit")) <= Version("3.11.0"):
        assert not any(terminations.values()) and not any(truncations.values())  # the end is lost
        with pytest.raises(RuntimeError, match="after every agent is done"):
            env.step(zeros)
    else:  # pragma: no cover - a SuperSuit with pull request 265
        assert all(terminations.values())
    fixed = ss.black_death_v3(recipe.EndBothWays(make_env(FAILING)))
    fixed.reset(seed=0)
    for _ in range(LAST_STEP):
        _, _, terminations, truncations, _ = fixed.step(zeros)
    assert all(terminations.values()) and all(truncations.values()) and fixed.agents == []


def test_stable_baselines3_trains_one_shared_policy_on_the_rows(recipe):
    # one rollout of 256 steps of the 5 rows: two failures and two episode ends
    model = recipe.main(["--set", "clock.duration=12", "--copies", "1", "--timesteps", "1280"])
    assert isinstance(model, PPO) and model.num_timesteps == 256 * N
    assert model.observation_space.shape == (D,) and model.action_space.shape == (3,)
    action, _ = model.predict(np.zeros(D, dtype=np.float32), deterministic=True)
    assert action.shape == (3,)  # one agent's observation in, one agent's action out: the shared policy


def test_a_bad_override_exits_in_one_line(recipe):
    with pytest.raises(SystemExit) as exit_:
        recipe.main(["--set", "swarm.n=abc"])
    assert str(exit_.value) == "--set: swarm.n: must be an integer (got 'abc')"
