"""The scenario schema (pydantic v2) and the one validation pass after Hydra composition.

Hydra composes plain YAML; ``OmegaConf.to_container(resolve=True)`` turns it into plain data;
:func:`validate` checks it in one pass: the engine's own keys against :class:`ScenarioConfig`, each
chosen plugin's keys against that plugin's ``Params``, then scenario-level checks (physics step
divides the guidance period, events name existing agents, agents start clear of obstacles and of
each other). Every problem becomes one line ``dotted.key: what is allowed (got value)``, collected in
a :class:`ConfigError`.
"""

from __future__ import annotations

import math
import warnings
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from .errors import ConfigError, format_validation_error
from .plugin import PLUGIN_KINDS, PluginParams


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


MAX_AGENTS = 1_000_000
"""Most agents in one scenario (state alone is ~100 bytes per agent; see docs/benchmarks.md)."""
MAX_SUBSTEPS = 10_000
"""Most physics steps per guidance tick (a smaller physics step is almost surely a typo)."""

Point2 = tuple[float, float]
Point3 = tuple[float, float, float]


class PolygonObstacle(_Strict):
    """A polygonal footprint; ``points`` in order, at least 3, not self-intersecting."""

    type: Literal["polygon"]
    points: list[Point2] = Field(min_length=3, description="vertices [x, y], m")


class CircleObstacle(_Strict):
    """A disc footprint (pillar, no-fly cylinder)."""

    type: Literal["circle"]
    center: Point2 = Field(description="[x, y], m")
    radius: float = Field(gt=0, description="m")


class WallObstacle(_Strict):
    """A thick wall: the polyline ``points`` buffered by ``thickness / 2`` with flat caps."""

    type: Literal["wall"]
    points: list[Point2] = Field(min_length=2, description="polyline [x, y], m")
    thickness: float = Field(gt=0, description="m")


Obstacle = Annotated[PolygonObstacle | CircleObstacle | WallObstacle, Field(discriminator="type")]


class EnvironmentConfig(_Strict):
    """The obstacle map (footprints in the x-y plane, extruded over all altitudes)."""

    name: str = Field("open", description="label of the map")
    obstacles: list[Obstacle] = Field(default_factory=list, description="obstacle footprints")


class StartConfig(_Strict):
    """Initial positions of the swarm.

    kinds: ``line`` (along +y through ``center``, ``spacing`` apart), ``grid`` (square-ish grid,
    ``spacing`` apart, centred on ``center``), ``circle`` (agent k at angle ``2 pi k / n`` on a ring
    of ``radius``, or of ``spacing * n / (2 pi)`` when ``radius`` is null),
    ``explicit`` (``positions``, one [x, y, z] per agent), ``random`` (uniform in a square of side
    ``extent`` around ``center``, redrawn until agents are ``spacing`` apart; seeded; with
    ``connected`` the whole swarm is redrawn until its communication graph at ``comm.range`` is
    connected, the "random eligible initial state" of the thesis' section 5.4).
    """

    kind: Literal["line", "grid", "circle", "explicit", "random"] = Field(
        "grid", description="layout: line | grid | circle | explicit | random (see above)"
    )
    spacing: float = Field(2.0, gt=0, description="distance between neighbours, m")
    center: Point3 = Field((0.0, 0.0, 1.0), description="[x, y, z] of the swarm's centre, m")
    extent: float = Field(10.0, gt=0, description="side of the square for kind=random, m")
    radius: float | None = Field(
        None, gt=0, description="for kind=circle: ring radius, m (null: spacing * n / (2 pi))"
    )
    positions: list[Point3] = Field(default_factory=list, description="for kind=explicit, m")
    connected: bool = Field(
        False, description="for kind=random: redraw until the comm graph (comm.range) is connected"
    )


class SwarmConfig(_Strict):
    """The agents."""

    n: int = Field(ge=1, le=MAX_AGENTS, description="number of agents N")
    leader: int | None = Field(0, ge=0, description="index of the leader, or null for none")
    start: StartConfig = Field(default_factory=StartConfig, description="initial positions")


class ClockConfig(_Strict):
    """Time: guidance (formation, avoidance, controllers) and physics run at their own periods."""

    guidance_period: float = Field(0.1, gt=0, description="T_s, s")
    physics_step: float | None = Field(
        None, gt=0, description="s; must divide guidance_period (null: equal to it)"
    )
    duration: float = Field(30.0, gt=0, description="simulated duration, s")


