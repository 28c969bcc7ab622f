"""The scenario schema (pydantic v2) and the one validation pass after Hydra composition.

Hydra composes plain YAML; ``OmegaConf.to_container(resolve=True)`` turns it into plain data;
:func:`validate` checks it in one pass: the engine's own keys against :class:`ScenarioConfig`, each
chosen plugin's keys against that plugin's ``Params``, then scenario-level checks (physics step
divides the guidance period, events name existing agents, agents start clear of obstacles and of
each other, the run fits the machine). Every problem becomes one line ``dotted.key: what is allowed
(got value)``, collected in a :class:`ConfigError`.

Validation builds what it checks (the obstacle footprints, the start positions) once: the returned
:class:`Scenario` carries them to the simulation, with the effective configuration (every default
resolved) that the run directory records.
"""

from __future__ import annotations

import warnings
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .errors import ConfigError, format_validation_error
from .disturbances import validate_disturbances
from .disturbances.comm import channel_errors
from .events import EventConfig, check_events
from .fields import MAX_DURATION, MAX_LENGTH, Coordinate, Point2, Point3, StrictModel
from .obstacles import CircleObstacle, EnvironmentConfig, Obstacle, PolygonObstacle, WallObstacle
from .plugin import PLUGIN_KINDS, PluginParams, shared_option_conflicts

_Strict = StrictModel  # the schema's sections below; other modules own theirs (events, obstacles)

__all__ = ["CircleObstacle", "Coordinate", "EnvironmentConfig", "EventConfig", "MAX_DURATION",
           "MAX_LENGTH", "Obstacle", "Point2", "PolygonObstacle", "Scenario", "ScenarioConfig",
           "WallObstacle", "validate"]

MAX_AGENTS = 1_000_000
"""Most agents in one scenario (state alone is ~100 bytes per agent; see docs/benchmarks.md)."""
MAX_SUBSTEPS = 10_000
"""Most physics steps per guidance tick (a smaller physics step is almost surely a typo)."""
MAX_TICKS = 10_000_000
"""Most guidance ticks in one run (``clock.duration / clock.guidance_period``): 11.5 days of
simulated time at T_s = 0.1 s; the kernel keeps 8 bytes of timing per tick."""
MAX_ANIMATION_FRAMES = 10_000
"""Most frames in the animation (each is drawn by matplotlib)."""
AGENT_WORKING_BYTES = 16 * 1024
"""Estimated engine memory per agent besides the trajectory record: state arrays, the tick's
k-d trees and neighbour lists, plugin arrays (measured peak 15.4 and 16.5 KiB per agent at
N = 2 x 10^4 and 10^5: reynolds_flocking with ~80 neighbours each and potential avoidance)."""
BASE_WORKING_BYTES = 256 * 2**20
"""Estimated memory of the interpreter and the imported packages."""

