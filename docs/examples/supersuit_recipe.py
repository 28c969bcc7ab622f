"""Parameter sharing through SuperSuit: the PettingZoo parallel environment as a vector environment
of its agents, which Stable-Baselines3 trains as one policy (docs/rl.md, "Parameter sharing").

    pip install -e '.[train]'
    python docs/examples/supersuit_recipe.py                 # the default scenario, its leader fails at 10 s
    python docs/examples/supersuit_recipe.py --set swarm.n=8 --copies 4 --timesteps 200000

Each agent of each copy is one row of the vector environment: ``copies * N`` rows, each observing
``(D,)`` and acting ``(3,)``. A vehicle that fails (a ``hover`` event) leaves ``env.agents``, which
SuperSuit's vectoriser refuses (``AssertionError: MarkovVectorEnv does not support environments
with varying numbers of active agents unless black_death is set to True``): ``black_death_v3``
keeps its row, with a zero observation and a zero reward, until the episode ends.

It shows the plumbing, one policy trained on every agent's experience; it makes no claim about
what PPO learns at the default budget (docs/examples/train_ppo.py measures that).
"""

from __future__ import annotations

import argparse
import sys

from pettingzoo.utils.wrappers import BaseParallelWrapper

DEFAULT_SCENARIO = ["scenario=default", "events=lead_fails"]
"""Five vehicles whose leader fails (hovers) at 10 s of 45: the case black_death is for."""


class EndBothWays(BaseParallelWrapper):
    """At the episode's end, mark every agent terminated *and* truncated.

    SuperSuit 3.11.0's ``black_death_v3`` ends an episode only when every agent is terminated and
    truncated at once (``(terminations & truncations).all()``; fixed by SuperSuit pull request 265,
    after that release), so on its own it never ends one of ours: the next step finds no agent
    left (``RuntimeError: step() called before reset() or after every agent is done``). Marked both
    ways, the end reaches SuperSuit whatever its version; nothing is lost, as black_death reports
    one flag for both. A single agent's end (its failure) is passed on unchanged.
    """

    def step(self, actions):
        obs, rewards, terminations, truncations, infos = self.env.step(actions)
        if all(terminations[a] or truncations[a] for a in terminations):
            terminations = {a: True for a in terminations}
            truncations = dict(terminations)
        return obs, rewards, terminations, truncations, infos


def shared_policy_vec_env(overrides: list[str], copies: int = 1, seed: int | None = None):
    """The recipe: parallel env -> black death -> one row per agent -> ``copies`` concatenated, as
    a Stable-Baselines3 ``VecEnv`` (``num_cpus=0``: the copies step in this process).

    ``seed``: copy i runs its first episode with seed + i and draws the next ones from that
    (docs/rl.md, Seeds). Seeded here because SB3 cannot: ``PPO(seed=...)`` calls ``VecEnv.seed``,
    which SuperSuit's wrapper hands to a Gymnasium 1 vector env that has none (AttributeError).
    """
    import supersuit as ss

    from swarmscene.env import make_env

    env = ss.black_death_v3(EndBothWays(make_env(overrides)))
    rows = ss.pettingzoo_env_to_vec_env_v1(env)
    venv = ss.concat_vec_envs_v1(rows, copies, num_cpus=0, base_class="stable_baselines3")
    if seed is not None:
        venv.venv.reset(seed=seed)  # the concatenated copies, under SB3's wrapper
    return venv


def main(argv: list[str] | None = None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", nargs="*", default=[], metavar="OVERRIDE",
                        help=f"Hydra overrides after {' '.join(DEFAULT_SCENARIO)}, e.g. --set swarm.n=8")
    parser.add_argument("--copies", type=int, default=2, help="copies of the scenario stepped together (default: %(default)s)")
    parser.add_argument("--timesteps", type=int, default=50_000, help="PPO training steps, all rows together (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the network, the sampling and the episodes")
    parser.add_argument("--threads", type=int, default=1,
                        help="torch threads (default 1: a small MLP is slower on more, where cores are shared)")
    args = parser.parse_args(argv)
    if args.copies < 1 or args.timesteps < 1 or args.threads < 1:
        parser.error("--copies, --timesteps and --threads must be positive")
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed

    torch.set_num_threads(args.threads)
    set_random_seed(args.seed)  # the network and the sampling (not PPO(seed=...): see above)
    from hydra.errors import HydraException

    try:
        venv = shared_policy_vec_env([*DEFAULT_SCENARIO, *args.set], args.copies, seed=args.seed)
    except (ValueError, HydraException) as exc:  # a bad override (ConfigError is a ValueError)
        raise SystemExit(f"--set: {' '.join(str(exc).split())}") from None
    print(f"{venv.num_envs} rows (agents x copies): observation {venv.observation_space.shape}, "
          f"action {venv.action_space.shape}")
    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=256, verbose=1, device="cpu")
    model.learn(total_timesteps=args.timesteps)
    venv.close()
    return model


if __name__ == "__main__":
    main(sys.argv[1:])
