"""The vector environments' worlds (``swarmscene.env``): B drivers ticked as one batch of worlds,
and each environment's reset and step over them as a *stepper* (:class:`CentralWorlds`,
:class:`AgentWorlds`), which :mod:`swarmscene.rl.workers` can run in worker processes."""

from __future__ import annotations

import multiprocessing
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from ..core.batch import lockstep
from ..core.state import WorldBatch
from .episode import Driver, EnvOptions, Episode, judge_batch, swarm_outcome
from .workers import Shards, Stepped


def _observations(episodes: Sequence[Episode]) -> np.ndarray:
    """The episodes' observations stacked (B, N, D): their policy avoidance's batched observation,
    each world's rows the bits of its own ``observe()``."""
    policies = [episode.policy for episode in episodes]
    return type(policies[0]).observe_batch(policies, [episode.sim.sensing for episode in episodes])


class Worlds:
    """The B worlds of a vector environment: one :class:`Driver` each, their going episodes ticked
    as one batch of worlds (:func:`swarmscene.core.batch.lockstep`: the physics in one call per
    physics step), and a world whose episode ended started again at its next step (Gymnasium's
    next-step autoreset). Both vector environments' steppers (:class:`CentralWorlds`,
    :class:`AgentWorlds`) are this, read two ways."""

    def __init__(self, num_envs: int, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
                 max_episode_steps: int | None) -> None:
        first = Driver(config, options)
        self.drivers = [first, *(first.twin() for _ in range(num_envs - 1))]
        self.n, self.layout_size = self.drivers[0].n, self.drivers[0].layout_size
        self.max_episode_steps = max_episode_steps
        self.steps = np.zeros(num_envs, dtype=int)  # ticks of each world's episode
        self.ended = np.zeros(num_envs, dtype=bool)  # the world's episode ended at the last step
        self._batch: tuple[list[Any], Any] | None = None  # (the worlds, their WorldBatch)

    def reset(self, seeds: Sequence[int | None]) -> list[Episode]:
        """Start every world's episode, world b's from ``seeds[b]`` (:func:`world_seeds`)."""
        self.steps[:] = 0
        self.ended[:] = False
        return [driver.reset(s) for driver, s in zip(self.drivers, seeds, strict=True)]

    def episodes(self) -> list[Episode]:
        """The worlds' current episodes (an error before :meth:`reset`)."""
        episodes = [driver.episode for driver in self.drivers]
        if any(episode is None for episode in episodes):
            raise RuntimeError("step() called before reset()")
        return cast(list[Episode], episodes)

    def restart_ended(self, episodes: list[Episode]) -> list[int]:
        """Start the next episode of each world whose episode ended at the last step (in place in
        ``episodes``, its seed from the world's own generator); the worlds restarted."""
        restarted = np.flatnonzero(self.ended).tolist()
        for b in restarted:
            episodes[b] = self.drivers[b].reset(None)
            self.steps[b] = 0
        return restarted

    def tick(self, episodes: list[Episode], going: list[int], actions: np.ndarray,
             active: np.ndarray) -> dict[int, tuple[np.ndarray, bool, bool, bool]]:
        """One guidance tick of the ``going`` worlds, their physics as one batch: world b acts
        ``actions[b]`` (N, 3) with its agents ``active[b]`` (N,); by world, the agents' rewards
        (N,), whether the episode terminated, whether it was truncated (its duration), and whether
        it reached ``max_episode_steps`` at this step (each environment reads that as its own)."""
        if not going:  # every world restarted at this step
            return {}
        before = np.stack([episodes[b].act(actions[b], active[b]) for b in going])
        sims = [episodes[b].sim for b in going]
        lockstep(sims, self._world_batch(sims))
        judged = {}
        for b, (reward, terminated, truncated) in zip(
                going, judge_batch([episodes[b] for b in going], actions[going], before), strict=True):
            self.steps[b] += 1
            at_limit = self.max_episode_steps is not None and self.steps[b] >= self.max_episode_steps
            judged[b] = (reward, terminated, truncated, at_limit)
        return judged

    def _world_batch(self, sims: list[Any]) -> Any:
        """The running worlds' WorldBatch, made again when a world started a new episode."""
        worlds = [sim.world for sim in sims]
        if self._batch is None or len(self._batch[0]) != len(worlds) or any(
                a is not c for a, c in zip(self._batch[0], worlds, strict=True)):
            self._batch = (worlds, WorldBatch(worlds))
        return self._batch[1]

    def close(self) -> None:
        """Drop the episodes."""
        for driver in self.drivers:
            driver.episode = None