class SafetyConfig(_Strict):
    """The limits every run is measured against."""

    min_separation: float = Field(0.5, ge=0, description="safety distance between agents, m")
    min_clearance: float = Field(0.2, ge=0, description="safety distance to obstacles, m")
    start_overlap: Literal["error", "warn"] = Field(
        "error",
        description="agents starting closer than min_separation: an error, or a warning where a "
        "scenario starts that way on purpose (thesis 4.5.2)",
    )


class CommConfig(_Strict):
    """Communication graph: agents within ``range`` of each other are linked."""

    range: float = Field(20.0, gt=0, description="m")


class TerminationConfig(_Strict):
    """Optional early ends of a run."""

    on_complete: bool = Field(True, description="stop when the formation reports its mission done")
    on_collision: bool = Field(False, description="stop at the first pair closer than min_separation")


class OutputConfig(_Strict):
    """What a run writes into its directory."""

    trajectory: bool = Field(True, description="write trajectory.npz")
    trajectory_every: int = Field(1, ge=1, description="record every k-th guidance tick")
    float32: bool = Field(False, description="store trajectory arrays as float32")
    trajectory_stream: Literal["auto", "on", "off"] = Field(
        "auto",
        description="stream frames to disk in chunks (auto: when the whole record exceeds "
        "trajectory_buffer_mb)",
    )
    trajectory_buffer_mb: float = Field(
        256.0, gt=0, description="MiB of frames held in memory; a streamed run flushes each full chunk"
    )
    trajectory_spill_dir: str | None = Field(
        None, description="directory for streamed chunks until the run dir is written (null: system temp)"
    )
    summary: bool = Field(True, description="print the run summary")
    progress: Literal["auto", "on", "off"] = Field(
        "auto", description="progress line on long runs (auto: only on a terminal)"
    )
    plots: bool = Field(
        False, description="write trajectories.png, safety.png and speed.png (needs the plots extra)"
    )
    animation: bool = Field(
        False, description="write animation.gif (animation.mp4 when ffmpeg is available); plots extra"
    )
    animation_frames: int = Field(150, ge=2, description="most frames in the animation (evenly subsampled)")
    comm_edges: bool = Field(False, description="draw communication edges (within comm.range) in the animation")
    rerun: bool = Field(False, description="write replay.rrd for the Rerun viewer (needs the rerun extra)")
    objective: list[str] = Field(
        default_factory=list,
        description="metrics the run returns to a Hydra sweeper (one: a float, several: a tuple), e.g. Optuna",
    )


class EventConfig(_Strict):
    """One scheduled event (see :mod:`swarmscene.core.events`)."""

    at: float = Field(ge=0, description="time, s")
    agents: list[int] = Field(min_length=1, description="indices of the agents hit")
    kind: Literal["hover", "comm_loss"] = Field(description="hover: failure, holds position")


class PluginChoice(BaseModel):
    """``name`` selects a registered plugin; the other keys are that plugin's Params."""

    model_config = ConfigDict(extra="allow", frozen=True)
    name: str


class ScenarioConfig(_Strict):
    """A whole scenario as composed by Hydra (the ``hydra`` node left out)."""

    name: str = Field("default", description="scenario label, used in output paths")
    description: str = Field("", description="one line on what the scenario shows")
    seed: int = Field(0, ge=0, description="seed of the run's one random generator")
    swarm: SwarmConfig
    clock: ClockConfig = Field(default_factory=ClockConfig)
    environment: EnvironmentConfig = Field(default_factory=EnvironmentConfig)
    formation: PluginChoice
    avoidance: PluginChoice
    dynamics: PluginChoice
    events: list[EventConfig] = Field(default_factory=list)
    safety: SafetyConfig = Field(default_factory=SafetyConfig)
    comm: CommConfig = Field(default_factory=CommConfig)
    termination: TerminationConfig = Field(default_factory=TerminationConfig)
    output: OutputConfig = Field(default_factory=OutputConfig)

    @model_validator(mode="after")
    def _explicit_positions_match_n(self) -> "ScenarioConfig":
        start = self.swarm.start
        if start.kind == "explicit" and len(start.positions) != self.swarm.n:
            raise ValueError(
                f"swarm.start.positions: must list swarm.n = {self.swarm.n} positions "
                f"(got {len(start.positions)})"
            )
        return self

    @property
    def physics_step(self) -> float:
        return self.clock.physics_step or self.clock.guidance_period

    @property
    def substeps(self) -> int:
        return int(round(self.clock.guidance_period / self.physics_step))


class Scenario(BaseModel):
    """A validated scenario: the engine config plus each chosen plugin's class and Params."""

    model_config = ConfigDict(arbitrary_types_allowed=True, frozen=True)
    config: ScenarioConfig
    plugin_classes: dict[str, Any]
    plugin_params: dict[str, PluginParams]
    data: dict[str, Any]


