"""The CMA-ES training example (docs/examples/train_cmaes_vector.py) on the multi-agent vector
environment, at a CI budget: 12 generations of 18 candidates, each generation one batch of 18
worlds of the default scenario's five vehicles flying 6 s. CMA-ES (the ``cma`` package) learns a
linear policy shared by the vehicles that makes progress towards their slots, against the policy at
its start and random weights on the same unseen seeds."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cma")

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "train_cmaes_vector.py"
CI_RUN = ["--generations", "12", "--set", "clock.duration=6", "--seed", "0", "--quiet"]


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("train_cmaes_vector", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    return module


def test_cma_es_learns_beyond_its_start_and_random_weights_on_unseen_seeds(example):
    result = example.main(CI_RUN)
    assert (result.generations, result.popsize) == (12, 18)
    assert result.zero_return == 0.0  # zero weights: every vehicle holds still, no progress, no penalty
    assert result.random_return < -1.0  # random weights fly the vehicles into each other
    # learned: at least 1 m of progress per vehicle more than either baseline, in 6 s
    assert result.trained_return > max(result.zero_return, result.random_return) + 1.0


def test_the_policy_is_linear_in_the_weights_and_shared_by_a_world_s_agents(example):
    policy = example.LinearPolicy(observation_size=4)
    rng = np.random.default_rng(0)
    weights, obs = rng.normal(size=(2, policy.size)), rng.normal(size=(2, 5, 4))
    actions = policy.act(weights, obs)
    w, c = weights[1, :12].reshape(3, 4), weights[1, 12:]
    np.testing.assert_allclose(actions[1, 3], np.tanh(w @ obs[1, 3] + c), rtol=1e-14)