def _check_counts(num_envs: Any, max_episode_steps: Any, workers: Any = 1) -> None:
    """One line for a bad world count, episode limit or worker count of a vector environment."""
    if not isinstance(num_envs, int) or isinstance(num_envs, bool) or num_envs < 1:
        raise ValueError(f"num_envs: must be an integer >= 1 (got {num_envs!r})")
    if max_episode_steps is not None and (not isinstance(max_episode_steps, int | np.integer)
                                          or isinstance(max_episode_steps, bool) or max_episode_steps < 1):
        raise ValueError(f"max_episode_steps: must be an integer >= 1 or None (got {max_episode_steps!r})")
    if not isinstance(workers, int) or isinstance(workers, bool) or not 1 <= workers <= num_envs:
        raise ValueError(f"workers: must be an integer from 1 to num_envs = {num_envs} (got {workers!r})")


def world_seeds(seed: int | Sequence[int | None] | None, b_worlds: int) -> list[int | None]:
    """Each world's seed at a reset: world b's is ``seed + b`` (as ``SyncVectorEnv`` seeds its
    copies) or ``seed[b]``; where it is None, the world draws it from its own generator (as the
    single environment's ``reset()``: before any seed was given, each world's generator starts from
    the scenario's ``seed``, so those worlds start alike)."""
    seeds: list[int | None] = [None] * b_worlds if seed is None else (
        [int(seed) + b for b in range(b_worlds)] if isinstance(seed, int | np.integer) else list(seed))
    if len(seeds) != b_worlds:
        raise ValueError(f"seed: {len(seeds)} seeds for {b_worlds} worlds")
    return seeds


class _Stepper:
    """What both steppers share: their worlds, and ``close`` (as :class:`~.workers.Shards` has)."""

    def __init__(self, num_envs: int, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
                 max_episode_steps: int | None) -> None:
        self.worlds = Worlds(num_envs, config, options, max_episode_steps)

    def close(self) -> None:
        """Drop the episodes (``reset`` starts them again)."""
        self.worlds.close()


