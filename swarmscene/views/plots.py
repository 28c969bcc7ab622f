"""Per-run pictures (the ``plots`` extra, matplotlib): what a person would otherwise dig out of arrays.

On ``output.plots=true`` a run directory gets:

    trajectories.png  top-down paths (x east, y north) with the obstacles, start and end points,
                      and every failed vehicle marked where it failed
    safety.png        the distribution over agents of each agent's nearest-neighbour distance
                      (top) and obstacle clearance (bottom, with obstacles only) over time: median, 10-90 % band and
                      min-max envelope, the minimum (the safety monitor's series) as a line, the
                      limits ``safety.separation_limit`` and ``safety.clearance_limit`` dashed red,
                      violations shaded
    speed.png         the distribution over healthy agents of the speed over time (median, bands);
                      a plugin's published ``<name>.speed_limit`` metric (m/s) is drawn as a limit
    altitude.png      the same distribution of the altitude z over time (the 6-DOF runs, the VRB
                      air show)

For swarms of at most ``INDIVIDUAL_LINES`` agents every agent's own thin line is drawn as well.
Agent i has the colour ``agent_colors(N)[i]`` in every picture, the animation and the Rerun
replay; red is kept for failures and limits.

On ``output.animation=true`` ``animation.mp4`` (when matplotlib finds ffmpeg) or
``animation.gif``: the top-down view over time, trails, failed vehicles, and with
``output.comm_edges=true`` the communication edges (healthy pairs within ``comm.range``). Writing it
reports the frames written and the time left on a terminal (:class:`swarmscene.views.summary.Progress`).

Everything works from a run directory alone (config.yaml + trajectory.npz, metrics.json when
present), so ``swarmscene-report RUN_DIR --run-plots`` redraws them later. Inside a run the safety
monitor's series (every guidance tick) give the minimum lines; from a directory they are recomputed
at the recorded frames. Only the object-oriented matplotlib API is used (no pyplot state, no display
needed).
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..runs.outputs import atomic_write_bytes, private_temp_dir, publish

FAILED_COLOR = "tab:red"
LIMIT_COLOR = "tab:red"
LEGEND = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "fontsize": 7, "borderaxespad": 0.0}
"""Legends beside the axes, so they never hide a series."""
OBSTACLE_COLOR = "0.6"
BAND_COLOR = "0.35"
"""Grey: the bands are no agent's colour."""
MEDIAN_COLOR = "0.05"
INDIVIDUAL_LINES = 10
"""Swarms up to this size also get one thin line per agent in the distribution plots."""

