"""Train one policy shared by every vehicle with CMA-ES, each generation flown as one batch of worlds.

    pip install -e '.[train]'
    python docs/examples/train_cmaes_vector.py                      # 5 vehicles of the default scenario
    python docs/examples/train_cmaes_vector.py --generations 20 --set clock.duration=6   # the CI test's run

The steps, each one line of a library's own API:

0. ``SwarmMultiAgentVectorEnv(popsize * starts, config)`` (docs/rl.md, "Many worlds as arrays"):
   every candidate CMA-ES hands out in a generation flown from ``--starts`` random starts, all in
   one batch of worlds. Every vehicle of a world flies the same candidate (parameter sharing), so
   a world's return scores its candidate on that start.
1. ``cma.CMAEvolutionStrategy(x0, sigma0)``: Hansen's CMA-ES (the ``cma`` package) over the
   weights of a linear policy (:class:`LinearPolicy`: a = tanh(W z + c), z the agent's observation
   normalised by running statistics as in ARS), starting from zero weights (the vehicles hold
   still).
2. Each generation: ``es.ask()`` hands out the candidates; the batch flies one episode of every
   world, every candidate from the generation's same starts (so that they are compared on the
   same tasks); ``es.tell`` takes their costs (minus the mean return per vehicle over the starts:
   CMA-ES minimises).
3. Evaluation on seeds the training never saw (one a world, from 10_000 on), the normalisation
   frozen: the mean return per vehicle of the trained policy (the mean of CMA-ES's last
   distribution) beside two baselines on the same seeds: the policy at its start (zero weights)
   and random weights of CMA-ES's first spread. Learning shows as the trained return above both.
   For scale, the same seeds flown by ``seek_reference``, the ``policy`` plugin's scripted
   baseline.

The reward is the environment's (docs/rl.md: progress towards the formation's reference, minus
the separation and clearance penalties). The script exits 0 whatever the returns: it reports them.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from swarmscene.env import SwarmMultiAgentVectorEnv

SCENARIO = ["scenario=default", "swarm.start.layout=random"]
"""The task: the default scenario's five vehicles following their slots around the pillar, from a
random start (a 10 m square, the vehicles 2 m apart or more) that the seed draws: without it every
seed would fly the same episode, and unseen seeds would be the training episode again."""
EVAL_SEED0 = 10_000
"""Evaluation seeds start here; generation g trains on seed ``--seed + g``."""
SIGMA0 = 0.1
"""CMA-ES's initial step size on the weights (the observation's entries are metres and m/s)."""


@dataclass
class Result:
    """What a training run reports: mean returns per vehicle over the same evaluation seeds."""

    generations: int
    popsize: int
    worlds: int
    zero_return: float
    random_return: float
    trained_return: float
    scripted_return: float
    medians: list[float]
    """Each generation's median return per vehicle over its candidates (the training starts)."""
    best_weights: np.ndarray


