"""Reinforcement-learning environments over any composed scenario (the ``rl`` extra).

    from swarmscene.env import make_env, make_gym_env
    env = make_env(["scenario=default", "swarm.n=10"])        # PettingZoo ParallelEnv
    obs, infos = env.reset(seed=0)
    obs, rewards, terminations, truncations, infos = env.step(
        {agent: env.action_space(agent).sample() for agent in env.agents})
    central = make_gym_env(["scenario=default"])             # one Gymnasium agent for the swarm
    gym.make("swarmscene.env:swarmscene/cem_six_vehicle-v0", render_mode="rgb_array")  # every preset has an id
    make_gym_env(["scenario=swap"], render_mode="human")     # a window, where a display exists
    envs = SwarmMultiAgentVectorEnv(64, ["scenario=swap"])   # 64 worlds in one batch: arrays (B, N, ...)
    envs = SwarmMultiAgentVectorEnv(256, ["scenario=swap"], workers=2)   # two processes, 128 worlds each

The scenario is composed and validated as for ``swarmscene`` (overrides, presets, plugins by
name) with its avoidance replaced by the ``policy`` plugin, which takes the agents' actions from
this environment: the scenario's formation is the task (its setpoint is the reference each agent
observes), the policy's actions go through the scenario's dynamics, and the engine's monitors
judge safety as in any run. The environment drives the one :class:`Simulation` tick by tick
(``Simulation.step``), calling the lifecycle hooks ``run_start`` at reset and ``run_end`` when the
episode ends, whose metrics (``min_separation``, ``collisions``...) it puts in the last infos.

Observation of an agent: ``methods/policy/observation.py`` (own state, k nearest neighbours within
range with a mask, nearest obstacle clearance and direction, the formation's reference).
Action: ``Box(-1, 1, (3,))``, a velocity or acceleration command (``avoidance.action``,
``avoidance.max_speed``/``max_accel``). Reward: :class:`RewardOptions`. An episode ends
(terminations) at the first pair closer than ``safety.separation_limit`` when
``termination.on_collision`` is set, or when the formation reports its mission complete with
``termination.on_complete``; it is truncated at ``clock.duration``. A failed agent (an ``hover``
event) is terminated alone and leaves ``agents``; it keeps hovering in the world, where the others
still sense it. ``reset(seed=s)`` runs the scenario with ``seed = s``; ``reset()`` draws the next
seed from a generator seeded by the last seed given (or the scenario's own).
"""

from __future__ import annotations

import copy
import multiprocessing
import os
import sys
import time
from collections.abc import Sequence
from typing import Any, NamedTuple, cast

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from . import api
from .core.batch import lockstep
from .core.config import Scenario
from .core.setpoint import Mode, is_mode
from .core.state import WorldBatch
from .rl.workers import Shards, Stepped

try:
    import gymnasium
    from pettingzoo import ParallelEnv
except ImportError as exc:  # pragma: no cover - the rl extra is part of the test extra
    raise ImportError(
        "swarmscene.env needs the 'rl' extra: pip install 'swarmscene[rl]'"
    ) from exc

POLICY = "policy"
"""The avoidance plugin that takes its actions from this environment."""


