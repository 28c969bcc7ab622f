"""The PPO training example (docs/examples/train_ppo.py) with Stable-Baselines3, at a CI budget.

8192 steps on one vehicle of the default scenario, 10 s episodes: enough for PPO to learn to fly
its reference (about 6 m of progress per episode where the scripted seek_reference makes 9.9),
against random actions and the same network untrained on the same evaluation seeds."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import script_modules

pytest.importorskip("stable_baselines3")
import gymnasium as gym  # noqa: E402
from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.env_checker import check_env  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "train_ppo.py"
CI_RUN = ["--set", "clock.duration=10", "--timesteps", "8192", "--seed", "0", "--quiet"]


def load_example():
    return script_modules.load("train_ppo", EXAMPLE)


@pytest.fixture(scope="module")
def example():
    return load_example()


@pytest.fixture(scope="module")
def trained(example, tmp_path_factory):
    """One CI-budget run of the example, its warnings recorded."""
    out = tmp_path_factory.mktemp("ppo") / "policy.zip"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = example.main([*CI_RUN, "--out", str(out)])
    return result, caught


def test_the_example_learns_beyond_random_and_untrained_on_the_same_seeds(trained):
    result, _ = trained
    assert result.env_id == "swarmscene/solo-v0" and result.timesteps == 8192
    assert result.untrained_return < 1.0 and result.random_return < 1.0  # neither gets anywhere
    # learned: at least 2 m more progress per 10 s episode than either baseline
    assert result.trained_return > max(result.random_return, result.untrained_return) + 2.0


def test_the_saved_policy_reloads_and_gives_the_same_actions(trained, example):
    result, _ = trained
    assert result.reload_same_actions
    reloaded = PPO.load(result.path, device="cpu")
    env = example.make_env(result.env_id, ["clock.duration=10"])
    obs, _ = env.reset(seed=123)
    for _ in range(5):
        action = result.model.predict(obs, deterministic=True)[0]
        np.testing.assert_array_equal(reloaded.predict(obs, deterministic=True)[0], action)
        obs, *_ = env.step(action)


def test_no_warning_from_stable_baselines3_or_gymnasium(trained):
    _, caught = trained
    ours = [w for w in caught if any(lib in str(w.filename) for lib in ("stable_baselines3", "gymnasium"))]
    assert ours == [], [str(w.message) for w in ours]


def test_sb3_check_env_passes_on_the_flat_env_and_warns_without_the_wrapper(example):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning from SB3's checker fails the flat env
        check_env(example.make_env("swarmscene/swap-v0", ["swarm.n=2"]))
    with pytest.warns(UserWarning, match="unconventional shape") as record:
        check_env(gym.make("swarmscene/swap-v0", config=["scenario=swap", "swarm.n=2"]))
    # SB3's warnings name its own files: the filter of the test above would see them
    assert any("stable_baselines3" in w.filename for w in record)


@pytest.mark.parametrize("args, message", [
    (["--env-id", "swarmscene/nope-v0"], "--env-id: Environment `nope` doesn't exist in namespace swarmscene."),
    (["--set", "swarm.n=abc"], "--set: swarm.n: must be an integer (got 'abc')"),
    (["--set", "nokey=1"], "--set: nokey: unknown key (got '1')"),
])
def test_a_bad_id_or_override_exits_in_one_line_before_training(example, args, message, tmp_path):
    out = tmp_path / "policy.zip"
    with pytest.raises(SystemExit) as exit_:
        example.main([*args, "--out", str(out), "--quiet"])
    assert str(exit_.value) == message
    assert not out.exists()