def validate(data: dict[str, Any], registry: "Any") -> Scenario:
    """Validate composed config ``data`` in one pass; raise :class:`ConfigError` listing every problem.

    Args:
        data: plain composed config (no ``hydra`` node).
        registry: a :class:`~swarmscene.core.registry.Registry` (plugin classes by kind and name).
    """
    errors: list[str] = []
    try:
        config = ScenarioConfig.model_validate(data)
    except ValidationError as exc:
        errors += format_validation_error(exc, ScenarioConfig, data)
        config = None
    classes, params = _validate_plugins(data, registry, errors)
    if config is not None:
        errors += _scenario_checks(config)
        formation = classes.get("formation")
        if formation is not None and formation.requires_leader and config.swarm.leader is None:
            errors.append(
                f"swarm.leader: formation {formation.name!r} needs a leader "
                f"(an agent index 0..{config.swarm.n - 1})"
            )
    if errors:
        raise ConfigError(errors)
    return Scenario(config=config, plugin_classes=classes, plugin_params=params, data=data)


def _validate_plugins(data: dict, registry: Any, errors: list[str]) -> tuple[dict, dict]:
    classes: dict[str, Any] = {}
    params: dict[str, PluginParams] = {}
    for kind in PLUGIN_KINDS:
        node = data.get(kind)
        if not isinstance(node, dict) or "name" not in node:
            continue  # ScenarioConfig already reported it
        name = node["name"]
        available = registry.names(kind)
        if name not in available:
            errors.append(f"{kind}.name: unknown {kind} {name!r} (valid: {', '.join(available)})")
            continue
        cls = registry.get(kind, name)
        options = {k: v for k, v in node.items() if k != "name"}
        try:
            params[kind] = cls.Params.model_validate(options)
            classes[kind] = cls
        except ValidationError as exc:
            errors += format_validation_error(exc, cls.Params, options, prefix=kind)
    return classes, params


def _scenario_checks(config: ScenarioConfig) -> list[str]:
    """Checks across sections that no single field can make."""
    from .geometry import build_obstacles, initial_positions  # geometry imports shapely lazily

    errors: list[str] = []
    clock = config.clock
    ratio = clock.guidance_period / config.physics_step
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
        errors.append(
            f"clock.physics_step: must divide clock.guidance_period = {clock.guidance_period} "
            f"(got {config.physics_step})"
        )
    elif clock.duration < clock.guidance_period:
        errors.append(
            f"clock.duration: must be >= clock.guidance_period = {clock.guidance_period} "
            f"(got {clock.duration})"
        )
    elif ratio > MAX_SUBSTEPS:
        errors.append(
            f"clock.physics_step: must be >= clock.guidance_period / {MAX_SUBSTEPS} "
            f"(got {config.physics_step})"
        )
    n = config.swarm.n
    if config.swarm.leader is not None and config.swarm.leader >= n:
        errors.append(f"swarm.leader: must be < swarm.n = {n} (got {config.swarm.leader})")
    for k, event in enumerate(config.events):
        bad = [a for a in event.agents if not 0 <= a < n]
        if bad:
            errors.append(f"events.{k}.agents: agents are 0..{n - 1} (got {bad})")
    obstacles, obstacle_errors = build_obstacles(config.environment)
    errors += obstacle_errors
    if errors:
        return errors
    try:
        pos = initial_positions(config, np.random.default_rng(config.seed))
    except ValueError as exc:
        return [str(exc)]
    errors += _start_checks(config, pos, obstacles)
    return errors


def _start_checks(config: ScenarioConfig, pos: np.ndarray, obstacles: list) -> list[str]:
    from scipy.spatial import cKDTree

    from .environment import Environment

    errors: list[str] = []
    env = Environment(obstacles)
    inside = np.flatnonzero(env.clearance(pos) < 0)
    if inside.size:
        errors.append(f"swarm.start: agents {inside.tolist()} start inside an obstacle")
    d_min = config.safety.min_separation
    if len(pos) > 1 and d_min > 0:
        pairs = cKDTree(pos).query_pairs(d_min, output_type="ndarray")
        if len(pairs):
            msg = (
                f"swarm.start: {len(pairs)} pairs of agents start closer than "
                f"safety.min_separation = {d_min} m (first: {pairs[0].tolist()})"
            )
            if config.safety.start_overlap == "error":
                errors.append(msg)
            else:
                warnings.warn(msg, stacklevel=2)
    if not math.isfinite(float(np.abs(pos).max(initial=0.0))):
        errors.append("swarm.start: positions must be finite")
    return errors