class CentralWorlds(_Stepper):
    """:class:`~swarmscene.env.SwarmVectorEnv`'s worlds: its reset and step, the infos not yet in vector form (a
    stepper of :mod:`swarmscene.rl.workers`, which can run it in a worker process)."""

    def __init__(self, num_envs: int, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
                 max_episode_steps: int | None) -> None:
        super().__init__(num_envs, config, options, max_episode_steps)
        self._every = np.ones((num_envs, self.worlds.n), dtype=bool)  # the centralised agent commands every vehicle

    def reset(self, seeds: Sequence[int | None]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Every world's episode from its seed; the observations (B, N, D) and no per-world arrays."""
        return _observations(self.worlds.reset(seeds)), {}

    def step(self, actions: np.ndarray) -> Stepped:
        """One tick of every world with its actions (B, N, 3): the swarms' summed rewards and ends (B,)."""
        worlds = self.worlds
        episodes = worlds.episodes()
        b_worlds = len(episodes)
        rewards = np.zeros(b_worlds)
        terminated = np.zeros(b_worlds, dtype=bool)
        truncated = np.zeros(b_worlds, dtype=bool)
        ended = []
        worlds.restart_ended(episodes)
        going = np.flatnonzero(~worlds.ended).tolist()
        for b, (reward, term, trunc, at_limit) in worlds.tick(episodes, going, actions, self._every).items():
            # the episode's own ends give its metrics; the limit truncates as Gymnasium's TimeLimit
            # does around the single environment (also where the episode terminated at that step,
            # and without the metrics, which that environment does not know it should give)
            rewards[b], terminated[b], truncated[b], info = swarm_outcome(episodes[b], reward, term, trunc)
            truncated[b] |= at_limit
            if info:
                ended.append((b, info))
        worlds.ended = terminated | truncated
        return Stepped(_observations(episodes), rewards, terminated, truncated, ended, {})


class AgentWorlds(_Stepper):
    """:class:`~swarmscene.env.SwarmMultiAgentVectorEnv`'s worlds: its reset and step, the infos not yet in vector
    form (a stepper of :mod:`swarmscene.rl.workers`)."""

    def __init__(self, num_envs: int, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
                 max_episode_steps: int | None) -> None:
        super().__init__(num_envs, config, options, max_episode_steps)
        self.agent_mask = np.zeros((num_envs, self.worlds.n), dtype=bool)  # the agents that act next

    def reset(self, seeds: Sequence[int | None]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Every world's episode from its seed; the observations (B, N, D) and ``agents`` (B, N)."""
        episodes = self.worlds.reset(seeds)
        for b, episode in enumerate(episodes):
            self._started(b, episode)
        return _observations(episodes), {"agents": self.agent_mask.copy()}

    def step(self, actions: np.ndarray) -> Stepped:
        """One tick of every world with its actions (B, N, 3): each agent's reward and ends (B, N),
        and the masks ``agents`` and ``acted``."""
        worlds = self.worlds
        episodes = worlds.episodes()
        b_worlds, n = self.agent_mask.shape
        going = ~worlds.ended  # a world restarted now shows its new episode's first observation
        for b in worlds.restart_ended(episodes):
            self._started(b, episodes[b])
        acted = self.agent_mask & going[:, None]
        rewards = np.zeros((b_worlds, n))
        terminated = np.zeros((b_worlds, n), dtype=bool)
        truncated = np.zeros((b_worlds, n), dtype=bool)
        ended = []
        flown = np.where(acted[..., None], actions, 0.0)  # the parallel env's action rows: 0 where none
        judged = {b: (reward, term, trunc or (at_limit and not term))  # the limit: a truncation of a going episode
                  for b, (reward, term, trunc, at_limit) in worlds.tick(
                      episodes, np.flatnonzero(going).tolist(), flown, acted).items()}
        observations = _observations(episodes)  # before run_end, as the parallel env observes
        if judged:  # the ticked worlds' rows at once (elementwise: each world's own bits)
            ticked = np.fromiter(judged, dtype=int, count=len(judged))
            ends = np.array([(term_b, trunc_b) for _, term_b, trunc_b in judged.values()], dtype=bool)
            term, trunc = ends[:, :1], ends[:, 1:]  # (G, 1): a world's ends, for each of its agents
            mask = acted[ticked]
            failed = mask & ~np.stack([episodes[b].sim.world.healthy for b in ticked])
            rewards[ticked] = np.where(mask, np.stack([reward for reward, _, _ in judged.values()]), 0.0)
            terminated[ticked] = mask & (term | failed)
            truncated[ticked] = mask & trunc
            self.agent_mask[ticked] = mask & ~failed & ~(term | trunc)
            worlds.ended[ticked] = ~self.agent_mask[ticked].any(axis=1)
        for b, (_, term_b, trunc_b) in judged.items():
            if term_b or trunc_b:
                metrics = episodes[b].finish()
                ended.append((b, {"metrics": metrics, "success": bool(metrics["success"])}))
        return Stepped(observations, rewards, terminated, truncated, ended,
                       {"agents": self.agent_mask.copy(), "acted": acted})

    def _started(self, b: int, episode: Episode) -> None:
        """World b's new episode: its healthy agents act first; with none, it ends at once (and is
        started again at its next step)."""
        self.agent_mask[b] = episode.sim.world.healthy
        self.worlds.ended[b] = not self.agent_mask[b].any()


def worlds_in(stepper: type[CentralWorlds] | type[AgentWorlds], num_envs: int,
              config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
              max_episode_steps: int | None, workers: int, context: str | None
              ) -> tuple[CentralWorlds | AgentWorlds | Shards, int, int]:
    """A vector environment's worlds, in this process or shared out to ``workers`` processes; the
    agents of a world and the length of an agent's observation. With workers, the scenario is
    first composed and validated here, so that its errors are the same in both."""
    _check_counts(num_envs, max_episode_steps, workers)
    if workers == 1:
        worlds = stepper(num_envs, config, options, max_episode_steps)
        return worlds, worlds.worlds.n, worlds.worlds.layout_size
    if context is not None and context not in multiprocessing.get_all_start_methods():
        raise ValueError(f"context: must be one of {multiprocessing.get_all_start_methods()} or None (got {context!r})")
    driver = Driver(config, options)
    return (Shards(stepper, num_envs, workers, context, (config, options, max_episode_steps)),
            driver.n, driver.layout_size)


def in_this_process(worlds: Any) -> Any:
    """The stepper of worlds stepped in this process; an error where workers step them."""
    if isinstance(worlds, Shards):
        raise RuntimeError(f"the worlds are stepped by {len(worlds.shares)} worker processes (workers="
                           f"{len(worlds.shares)}): make the environment with workers=1 to read them here")
    return worlds
