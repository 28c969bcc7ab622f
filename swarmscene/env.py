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

import os
import sys
import time
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from .rl.episode import (  # noqa: F401 - POLICY, RewardOptions, scenario_for_env: public names of this module
    POLICY,
    Driver,
    EnvOptions,
    RewardOptions,
    scenario_for_env,
    swarm_outcome,
)
from .rl.workers import Stepped
from .rl.worlds import AgentWorlds, CentralWorlds, Worlds, in_this_process, world_seeds, worlds_in

try:
    import gymnasium
    from pettingzoo import ParallelEnv
except ImportError as exc:  # pragma: no cover - the rl extra is part of the test extra
    raise ImportError(
        "swarmscene.env needs the 'rl' extra: pip install 'swarmscene[rl]'"
    ) from exc



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
        self.driver = Driver(config, options)
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
        self.driver = Driver(config, options)
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
        outcome = swarm_outcome(episode, reward, terminated, truncated)
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
        max_episode_steps: truncate each episode after this many steps as Gymnasium's ``TimeLimit``
            does (which ``make_vec`` passes from the id's spec): ``truncated`` also where the
            episode terminated at that step, and no ``metrics`` for an episode it cuts short.
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
        self._worlds, n, size = worlds_in(CentralWorlds, num_envs, config, options, max_episode_steps,
                                          workers, context)
        self.num_envs = num_envs
        self._max_episode_steps = max_episode_steps
        self.single_observation_space = _observation_box((n, size))
        self.single_action_space = _action_box((n, 3))
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)

    @property
    def worlds(self) -> Worlds:
        """The worlds (with ``workers=1``)."""
        return in_this_process(self._worlds).worlds

    @property
    def drivers(self) -> list[Driver]:
        """The worlds' drivers (each holds its validated scenario and current episode; with ``workers=1``)."""
        return self.worlds.drivers

    @property
    def max_episode_steps(self) -> int | None:
        """Each episode is truncated after this many steps (None: at ``clock.duration``)."""
        return self._max_episode_steps

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict | None = None):
        """Start every world's episode (world b from ``seed + b``, or ``seed[b]``); the stacked
        observations and an empty info."""
        observations, _ = self._worlds.reset(world_seeds(seed, self.num_envs))
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
        self._worlds.close()


def _vector_infos(env: Any, stepped: Stepped) -> dict[str, Any]:
    """The step's infos in Gymnasium's vector form (the ended worlds' infos with their masks), and
    the per-world arrays."""
    infos: dict[str, Any] = {}
    for b, info in stepped.ended:
        infos = env._add_info(infos, info, b)
    infos.update(stepped.arrays)
    return infos


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
        self._worlds, n, size = worlds_in(AgentWorlds, num_envs, config, options, max_episode_steps,
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
        observations, arrays = self._worlds.reset(world_seeds(seed, self.num_envs))
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
    def worlds(self) -> Worlds:
        """The worlds (with ``workers=1``)."""
        return in_this_process(self._worlds).worlds

    @property
    def sims(self) -> list[Any]:
        """The worlds' current :class:`~swarmscene.core.simulation.Simulation` objects (read them,
        e.g. ``sims[b].world``; ``sims[b].avoidance`` is the ``policy`` plugin with the observation
        ``layout`` and action ``spec`` a scripted policy is built with; with ``workers=1``)."""
        return [episode.sim for episode in self.worlds.episodes()]

    def close(self) -> None:
        """Drop the episodes (and end the workers)."""
        self._worlds.close()


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

    def render(self, driver: Driver) -> np.ndarray | None:
        frame = render_frame(driver, self.mode)
        if self.window is None or frame is None:
            return frame
        self.window.show(frame)
        return None

    def after_step(self, driver: Driver) -> None:
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


def render_frame(driver: Driver, render_mode: str | None) -> np.ndarray | None:
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