class RewardOptions(BaseModel):
    """Each agent's reward for one guidance tick, from the engine's own safety definitions.

        r_i = progress * (|p_ref - p_i(t)| - |p_ref - p_i(t + T_s)|)
              - separation * [nearest other agent closer than safety.separation_limit]
              - clearance  * [nearest obstacle closer than safety.clearance_limit]
              - effort * |a_i|^2
              + complete * [the formation reports its mission complete]

    p_ref is the formation's reference position of the tick (agents without one, e.g. in a
    velocity-mode formation, get no progress term). The two indicator terms are the per-agent
    form of the safety monitor's ``collisions`` and ``clearance_violations``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    progress: float = Field(1.0, description="per metre gained toward the formation's reference position")
    separation: float = Field(
        10.0, ge=0, description="penalty per tick closer than safety.separation_limit to another agent")
    clearance: float = Field(
        10.0, ge=0, description="penalty per tick closer than safety.clearance_limit to an obstacle")
    effort: float = Field(0.0, ge=0, description="penalty per unit squared norm of the normalised action")
    complete: float = Field(0.0, description="bonus to every agent when the mission completes")


class EnvOptions(BaseModel):
    """Options of the environments (not part of the scenario: the scenario's keys stay its own)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    reward: RewardOptions = Field(default_factory=RewardOptions, description="reward terms")
    record_trajectory: bool = Field(
        False, description="keep the recorder's trajectory (memory grows with the episode)")


def scenario_for_env(config: Sequence[str] | dict[str, Any]) -> Scenario:
    """Compose and validate ``config`` with its avoidance replaced by the environment-driven
    ``policy`` plugin (its observation and action options kept when the scenario chose it)."""
    data = dict(config) if isinstance(config, dict) else api.compose(config)
    data = {k: v for k, v in data.items() if k != "hydra"}
    chosen = data.get("avoidance") or {}
    options = {k: v for k, v in chosen.items() if k != "name"} if chosen.get("name") == POLICY else {}
    data["avoidance"] = {**options, "name": POLICY, "policy": None}
    return api.load(data)


class _Episode:
    """One simulation run, stepped by an environment: observations, rewards, ends (arrays)."""

    def __init__(self, scenario: Scenario, options: EnvOptions) -> None:
        self.sim = sim = api.build(scenario)
        self.options = options
        # the policy avoidance (observe, command, reference), a plugin this module does not import
        self.policy: Any = sim.avoidance
        self.n = sim.world.n
        self.done = False
        self.stop_reason: str | None = None
        sim.hook.swarmscene_run_start(sim=sim)

    def observe(self) -> np.ndarray:
        return self.policy.observe(self.sim.sensing)

    def step(self, action: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, bool, bool]:
        """Advance one tick; the rewards (N,), whether the episode terminated, was truncated."""
        before = self.act(action, active)
        self.sim.step()
        return self.judge(action, before)

    def act(self, action: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Hand the tick's action to the policy avoidance; the positions before the tick."""
        before = self.sim.world.pos.copy()
        self.policy.command(action, active)
        return before

    def judge(self, action: np.ndarray, before: np.ndarray) -> tuple[np.ndarray, bool, bool]:
        """After the tick: the rewards (N,), whether the episode terminated, was truncated."""
        complete = self.completed()
        reward = _rewards(self.options.reward, action, before, *self.reward_terms(), np.array(complete))
        return (reward, *self.ends())

    def completed(self) -> bool:
        """Whether the formation is complete where that ends the run (then the run is asked to stop)."""
        sim = self.sim
        complete = bool(sim.config.termination.on_complete and sim.formation.complete(sim.world) is True)
        if complete:
            sim.request_stop("complete")
        return complete

    def reward_terms(self) -> _RewardTerms:
        """What the rewards read of the tick (:func:`_rewards`)."""
        sim, weights, ref = self.sim, self.options.reward, self.policy.reference
        sensing, limit = sim.sensing, sim.config.safety.clearance_limit
        near = sensing.nearest[0] < sim.config.safety.separation_limit if weights.separation else _NONE
        if not weights.clearance:
            close = _NONE
        elif sensing.nothing_within(limit):  # (no query: what clearance_within would show)
            close = np.zeros(self.n, dtype=bool)
        else:
            close = sensing.clearance_within(limit) < limit
        return _RewardTerms(sim.world.pos, sim.world.healthy, ref.mode, ref.pos, near, close)

    def ends(self) -> tuple[bool, bool]:
        """Whether the episode terminated (a stop, or no healthy agent), or was truncated (its duration)."""
        sim = self.sim
        terminated = sim.stop_reason is not None or not sim.world.healthy.any()
        return terminated, not terminated and sim.step_count >= sim.total_steps

    def finish(self) -> dict[str, Any]:
        """The run's metrics, as ``metrics.json`` would hold them (lifecycle hook ``run_end``)."""
        sim = self.sim
        metrics: dict[str, Any] = {
            "duration": float(sim.world.t),
            "steps": sim.step_count,
            "agents": self.n,
            "stop_reason": sim.stop_reason or "duration",
            "healthy_at_end": int(sim.world.healthy.sum()),
        }
        sim.hook.swarmscene_run_end(sim=sim, metrics=metrics)
        metrics.setdefault("success", sim.default_success(metrics))  # as a run's metrics.json
        self.done = True
        return metrics


class _RewardTerms(NamedTuple):
    """What the rewards read of a tick (:func:`_rewards`'s arguments after ``before``), of one
    world (N, ...) or of B worlds stacked (B, N, ...)."""

    pos: np.ndarray
    """The agents' positions after the tick."""
    healthy: np.ndarray
    mode: np.ndarray
    """The reference's setpoint modes."""
    ref_pos: np.ndarray
    """The reference's positions."""
    near: np.ndarray
    """The agents nearer another than the separation limit (empty where its weight is 0)."""
    close: np.ndarray
    """The agents nearer an obstacle than the clearance limit (empty where its weight is 0)."""


_NONE = np.zeros(0, dtype=bool)
"""A reward term its weight leaves out (0); read-only, as it is shared."""
_NONE.setflags(write=False)


def _rewards(weights: RewardOptions, action: np.ndarray, before: np.ndarray, pos: np.ndarray, healthy: np.ndarray,
             mode: np.ndarray, ref_pos: np.ndarray, near: np.ndarray, close: np.ndarray, complete: np.ndarray
             ) -> np.ndarray:
    """Each agent's reward for a tick, of one world (N,) or of B worlds stacked (B, N): the same
    elementwise arithmetic (and per-row sums of three terms), so each world's are its own bits.

    progress (the distance to a position reference gained in the tick, healthy agents with one)
    - effort (|a|^2) - separation (nearer another agent than the separation limit) - clearance
    (nearer an obstacle than the clearance limit) + complete (the formation complete; ``complete``
    () or (B,)), each times its weight."""
    has = is_mode(mode, Mode.POSITION, Mode.TRACK)
    gained = np.linalg.norm(ref_pos - before, axis=-1) - np.linalg.norm(ref_pos - pos, axis=-1)
    reward = weights.progress * np.where(has & healthy, gained, 0.0) - weights.effort * np.einsum(
        "...j,...j->...", action, action)
    if weights.separation:
        reward -= weights.separation * near
    if weights.clearance:
        reward -= weights.clearance * close
    return np.where(complete[..., None], reward + weights.complete, reward)


def _judge_batch(episodes: Sequence[_Episode], actions: np.ndarray, before: np.ndarray
                 ) -> list[tuple[np.ndarray, bool, bool]]:
    """:meth:`_Episode.judge` of B episodes of one scenario (one set of options), ``actions`` and
    ``before`` (B, N, 3): the reward arithmetic over the stacked worlds (:func:`_rewards`), each
    world's rewards the bits of its own ``judge``; what a world's plugins answer (completion) and its
    ends are asked world by world, in ``judge``'s order."""
    complete = np.array([episode.completed() for episode in episodes])
    terms = _RewardTerms._make(
        np.stack(term) for term in zip(*(episode.reward_terms() for episode in episodes), strict=True))
    rewards = _rewards(episodes[0].options.reward, actions, before, *terms, complete)
    return [(reward, *episode.ends()) for reward, episode in zip(rewards, episodes, strict=True)]


class _Driver:
    """What both environments share: the validated scenario, its seeds, the current episode."""

    def __init__(self, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None) -> None:
        self.options = options if isinstance(options, EnvOptions) else EnvOptions.model_validate(options or {})
        scenario = scenario_for_env(config)
        if not self.options.record_trajectory:
            scenario = _with(scenario, output={**scenario.data.get("output", {}), "trajectory": False})
        self.scenario = scenario
        self.seeds = np.random.default_rng(scenario.config.seed)
        params: Any = scenario.plugin_params["avoidance"]  # the policy avoidance's Params
        self.layout_size = 19 + 7 * params.neighbours
        self.n = scenario.config.swarm.n
        self.episode: _Episode | None = None

    def twin(self) -> _Driver:
        """A driver of the same validated scenario and options, as one made from the same config
        would be (its seeds from the scenario's ``seed``, no episode), without composing again
        (~80 ms a world; an episode's scenario is a new one, :func:`_with`, so theirs is shared)."""
        twin = copy.copy(self)
        twin.seeds = np.random.default_rng(self.scenario.config.seed)
        twin.episode = None
        return twin

    def reset(self, seed: int | None) -> _Episode:
        if seed is not None:
            self.seeds = np.random.default_rng(seed)
        else:
            seed = int(self.seeds.integers(2**31 - 1))
        self.episode = _Episode(_with(self.scenario, seed=int(seed)), self.options)
        return self.episode


def _with(scenario: Scenario, **changes: Any) -> Scenario:
    """``scenario`` with top-level keys changed, validated again (so the data and config agree)."""
    return api.load({**scenario.data, **changes})


def _observation_box(shape: tuple[int, ...]) -> gymnasium.spaces.Box:
    return gymnasium.spaces.Box(-np.inf, np.inf, shape=shape, dtype=np.float32)


def _action_box(shape: tuple[int, ...]) -> gymnasium.spaces.Box:
    return gymnasium.spaces.Box(-1.0, 1.0, shape=shape, dtype=np.float32)


def checked_action(value: Any, shape: tuple[int, ...], where: str) -> np.ndarray:
    """``value`` as a float array of exactly ``shape``, or a ValueError in one line naming ``where``.

    Refused: None, non-numeric dtypes (strings, objects, booleans, complex), any other shape (no
    broadcasting: a 1-element action for a 3-axis agent is a mistake, not a command) and NaN or
    infinite entries. Finite values outside [-1, 1] are the policy's to clip, as the space says.
    """
    expected = f"an array of shape {shape} of finite numbers in [-1, 1]"
    if value is None:
        raise ValueError(f"{where}: got None; expected {expected}")
    try:
        array = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nested lists
        raise ValueError(f"{where}: not an array ({exc}); expected {expected}") from None
    if array.dtype.kind not in "iuf":
        raise ValueError(f"{where}: dtype {array.dtype} is not a real number type; expected {expected}")
    if array.shape != shape:
        raise ValueError(f"{where}: shape {array.shape}; expected {expected}")
    array = array.astype(float)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{where}: holds NaN or infinite values; expected {expected}")
    return array


class SwarmParallelEnv(ParallelEnv):
    """PettingZoo parallel environment: one agent per vehicle, ``agent_0`` .. ``agent_{N-1}``.

    Args:
        config: Hydra overrides (``["scenario=cem_six_vehicle", "swarm.n=10"]``) or a composed dict.
        options: :class:`EnvOptions` (or its dict).
    """

    metadata: dict[str, Any] = {"name": "swarmscene_v0", "render_modes": ["rgb_array", "human"], "render_fps": 10,
                "is_parallelizable": True}

    def __init__(self, config: Sequence[str] | dict[str, Any] = (), options: EnvOptions | dict | None = None,
                 render_mode: str | None = None) -> None:
        self.renderer = _Renderer(render_mode, self.metadata["render_fps"])
        self.driver = _Driver(config, options)
        self.render_mode = render_mode
        self.possible_agents = [f"agent_{i}" for i in range(self.driver.n)]
        self.agents: list[str] = []
        self._index = {name: i for i, name in enumerate(self.possible_agents)}
        self._observation_space = _observation_box((self.driver.layout_size,))
        self._action_space = _action_box((3,))
        self._active = np.zeros(self.driver.n, dtype=bool)

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        """Every agent's observation space (all agents share one)."""
        return self._observation_space

    def action_space(self, agent: str) -> gymnasium.spaces.Box:
        """Every agent's action space (all agents share one)."""
        return self._action_space

    @property
    def sim(self):
        """The current episode's :class:`~swarmscene.core.simulation.Simulation` (read it, e.g. ``sim.world``)."""
        return self.driver.episode.sim

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode from ``seed``; the observations and (empty) infos of the healthy agents."""
        episode = self.driver.reset(seed)
        self._active = episode.sim.world.healthy.copy()
        self.agents = [a for a, alive in zip(self.possible_agents, self._active, strict=True) if alive]
        obs = episode.observe()
        self.renderer.after_step(self.driver)
        return {a: obs[self._index[a]] for a in self.agents}, {a: {} for a in self.agents}

    def step(self, actions: dict[str, np.ndarray]):
        """One guidance tick with each live agent's action; observations, rewards, terminations,
        truncations and infos by agent (an agent that fails is done)."""
        episode = self.driver.episode
        if episode is None or not self.agents:
            raise RuntimeError("step() called before reset() or after every agent is done")
        if not isinstance(actions, dict):
            raise ValueError(f"actions: expected a dict {{agent name: action}}, got {type(actions).__name__}")
        action = np.zeros((self.driver.n, 3))
        given = np.zeros(self.driver.n, dtype=bool)
        for name, value in actions.items():
            i = self._index.get(name)
            if i is None:
                raise ValueError(f"actions: unknown agent {name!r} (agents: agent_0 .. agent_{self.driver.n - 1})")
            action[i], given[i] = checked_action(value, (3,), f"action of {name}"), True
        acting = self.agents
        reward, terminated, truncated = episode.step(action, given & self._active)
        failed = self._active & ~episode.sim.world.healthy
        obs = episode.observe()
        ends = {a: bool(terminated or failed[self._index[a]]) for a in acting}
        truncs = {a: bool(truncated) for a in acting}
        infos: dict[str, dict] = {a: {} for a in acting}
        if terminated or truncated:
            metrics = episode.finish()
            for a in acting:
                infos[a] = {"metrics": metrics}
        self._active &= ~failed
        if terminated or truncated:
            self._active[:] = False
        self.agents = [a for a in acting if not (ends[a] or truncs[a])]
        self.renderer.after_step(self.driver)
        return (
            {a: obs[self._index[a]] for a in acting},
            {a: float(reward[self._index[a]]) for a in acting},
            ends, truncs, infos,
        )

    def render(self) -> np.ndarray | None:
        """The current top-down view (:func:`render_frame`): returned with ``render_mode="rgb_array"``,
        shown in the window with ``"human"`` (which ``reset`` and ``step`` also do)."""
        return self.renderer.render(self.driver)

    def close(self) -> None:
        """Close the window, if any, and drop the episode."""
        self.renderer.close()
        self.driver.episode = None


class SwarmGymEnv(gymnasium.Env):
    """Gymnasium environment for centralised control: one agent acting for the whole swarm.

    Observation ``Box((N, D))`` (every vehicle's row, failed ones included), action
    ``Box(-1, 1, (N, 3))``, reward the sum of the vehicles' rewards (:class:`RewardOptions`);
    terminated and truncated as the parallel environment's episode (failed vehicles hover).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}

    def __init__(self, config: Sequence[str] | dict[str, Any] = (), options: EnvOptions | dict | None = None,
                 render_mode: str | None = None) -> None:
        self.renderer = _Renderer(render_mode, self.metadata["render_fps"])
        self.driver = _Driver(config, options)
        self.render_mode = render_mode
        n = self.driver.n
        self.observation_space = _observation_box((n, self.driver.layout_size))
        self.action_space = _action_box((n, 3))

    @property
    def sim(self):
        """The current episode's :class:`~swarmscene.core.simulation.Simulation` (read it, e.g. ``sim.world``)."""
        return self.driver.episode.sim

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode from ``seed``; the swarm's observation and an empty info."""
        super().reset(seed=seed)
        episode = self.driver.reset(seed)
        self.renderer.after_step(self.driver)
        return episode.observe(), {}

    def step(self, action: np.ndarray):
        """One guidance tick with the whole swarm's action; observation, summed reward, terminated,
        truncated and info."""
        episode = self.driver.episode
        if episode is None:
            raise RuntimeError("step() called before reset()")
        action = checked_action(action, (self.driver.n, 3), "action")
        reward, terminated, truncated = episode.step(action, np.ones(self.driver.n, dtype=bool))
        outcome = _swarm_outcome(episode, reward, terminated, truncated)
        observation = episode.observe()
        self.renderer.after_step(self.driver)
        return observation, *outcome

    def render(self) -> np.ndarray | None:
        """The current top-down view (:func:`render_frame`): returned with ``render_mode="rgb_array"``,
        shown in the window with ``"human"`` (which ``reset`` and ``step`` also do)."""
        return self.renderer.render(self.driver)

    def close(self) -> None:
        """Close the window, if any."""
        self.renderer.close()


def _swarm_outcome(episode: _Episode, reward: np.ndarray, terminated: bool, truncated: bool
                   ) -> tuple[float, bool, bool, dict[str, Any]]:
    """What the centralised environment returns for a tick besides the swarm's observation (made
    after this, once the run has ended): the healthy vehicles' summed reward, the ends, and at the
    end the run's metrics and its ``success``."""
    info: dict[str, Any] = {}
    if terminated or truncated:
        metrics = episode.finish()
        info.update(metrics=metrics, success=bool(metrics["success"]))
    healthy = episode.sim.world.healthy
    return float(reward[healthy].sum()), bool(terminated), bool(truncated), info


def _observations(episodes: Sequence[_Episode]) -> np.ndarray:
    """The episodes' observations stacked (B, N, D): their policy avoidance's batched observation,
    each world's rows the bits of its own ``observe()``."""
    policies = [episode.policy for episode in episodes]
    return type(policies[0]).observe_batch(policies, [episode.sim.sensing for episode in episodes])


class _Worlds:
    """The B worlds of a vector environment: one :class:`_Driver` each, their going episodes ticked
    as one batch of worlds (:func:`swarmscene.core.batch.lockstep`: the physics in one call per
    physics step), and a world whose episode ended started again at its next step (Gymnasium's
    next-step autoreset). Both vector environments' steppers (:class:`_CentralWorlds`,
    :class:`_AgentWorlds`) are this, read two ways."""

    def __init__(self, num_envs: int, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
                 max_episode_steps: int | None) -> None:
        first = _Driver(config, options)
        self.drivers = [first, *(first.twin() for _ in range(num_envs - 1))]
        self.n, self.layout_size = self.drivers[0].n, self.drivers[0].layout_size
        self.max_episode_steps = max_episode_steps
        self.steps = np.zeros(num_envs, dtype=int)  # ticks of each world's episode
        self.ended = np.zeros(num_envs, dtype=bool)  # the world's episode ended at the last step
        self._batch: tuple[list[Any], Any] | None = None  # (the worlds, their WorldBatch)

    def reset(self, seeds: Sequence[int | None]) -> list[_Episode]:
        """Start every world's episode, world b's from ``seeds[b]`` (:func:`_world_seeds`)."""
        self.steps[:] = 0
        self.ended[:] = False
        return [driver.reset(s) for driver, s in zip(self.drivers, seeds, strict=True)]

    def episodes(self) -> list[_Episode]:
        """The worlds' current episodes (an error before :meth:`reset`)."""
        episodes = [driver.episode for driver in self.drivers]
        if any(episode is None for episode in episodes):
            raise RuntimeError("step() called before reset()")
        return cast(list[_Episode], episodes)

    def restart_ended(self, episodes: list[_Episode]) -> list[int]:
        """Start the next episode of each world whose episode ended at the last step (in place in
        ``episodes``, its seed from the world's own generator); the worlds restarted."""
        restarted = np.flatnonzero(self.ended).tolist()
        for b in restarted:
            episodes[b] = self.drivers[b].reset(None)
            self.steps[b] = 0
        return restarted

    def tick(self, episodes: list[_Episode], going: list[int], actions: np.ndarray,
             active: np.ndarray) -> dict[int, tuple[np.ndarray, bool, bool]]:
        """One guidance tick of the ``going`` worlds, their physics as one batch: world b acts
        ``actions[b]`` (N, 3) with its agents ``active[b]`` (N,); by world, the agents' rewards
        (N,), whether the episode terminated, whether it was truncated (``max_episode_steps``)."""
        if not going:  # every world restarted at this step
            return {}
        before = np.stack([episodes[b].act(actions[b], active[b]) for b in going])
        sims = [episodes[b].sim for b in going]
        lockstep(sims, self._world_batch(sims))
        judged = {}
        for b, (reward, terminated, truncated) in zip(
                going, _judge_batch([episodes[b] for b in going], actions[going], before), strict=True):
            self.steps[b] += 1
            if self.max_episode_steps is not None and self.steps[b] >= self.max_episode_steps:
                truncated = not terminated
            judged[b] = (reward, terminated, truncated)
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


def _world_seeds(seed: int | Sequence[int | None] | None, b_worlds: int) -> list[int | None]:
    """Each world's seed at a reset: world b's is ``seed + b`` (as ``SyncVectorEnv`` seeds its
    copies) or ``seed[b]``; where it is None, the world draws it from its own generator (as the
    single environment's ``reset()``: before any seed was given, each world's generator starts from
    the scenario's ``seed``, so those worlds start alike)."""
    seeds: list[int | None] = [None] * b_worlds if seed is None else (
        [int(seed) + b for b in range(b_worlds)] if isinstance(seed, int | np.integer) else list(seed))
    if len(seeds) != b_worlds:
        raise ValueError(f"seed: {len(seeds)} seeds for {b_worlds} worlds")
    return seeds


class _CentralWorlds:
    """:class:`SwarmVectorEnv`'s worlds: its reset and step, the infos not yet in vector form (a
    stepper of :mod:`swarmscene.rl.workers`, which can run it in a worker process)."""

    def __init__(self, num_envs: int, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
                 max_episode_steps: int | None) -> None:
        self.worlds = _Worlds(num_envs, config, options, max_episode_steps)
        self._every = np.ones((num_envs, self.worlds.n), dtype=bool)  # the centralised agent commands every vehicle

    def reset(self, seeds: Sequence[int | None]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        return _observations(self.worlds.reset(seeds)), {}

    def step(self, actions: np.ndarray) -> Stepped:
        worlds = self.worlds
        episodes = worlds.episodes()
        b_worlds = len(episodes)
        rewards = np.zeros(b_worlds)
        terminated = np.zeros(b_worlds, dtype=bool)
        truncated = np.zeros(b_worlds, dtype=bool)
        ended = []
        worlds.restart_ended(episodes)
        going = np.flatnonzero(~worlds.ended).tolist()
        for b, (reward, term, trunc) in worlds.tick(episodes, going, actions, self._every).items():
            rewards[b], terminated[b], truncated[b], info = _swarm_outcome(episodes[b], reward, term, trunc)
            if info:
                ended.append((b, info))
        worlds.ended = terminated | truncated
        return Stepped(_observations(episodes), rewards, terminated, truncated, ended, {})


class _AgentWorlds:
    """:class:`SwarmMultiAgentVectorEnv`'s worlds: its reset and step, the infos not yet in vector
    form (a stepper of :mod:`swarmscene.rl.workers`)."""

    def __init__(self, num_envs: int, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
                 max_episode_steps: int | None) -> None:
        self.worlds = _Worlds(num_envs, config, options, max_episode_steps)
        self.agent_mask = np.zeros((num_envs, self.worlds.n), dtype=bool)  # the agents that act next

    def reset(self, seeds: Sequence[int | None]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        episodes = self.worlds.reset(seeds)
        for b, episode in enumerate(episodes):
            self._started(b, episode)
        return _observations(episodes), {"agents": self.agent_mask.copy()}

    def step(self, actions: np.ndarray) -> Stepped:
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
        judged = worlds.tick(episodes, np.flatnonzero(going).tolist(), flown, acted)
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

    def _started(self, b: int, episode: _Episode) -> None:
        """World b's new episode: its healthy agents act first; with none, it ends at once (and is
        started again at its next step)."""
        self.agent_mask[b] = episode.sim.world.healthy
        self.worlds.ended[b] = not self.agent_mask[b].any()


def _worlds_in(stepper: type[_CentralWorlds] | type[_AgentWorlds], num_envs: int,
               config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None,
               max_episode_steps: int | None, workers: int, context: str | None
               ) -> tuple[_CentralWorlds | _AgentWorlds | Shards, int, int]:
    """A vector environment's worlds, in this process or shared out to ``workers`` processes; the
    agents of a world and the length of an agent's observation. With workers, the scenario is
    first composed and validated here, so that its errors are the same in both."""
    _check_counts(num_envs, max_episode_steps, workers)
    if workers == 1:
        worlds = stepper(num_envs, config, options, max_episode_steps)
        return worlds, worlds.worlds.n, worlds.worlds.layout_size
    if context is not None and context not in multiprocessing.get_all_start_methods():
        raise ValueError(f"context: must be one of {multiprocessing.get_all_start_methods()} or None (got {context!r})")
    driver = _Driver(config, options)
    return (Shards(stepper, num_envs, workers, context, (config, options, max_episode_steps)),
            driver.n, driver.layout_size)


def _in_this_process(worlds: Any) -> Any:
    """The stepper of worlds stepped in this process; an error where workers step them."""
    if isinstance(worlds, Shards):
        raise RuntimeError(f"the worlds are stepped by {len(worlds.shares)} worker processes (workers="
                           f"{len(worlds.shares)}): make the environment with workers=1 to read them here")
    return worlds


def _refuse_rendering(render_mode: str | None) -> None:
    if render_mode is not None:
        raise ValueError(f"render_mode: the vector environment does not render (got {render_mode!r}); "
                         "render one world with gym.make(id, render_mode=...)")


class SwarmVectorEnv(gymnasium.vector.VectorEnv):
    """B copies of :class:`SwarmGymEnv` stepped as one batch of worlds (docs/batched.md).

    What ``gym.make_vec(id, num_envs=B)`` returns for a swarmscene id (``vectorization_mode``
    ``"vector_entry_point"``, the default for them). Each world is the single environment's episode,
    step for step: ``reset(seed=s)`` seeds world b with ``s + b`` (as ``SyncVectorEnv`` does) and a
    world's later episodes draw their seeds from its own generator, as the single environment's
    ``reset()`` does; an episode that ends is reset at the world's next step (Gymnasium's
    next-step autoreset: that step returns the new episode's first observation, reward 0, and
    ignores the world's action). Infos hold, for the worlds that ended, the run's ``metrics`` and
    its ``success``, in Gymnasium's vector form (``infos["success"]`` and the mask
    ``infos["_success"]``). The worlds' physics is one batched call per physics step
    (:func:`swarmscene.core.batch.lockstep`); rendering is the single environment's.

    Args:
        num_envs: B, the number of worlds.
        config, options: as for :class:`SwarmGymEnv` (one scenario for every world).
        max_episode_steps: truncate each episode after this many steps (Gymnasium's ``TimeLimit``,
            which ``make_vec`` passes from the id's spec).
        workers: processes that step the worlds, each a contiguous share of them as one batch
            (:mod:`swarmscene.rl.workers`); the answers are those of ``workers=1``, bit for bit.
            With more than 1, the worlds' simulations (:attr:`drivers`) are not in this process.
        context: the workers' ``multiprocessing`` start method (None: the platform's default);
            ``"spawn"`` and ``"forkserver"`` need an ``if __name__ == "__main__":`` guard.
    """

    metadata = {"autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, config: Sequence[str] | dict[str, Any] = (),
                 options: EnvOptions | dict | None = None, max_episode_steps: int | None = None,
                 render_mode: str | None = None, workers: int = 1, context: str | None = None) -> None:
        _refuse_rendering(render_mode)
        self._worlds, n, size = _worlds_in(_CentralWorlds, num_envs, config, options, max_episode_steps,
                                           workers, context)
        self.num_envs = num_envs
        self._max_episode_steps = max_episode_steps
        self.single_observation_space = _observation_box((n, size))
        self.single_action_space = _action_box((n, 3))
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)

    @property
    def worlds(self) -> _Worlds:
        """The worlds (with ``workers=1``)."""
        return _in_this_process(self._worlds).worlds

    @property
    def drivers(self) -> list[_Driver]:
        """The worlds' drivers (each holds its validated scenario and current episode; with ``workers=1``)."""
        return self.worlds.drivers

    @property
    def max_episode_steps(self) -> int | None:
        """Each episode is truncated after this many steps (None: at ``clock.duration``)."""
        return self._max_episode_steps

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict | None = None):
        """Start every world's episode (world b from ``seed + b``, or ``seed[b]``); the stacked
        observations and an empty info."""
        observations, _ = self._worlds.reset(_world_seeds(seed, self.num_envs))
        return observations, {}

    def step(self, actions: np.ndarray):
        """One guidance tick of every world; observations, rewards, terminations, truncations (B,)
        and infos. A world whose episode ended at the last step starts its next one instead."""
        actions = checked_action(actions, cast(tuple[int, ...], self.action_space.shape), "actions")
        stepped = self._worlds.step(actions)
        return (stepped.observations, stepped.rewards, stepped.terminated, stepped.truncated,
                _vector_infos(self, stepped))

    def close(self, **kwargs: Any) -> None:
        """Drop the episodes (and end the workers)."""
        _close(self._worlds)


def _vector_infos(env: Any, stepped: Stepped) -> dict[str, Any]:
    """The step's infos in Gymnasium's vector form (the ended worlds' infos with their masks), and
    the per-world arrays."""
    infos: dict[str, Any] = {}
    for b, info in stepped.ended:
        infos = env._add_info(infos, info, b)
    infos.update(stepped.arrays)
    return infos


def _close(worlds: _CentralWorlds | _AgentWorlds | Shards) -> None:
    """A vector environment's ``close``: end its workers, or drop its episodes (which ``reset`` starts again)."""
    if isinstance(worlds, Shards):
        worlds.close()
    else:
        worlds.worlds.close()


class SwarmMultiAgentVectorEnv:
    """B copies of :class:`SwarmParallelEnv` stepped as one batch of worlds, as arrays over worlds
    and agents (B, N, ...) for multi-agent learners (docs/rl.md).

    World b is the parallel environment's episode, step for step: ``reset(seed=s)`` seeds it with
    ``s + b`` and its later episodes draw their seeds from its own generator; an episode that ends
    (terminated, truncated, or every agent done) is reset at the world's next step (next-step
    autoreset: the new episode's first observations, rewards 0, no ends), and so is an episode
    that starts with no healthy agent. Where the parallel environment gives dicts over its live
    agents, this gives arrays over all N, with masks:

    - ``infos["agents"]`` (B, N) bool: the agents that act at the next step (the parallel
      environment's ``agents``; also :attr:`agent_mask`); the others' actions are ignored (the
      policy holds them, as the parallel environment holds an agent it is given no action for);
    - ``infos["acted"]`` (B, N) bool: the agents that acted at this step; their entries of the
      rewards (B, N), terminations (B, N) and truncations (B, N) are the parallel environment's
      values, the others are 0 and False;
    - observations (B, N, D): every agent's row, as the parallel environment observes it.

    For the worlds whose episode ended, ``infos["metrics"]`` and ``infos["success"]`` hold the run's
    metrics and success in Gymnasium's vector form (with the masks ``infos["_metrics"]``,
    ``infos["_success"]``). Not a ``gymnasium.vector.VectorEnv``: its rewards and ends are per agent,
    which Gymnasium's vector wrappers do not expect.

    Args:
        num_envs: B, the number of worlds.
        config, options: as for :class:`SwarmParallelEnv` (one scenario for every world).
        max_episode_steps: truncate each episode after this many steps (None: at ``clock.duration``).
        workers, context: as for :class:`SwarmVectorEnv` (with more than 1 worker, :attr:`sims` are
            not in this process).
    """

    metadata: dict[str, Any] = {"name": "swarmscene_vector_v0",
                                "autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP}
    # Gymnasium's own function, so that the infos have its vector form, as SwarmVectorEnv's do; it
    # reads nothing of its object but num_envs (and itself, for nested dicts)
    _add_info = gymnasium.vector.VectorEnv._add_info

    def __init__(self, num_envs: int = 1, config: Sequence[str] | dict[str, Any] = (),
                 options: EnvOptions | dict | None = None, max_episode_steps: int | None = None,
                 render_mode: str | None = None, workers: int = 1, context: str | None = None) -> None:
        _refuse_rendering(render_mode)
        self._worlds, n, size = _worlds_in(_AgentWorlds, num_envs, config, options, max_episode_steps,
                                           workers, context)
        self.num_envs, self.num_agents = num_envs, n
        self.possible_agents = [f"agent_{i}" for i in range(self.num_agents)]  # the parallel env's names
        self.single_agent_observation_space = _observation_box((size,))
        self.single_agent_action_space = _action_box((3,))
        self.observation_space = _observation_box((num_envs, self.num_agents, size))
        self.action_space = _action_box((num_envs, self.num_agents, 3))
        self.agent_mask = np.zeros((num_envs, self.num_agents), dtype=bool)
        """(B, N): the agents that act at the next step."""

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict | None = None):
        """Start every world's episode (world b from ``seed + b``, or ``seed[b]``); the observations
        (B, N, D) and ``{"agents": mask}`` (the healthy agents, which act first)."""
        observations, arrays = self._worlds.reset(_world_seeds(seed, self.num_envs))
        self.agent_mask[...] = arrays["agents"]
        return observations, arrays

    def step(self, actions: np.ndarray):
        """One guidance tick of every world with actions (B, N, 3); observations (B, N, D), rewards,
        terminations and truncations (B, N), and infos (the masks ``agents`` and ``acted``, and the
        ended worlds' ``metrics`` and ``success``). A world whose episode ended at the last step
        starts its next one instead."""
        actions = checked_action(actions, self.action_space.shape, "actions")
        stepped = self._worlds.step(actions)
        self.agent_mask[...] = stepped.arrays["agents"]
        return (stepped.observations, stepped.rewards, stepped.terminated, stepped.truncated,
                _vector_infos(self, stepped))

    @property
    def worlds(self) -> _Worlds:
        """The worlds (with ``workers=1``)."""
        return _in_this_process(self._worlds).worlds

    @property
    def sims(self) -> list[Any]:
        """The worlds' current :class:`~swarmscene.core.simulation.Simulation` objects (read them,
        e.g. ``sims[b].world``; ``sims[b].avoidance`` is the ``policy`` plugin with the observation
        ``layout`` and action ``spec`` a scripted policy is built with; with ``workers=1``)."""
        return [episode.sim for episode in self.worlds.episodes()]

    def close(self) -> None:
        """Drop the episodes (and end the workers)."""
        _close(self._worlds)


RENDER_MODES = ("rgb_array", "human")
"""``render_mode`` values both environments take (None: no rendering): ``rgb_array`` returns the
frames; ``human`` shows them in a matplotlib window, where a display exists."""
FRAME_PIXELS = (480, 480)
"""Width and height of a rendered frame."""


class _Renderer:
    """An environment's ``render_mode``: checked when the environment is made, then each frame
    returned (``rgb_array``) or shown in a :class:`_Window` after every reset and step (``human``,
    Gymnasium's convention for that mode)."""

    def __init__(self, render_mode: str | None, fps: float) -> None:
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode: must be one of {', '.join(RENDER_MODES)} or None (got {render_mode!r})")
        if render_mode == "human":
            why_not = _no_window_because()
            if why_not:
                raise ValueError(f"render_mode: 'human' needs a window, and {why_not}; "
                                 "render_mode='rgb_array' returns the frames instead")
        self.mode = render_mode
        self.window = _Window(fps) if render_mode == "human" else None

    def render(self, driver: _Driver) -> np.ndarray | None:
        frame = render_frame(driver, self.mode)
        if self.window is None or frame is None:
            return frame
        self.window.show(frame)
        return None

    def after_step(self, driver: _Driver) -> None:
        if self.window is not None:
            self.render(driver)

    def close(self) -> None:
        if self.window is not None:
            self.window.close()


def _no_window_because() -> str | None:
    """Why no window can open here (None when one can): no display on Linux, no matplotlib, or a
    non-interactive matplotlib backend (Agg, chosen by MPLBACKEND or by matplotlib itself when no
    GUI toolkit is installed)."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "there is no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        return "matplotlib is not installed (the plots extra)"
    backend = plt.get_backend()  # resolves matplotlib's automatic choice
    if backend.lower() in _non_interactive_backends():
        return f"matplotlib's backend {backend!r} is not interactive"
    return None


def _non_interactive_backends() -> set[str]:
    try:  # matplotlib >= 3.9
        from matplotlib.backends import BackendFilter, backend_registry
        return set(backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE))
    except ImportError:  # pragma: no cover - matplotlib 3.8
        from matplotlib import rcsetup
        return {b.lower() for b in rcsetup.non_interactive_bk}  # type: ignore[attr-defined]  # 3.8 only


class _Window:
    """``render_mode="human"``: one pyplot figure showing the frames, updated in place and paced at
    ``fps`` (one frame per guidance tick at the default 10: real time). Closing the window does not
    stop the episode; the next frame opens a new one."""

    def __init__(self, fps: float) -> None:
        self.period = 1.0 / fps
        self.figure: Any = None  # pyplot's Figure and its image once shown (None: no window yet)
        self.image: Any = None
        self.shown_at: float | None = None

    def show(self, frame: np.ndarray) -> None:
        import matplotlib.pyplot as plt

        if self.figure is None or not plt.fignum_exists(self.figure.number):
            width, height = FRAME_PIXELS
            self.figure = plt.figure(figsize=(width / 100, height / 100), dpi=100)
            ax = self.figure.add_axes((0, 0, 1, 1))
            ax.set_axis_off()
            self.image = ax.imshow(frame)
            plt.show(block=False)
        else:
            self.image.set_data(frame)
        self.figure.canvas.draw_idle()
        # run the GUI's event loop for what is left of the frame period (the window stays live)
        elapsed = 0.0 if self.shown_at is None else time.monotonic() - self.shown_at
        self.figure.canvas.start_event_loop(max(self.period - elapsed, 1e-3))
        self.shown_at = time.monotonic()

    def close(self) -> None:
        if self.figure is not None:
            import matplotlib.pyplot as plt

            plt.close(self.figure)
            self.figure = self.image = None


def render_frame(driver: _Driver, render_mode: str | None) -> np.ndarray | None:
    """The current top-down view as an (H, W, 3) uint8 array: the obstacles and every agent (failed
    ones as red crosses), titled with the time; None when ``render_mode`` is None or before
    ``reset``. Drawn with matplotlib (the plots extra), off screen (``human`` shows this frame)."""
    if render_mode is None or driver.episode is None:
        return None
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .views.plots import FAILED_COLOR, _draw_obstacles

    sim = driver.episode.sim
    width, height = FRAME_PIXELS
    fig = Figure(figsize=(width / 100, height / 100), dpi=100, layout="constrained")
    canvas = FigureCanvasAgg(fig)  # off screen, whatever matplotlib's default backend
    ax = fig.add_subplot()
    _draw_obstacles(ax, sim.environment.obstacles)
    pos, healthy = sim.world.pos, sim.world.healthy
    ax.scatter(pos[healthy, 0], pos[healthy, 1], s=14, color="tab:blue")
    ax.scatter(pos[~healthy, 0], pos[~healthy, 1], s=40, marker="x", color=FAILED_COLOR)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"t = {sim.world.t:.1f} s", fontsize=9)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def register_gym_ids() -> list[str]:
    """Register ``swarmscene/<preset>-v0`` for every shipped preset with Gymnasium (idempotent);
    return the ids. Importing this module does it, so ``gym.make("swarmscene.env:swarmscene/swap-v0")``
    works without an import, and ``make_vec`` and RL-zoo configs can name the environments."""
    from .composition.groups import group_options

    ids = []
    for preset in group_options("scenario"):
        ids.append(register_scenario(f"swarmscene/{preset}-v0", [f"scenario={preset}"]))
    return ids


def register_scenario(env_id: str, config: Sequence[str] | dict[str, Any],
                      options: EnvOptions | dict | None = None, **spec: Any) -> str:
    """Register any scenario (overrides or a composed dict) as a Gymnasium id for
    :class:`SwarmGymEnv`; ``spec`` goes to ``gymnasium.register`` (e.g. ``max_episode_steps``).
    Registering the same id again replaces it."""
    kwargs: dict[str, Any] = {"config": list(config) if not isinstance(config, dict) else config}
    if options is not None:
        kwargs["options"] = options
    gymnasium.register(id=env_id, entry_point="swarmscene.env:SwarmGymEnv",
                       vector_entry_point="swarmscene.env:SwarmVectorEnv", kwargs=kwargs, **spec)
    return env_id


def make_env(config: Sequence[str] | dict[str, Any] = (), options: EnvOptions | dict | None = None,
             render_mode: str | None = None) -> SwarmParallelEnv:
    """A PettingZoo ``ParallelEnv`` over the scenario composed from ``config`` (overrides or dict)."""
    return SwarmParallelEnv(config, options, render_mode)


def make_gym_env(config: Sequence[str] | dict[str, Any] = (), options: EnvOptions | dict | None = None,
                 render_mode: str | None = None) -> SwarmGymEnv:
    """A Gymnasium ``Env`` for centralised control of the scenario composed from ``config``."""
    return SwarmGymEnv(config, options, render_mode)


GYM_IDS = register_gym_ids()
"""The Gymnasium ids of the shipped presets, registered at import."""
