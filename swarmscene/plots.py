"""Per-run pictures (the ``plots`` extra, matplotlib): what a person would otherwise dig out of arrays.

On ``output.plots=true`` a run directory gets:

    trajectories.png  top-down paths (x east, y north) with the obstacles, start and end points,
                      and every failed vehicle marked where it failed
    safety.png        minimum separation and minimum clearance over time against their limits
                      (``safety.min_separation``, ``safety.min_clearance``), violations shaded
    speed.png         every agent's speed over time (failed agents dashed)

and on ``output.animation=true`` ``animation.mp4`` (when matplotlib finds ffmpeg) or
``animation.gif``: the top-down view over time, trails, failed vehicles, and with
``output.comm_edges=true`` the communication edges (healthy pairs within ``comm.range``).

Everything works from a run directory alone (config.yaml + trajectory.npz), so
``swarmscene-report RUN_DIR --run-plots`` redraws them later. Inside a run the safety monitor's
series (every guidance tick) are used; from a directory they are recomputed at the recorded frames.
Only the object-oriented matplotlib API is used (no pyplot state, no display needed).
"""

from __future__ import annotations

import io
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .core.outputs import atomic_write_bytes

HEALTHY_COLOR = "tab:blue"
FAILED_COLOR = "tab:red"
LIMIT_COLOR = "tab:red"
OBSTACLE_COLOR = "0.6"


@dataclass
class RunData:
    """What the pictures need from one run (see :func:`load_run`)."""

    config: dict[str, Any]
    t: np.ndarray  # (T,) s
    pos: np.ndarray  # (T, N, 3) m
    vel: np.ndarray  # (T, N, 3) m/s
    healthy: np.ndarray  # (T, N) bool
    obstacles: list[Any] = field(default_factory=list)  # shapely polygons
    series: dict[str, np.ndarray] | None = None  # the safety monitor's, when known

    @property
    def n(self) -> int:
        return self.pos.shape[1]

    @property
    def min_separation_limit(self) -> float:
        return float(self.config.get("safety", {}).get("min_separation", 0.0))

    @property
    def min_clearance_limit(self) -> float:
        return float(self.config.get("safety", {}).get("min_clearance", 0.0))

    @property
    def comm_range(self) -> float:
        return float(self.config.get("comm", {}).get("range", np.inf))

    def failures(self) -> list[tuple[int, float, np.ndarray]]:
        """(agent, time, position) of every agent that failed during the recorded run.

        The time is the scheduled event's (``events``) when one names the agent; the frames only
        bound it (an event at the start of a tick shows in the frame recorded at its end).
        """
        scheduled: dict[int, list[float]] = {}
        for event in self.config.get("events") or []:
            if event.get("kind") == "hover":
                for agent in event.get("agents", []):
                    scheduled.setdefault(int(agent), []).append(float(event["at"]))
        out = []
        for agent in np.flatnonzero(~self.healthy.all(axis=0)):
            k = int(np.argmax(~self.healthy[:, agent]))
            times = [at for at in scheduled.get(int(agent), []) if at <= self.t[k] + 1e-9]
            when = max(times) if times else float(self.t[max(k - 1, 0)])
            out.append((int(agent), when, self.pos[k, agent]))
        return out


def _obstacles(config: dict[str, Any]) -> list[Any]:
    from .core.config import EnvironmentConfig
    from .core.geometry import build_obstacles

    env = EnvironmentConfig.model_validate(config.get("environment") or {})
    obstacles, _ = build_obstacles(env)
    return obstacles


def load_run(run_dir: Path) -> RunData:
    """Read a run directory's config.yaml and trajectory.npz."""
    import yaml

    run_dir = Path(run_dir)
    config = yaml.safe_load((run_dir / "config.yaml").read_text()) or {}
    path = run_dir / "trajectory.npz"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no trajectory recorded (output.trajectory=false?)")
    with np.load(path) as traj:
        arrays = {k: traj[k] for k in ("t", "pos", "vel", "healthy")}
    return RunData(config=config, obstacles=_obstacles(config), **arrays)