# tab10 without its red (d62728), which marks failures and limits.
_PALETTE = np.array(
    [
        (31, 119, 180), (255, 127, 14), (44, 160, 44), (148, 103, 189), (140, 86, 75),
        (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
    ],
    dtype=np.uint8,
)


def safety_limit(config: dict, key: str) -> float:
    """``safety.<key>`` of a run's config.yaml (0 when absent); run directories written before the
    limits were renamed hold them as ``min_separation`` / ``min_clearance``."""
    safety = config.get("safety") or {}
    old = {"separation_limit": "min_separation", "clearance_limit": "min_clearance"}[key]
    return float(safety.get(key, safety.get(old, 0.0)))


def agent_colors(n: int) -> np.ndarray:
    """(n, 3) uint8 RGB: agent i's colour in every picture, the animation and the replay.

    Up to nine agents: the tab10 colours without red. More: evenly spaced hues from orange
    (30 degrees) round to magenta (330 degrees), so red stays free for failures and limits.
    """
    if n <= len(_PALETTE):
        return _PALETTE[:n].copy()
    hue = np.linspace(30.0, 330.0, n) / 60.0  # HSV with S = 0.75, V = 0.85, vectorised
    sector = np.floor(hue).astype(int) % 6
    frac = hue - np.floor(hue)
    v, s = 0.85, 0.75
    p, q, t = v * (1 - s), v * (1 - s * frac), v * (1 - s * (1 - frac))
    table = np.stack(
        [np.stack([np.full(n, v), t, np.full(n, p)], 1), np.stack([q, np.full(n, v), np.full(n, p)], 1),
         np.stack([np.full(n, p), np.full(n, v), t], 1), np.stack([np.full(n, p), q, np.full(n, v)], 1),
         np.stack([t, np.full(n, p), np.full(n, v)], 1), np.stack([np.full(n, v), np.full(n, p), q], 1)]
    )  # (6, n, 3)
    rgb = table[sector, np.arange(n)]
    return np.round(rgb * 255).astype(np.uint8)


def _mpl_colors(n: int) -> np.ndarray:
    """agent_colors as matplotlib RGB floats in [0, 1]."""
    return agent_colors(n) / 255.0


@dataclass
class RunData:
    """What the pictures and the replay need from one run (see :func:`load_run`)."""

    config: dict[str, Any]
    t: np.ndarray  # (T,) s
    pos: np.ndarray  # (T, N, 3) m
    vel: np.ndarray  # (T, N, 3) m/s
    healthy: np.ndarray  # (T, N) bool
    obstacles: list[Any] = field(default_factory=list)  # shapely polygons
    series: dict[str, np.ndarray] | None = None  # the safety monitor's, when known
    quat: np.ndarray | None = None  # (T, N, 4) (w, x, y, z) body to world, attitude dynamics only
    metrics: dict[str, Any] = field(default_factory=dict)  # metrics.json
    config_hash: str | None = None  # the manifest's (or the one it will hold)

    @property
    def n(self) -> int:
        """Number of agents, N."""
        return self.pos.shape[1]

    @property
    def name(self) -> str:
        """The scenario's name (``run`` when the config gives none)."""
        return str(self.config.get("name", "run"))

    @property
    def seed(self) -> int | None:
        """The run's seed, or None when the config gives none."""
        seed = self.config.get("seed")
        return None if seed is None else int(seed)

    @property
    def min_separation_limit(self) -> float:
        """The safety section's separation limit, m (the line drawn on the separation plot)."""
        return safety_limit(self.config, "separation_limit")

    @property
    def min_clearance_limit(self) -> float:
        """The safety section's clearance limit, m (the line drawn on the clearance plot)."""
        return safety_limit(self.config, "clearance_limit")

    @property
    def comm_range(self) -> float:
        """The communication range, m (inf when the config gives none)."""
        return float(self.config.get("comm", {}).get("range", np.inf))

    def speed_limits(self) -> dict[str, float]:
        """Speed limits plugins publish as ``<name>.speed_limit`` metrics (m/s), by metric key."""
        return {k: float(v) for k, v in sorted(self.metrics.items())
                if k.endswith(".speed_limit") and isinstance(v, (int, float)) and np.isfinite(v)}

    def failures(self) -> list[tuple[int, float, np.ndarray]]:
        """(agent, time, position) of every agent that failed during the recorded run.

        The time is the scheduled event's (``events``) when one names the agent; the frames only
        bound it (an event at the start of a tick shows in the frame recorded at its end).
        """
        from ..core.spelling import recorded_name  # an event's name, or its kind as recorded until 0.6.0

        scheduled: dict[int, list[float]] = {}
        for k, event in enumerate(self.config.get("events") or []):
            # a random event's time and agents are the run's draws (metrics events.<k>.*)
            agents = self.metrics.get(f"events.{k}.agents", event.get("agents", []))
            at = self.metrics.get(f"events.{k}.at", event.get("at"))
            if recorded_name(event) == "hover" and isinstance(agents, list) and isinstance(at, (int, float)):
                for agent in agents:
                    scheduled.setdefault(int(agent), []).append(float(at))
        out = []
        for agent in np.flatnonzero(~self.healthy.all(axis=0)):
            k = int(np.argmax(~self.healthy[:, agent]))
            times = [at for at in scheduled.get(int(agent), []) if at <= self.t[k] + 1e-9]
            when = max(times) if times else float(self.t[max(k - 1, 0)])
            out.append((int(agent), when, self.pos[k, agent]))
        return out


def _obstacles(config: dict[str, Any]) -> list[Any]:
    """The run's obstacles, rebuilt from its environment section with the installed registry, so
    a run whose map came from a plugin's generator reads back like a built-in's."""
    from ..builtins import BUILTIN_PLUGINS
    from ..core.config import EnvironmentConfig
    from ..core.geometry import build_obstacles
    from ..core.registry import make_plugin_manager

    registry = make_plugin_manager(BUILTIN_PLUGINS)[1]  # the installed plugins, as api.plugins()
    env = EnvironmentConfig.model_validate(config.get("environment") or {}, context={"registry": registry})
    obstacles, _ = build_obstacles(env)
    return obstacles


CONFIG_SECTIONS = ("clock", "safety", "comm", "environment", "swarm", "formation", "avoidance", "dynamics",
                   "termination", "output")
"""Sections of a run's config.yaml the pictures and exports read: each must be a mapping."""


def load_run(run_dir: Path) -> RunData:
    """Read a run directory's config.yaml and trajectory.npz (metrics.json, manifest.json if there).

    Every file goes through :mod:`swarmscene.runs.rundir`: a missing, damaged or planted one raises
    :class:`~swarmscene.runs.rundir.RunFileError`, one line naming the file and what is wrong.
    """
    from ..runs.rundir import CONFIG, MANIFEST, METRICS, RunDir, RunFileError

    run = RunDir(run_dir)
    config = run.config()
    _check_sections(run.path / CONFIG, config)
    arrays: dict[str, Any] = run.trajectory()  # t, pos, vel, healthy (and quat): RunData's fields
    quat = arrays.pop("quat", None)
    manifest = run.manifest() if run.has(MANIFEST) else {}
    metrics = run.metrics() if run.has(METRICS) else {}
    try:
        obstacles = _obstacles(config)
    except (ValueError, TypeError) as exc:  # pydantic's ValidationError is a ValueError
        first = " ".join(str(exc).split())[:200]
        raise RunFileError(run.path / CONFIG, f"its environment cannot be built ({first})") from None
    config_hash = manifest.get("config_hash")
    if not isinstance(config_hash, str):
        config_hash = _hash(config)
    return RunData(config=config, obstacles=obstacles, quat=quat, metrics=metrics, config_hash=config_hash,
                   **arrays)


def _check_sections(path: Path, config: dict[str, Any]) -> None:
    """A config.yaml whose sections are not mappings (or whose events are not a list of them) is
    damaged: say so here rather than fail deep inside a figure."""
    from ..runs.rundir import RunFileError

    for key in CONFIG_SECTIONS:
        if config.get(key) is not None and not isinstance(config[key], dict):
            raise RunFileError(path, f"{key!r} should be a mapping, holds {type(config[key]).__name__}")
    events = config.get("events")
    if events is not None and not (isinstance(events, list) and all(isinstance(e, dict) for e in events)):
        raise RunFileError(path, "'events' should be a list of mappings")
    for k, event in enumerate(events or []):
        if not _number(event.get("at")):
            raise RunFileError(path, f"events.{k}.at should be a number of seconds, holds {event.get('at')!r}")
    # the scalars the views read: a number where the run wrote one (the run itself validated them)
    for dotted, value in (("seed", config.get("seed")), ("comm.range", (config.get("comm") or {}).get("range")),
                          ("clock.duration", (config.get("clock") or {}).get("duration")),
                          *((f"safety.{key}", (config.get("safety") or {}).get(key))
                            for key in ("separation_limit", "clearance_limit"))):
        if (value is not None and not _number(value)) or (dotted == "seed" and isinstance(value, float)):
            raise RunFileError(path, f"{dotted} should be a number, holds {value!r}")


def _number(value: Any) -> bool:
    """A real number of YAML's (not a flag, not text)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _hash(config: dict[str, Any]) -> str:
    """The config hash the manifest holds for this config (the manifest is written last)."""
    from ..runs.outputs import config_hash

    return config_hash(config)


def from_simulation(sim: Any, result: Any) -> RunData:
    """The same data straight from a finished simulation (no re-reading, full-rate series)."""
    traj = result.trajectory
    if not traj:
        raise ValueError("no trajectory recorded (output.trajectory=false)")
    return RunData(
        config=sim.scenario.data,
        t=traj["t"], pos=traj["pos"], vel=traj["vel"], healthy=traj["healthy"],
        obstacles=list(sim.environment.obstacles),
        series=result.series, quat=traj.get("quat"), metrics=dict(result.metrics),
        config_hash=_hash(sim.scenario.data),
    )


def safety_series(run: RunData) -> dict[str, np.ndarray]:
    """Min separation and min clearance over time: the monitor's series, or recomputed per frame."""
    if run.series is not None:
        return {k: np.asarray(run.series[k]) for k in ("t", "min_separation", "min_clearance")}
    return {"t": run.t, "min_separation": nearest_neighbour(run).min(axis=1),
            "min_clearance": agent_clearance(run).min(axis=1)}


def nearest_neighbour(run: RunData) -> np.ndarray:
    """(T, N) m: each agent's distance to its nearest other agent at every recorded frame."""
    from scipy.spatial import cKDTree

    if run.n < 2:
        return np.full(run.pos.shape[:2], np.inf)
    # one k-d tree query per frame (a C call over all agents)
    return np.stack([cKDTree(frame).query(frame, k=2)[0][:, 1] for frame in np.asarray(run.pos)])


def agent_clearance(run: RunData) -> np.ndarray:
    """(T, N) m: each agent's signed distance to the nearest obstacle (inf without obstacles)."""
    pos = np.asarray(run.pos)
    if not run.obstacles:
        return np.full(pos.shape[:2], np.inf)
    from ..core.environment import Environment

    return Environment(run.obstacles).clearance(pos.reshape(-1, 3)).reshape(pos.shape[:2])


def agent_speed(run: RunData) -> np.ndarray:
    """(T, N) m/s: each agent's speed; NaN once the agent has failed (it hovers, speed 0)."""
    speed = np.linalg.norm(run.vel, axis=2)
    return np.where(run.healthy, speed, np.nan)


BANDS = {"median": 50.0, "p10": 10.0, "p90": 90.0, "min": 0.0, "max": 100.0}
"""Percentiles over agents drawn by the distribution plots."""


def bands(values: np.ndarray) -> dict[str, np.ndarray]:
    """Percentiles over agents (axis 1) of (T, N) values, ignoring NaN and inf: {name: (T,)}."""
    finite = np.where(np.isfinite(values), values, np.nan)
    out = {k: np.full(len(values), np.nan) for k in BANDS}
    rows = ~np.all(np.isnan(finite), axis=1)
    if rows.any():
        q = np.nanpercentile(finite[rows], list(BANDS.values()), axis=1)
        for k, row in zip(BANDS, q, strict=True):
            out[k][rows] = row
    return out


# -- figures ------------------------------------------------------------------------------------
def _draw_obstacles(ax: Any, obstacles: list[Any]) -> None:
    from matplotlib.patches import Polygon as PolygonPatch

    for k, geom in enumerate(obstacles):
        polys = getattr(geom, "geoms", [geom])
        for poly in polys:
            ax.add_patch(
                PolygonPatch(np.asarray(poly.exterior.coords), closed=True, facecolor=OBSTACLE_COLOR,
                             edgecolor="0.3", linewidth=0.5, label="obstacle" if k == 0 else None)
            )


def wrap_steps(run: RunData) -> np.ndarray:
    """(T - 1, N) bool: the frames after which an agent jumped more than half the extent of the
    whole run along x or y, i.e. was folded back into a periodic space (a torus' seam: the
    engine's wrap phase, Formation.periodic_box). No agent flies half the map between two frames,
    so a picture draws no line across these."""
    xy = run.pos[..., :2]
    extent = xy.max(axis=(0, 1)) - xy.min(axis=(0, 1))
    jump = np.abs(np.diff(xy, axis=0))
    return np.any(jump > 0.5 * extent, axis=2) & np.any(extent > 0)


def trajectory_figure(run: RunData) -> Any:
    """Top-down paths in the agents' colours, obstacles, start (circle) and end (square) points,
    failures (red x)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 6), layout="constrained")
    ax = fig.add_subplot()
    _draw_obstacles(ax, run.obstacles)
    failed = {agent for agent, _, _ in run.failures()}
    colors = _mpl_colors(run.n)
    xy = run.pos[..., :2]
    wraps = wrap_steps(run)
    for i in range(run.n):
        path = np.insert(xy[:, i], np.flatnonzero(wraps[:, i]) + 1, np.nan, axis=0)  # no line across a wrap
        ax.plot(path[:, 0], path[:, 1], color=colors[i], linewidth=0.8, alpha=0.8, gid=f"agent{i}",
                linestyle="--" if i in failed else "-")
    ax.scatter(xy[0, :, 0], xy[0, :, 1], s=12, facecolors="none", edgecolors="k", label="start")
    ax.scatter(xy[-1, :, 0], xy[-1, :, 1], s=12, marker="s", color="k", label="end")
    fails = run.failures()
    if fails:
        where = np.array([p[:2] for _, _, p in fails])
        ax.scatter(where[:, 0], where[:, 1], s=80, marker="x", color=FAILED_COLOR, linewidths=2,
                   label=f"failed ({len(fails)})", zorder=5, gid="failed")
        for agent, t, p in fails:
            ax.annotate(f"{agent} @ {t:.1f} s", tuple(p[:2]), textcoords="offset points", xytext=(5, 5), fontsize=8)
    ax.set_xlabel("x (m, east)")
    ax.set_ylabel("y (m, north)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_title(f"{run.name}: trajectories of {run.n} agents")
    ax.legend(loc="best", fontsize=8)
    return fig


def _distribution(ax: Any, t: np.ndarray, values: np.ndarray, run: RunData, name: str) -> dict[str, np.ndarray]:
    """Median, 10-90 % band and min-max envelope over agents of (T, N) ``values`` on ``ax``.

    Swarms of at most ``INDIVIDUAL_LINES`` agents also get one thin line per agent in its colour
    (gid ``<name>_agent<i>``). Returns the bands.
    """
    b = bands(values)
    if run.n <= INDIVIDUAL_LINES:
        colors = _mpl_colors(run.n)
        for i in range(run.n):
            ax.plot(t, values[:, i], color=colors[i], linewidth=0.7, alpha=0.85, zorder=3,
                    gid=f"{name}_agent{i}", label=f"agent {i}")
    ax.fill_between(t, b["min"], b["max"], color=BAND_COLOR, alpha=0.12, linewidth=0, label="min-max",
                    gid=f"{name}_envelope")
    ax.fill_between(t, b["p10"], b["p90"], color=BAND_COLOR, alpha=0.3, linewidth=0, label="10-90 %",
                    gid=f"{name}_band")
    ax.plot(t, b["median"], color=MEDIAN_COLOR, linewidth=1.8, zorder=4, label="median", gid=f"{name}_median")
    return b


def _limit(ax: Any, limit: float, name: str, label: str) -> None:
    ax.axhline(limit, color=LIMIT_COLOR, linestyle="--", linewidth=1.2, label=label, gid=f"{name}_limit")


def safety_figure(run: RunData) -> Any:
    """Nearest-neighbour distance (top) and obstacle clearance (bottom) over agents and time: the
    distribution, the minimum (the monitor's series when known) and the limits."""
    from matplotlib.figure import Figure

    series = safety_series(run)
    per_agent = {"separation": nearest_neighbour(run), "clearance": agent_clearance(run)}
    with_obstacles = bool(run.obstacles)
    fig = Figure(figsize=(9, 6.5 if with_obstacles else 4), layout="constrained")
    axes = fig.subplots(2 if with_obstacles else 1, 1, sharex=True, squeeze=False)[:, 0]
    panels = [(axes[0], "separation", series["min_separation"], run.min_separation_limit,
               "nearest neighbour (m)", "min separation")]
    if with_obstacles:
        panels.append((axes[1], "clearance", series["min_clearance"], run.min_clearance_limit,
                       "obstacle clearance (m)", "min clearance"))
    for ax, name, minimum, limit, label, min_label in panels:
        values = per_agent[name]
        if np.isfinite(values).any():
            _distribution(ax, run.t, values, run, name)
            finite = np.isfinite(minimum)
            ax.plot(series["t"], np.where(finite, minimum, np.nan), color="k", linewidth=1.4, linestyle=":",
                    zorder=5, label=min_label, gid=f"{name}_min")
            below = finite & (minimum < limit)
            if below.any():
                ax.fill_between(series["t"], 0, 1, where=below, color=LIMIT_COLOR, alpha=0.15,
                                transform=ax.get_xaxis_transform(), label="below limit")
        else:
            ax.text(0.5, 0.5, f"no {'obstacles' if name == 'clearance' else 'pairs'}", transform=ax.transAxes,
                    ha="center", va="center")
        _limit(ax, limit, name, f"limit {limit:g} m")
        ax.set_ylabel(label)
        ax.legend(**LEGEND)
    axes[-1].set_xlabel("time (s)")
    what = "agent and obstacle" if with_obstacles else "agent (no obstacles)"
    axes[0].set_title(f"{run.name}: distance to the nearest {what}, over {run.n} agents")
    return fig


def speed_figure(run: RunData) -> Any:
    """Speed of the healthy agents over time: median and bands, published speed limits."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4), layout="constrained")
    ax = fig.add_subplot()
    speed = agent_speed(run)
    _distribution(ax, run.t, speed, run, "speed")
    for key, limit in run.speed_limits().items():
        _limit(ax, limit, "speed", f"{key} {limit:g} m/s")
    peak = np.nanmax(speed) if np.isfinite(speed).any() else 0.0
    ax.set_xlabel("time (s)")
    ax.set_ylabel("speed (m/s)")
    ax.set_ylim(bottom=0)
    ax.set_title(f"{run.name}: speed of the healthy agents (max {peak:.2f} m/s)")
    ax.legend(**LEGEND)
    return fig


def altitude_figure(run: RunData) -> Any:
    """Altitude z of every agent over time: median and bands (failed agents included: they hover)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4), layout="constrained")
    ax = fig.add_subplot()
    z = np.asarray(run.pos[..., 2], float)
    _distribution(ax, run.t, z, run, "altitude")
    ax.axhline(0.0, color="0.3", linewidth=0.8, gid="ground")
    for agent, t, p in run.failures():
        ax.plot([t], [p[2]], marker="x", color=FAILED_COLOR, markersize=8, mew=2, gid=f"failed{agent}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("altitude z (m)")
    ax.set_title(f"{run.name}: altitude (range {z.min():.2f} to {z.max():.2f} m)")
    ax.legend(**LEGEND)
    return fig


FIGURES = {"trajectories": trajectory_figure, "safety": safety_figure, "speed": speed_figure,
           "altitude": altitude_figure}
"""The pictures of ``output.plots=true``, by file stem."""


def _png(fig: Any) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    return buffer.getvalue()


# -- animation ----------------------------------------------------------------------------------
def comm_edges(xy: np.ndarray, healthy: np.ndarray, comm_range: float) -> np.ndarray:
    """(E, 2) index pairs of healthy agents within ``comm_range`` of each other (one frame)."""
    from scipy.spatial import cKDTree

    idx = np.flatnonzero(healthy)
    if len(idx) < 2 or not np.isfinite(comm_range):
        return np.empty((0, 2), dtype=int)
    pairs = cKDTree(xy[idx]).query_pairs(comm_range, output_type="ndarray")
    return idx[pairs]


def write_animation(run: RunData, run_dir: Path, frames: int = 150, edges: bool = False,
                    progress: Any = None) -> Path:
    """animation.mp4 when an ffmpeg writer exists, else animation.gif; returns the path.

    ``progress``: a :class:`swarmscene.views.summary.Progress` told of every frame written (None: quiet).
    """
    from matplotlib import animation
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    keys = np.unique(np.linspace(0, len(run.t) - 1, min(frames, len(run.t))).round().astype(int))
    xy = run.pos[..., :2]
    lo, hi = xy.reshape(-1, 2).min(axis=0), xy.reshape(-1, 2).max(axis=0)
    pad = 0.05 * max(hi - lo) + 0.5
    aspect = (hi[1] - lo[1] + 2 * pad) / (hi[0] - lo[0] + 2 * pad)
    fig = Figure(figsize=(7, float(np.clip(7 * aspect, 2.5, 7)) + 0.8), layout="constrained")
    ax = fig.add_subplot()
    _draw_obstacles(ax, run.obstacles)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, east)")
    ax.set_ylabel("y (m, north)")
    edge_lines = LineCollection([], colors="tab:green", linewidths=0.5, alpha=0.6)
    ax.add_collection(edge_lines)
    colors = _mpl_colors(run.n)
    trails = LineCollection([], colors=colors, linewidths=0.6, alpha=0.7)
    ax.add_collection(trails)
    dots = ax.scatter(xy[0, :, 0], xy[0, :, 1], s=20, color=colors, zorder=3)
    crosses = ax.scatter([], [], s=70, marker="x", color=FAILED_COLOR, linewidths=2, zorder=4)
    title = ax.set_title("")
    trail_len = max(1, len(run.t) // 20)

    def draw(k: int) -> tuple[Any, ...]:
        start = max(0, k - trail_len)
        trails.set_segments([xy[start : k + 1, i] for i in range(run.n)])
        dots.set_offsets(xy[k])
        crosses.set_offsets(xy[k][~run.healthy[k]].reshape(-1, 2))
        if edges:
            pairs = comm_edges(xy[k], run.healthy[k], run.comm_range)
            edge_lines.set_segments(xy[k][pairs])
        title.set_text(f"{run.name}  t = {run.t[k]:.1f} s")
        return dots, crosses, trails, edge_lines, title

    draw(keys[-1])
    engine = fig.get_layout_engine()  # the figure's "constrained" one
    assert engine is not None
    engine.execute(fig)  # lay out once (widest title), then keep it for every frame
    fig.set_layout_engine("none")
    anim = animation.FuncAnimation(fig, draw, frames=keys, blit=False)
    use_mp4 = animation.writers.is_available("ffmpeg")
    suffix = "mp4" if use_mp4 else "gif"
    writer = animation.FFMpegWriter(fps=15) if use_mp4 else animation.PillowWriter(fps=15)
    target = Path(run_dir) / f"animation.{suffix}"
    report = None
    if progress is not None:
        def report(frame: int, total: int) -> None:
            progress.update(frame + 1, len(keys), f"{target.name}: frame")
    try:
        # matplotlib (and ffmpeg) open the file by name: a private directory, no planted link
        with private_temp_dir(run_dir, target.name) as tmp:
            anim.save(tmp, writer=writer, dpi=80, progress_callback=report)
            publish(tmp, target)  # atomic, like every other output
    finally:
        if progress is not None:
            progress.close()
    return target


def write_run_plots(run_dir: Path, sim: Any = None, result: Any = None, plots: bool | None = None,
                    animation: bool | None = None) -> list[Path]:
    """Write the pictures the run's ``output`` options ask for; returns the files written.

    The animation reports its progress on a terminal as ``output.progress`` allows.
    """
    from .summary import Progress

    run_dir = Path(run_dir)
    run = from_simulation(sim, result) if sim is not None else load_run(run_dir)
    output = run.config.get("output", {})
    plots = output.get("plots", True) if plots is None else plots
    animation = output.get("animation", False) if animation is None else animation
    written = []
    if plots:
        for name, make in FIGURES.items():
            path = run_dir / f"{name}.png"
            atomic_write_bytes(path, _png(make(run)))
            written.append(path)
    if animation:
        progress = Progress.maybe(str(output.get("progress", "auto")), delay=0.0)
        written.append(write_animation(run, run_dir, int(output.get("animation_frames", 150)),
                                       bool(output.get("comm_edges", False)), progress=progress))
    return written
