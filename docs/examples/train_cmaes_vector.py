"""Train one policy shared by every vehicle with CMA-ES, each generation flown as one batch of worlds.

    pip install -e '.[train]'
    python docs/examples/train_cmaes_vector.py                      # 5 vehicles of the default scenario
    python docs/examples/train_cmaes_vector.py --generations 12 --set clock.duration=6   # the CI test's run

The steps, each one line of a library's own API:

0. ``SwarmMultiAgentVectorEnv(popsize, config)`` (docs/rl.md, "Many worlds as arrays"): as many
   worlds as CMA-ES has candidates in a generation, stepped as one batch. Every vehicle of a
   world flies the same candidate (parameter sharing), so a world's return scores its candidate.
1. ``cma.CMAEvolutionStrategy(x0, sigma0)``: Hansen's CMA-ES (the ``cma`` package) over the
   weights of a linear policy, a = tanh(W o + c) with o an agent's observation (D values) and
   W, c its 3 x D + 3 weights, starting from zero (the vehicles hold still).
2. Each generation: ``es.ask()`` hands out the candidates; the batch flies one episode of every
   world from the same start (every world reset with the generation's seed, so that the candidates
   are compared on the same task); ``es.tell`` takes their costs (minus the mean return per
   vehicle: CMA-ES minimises).
3. Evaluation on seeds the training never saw (one a world, from 10_000 on): the mean return per
   vehicle of the trained policy (the mean of CMA-ES's last distribution) beside two baselines on
   the same seeds: the policy at its start (zero weights) and random weights of CMA-ES's first
   spread. Learning shows as the trained return above both.

The reward is the environment's (docs/rl.md: progress towards the formation's reference, minus
the separation and clearance penalties). The script exits 0 whatever the returns: it reports them.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from swarmscene.env import SwarmMultiAgentVectorEnv

SCENARIO = ["scenario=default"]
"""The task: the default scenario's five vehicles following their slots around the pillar."""
EVAL_SEED0 = 10_000
"""Evaluation seeds start here; generation g trains on seed ``--seed + g``."""
SIGMA0 = 0.1
"""CMA-ES's initial step size on the weights (the observation's entries are metres and m/s)."""


@dataclass
class Result:
    """What a training run reports: mean returns per vehicle over the same evaluation seeds."""

    generations: int
    popsize: int
    zero_return: float
    random_return: float
    trained_return: float
    best_weights: np.ndarray


class LinearPolicy:
    """a = tanh(W o + c) for every agent of every world: ``weights`` holds W (3 x D) row by row,
    then c (3)."""

    def __init__(self, observation_size: int) -> None:
        self.d = observation_size
        self.size = 3 * observation_size + 3

    def act(self, weights: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Actions (B, N, 3) of observations (B, N, D), world b flying ``weights[b]`` (B, size)."""
        w = weights[:, : 3 * self.d].reshape(len(weights), 3, self.d)
        c = weights[:, 3 * self.d:]
        return np.tanh(np.einsum("bnd,bkd->bnk", obs, w) + c[:, None, :])


def fly(envs: SwarmMultiAgentVectorEnv, policy: LinearPolicy, weights: np.ndarray,
        seeds: Sequence[int]) -> np.ndarray:
    """One episode of every world, world b flying ``weights[b]`` from ``seeds[b]``; each world's
    return per vehicle (the sum of its agents' rewards over the episode, over N).

    A world's episode ends when the environment says so (``infos["_metrics"]``); its later steps
    (the next episode, which the autoreset starts) are not counted."""
    obs, _ = envs.reset(seed=list(seeds))
    total = np.zeros(envs.num_envs)
    ended = np.zeros(envs.num_envs, dtype=bool)
    while not ended.all():
        obs, rewards, _, _, infos = envs.step(policy.act(weights, obs))
        total += np.where(ended, 0.0, rewards.sum(axis=1))
        ended |= infos.get("_metrics", False)
    return total / envs.num_agents


def evaluate(envs: SwarmMultiAgentVectorEnv, policy: LinearPolicy, weights: np.ndarray) -> float:
    """Mean return per vehicle over the evaluation seeds (one a world), world b flying
    ``weights[b]`` (B, size)."""
    return float(fly(envs, policy, weights, [EVAL_SEED0 + b for b in range(envs.num_envs)]).mean())


def train(config: Sequence[str], generations: int, seed: int, quiet: bool) -> Result:
    """CMA-ES on the linear policy, one batch of worlds per generation; the evaluation beside the
    two baselines, on as many unseen seeds as a generation has candidates."""
    import cma

    probe = SwarmMultiAgentVectorEnv(1, config)
    policy = LinearPolicy(probe.single_agent_observation_space.shape[0])
    es = cma.CMAEvolutionStrategy(np.zeros(policy.size), SIGMA0,
                                  {"seed": seed + 1, "verbose": -9})  # cma's seed 0 means "from the clock"
    envs = SwarmMultiAgentVectorEnv(es.popsize, config)
    for generation in range(generations):
        candidates = np.array(es.ask())
        returns = fly(envs, policy, candidates, [seed + generation] * envs.num_envs)  # one start for all
        es.tell(list(candidates), (-returns).tolist())  # CMA-ES minimises
        if not quiet:
            print(f"generation {generation + 1:3d}/{generations}: return per vehicle, best "
                  f"{returns.max():7.3f}, median {np.median(returns):7.3f}", flush=True)
    best = np.asarray(es.result.xfavorite)  # the distribution's mean: CMA-ES's estimate of the optimum
    every = np.ones((envs.num_envs, 1))
    spread = np.random.default_rng(seed).normal(0.0, SIGMA0, (envs.num_envs, policy.size))
    return Result(generations, es.popsize, zero_return=evaluate(envs, policy, 0.0 * every * best),
                  random_return=evaluate(envs, policy, spread), trained_return=evaluate(envs, policy, every * best),
                  best_weights=best)


def main(argv: Sequence[str] | None = None) -> Result:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=30, help="CMA-ES generations (one batch each)")
    parser.add_argument("--seed", type=int, default=0, help="CMA-ES's seed and the first training start")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                        help="overrides appended to the scenario (e.g. clock.duration=6)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    result = train([*SCENARIO, *args.set], args.generations, args.seed, args.quiet)
    print(f"{result.generations} generations of {result.popsize} worlds; mean return per vehicle on "
          f"{result.popsize} unseen seeds: trained {result.trained_return:.3f}, at its start (zero "
          f"weights) {result.zero_return:.3f}, random weights {result.random_return:.3f}")
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