class LinearPolicy:
    """a = tanh(W (o - mu) / sigma + c) for every agent of every world: ``weights`` holds W (3 x D)
    row by row, then c (3); mu and sigma are the running mean and standard deviation of the
    observations seen while training (Mania, Guy and Recht 2018, ARS V2: a linear policy on
    normalised states), so that metres of position and flags of masks weigh alike; frozen for the
    evaluation."""

    def __init__(self, observation_size: int) -> None:
        self.d = observation_size
        self.size = 3 * observation_size + 3
        self.count, self.mean, self.m2 = 0, np.zeros(observation_size), np.zeros(observation_size)
        self.learning = True  # update mu and sigma with every observation acted on

    def act(self, weights: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Actions (B, N, 3) of observations (B, N, D), world b flying ``weights[b]`` (B, size)."""
        if self.learning:
            self._observe(obs.reshape(-1, self.d))
        sigma = np.sqrt(self.m2 / max(self.count - 1, 1))
        z = (obs - self.mean) / np.where(sigma > 1e-8, sigma, 1.0)  # a constant entry: left as it is
        w = weights[:, : 3 * self.d].reshape(len(weights), 3, self.d)
        c = weights[:, 3 * self.d:]
        return np.tanh(np.einsum("bnd,bkd->bnk", z, w) + c[:, None, :])

    def _observe(self, rows: np.ndarray) -> None:
        """Chan et al.'s parallel update of the running mean and sum of squared deviations."""
        n, mean = len(rows), rows.mean(axis=0)
        delta, total = mean - self.mean, self.count + n
        self.m2 += ((rows - mean) ** 2).sum(axis=0) + delta**2 * self.count * n / total
        self.mean += delta * n / total
        self.count = total


def fly(envs: SwarmMultiAgentVectorEnv, act: Callable[[np.ndarray], np.ndarray], seeds: Sequence[int]) -> np.ndarray:
    """One episode of every world from ``seeds[b]``, the actions (B, N, 3) ``act(observations)``;
    each world's return per vehicle (the sum of its agents' rewards over the episode, over N).

    A world's episode is over when none of its agents acts any more (``infos["agents"]``); its
    later steps (the next episode, which the autoreset starts) are not counted."""
    obs, _ = envs.reset(seed=list(seeds))
    total = np.zeros(envs.num_envs)
    ended = np.zeros(envs.num_envs, dtype=bool)
    while not ended.all():
        obs, rewards, _, _, infos = envs.step(act(obs))
        total += np.where(ended, 0.0, rewards.sum(axis=1))
        ended |= ~infos["agents"].any(axis=1)
    return total / envs.num_agents


def evaluate(envs: SwarmMultiAgentVectorEnv, act: Callable[[np.ndarray], np.ndarray]) -> float:
    """Mean return per vehicle of ``act`` over the evaluation seeds, one a world."""
    return float(fly(envs, act, [EVAL_SEED0 + b for b in range(envs.num_envs)]).mean())


def scripted(envs: SwarmMultiAgentVectorEnv) -> Callable[[np.ndarray], np.ndarray]:
    """``seek_reference``, the ``policy`` plugin's scripted baseline (docs/rl.md), every agent of
    every world acting on its own observation row."""
    from swarmscene import api

    envs.reset(seed=0)  # the worlds' policy plugins, which hold the observation layout and action spec
    avoidance = envs.sims[0].avoidance
    seek = api.plugins()[1].get("policy", "seek_reference")
    policy = seek(seek.Params.model_validate({}), avoidance.layout, avoidance.spec)
    return lambda obs: np.stack([policy(rows) for rows in obs])


def train(config: Sequence[str], generations: int, starts: int, seed: int, quiet: bool) -> Result:
    """CMA-ES on the linear policy, one batch of worlds per generation (every candidate from the
    generation's ``starts`` starts); the evaluation beside the baselines on as many unseen seeds as
    the batch has worlds."""
    import cma

    probe = SwarmMultiAgentVectorEnv(1, config)
    policy = LinearPolicy(probe.single_agent_observation_space.shape[0])
    es = cma.CMAEvolutionStrategy(np.zeros(policy.size), SIGMA0,
                                  {"seed": seed + 1, "verbose": -9})  # cma's seed 0 means "from the clock"
    envs = SwarmMultiAgentVectorEnv(es.popsize * starts, config)
    medians = []
    for generation in range(generations):
        candidates = np.array(es.ask())
        first = seed + generation * starts  # the generation's starts, the same for every candidate
        weights = np.repeat(candidates, starts, axis=0)
        flown = fly(envs, lambda obs: policy.act(weights, obs), [first + j for j in range(starts)] * es.popsize)
        returns = flown.reshape(es.popsize, starts).mean(axis=1)
        es.tell(list(candidates), (-returns).tolist())  # CMA-ES minimises
        medians.append(float(np.median(returns)))
        if not quiet:
            print(f"generation {generation + 1:3d}/{generations}: return per vehicle, best "
                  f"{returns.max():7.3f}, median {np.median(returns):7.3f}", flush=True)
    best = np.asarray(es.result.xfavorite)  # the distribution's mean: CMA-ES's estimate of the optimum
    policy.learning = False
    spread = np.random.default_rng(seed).normal(0.0, SIGMA0, (envs.num_envs, policy.size))
    every = np.tile(best, (envs.num_envs, 1))
    return Result(generations, es.popsize, envs.num_envs,
                  zero_return=evaluate(envs, lambda obs: np.zeros(obs.shape[:2] + (3,))),
                  random_return=evaluate(envs, lambda obs: policy.act(spread, obs)),
                  trained_return=evaluate(envs, lambda obs: policy.act(every, obs)),
                  scripted_return=evaluate(envs, scripted(envs)), medians=medians, best_weights=best)


def main(argv: Sequence[str] | None = None) -> Result:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=30, help="CMA-ES generations (one batch each)")
    parser.add_argument("--starts", type=int, default=2,
                        help="starts each candidate flies per generation (its score: their mean return)")
    parser.add_argument("--seed", type=int, default=0, help="CMA-ES's seed and the first training start")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                        help="overrides appended to the scenario (e.g. clock.duration=6)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    result = train([*SCENARIO, *args.set], args.generations, args.starts, args.seed, args.quiet)
    print(f"{result.generations} generations of {result.popsize} candidates, {result.worlds} worlds; mean return per vehicle on "
          f"{result.worlds} unseen seeds: trained {result.trained_return:.3f}, at its start (zero "
          f"weights) {result.zero_return:.3f}, random weights {result.random_return:.3f}; the scripted "
          f"seek_reference {result.scripted_return:.3f}")
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
