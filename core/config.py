"""The scenario schema (pydantic v2): the engine's own sections and the validated :class:`Scenario`.

Split by concept (each module one thing a reader holds):

* here, the schema: what a scenario may say, section by section (the environment's and the
  events' sections in :mod:`.obstacles` and :mod:`.events`);
* :mod:`.validation`, the one validation pass after Hydra composition (:func:`validate`);
* :mod:`.resources`, what a run needs of the machine (the memory estimate, ``/proc/meminfo``).

Both import this schema, and this module imports neither (no import circle, tests/test_layout.py):
``validate``, ``effective_config`` and the memory checks are imported from their own modules.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_serializer, model_validator

from .errors import validate_renamed
from .events import EventConfig
from .fields import MAX_DURATION, MAX_LENGTH, Coordinate, Point2, Point3, StrictModel
from .obstacles import CircleObstacle, EnvironmentConfig, Obstacle, PolygonObstacle, WallObstacle
from .plugin import PluginParams
from .spelling import KIND_UNTIL, START_RENAMES
from .task import TaskConfig

_Strict = StrictModel  # the schema's sections below; other modules own theirs (events, obstacles)

__all__ = ["CircleObstacle", "Coordinate", "EnvironmentConfig", "EventConfig", "MAX_DURATION", "MAX_LENGTH",
           "Obstacle", "Point2", "PolygonObstacle", "Scenario", "ScenarioConfig", "WallObstacle"]

def _without_unset(data: dict[str, Any], keys: tuple[str, ...]) -> dict[str, Any]:
    """``data`` without those of ``keys`` that are null: an option added later is recorded only when
    set, so a run that does not set it keeps the record (and config hash) it had before."""
    for key in keys:
        if key in data and data[key] is None:
            del data[key]
    return data


MAX_AGENTS = 1_000_000
"""Most agents in one scenario (state alone is ~100 bytes per agent; see docs/benchmarks.md)."""
MAX_SUBSTEPS = 10_000
"""Most physics steps per guidance tick (a smaller physics step is almost surely a typo)."""
MAX_TICKS = 10_000_000
"""Most guidance ticks in one run (``clock.duration / clock.guidance_period``): 11.5 days of
simulated time at T_s = 0.1 s; the kernel keeps 8 bytes of timing per tick."""
MAX_ANIMATION_FRAMES = 10_000
"""Most frames in the animation (each is drawn by matplotlib)."""
MAX_PERIOD = 3600.0
"""Longest guidance period, s."""


class StartConfig(_Strict):
    """Initial positions of the swarm.

    layouts: ``line`` (along +y through ``center``, ``spacing`` apart), ``grid`` (square-ish grid,
    ``spacing`` apart, centred on ``center``), ``circle`` (agent k at angle ``2 pi k / n`` on a ring
    of ``radius``, or of ``spacing * n / (2 pi)`` when ``radius`` is null),
    ``explicit`` (``positions``, one [x, y, z] per agent), ``random`` (uniform in a square of side
    ``extent`` around ``center``, redrawn until agents are ``spacing`` apart; seeded; with
    ``connected`` the whole swarm is redrawn until its communication graph at ``comm.range`` is
    connected, the "random eligible initial state" of the thesis' section 5.4).
    """

    layout: Literal["line", "grid", "circle", "explicit", "random"] = Field(
        "grid", description="line | grid | circle | explicit | random (see above); swarm.start.kind, its old "
        "key, is read until 0.9.0"
    )
    spacing: float = Field(2.0, gt=0, le=MAX_LENGTH, description="distance between neighbours, m")
    center: Point3 = Field((0.0, 0.0, 1.0), description="[x, y, z] of the swarm's centre, m")
    extent: float = Field(10.0, gt=0, le=MAX_LENGTH, description="side of the square for layout=random, m")
    radius: float | None = Field(
        None, gt=0, le=MAX_LENGTH, description="for layout=circle: ring radius, m (null: spacing * n / (2 pi))"
    )
    positions: list[Point3] = Field(default_factory=list, description="for layout=explicit, m")
    connected: bool = Field(
        False, description="for layout=random: redraw until the comm graph (comm.range) is connected"
    )

    @model_validator(mode="wrap")
    @classmethod
    def _layout_was_kind(cls, data: Any, handler: Any) -> Any:
        """``swarm.start.kind`` still chooses the layout until 0.9.0, with a warning: ``kind`` now
        means only a plugin's kind (:mod:`.spelling`). Given with ``layout`` (an old command line
        over a new file), ``kind`` wins."""
        return validate_renamed(data, handler, START_RENAMES, "swarm.start", until=KIND_UNTIL)


class SwarmConfig(_Strict):
    """The agents."""

    n: int = Field(ge=1, le=MAX_AGENTS, description="number of agents N")
    leader: int | None = Field(0, ge=0, description="index of the leader, or null for none")
    start: StartConfig = Field(default_factory=StartConfig, description="initial positions")
    takeoff: float | None = Field(
        None, gt=0, le=MAX_DURATION,
        description="take-off, s: the swarm starts on environment.floor below its start positions at "
        "t = -takeoff and climbs to them by t = 0 (null: it starts in the air; core/phases.py)",
    )
    land: float | None = Field(
        None, gt=0, le=MAX_DURATION,
        description="landing, s: when the mission ends every vehicle descends to environment.floor in "
        "this time, then the run ends (null: it ends in the air; core/phases.py)",
    )

    @model_serializer(mode="wrap")
    def _recorded(self, handler: Any) -> dict[str, Any]:
        """No ``takeoff: null`` / ``land: null``: the record (and config hash) of a run without them
        is as before they existed."""
        return _without_unset(handler(self), ("takeoff", "land"))


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
    """The limits and conditions every run is measured against (core/monitors.py).

    The measured values are the metrics ``min_separation``, ``min_clearance`` and, with ``keep_out``
    set, ``min_keep_out`` (docs/outputs.md)."""

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
    keep_out: tuple[float, float, float] | None = Field(
        None,
        description="radii [rx, ry, rz] of the keep-out ellipsoid, m: two agents with "
        "||E^-1 (p_i - p_j)|| < 1, E = diag(radii), are in conflict (Crazyswarm's planners: 0.12, 0.12, "
        "0.3; Preiss et al., IROS 2017); null: not checked",
    )

    @field_validator("keep_out", mode="before")
    @classmethod
    def _three_radii(cls, value: Any) -> Any:
        """Three finite radii in (0, MAX_LENGTH], or null: one line naming the key, not one per item."""
        if value is None:
            return None
        items = list(value) if isinstance(value, (list, tuple)) else []
        numbers = [v for v in items if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if len(items) != 3 or len(numbers) != 3 or not all(0 < v <= MAX_LENGTH for v in numbers):
            raise ValueError(f"must be three radii [rx, ry, rz], each > 0 and at most {MAX_LENGTH:g} m, or null")
        return value

    @model_serializer(mode="wrap")
    def _recorded(self, handler: Any) -> dict[str, Any]:
        """No ``keep_out: null``: the record (and config hash) of a run without it is as before the option."""
        return _without_unset(handler(self), ("keep_out",))

    @model_validator(mode="wrap")
    @classmethod
    def _deprecated_names(cls, data: Any, handler: Any) -> Any:
        """``safety.min_separation``/``min_clearance`` still work for one release, with a warning
        (they name the limits, not the measured metrics of the same names); an old key given (e.g. on
        the command line) wins over the new one's default, and an error in its value names it."""
        return validate_renamed(data, handler, DEPRECATED_SAFETY_KEYS, "safety")


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
    mcap: bool = Field(
        False, description="write bag/, a ROS 2 bag (MCAP and metadata.yaml) streamed while the run goes: "
        "/tf, odometry, markers, events and verdicts (needs the ros extra; docs/ros.md)"
    )
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

        # the grammar only; swarmscene.views.live starts or reaches the viewer (ports: Rerun's 9876 and 9090)
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
    r"""Why ``name`` cannot name an output directory, or None.

    The name is one path component under ``outputs/`` or ``multirun/``, so it stays inside the
    working directory: no ``/`` or ``\``, not ``.`` or ``..`` (nor any name starting with a dot,
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
    observers: dict[str, Any] = Field(
        default_factory=dict,
        exclude=True,  # dumped validated, by effective_config (each observer's Params)
        description="options of the observers that take some, by name (observers=[swarmlab]: "
        "SwarmLab's metrics); each validated by that observer's Params",
    )
    task: TaskConfig | None = Field(
        None,
        exclude=True,  # dumped by effective_config when a task is declared
        description="the benchmark task this scenario is (task=<name>: its score, horizon and seeds; "
        "docs/suite.md)",
    )

    @field_validator("name")
    @classmethod
    def _name_is_one_directory(cls, name: str) -> str:
        problem = name_problem(name)
        if problem is not None:
            raise ValueError(problem)
        return name

    @model_validator(mode="after")
    def _explicit_positions_match_n(self) -> ScenarioConfig:
        start = self.swarm.start
        if start.layout == "explicit" and len(start.positions) != self.swarm.n:
            raise ValueError(
                f"swarm.start.positions: must list swarm.n = {self.swarm.n} positions "
                f"(got {len(start.positions)})"
            )
        return self

    @model_validator(mode="after")
    def _phases_need_a_floor(self) -> ScenarioConfig:
        for key in ("takeoff", "land"):
            seconds = getattr(self.swarm, key)
            if seconds is None:
                continue
            if self.environment.floor is None:
                raise ValueError(f"swarm.{key}: needs a ground: set environment.floor (e.g. environment.floor=0)")
            if seconds < self.clock.guidance_period:
                raise ValueError(f"swarm.{key}: {seconds:g} s is shorter than one guidance tick "
                                 f"(clock.guidance_period = {self.clock.guidance_period:g} s)")
        return self

    @property
    def physics_step(self) -> float:
        """The physics step, s: ``clock.physics_step``, or the guidance period T_s when it is null."""
        return self.clock.physics_step or self.clock.guidance_period

    @property
    def substeps(self) -> int:
        """Physics steps per guidance tick, T_s / physics step (validation checks it is whole)."""
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