MAX_PERIOD = 3600.0
"""Longest guidance period, s."""


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
    spacing: float = Field(2.0, gt=0, le=MAX_LENGTH, description="distance between neighbours, m")
    center: Point3 = Field((0.0, 0.0, 1.0), description="[x, y, z] of the swarm's centre, m")
    extent: float = Field(10.0, gt=0, le=MAX_LENGTH, description="side of the square for kind=random, m")
    radius: float | None = Field(
        None, gt=0, le=MAX_LENGTH, description="for kind=circle: ring radius, m (null: spacing * n / (2 pi))"
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

    guidance_period: float = Field(0.1, gt=0, le=MAX_PERIOD, description="T_s, s")
    physics_step: float | None = Field(
        None, gt=0, description="s; must divide guidance_period (null: equal to it)"
    )
    duration: float = Field(
        30.0, gt=0, le=MAX_DURATION, description="simulated duration, s (at most 10^7 guidance ticks)"
    )


DEPRECATED_SAFETY_KEYS = {"min_separation": "separation_limit", "min_clearance": "clearance_limit"}
"""Old names of the safety limits (they named the measured metrics too), accepted for one release."""


class SafetyConfig(_Strict):
    """The limits every run is measured against (the measured values are the metrics
    ``min_separation`` and ``min_clearance``)."""

    separation_limit: float = Field(
        0.5, ge=0, le=MAX_LENGTH, description="safety distance between agents, m (was min_separation)"
    )
    clearance_limit: float = Field(
        0.2, ge=0, le=MAX_LENGTH, description="safety distance to obstacles, m (was min_clearance)"
    )
    start_overlap: Literal["error", "warn"] = Field(
        "error",
        description="agents starting closer than separation_limit: an error, or a warning where a "
        "scenario starts that way on purpose (thesis 4.5.2)",
    )

    @model_validator(mode="before")
    @classmethod
    def _deprecated_names(cls, data: Any) -> Any:
        """``safety.min_separation``/``min_clearance`` still work for one release, with a warning;
        an old key given (e.g. on the command line) wins over the new one's default."""
        if not isinstance(data, dict):
            return data
        data = dict(data)
        for old, new in DEPRECATED_SAFETY_KEYS.items():
            if old in data:
                warnings.warn(
                    f"safety.{old} is deprecated: write safety.{new} (the limit; {old} is the "
                    "measured metric)", DeprecationWarning, stacklevel=2,
                )
                data[new] = data.pop(old)
        return data


class CommConfig(_Strict):
    """Communication graph: agents within ``range`` of each other are linked."""

    range: float = Field(20.0, gt=0, le=MAX_LENGTH, description="m")


class TerminationConfig(_Strict):
    """Optional early ends of a run."""

    on_complete: bool = Field(True, description="stop when the formation reports its mission done")
    on_collision: bool = Field(False, description="stop at the first pair closer than safety.separation_limit")


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
    animation_frames: int = Field(
        150, ge=2, le=MAX_ANIMATION_FRAMES, description="most frames in the animation (evenly subsampled)"
    )
    comm_edges: bool = Field(False, description="draw communication edges (within comm.range) in the animation")
    rerun: bool = Field(False, description="write replay.rrd for the Rerun viewer (needs the rerun extra)")
    live: str = Field(
        "off",
        description="stream the run to a Rerun viewer as it is simulated (rerun extra): off; spawn[:PORT] "
        "(the native viewer on this machine); serve[:PORT[:WEB_PORT]] (a background web viewer, for "
        "headless nodes); connect[:URL] (a viewer already running); docs/outputs.md",
    )
    objective: list[str] = Field(
        default_factory=list,
        description="metrics the run returns to a Hydra sweeper (one: a float, several: a tuple), e.g. Optuna",
    )

    @field_validator("live")
    @classmethod
    def _live_view(cls, value: str) -> str:
        import re

        # the grammar only; swarmscene.live starts or reaches the viewer (ports: Rerun's 9876 and 9090)
        match = re.fullmatch(LIVE_PATTERN, value)
        ports = [int(p) for p in match.groupdict(default="0").values() if p.isdigit()] if match else []
        if match is None or any(port > 65535 for port in ports):
            raise ValueError("must be off, spawn[:PORT], serve[:PORT[:WEB_PORT]] or connect[:URL] with a port "
                             "1-65535 and a URL rerun+http(s)://HOST:PORT/proxy")
        return value


LIVE_PATTERN = (r"off|spawn(?::(?P<spawn>[1-9]\d{0,4}))?"
                r"|serve(?::(?P<serve>[1-9]\d{0,4})(?::(?P<web>[1-9]\d{0,4}))?)?"
                r"|connect(?::rerun\+https?://[^\s/:]+:(?P<connect>[1-9]\d{0,4})/proxy)?")
"""``output.live``'s values (:class:`OutputConfig`)."""


class PluginChoice(BaseModel):
    """``name`` selects a registered plugin; the other keys are that plugin's Params."""

    model_config = ConfigDict(extra="allow", frozen=True)
    name: str


MAX_NAME_LENGTH = 100
"""Longest scenario ``name``: it becomes one directory name (``outputs/<name>/...``)."""


def name_problem(name: Any) -> str | None:
    """Why ``name`` cannot name an output directory, or None.

    The name is one path component under ``outputs/`` or ``multirun/``, so it stays inside the
    working directory: no ``/`` or ``\\``, not ``.`` or ``..`` (nor any name starting with a dot,
    which would hide the directory), no control characters, at most ``MAX_NAME_LENGTH`` characters.
    """
    if not isinstance(name, str) or not name.strip():
        return "must be a non-empty label"
    if "/" in name or "\\" in name:
        return "must not contain '/' or '\\' (it names one output directory)"
    if name.startswith("."):
        return "must not start with '.' (it names one output directory inside the working directory)"
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        return "must not contain control characters"
    if len(name) > MAX_NAME_LENGTH:
        return f"must be at most {MAX_NAME_LENGTH} characters (got {len(name)})"
    return None


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
    disturbances: dict[str, Any] = Field(
        default_factory=dict,
        exclude=True,  # dumped validated, by effective_config (from Scenario.disturbances)
        description="disturbance models by name (wind, sensing noise, communication; "
        "docs/disturbances.md), chosen with disturbances=[dryden,gps]; each validated by its kind's "
        "Params (swarmscene.core.disturbances)",
    )
    safety: SafetyConfig = Field(default_factory=SafetyConfig)
    comm: CommConfig = Field(default_factory=CommConfig)
    termination: TerminationConfig = Field(default_factory=TerminationConfig)
    output: OutputConfig = Field(default_factory=OutputConfig)

    @field_validator("name")
    @classmethod
    def _name_is_one_directory(cls, name: str) -> str:
        problem = name_problem(name)
        if problem is not None:
            raise ValueError(problem)
        return name

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
    """A validated scenario, ready to build: the engine config, each chosen plugin's class and
    Params, and what validation built to check it.

    Attributes:
        config: the engine's validated config.
        plugin_classes: the chosen class of each kind (``formation``, ``avoidance``, ``dynamics``).
        plugin_params: each chosen plugin's validated Params, defaults included.
        data: the effective configuration: ``config`` with every field and each chosen plugin's
            ``name`` and Params with every field, as plain data in the shape a user writes (what
            the run directory's ``config.yaml`` records; validating it again gives this scenario).
        composed: the data as composed (the input to :func:`validate`).
        obstacles: the obstacle footprints, shapely geometries (:func:`~.geometry.build_obstacles`).
        initial_positions: positions at t = 0, (N, 3), m, read-only.
        rng_state: the state of ``numpy.random.default_rng(seed)`` after drawing the start, so the
            run continues the same random stream as if it had drawn the start itself.
        disturbances: each declared disturbance's model class and validated Params, by name
            (sorted; empty when none is declared).
    """

    model_config = ConfigDict(arbitrary_types_allowed=True, frozen=True)
    config: ScenarioConfig
    plugin_classes: dict[str, Any]
    plugin_params: dict[str, PluginParams]
    data: dict[str, Any]
    composed: dict[str, Any] = Field(default_factory=dict)
    obstacles: list[Any] = Field(default_factory=list)
    initial_positions: np.ndarray
    rng_state: dict[str, Any]
    disturbances: dict[str, Any] = Field(default_factory=dict)


def effective_config(config: ScenarioConfig, classes: dict[str, Any], params: dict[str, PluginParams],
                     disturbances: dict[str, Any] | None = None) -> dict[str, Any]:
    """The configuration a run uses, every default resolved, as plain data (JSON types) in the
    nested shape of the composed config: the engine schema's fields, then for each plugin kind its
    ``name`` and every field of its Params, then each declared disturbance with every option.
    ``disturbances`` is left out when none is declared, so the record (and its hash) of such a run
    is the one it had before disturbances existed."""
    from .disturbances import effective

    data = config.model_dump(mode="json")
    for kind in PLUGIN_KINDS:
        data[kind] = {"name": classes[kind].name, **params[kind].model_dump(mode="json")}
    if disturbances:
        data["disturbances"] = effective(disturbances)
    return data


def validate(data: dict[str, Any], registry: "Any") -> Scenario:
    """Validate composed config ``data`` in one pass; raise :class:`ConfigError` listing every problem.

    Args:
        data: plain composed config (no ``hydra`` node).
        registry: a :class:`~swarmscene.core.registry.Registry` (plugin classes by kind and name).
    Returns:
        the :class:`Scenario`, with the obstacles and start positions built while checking it.
    """
    errors: list[str] = []
    try:
        config = ScenarioConfig.model_validate(data)
    except ValidationError as exc:
        errors += format_validation_error(exc, ScenarioConfig, data)
        config = None
    classes, params = _validate_plugins(data, registry, errors)
    disturbances = validate_disturbances(data.get("disturbances"), errors)
    errors += shared_option_conflicts(params)  # e.g. the thesis' graph parameters, declared twice
    world = None
    if config is not None:
        errors += _scenario_checks(config)
        formation = classes.get("formation")
        if formation is not None and formation.requires_leader and config.swarm.leader is None:
            errors.append(
                f"swarm.leader: formation {formation.name!r} needs a leader "
                f"(an agent index 0..{config.swarm.n - 1})"
            )
        if "dynamics" in classes:
            errors += _rotor_checks(config, classes["dynamics"])
        errors += channel_errors(disturbances, config.swarm.n, config.clock.guidance_period)
        if not errors and len(classes) == len(PLUGIN_KINDS):
            errors += memory_checks(config, classes["dynamics"])
        if not errors:
            world, world_errors = _build_world(config)
            errors += world_errors
    if errors:
        raise ConfigError(errors)
    obstacles, positions, rng_state = world
    return Scenario(
        config=config,
        plugin_classes=classes,
        plugin_params=params,
        data=effective_config(config, classes, params, disturbances),
        composed=data,
        obstacles=obstacles,
        initial_positions=positions,
        rng_state=rng_state,
        disturbances=disturbances,
    )


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
    """Checks across sections that no single field can make (before anything is built)."""
    from .geometry import build_obstacles

    errors: list[str] = _clock_checks(config)
    n = config.swarm.n
    if config.swarm.leader is not None and config.swarm.leader >= n:
        errors.append(f"swarm.leader: must be < swarm.n = {n} (got {config.swarm.leader})")
    errors += check_events(config.events, n)
    errors += build_obstacles(config.environment)[1]
    return errors


def _rotor_checks(config: ScenarioConfig, dynamics: Any) -> list[str]:
    """``motor_failure`` events need a dynamics model with rotors, and a rotor it has."""
    errors = []
    rotors = getattr(dynamics, "rotors", 0)
    for k, event in enumerate(config.events):
        if event.kind != "motor_failure":
            continue
        if rotors == 0:
            errors.append(f"events.{k}.kind: motor_failure needs a dynamics model with rotors "
                          f"(dynamics {dynamics.name!r} has none; e.g. dynamics=quadrotor)")
        elif event.rotor is not None and event.rotor >= rotors:
            errors.append(f"events.{k}.rotor: must be < {rotors}, the rotors of dynamics "
                          f"{dynamics.name!r} (got {event.rotor})")
    return errors


def _clock_checks(config: ScenarioConfig) -> list[str]:
    """The physics step divides the guidance period, and the run has a bounded number of ticks."""
    clock = config.clock
    substeps = clock.guidance_period / config.physics_step  # may overflow to inf: no round() before
    if not substeps <= MAX_SUBSTEPS:
        return [f"clock.physics_step: must be >= clock.guidance_period / {MAX_SUBSTEPS} "
                f"(got {config.physics_step})"]
    if abs(substeps - round(substeps)) > 1e-9 * max(1.0, substeps) or round(substeps) < 1:
        return [f"clock.physics_step: must divide clock.guidance_period = {clock.guidance_period} "
                f"(got {config.physics_step})"]
    if clock.duration < clock.guidance_period:
        return [f"clock.duration: must be >= clock.guidance_period = {clock.guidance_period} "
                f"(got {clock.duration})"]
    ticks = clock.duration / clock.guidance_period
    if not ticks <= MAX_TICKS:
        return [f"clock.duration: at most {MAX_TICKS} guidance ticks of clock.guidance_period = "
                f"{clock.guidance_period} s (got {clock.duration}: {ticks:.3g} ticks)"]
    return []


def memory_checks(config: ScenarioConfig, dynamics: Any) -> list[str]:
    """The run's estimated peak memory against the machine's: one line when it does not fit.

    Estimate: :data:`BASE_WORKING_BYTES` + N x :data:`AGENT_WORKING_BYTES` + 8 bytes per tick
    (timing) + the trajectory frames held in memory (the whole record, or one chunk of
    ``output.trajectory_buffer_mb`` when it is streamed; see :mod:`swarmscene.core.recorder`).
    """
    need = estimated_memory(config, getattr(dynamics, "has_attitude", False))
    have = machine_memory()
    if have is None or need <= have:
        return []
    return [
        f"swarm.n: the run needs an estimated {need / 2**30:.3g} GiB of memory, the machine has "
        f"{have / 2**30:.3g} GiB (got swarm.n = {config.swarm.n}, {config.clock.duration / config.clock.guidance_period:.3g}"
        f" ticks, output.trajectory_buffer_mb = {config.output.trajectory_buffer_mb})"
    ]


def estimated_memory(config: ScenarioConfig, has_attitude: bool) -> float:
    """Estimated peak memory of a run, bytes (see :func:`memory_checks`)."""
    n, out = config.swarm.n, config.output
    ticks = config.clock.duration / config.clock.guidance_period
    total = BASE_WORKING_BYTES + n * AGENT_WORKING_BYTES + 8.0 * ticks
    if out.trajectory:
        itemsize = 4 if out.float32 else 8
        frame = n * ((6 + (4 if has_attitude else 0)) * itemsize + 1)
        frames = ticks // out.trajectory_every + 1
        held = frames * frame
        streamed = out.trajectory_stream == "on" or (
            out.trajectory_stream == "auto" and held > out.trajectory_buffer_mb * 2**20
        )
        if streamed:
            held = max(1.0, min(frames, out.trajectory_buffer_mb * 2**20 // frame)) * frame
        total += held + 8.0 * frames
    return total


def machine_memory() -> int | None:
    """Memory the run may use, bytes: MemAvailable of /proc/meminfo, else physical memory
    (``os.sysconf``), else None (unknown: not checked)."""
    import os

    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def _build_world(config: ScenarioConfig) -> tuple[tuple | None, list[str]]:
    """The obstacles, the start positions and the generator state after drawing them, or errors."""
    from .geometry import build_obstacles, initial_positions

    obstacles, _ = build_obstacles(config.environment)
    rng = np.random.default_rng(config.seed)
    try:
        pos = initial_positions(config, rng)
    except ValueError as exc:
        return None, [str(exc)]
    errors = _start_checks(config, pos, obstacles)
    pos.flags.writeable = False
    return (obstacles, pos, rng.bit_generator.state), errors


def _start_checks(config: ScenarioConfig, pos: np.ndarray, obstacles: list) -> list[str]:
    from .environment import Environment
    from .vectors import pairs_within

    reach = float(np.abs(pos).max(initial=0.0))
    if not reach <= MAX_LENGTH:  # NaN too
        return [f"swarm.start: positions must lie within {MAX_LENGTH:g} m of the origin on each axis "
                f"(got {reach:.3g} m from swarm.start with swarm.n = {config.swarm.n})"]
    errors: list[str] = []
    env = Environment(obstacles)
    inside = np.flatnonzero(env.clearance(pos) < 0)
    if inside.size:
        errors.append(f"swarm.start: agents {inside.tolist()} start inside an obstacle")
    d_min = config.safety.separation_limit
    if len(pos) > 1 and d_min > 0:
        pairs, _ = pairs_within(pos, d_min)
        if len(pairs):
            msg = (
                f"swarm.start: {len(pairs)} pairs of agents start closer than "
                f"safety.separation_limit = {d_min} m (first: {pairs[0].tolist()})"
            )
            if config.safety.start_overlap == "error":
                errors.append(msg)
            else:
                warnings.warn(msg, stacklevel=2)
    return errors