def from_simulation(sim: Any, result: Any) -> RunData:
    """The same data straight from a finished simulation (no re-reading, full-rate series)."""
    traj = result.trajectory
    if not traj:
        raise ValueError("no trajectory recorded (output.trajectory=false)")
    return RunData(
        config=sim.scenario.data,
        t=traj["t"], pos=traj["pos"], vel=traj["vel"], healthy=traj["healthy"],
        obstacles=list(sim.environment.obstacles),
        series=result.series,
    )


def safety_series(run: RunData) -> dict[str, np.ndarray]:
    """Min separation and min clearance over time: the monitor's series, or recomputed per frame."""
    if run.series is not None:
        return {k: np.asarray(run.series[k]) for k in ("t", "min_separation", "min_clearance")}
    from scipy.spatial.distance import pdist

    pos = run.pos
    if run.n > 1:
        sep = np.array([pdist(frame).min() for frame in pos])  # one C call per frame
    else:
        sep = np.full(len(pos), np.inf)
    clear = np.full(len(pos), np.inf)
    if run.obstacles:
        from .core.environment import Environment

        env = Environment(run.obstacles)
        clear = env.clearance(pos.reshape(-1, 3)).reshape(pos.shape[:2]).min(axis=1)
    return {"t": run.t, "min_separation": sep, "min_clearance": clear}


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


