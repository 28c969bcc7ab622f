"""One simulation run stepped by an RL environment (``swarmscene.env``): the environments'
options, the episode (observations, rewards, ends), the rewards' arithmetic over one world or B
stacked worlds, and the driver that holds the validated scenario and its seeds."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from ..composition.compose import compose
from ..core.config import Scenario
from ..core.errors import ConfigError, format_validation_error
from ..core.setpoint import Mode, is_mode
from ..runs import build as assembly

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
    complete: float = Field(0.0, description="bonus to every agent at the first tick the formation reports its "
                                               "mission complete (once, whether or not that ends the run)")


class EnvOptions(BaseModel):
    """Options of the environments (not part of the scenario: the scenario's keys stay its own)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    reward: RewardOptions = Field(default_factory=RewardOptions, description="reward terms")
    record_trajectory: bool = Field(
        False, description="keep the recorder's trajectory (memory grows with the episode)")


def scenario_for_env(config: Sequence[str] | dict[str, Any]) -> Scenario:
    """Compose and validate ``config`` with its avoidance replaced by the environment-driven
    ``policy`` plugin (its observation and action options kept when the scenario chose it). An
    ``avoidance.<key>`` override given with another avoidance is a ConfigError: it would be
    dropped with that avoidance (the command line and ``api`` refuse it as an unknown key)."""
    if isinstance(config, str):
        raise ConfigError([f"config: a list of overrides or a composed mapping, not the string {config!r} "
                           f"(write [{config!r}])"])
    data = dict(config) if isinstance(config, dict) else compose(config)
    data = {k: v for k, v in data.items() if k != "hydra"}
    chosen = data.get("avoidance") or {}
    if chosen.get("name") != POLICY and not isinstance(config, dict):
        given = [o.split("=", 1)[0].lstrip("+~") for o in config if o.lstrip("+~").startswith("avoidance.")]
        if given:
            raise ConfigError([f"{given[0]}: the environment flies avoidance=policy in place of "
                               f"{chosen.get('name')!r}, whose options would be dropped: give avoidance=policy "
                               "with the policy's options"])
    options = {k: v for k, v in chosen.items() if k != "name"} if chosen.get("name") == POLICY else {}
    data["avoidance"] = {**options, "name": POLICY, "policy": None}
    return assembly.load(data, None)


class Episode:
    """One simulation run, stepped by an environment: observations, rewards, ends (arrays)."""

    def __init__(self, scenario: Scenario, options: EnvOptions) -> None:
        self.sim = sim = assembly.build(scenario, None)
        self.options = options
        # the policy avoidance (observe, command, reference), a plugin this module does not import
        self.policy: Any = sim.avoidance
        self.n = sim.world.n
        self.done = False
        self.stop_reason: str | None = None
        self.completed_at: int | None = None  # the tick the formation first reported its mission complete
        sim.hook.swarmscene_run_start(sim=sim)

    def observe(self) -> np.ndarray:
        """Every agent's observation (N, D), as the policy avoidance observes it."""
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
        """Whether the formation completed its mission at this tick: the first tick it reports so
        (the ``complete`` bonus is paid once, whether or not that ends the run); where
        ``termination.on_complete`` ends the run, the run is asked to stop. The formation is asked
        only where one of the two needs it."""
        sim = self.sim
        on_complete = sim.config.termination.on_complete
        if self.completed_at is not None or not (on_complete or self.options.reward.complete):
            return False
        if sim.formation.complete(sim.world) is not True:
            return False
        self.completed_at = sim.step_count
        if on_complete:
            sim.request_stop("complete")
        return True

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


def judge_batch(episodes: Sequence[Episode], actions: np.ndarray, before: np.ndarray
                 ) -> list[tuple[np.ndarray, bool, bool]]:
    """:meth:`Episode.judge` of B episodes of one scenario (one set of options), ``actions`` and
    ``before`` (B, N, 3): the reward arithmetic over the stacked worlds (:func:`_rewards`), each
    world's rewards the bits of its own ``judge``; what a world's plugins answer (completion) and its
    ends are asked world by world, in ``judge``'s order."""
    complete = np.array([episode.completed() for episode in episodes])
    terms = _RewardTerms._make(
        np.stack(term) for term in zip(*(episode.reward_terms() for episode in episodes), strict=True))
    rewards = _rewards(episodes[0].options.reward, actions, before, *terms, complete)
    return [(reward, *episode.ends()) for reward, episode in zip(rewards, episodes, strict=True)]


class Driver:
    """What both environments share: the validated scenario, its seeds, the current episode."""

    def __init__(self, config: Sequence[str] | dict[str, Any], options: EnvOptions | dict | None) -> None:
        self.options = options if isinstance(options, EnvOptions) else _env_options(options)
        scenario = scenario_for_env(config)
        if not self.options.record_trajectory:
            scenario = _with(scenario, output={**scenario.data.get("output", {}), "trajectory": False})
        self.scenario = scenario
        self.seeds = np.random.default_rng(scenario.config.seed)
        params: Any = scenario.plugin_params["avoidance"]  # the policy avoidance's Params
        self.layout_size = 19 + 7 * params.neighbours
        self.n = scenario.config.swarm.n
        self.episode: Episode | None = None

    def twin(self) -> Driver:
        """A driver of the same validated scenario and options, as one made from the same config
        would be (its seeds from the scenario's ``seed``, no episode), without composing again
        (~80 ms a world; an episode's scenario is a new one, :func:`_with`, so theirs is shared)."""
        twin = copy.copy(self)
        twin.seeds = np.random.default_rng(self.scenario.config.seed)
        twin.episode = None
        return twin

    def reset(self, seed: int | None) -> Episode:
        """A new episode from ``seed`` (its generator then starts from it), or, for None, from the
        next seed this driver's generator draws."""
        if seed is not None:
            self.seeds = np.random.default_rng(seed)
        else:
            seed = int(self.seeds.integers(2**31 - 1))
        self.episode = Episode(_with(self.scenario, seed=int(seed)), self.options)
        return self.episode


def _env_options(options: dict | None) -> EnvOptions:
    """``options`` validated, each problem one line (``reward.efort: unknown key ...``)."""
    from pydantic import ValidationError

    try:
        return EnvOptions.model_validate(options or {})
    except ValidationError as exc:
        raise ConfigError(format_validation_error(exc, EnvOptions, options or {})) from None


def _with(scenario: Scenario, **changes: Any) -> Scenario:
    """``scenario`` with top-level keys changed, validated again (so the data and config agree)."""
    return assembly.load({**scenario.data, **changes}, None)


def swarm_outcome(episode: Episode, reward: np.ndarray, terminated: bool, truncated: bool
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
