"""Train a PPO policy (Stable-Baselines3) on a swarmscene Gymnasium id, and show what it learned.

    pip install -e '.[train]'
    python docs/examples/train_ppo.py                                  # swarmscene/solo-v0, 30k steps
    python docs/examples/train_ppo.py --env-id swarmscene/default-v0                  # five vehicles, a preset
    python docs/examples/train_ppo.py --set clock.duration=10 --timesteps 8192   # the CI test's run

The steps, each one line of a library's own API:

0. ``register_scenario``: the default id, ``swarmscene/solo-v0``, is the default scenario flown by
   one vehicle (no leader), whose reference is its slot moving along the path around the pillar:
   a task PPO learns in a minute. Any id works, e.g. a preset's ``swarmscene/<preset>-v0``.
1. ``gym.make(env_id)``: the centralised environment (one agent for the whole swarm), wrapped in
   Gymnasium's ``FlattenObservation`` because SB3's MLP policy wants a flat vector (without it SB3
   warns and flattens on its own); ``--set`` appends overrides to the id's scenario.
2. ``stable_baselines3.common.env_checker.check_env``: SB3's own check of the spaces and the API.
3. ``PPO("MlpPolicy", env).learn(timesteps)``, with SB3's progress table every rollout.
4. Evaluation on seeds the training never saw (``--eval-episodes`` of them, from 10_000 on): the
   mean episode return of the trained policy (deterministic actions) beside two baselines on the
   same seeds: uniform random actions, and the same network before training. Learning shows as the
   trained return above both.
5. ``model.save(out)``, ``PPO.load(out)``: the reloaded policy gives the same actions.

The reward is the environment's (docs/rl.md: progress towards the formation's reference, minus
the separation and clearance penalties). The script exits 0 whatever the returns: it reports
them; whether a budget is enough is for the reader (docs/rl.md quotes measured ones).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from swarmscene.env import register_scenario

SOLO_ID = register_scenario("swarmscene/solo-v0", ["scenario=default", "swarm.n=1", "swarm.leader=null"])
"""One vehicle of the default scenario: the example's default task."""
EVAL_SEED0 = 10_000
"""Evaluation seeds start here; the training episodes' seeds are drawn from ``--seed`` (docs/rl.md, Seeds)."""
N_STEPS = 512
"""PPO rollout length per update (SB3's default 2048 would leave a small budget with few updates)."""
BATCH_SIZE = 64


@dataclass
class Result:
    """What a training run reports: mean evaluation returns over the same seeds, and the checks."""

    env_id: str
    timesteps: int
    random_return: float
    untrained_return: float
    trained_return: float
    reload_same_actions: bool
    path: Path
    model: object


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env-id", default=SOLO_ID,
                        help="a registered Gymnasium id (default: %(default)s; a preset: swarmscene/<preset>-v0)")
    parser.add_argument("--set", nargs="*", default=[], metavar="OVERRIDE",
                        help="Hydra overrides appended to the id's scenario, e.g. --set swarm.n=1 clock.duration=10")
    parser.add_argument("--timesteps", type=int, default=30_000,
                        help="environment steps of training (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the network, the sampling and the training episodes")
    parser.add_argument("--eval-episodes", type=int, default=5,
                        help="episodes per policy in the evaluation (seeds 10000, 10001, ...; default: %(default)s)")
    parser.add_argument("--out", type=Path, default=Path("ppo_swarmscene.zip"),
                        help="where the trained policy is saved (SB3's zip; default: %(default)s)")
    parser.add_argument("--threads", type=int, default=1,
                        help="torch threads (default 1: a small MLP is slower on more, where cores are shared)")
    parser.add_argument("--quiet", action="store_true", help="no progress table, only the summary")
    args = parser.parse_args(argv)
    if args.timesteps < 1 or args.eval_episodes < 1 or args.threads < 1:
        parser.error("--timesteps, --eval-episodes and --threads must be positive")
    return args


def make_env(env_id: str, overrides: list[str]):
    """``gym.make(env_id)`` with ``overrides`` appended to its scenario, flattened for SB3; a bad id
    or override exits with one line naming it."""
    import gymnasium as gym
    from hydra.errors import HydraException

    try:
        kwargs = {}
        if overrides:
            config = gym.spec(env_id).kwargs.get("config", [])
            if isinstance(config, dict):
                raise SystemExit(f"--set: {env_id} was registered with a composed dict; overrides need a list")
            kwargs["config"] = [*config, *overrides]
        env = gym.make(env_id, **kwargs)
    except gym.error.Error as exc:
        raise SystemExit(f"--env-id: {exc}") from None
    except (ValueError, HydraException) as exc:  # ConfigError is a ValueError
        raise SystemExit(f"--set: {' '.join(str(exc).split())}") from None
    return gym.wrappers.FlattenObservation(env)


def mean_return(env, act, episodes: int) -> float:
    """Mean undiscounted return of ``act(obs) -> action`` over the evaluation seeds."""
    totals = []
    for k in range(episodes):
        obs, _ = env.reset(seed=EVAL_SEED0 + k)
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(act(obs))
            total += reward
            done = terminated or truncated
        totals.append(total)
    return float(np.mean(totals))


def random_actions(env, seed: int):
    """Uniform random actions from a seeded copy of the action space (the same on every call)."""
    space = env.action_space
    space.seed(seed)
    return lambda obs: space.sample()


def greedy(model):
    return lambda obs: model.predict(obs, deterministic=True)[0]


def train(args: argparse.Namespace) -> Result:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env

    torch.set_num_threads(args.threads)
    env = make_env(args.env_id, args.set)
    check_env(env)  # raises on a broken space or API; warns on what SB3 would change
    say = (lambda *a: None) if args.quiet else print
    model = PPO("MlpPolicy", env, n_steps=N_STEPS, batch_size=BATCH_SIZE, seed=args.seed,
                verbose=0 if args.quiet else 1, device="cpu")
    say(f"{args.env_id}: observation {env.observation_space.shape}, action {env.action_space.shape}")
    random_return = mean_return(env, random_actions(env, args.seed), args.eval_episodes)
    untrained_return = mean_return(env, greedy(model), args.eval_episodes)
    model.learn(total_timesteps=args.timesteps)
    trained_return = mean_return(env, greedy(model), args.eval_episodes)

    args.out.parent.mkdir(parents=True, exist_ok=True)
    model.save(args.out)
    reloaded = PPO.load(args.out, device="cpu")
    probes = [env.observation_space.sample() for _ in range(8)]
    probes.append(env.reset(seed=EVAL_SEED0)[0])
    same = all(np.array_equal(greedy(model)(o), greedy(reloaded)(o)) for o in probes)
    env.close()
    return Result(args.env_id, args.timesteps, random_return, untrained_return, trained_return, same, args.out,
                  model)


def main(argv: list[str] | None = None) -> Result:
    args = parse_args(argv)
    result = train(args)
    print(f"mean return over {args.eval_episodes} evaluation episodes (seeds {EVAL_SEED0}..): "
          f"random {result.random_return:.2f}, untrained {result.untrained_return:.2f}, "
          f"trained {result.trained_return:.2f} after {result.timesteps} steps")
    print(f"saved {result.path}; reloaded, it gives the same actions: {result.reload_same_actions}")
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