def trajectory_figure(run: RunData) -> Any:
    """Top-down paths, obstacles, start (circle) and end (square) points, failures (red x)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 6), layout="constrained")
    ax = fig.add_subplot()
    _draw_obstacles(ax, run.obstacles)
    failed = {agent for agent, _, _ in run.failures()}
    xy = run.pos[..., :2]
    for i in range(run.n):
        color = FAILED_COLOR if i in failed else HEALTHY_COLOR
        ax.plot(xy[:, i, 0], xy[:, i, 1], color=color, linewidth=0.8, alpha=0.8, gid=f"agent{i}")
    ax.scatter(xy[0, :, 0], xy[0, :, 1], s=12, facecolors="none", edgecolors="k", label="start")
    ax.scatter(xy[-1, :, 0], xy[-1, :, 1], s=12, marker="s", color="k", label="end")
    fails = run.failures()
    if fails:
        where = np.array([p[:2] for _, _, p in fails])
        ax.scatter(where[:, 0], where[:, 1], s=80, marker="x", color=FAILED_COLOR, linewidths=2,
                   label=f"failed ({len(fails)})", zorder=5, gid="failed")
        for agent, t, p in fails:
            ax.annotate(f"{agent} @ {t:.1f} s", p[:2], textcoords="offset points", xytext=(5, 5), fontsize=8)
    ax.set_xlabel("x (m, east)")
    ax.set_ylabel("y (m, north)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_title(f"{run.config.get('name', 'run')}: trajectories of {run.n} agents")
    ax.legend(loc="best", fontsize=8)
    return fig


def safety_figure(run: RunData) -> Any:
    """Separation (top) and clearance (bottom) over time with their limits as dashed red lines."""
    from matplotlib.figure import Figure

    series = safety_series(run)
    fig = Figure(figsize=(8, 6), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    panels = (
        (top, series["min_separation"], run.min_separation_limit, "min separation (m)", "separation"),
        (bottom, series["min_clearance"], run.min_clearance_limit, "min clearance (m)", "clearance"),
    )
    for ax, values, limit, label, name in panels:
        finite = np.isfinite(values)
        if finite.any():
            ax.plot(series["t"], np.where(finite, values, np.nan), color=HEALTHY_COLOR, label=label.split(" (")[0])
            if (finite & (values < limit)).any():
                ax.fill_between(series["t"], 0, 1, where=finite & (values < limit), color=LIMIT_COLOR,
                                alpha=0.15, transform=ax.get_xaxis_transform(), label="below limit")
        else:
            ax.text(0.5, 0.5, f"no {'obstacles' if name == 'clearance' else 'pairs'}", transform=ax.transAxes,
                    ha="center", va="center")
        ax.axhline(limit, color=LIMIT_COLOR, linestyle="--", label=f"limit {limit:g} m", gid=f"{name}_limit")
        ax.set_ylabel(label)
        ax.legend(loc="best", fontsize=8)
    bottom.set_xlabel("time (s)")
    top.set_title(f"{run.config.get('name', 'run')}: safety over time")
    return fig


def speed_figure(run: RunData) -> Any:
    """Every agent's speed over time; failed agents dashed."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.add_subplot()
    speed = np.linalg.norm(run.vel, axis=2)
    failed = {agent for agent, _, _ in run.failures()}
    for i in range(run.n):
        ax.plot(run.t, speed[:, i], linewidth=0.8, color=FAILED_COLOR if i in failed else None,
                linestyle="--" if i in failed else "-", alpha=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("speed (m/s)")
    ax.set_title(f"{run.config.get('name', 'run')}: speed of each agent (max {speed.max():.2f} m/s)")
    return fig


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


def write_animation(run: RunData, run_dir: Path, frames: int = 150, edges: bool = False) -> Path:
    """animation.mp4 when an ffmpeg writer exists, else animation.gif; returns the path."""
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
    trails = LineCollection([], colors="0.5", linewidths=0.6)
    ax.add_collection(trails)
    dots = ax.scatter(xy[0, :, 0], xy[0, :, 1], s=20)
    title = ax.set_title("")
    trail_len = max(1, len(run.t) // 20)

    def draw(k: int) -> tuple[Any, ...]:
        start = max(0, k - trail_len)
        trails.set_segments([xy[start : k + 1, i] for i in range(run.n)])
        dots.set_offsets(xy[k])
        dots.set_color(np.where(run.healthy[k], HEALTHY_COLOR, FAILED_COLOR))
        if edges:
            pairs = comm_edges(xy[k], run.healthy[k], run.comm_range)
            edge_lines.set_segments(xy[k][pairs])
        title.set_text(f"{run.config.get('name', 'run')}  t = {run.t[k]:.1f} s")
        return dots, trails, edge_lines, title

    draw(keys[-1])
    fig.get_layout_engine().execute(fig)  # lay out once (widest title), then keep it for every frame
    fig.set_layout_engine("none")
    anim = animation.FuncAnimation(fig, draw, frames=keys, blit=False)
    use_mp4 = animation.writers.is_available("ffmpeg")
    suffix = "mp4" if use_mp4 else "gif"
    writer = animation.FFMpegWriter(fps=15) if use_mp4 else animation.PillowWriter(fps=15)
    target = Path(run_dir) / f"animation.{suffix}"
    fd, tmp = tempfile.mkstemp(dir=run_dir, prefix=".animation.", suffix=f".{suffix}")
    os.close(fd)
    try:
        anim.save(tmp, writer=writer, dpi=80)
        os.replace(tmp, target)  # atomic, like every other output
    finally:
        Path(tmp).unlink(missing_ok=True)
    return target


def write_run_plots(run_dir: Path, sim: Any = None, result: Any = None, plots: bool | None = None,
                    animation: bool | None = None) -> list[Path]:
    """Write the pictures the run's ``output`` options ask for; returns the files written."""
    run_dir = Path(run_dir)
    run = from_simulation(sim, result) if sim is not None else load_run(run_dir)
    output = run.config.get("output", {})
    plots = output.get("plots", True) if plots is None else plots
    animation = output.get("animation", False) if animation is None else animation
    written = []
    if plots:
        for name, make in (("trajectories", trajectory_figure), ("safety", safety_figure), ("speed", speed_figure)):
            path = run_dir / f"{name}.png"
            atomic_write_bytes(path, _png(make(run)))
            written.append(path)
    if animation:
        written.append(write_animation(run, run_dir, int(output.get("animation_frames", 150)),
                                       bool(output.get("comm_edges", False))))
    return written
