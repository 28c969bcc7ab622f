"""Replay in a 3-D viewer: export a run to a Rerun recording (``replay.rrd``; the ``rerun`` extra).

On ``output.rerun=true`` (or ``swarmscene-report RUN_DIR --rerun``) the run directory gets
``replay.rrd``; open it with ``rerun replay.rrd`` (the viewer ships with rerun-sdk). Entities,
world frame (x east, y north, z up, metres), timeline ``sim_time`` (seconds):

    world/obstacles        obstacle footprints, outlined at the ground and at the flight ceiling
    world/agents           one point per agent, blue healthy, red failed (radius: half the
                           separation limit, so touching spheres mean a separation violation)
    world/trails           each agent's last few seconds of path
    world/exclusion        an exclusion zone around every failed vehicle: a circle of the CEM
                           planned exclusion radius a_p = a_f + delta + eps when the avoidance is
                           ``cem``, else of ``safety.min_separation``
    world/comm_edges       communication edges: healthy pairs within ``comm.range``

Time-varying entities are sent as columns (one ``send_columns`` call per entity), not frame by
frame, so exporting long runs stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .plots import RunData, comm_edges, from_simulation, load_run

TIMELINE = "sim_time"
HEALTHY_RGB = (31, 119, 180)
FAILED_RGB = (214, 39, 40)
CIRCLE_POINTS = 48


def exclusion_radius(config: dict[str, Any]) -> float:
    """Radius of the zone drawn around a failed vehicle (see the module docstring), m."""
    avoidance = config.get("avoidance") or {}
    if avoidance.get("name") == "cem" and {"a_f", "delta", "eps"} <= set(avoidance):
        return float(avoidance["a_f"]) + float(avoidance["delta"]) + float(avoidance["eps"])
    return float((config.get("safety") or {}).get("min_separation", 0.5))


def _circle(center: np.ndarray, radius: float) -> np.ndarray:
    angle = np.linspace(0.0, 2.0 * np.pi, CIRCLE_POINTS + 1)
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=1) * radius
    return ring + center


def _ceiling(run: RunData) -> float:
    top = float(run.pos[..., 2].max()) if run.pos.size else 1.0
    return max(top + 0.5, 1.0)


def obstacle_strips(run: RunData) -> list[np.ndarray]:
    """Each obstacle's outline at z = 0 and at the ceiling, with the vertical corner edges."""
    strips = []
    top = _ceiling(run)
    for geom in run.obstacles:
        for poly in getattr(geom, "geoms", [geom]):
            ring = np.asarray(poly.exterior.coords)[:, :2]
            for z in (0.0, top):
                strips.append(np.column_stack([ring, np.full(len(ring), z)]))
            for x, y in ring[:-1]:
                strips.append(np.array([[x, y, 0.0], [x, y, top]]))
    return strips


def _frames(run: RunData, every: int) -> np.ndarray:
    return np.arange(0, len(run.t), max(1, every))


def export(run: RunData, path: Path, every: int = 1, trail_seconds: float = 3.0) -> Path:
    """Write ``path`` (.rrd) from a run's data; returns the path."""
    import rerun as rr

    path = Path(path)
    rec = rr.RecordingStream("swarmscene", recording_id=f"{run.config.get('name', 'run')}")
    rec.save(str(path))
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    strips = obstacle_strips(run)
    if strips:
        rec.log("world/obstacles", rr.LineStrips3D(strips, colors=[(150, 150, 150)]), static=True)

    frames = _frames(run, every)
    times = run.t[frames]
    index = [rr.TimeColumn(TIMELINE, duration=times)]
    n = run.n
    radius = 0.5 * float((run.config.get("safety") or {}).get("min_separation", 0.5))
    colors = np.where(run.healthy[frames][..., None], HEALTHY_RGB, FAILED_RGB).astype(np.uint8)
    rec.send_columns(
        "world/agents",
        indexes=index,
        columns=rr.Points3D.columns(
            positions=run.pos[frames].reshape(-1, 3),
            colors=colors.reshape(-1, 3),
            radii=np.full(n * len(frames), radius),
        ).partition([n] * len(frames)),  # N points per frame
    )
    # Trails and the other time-varying shapes are logged per recorded frame on the timeline.
    dt = float(np.median(np.diff(run.t))) if len(run.t) > 1 else 1.0
    trail = max(1, int(round(trail_seconds / dt)))
    zone = exclusion_radius(run.config)
    comm_range = run.comm_range
    for k in frames:
        rec.set_time(TIMELINE, duration=float(run.t[k]))
        start = max(0, k - trail)
        rec.log("world/trails", rr.LineStrips3D(np.transpose(run.pos[start : k + 1], (1, 0, 2)), radii=0.02))
        failed = np.flatnonzero(~run.healthy[k])
        rec.log("world/exclusion", rr.LineStrips3D([_circle(run.pos[k, i], zone) for i in failed],
                                                   colors=[FAILED_RGB]))
        pairs = comm_edges(run.pos[k, :, :2], run.healthy[k], comm_range)
        rec.log("world/comm_edges", rr.LineStrips3D(run.pos[k][pairs], colors=[(44, 160, 44)], radii=0.01))
    rec.flush()
    rec.disconnect()
    return path


def export_rerun(run_dir: Path, sim: Any = None, result: Any = None, every: int | None = None) -> Path:
    """``replay.rrd`` in ``run_dir``, from a finished simulation or from the directory's files.

    ``every`` thins the frames for the per-frame shapes (default: at most ~600 frames).
    """
    run_dir = Path(run_dir)
    run = from_simulation(sim, result) if sim is not None else load_run(run_dir)
    if every is None:
        every = max(1, len(run.t) // 600)
    target = run_dir / "replay.rrd"
    tmp = run_dir / ".replay.rrd.tmp"
    export(run, tmp, every=every)
    tmp.replace(target)  # atomic, like every other output
    return target
