"""Replay in a 3-D viewer: export a run to a Rerun recording (``replay.rrd``; the ``rerun`` extra).

On ``output.rerun=true`` (or ``swarmscene-report RUN_DIR --rerun``, or
``python -m swarmscene.views.replay RUN_DIR``) the run directory gets ``replay.rrd``; open it with
``rerun replay.rrd`` (the viewer ships with rerun-sdk), or stream it to a viewer that is already
running with ``python -m swarmscene.views.replay RUN_DIR --connect rerun+http://HOST:9876/proxy``.

Every run is its own recording: the recording id is ``<name>-seed<seed>-<hash>`` with the first 12
hex digits of the manifest's ``config_hash`` (:func:`recording_id`), so two seeds of one scenario
open as two recordings side by side, and the same run exported twice replaces itself. The
recording's name is ``<name> seed <seed>``.

Entities, world frame (x east, y north, z up, metres), timeline ``sim_time`` (seconds):

    world/obstacles        obstacle prisms from the ground to above the highest flight level:
                           translucent walls and roof (``world/obstacles/solid``) and outlines
    world/agents           one point per agent in its colour (``plots.agent_colors``, the colours of
                           the pictures and the animation), labelled with its index ("3 failed"
                           once failed; up to 500 agents, drawn up to 30); radius half the
                           separation limit, so touching spheres mean a separation violation
                           (a quarter of that with attitude boxes)
    world/bodies           with attitude dynamics (``quat`` in the trajectory): a flat box per
                           vehicle oriented by its attitude, in the agent's colour, red once failed
    world/body_axes        ... and its body axes x (red), y (green), z (blue, the thrust axis)
    world/failures         a red marker where each vehicle failed, from the time it failed
    world/trails           each agent's last few seconds of path, in its colour
    world/exclusion        a circle around every failed vehicle: of the avoidance's published
                           planned exclusion radius (the ``cem.a_p`` metric, a_p = a_f + delta +
                           eps) with ``avoidance=cem``, none when a cem run lacks that metric; of
                           ``safety.separation_limit`` with any other avoidance
    world/comm_edges       communication edges: healthy pairs within ``comm.range``
    safety/separation/min  minimum pairwise distance over time (the safety monitor's series, every
                           guidance tick, inside a run; recomputed at the recorded frames from a
                           directory), ``safety/separation/limit`` (``safety.separation_limit``) and
                           ``safety/separation/events``, a marker on the series at every event
    safety/clearance/min   minimum obstacle clearance and ``safety/clearance/limit`` (with
                           obstacles only)
    events                 a text log line per event: failures and radio losses (``events``), the
                           first violation of each safety condition (``violations.*`` metrics) and
                           the end of the run (``stop_reason``)

The recording carries a default layout (blueprint): the 3-D world beside the separation and
clearance series and the event log.

Time-varying entities are sent as columns (one ``send_columns`` call per entity), not frame by
frame, so exporting long runs stays fast. Read a recording back in Python with
:func:`read_recordings` (the extra installs what that needs: rerun-sdk's ``catalog`` extra).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from ..runs.outputs import private_temp_dir, publish
from .plots import RunData, agent_colors, comm_edges, from_simulation, load_run, safety_limit, safety_series

TIMELINE = "sim_time"
APPLICATION_ID = "swarmscene"
FAILED_RGB = (214, 39, 40)
LIMIT_RGB = (214, 39, 40)
EDGE_RGB = (44, 160, 44)
OBSTACLE_RGB = (150, 150, 150)
AXIS_RGB = np.array([(230, 60, 60), (60, 200, 60), (60, 110, 240)], dtype=np.uint8)
CIRCLE_POINTS = 48
HASH_DIGITS = 12
"""Hex digits of the config hash in the recording id."""
MAX_LABELLED = 500
"""Agents are labelled (index, "failed") in swarms up to this size."""
SHOWN_LABELS = 30
"""... and the labels drawn in the 3-D view up to this size (else on hover only)."""
PLANNED_EXCLUSION = {"cem": "cem.a_p"}
"""Avoidances that plan an exclusion radius around failed vehicles, and the metric holding it."""


def recording_id(run: RunData) -> str:
    """``<name>-seed<seed>-<first 12 hex digits of the config hash>``: unique per run config."""
    digest = (run.config_hash or "")[:HASH_DIGITS] or "nohash"
    return f"{run.name}-seed{run.seed}-{digest}"


def exclusion_radius(config: dict[str, Any], metrics: dict[str, Any]) -> float | None:
    """Radius of the zone drawn around a failed vehicle (module docstring), m; None: draw none.

    A value an avoidance derives (CEM's a_p) is read from the run's metrics, never re-derived from
    its YAML: the app layer does not know a plugin's defaults.
    """
    avoidance = (config.get("avoidance") or {}).get("name")
    if avoidance in PLANNED_EXCLUSION:
        value = metrics.get(PLANNED_EXCLUSION[avoidance])
        return float(value) if isinstance(value, (int, float)) and np.isfinite(value) else None
    return safety_limit(config, "separation_limit") or 0.5


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


def obstacle_mesh(run: RunData) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3), triangles (F, 3)) of the obstacle prisms: walls and roof."""
    import shapely

    top = _ceiling(run)
    verts: list[np.ndarray] = []
    tris: list[np.ndarray] = []
    base = 0
    for geom in run.obstacles:
        for poly in getattr(geom, "geoms", [geom]):
            ring = np.asarray(poly.exterior.coords)[:-1, :2]
            m = len(ring)
            walls = np.concatenate([np.column_stack([ring, np.zeros(m)]), np.column_stack([ring, np.full(m, top)])])
            i = np.arange(m)
            j = (i + 1) % m
            tris.append(base + np.concatenate([np.stack([i, j, m + j], 1), np.stack([i, m + j, m + i], 1)]))
            verts.append(walls)
            base += 2 * m
            roof = shapely.constrained_delaunay_triangles(poly)
            corners = np.array([np.asarray(t.exterior.coords)[:3, :2] for t in roof.geoms]).reshape(-1, 2)
            verts.append(np.column_stack([corners, np.full(len(corners), top)]))
            tris.append(base + np.arange(len(corners)).reshape(-1, 3))
            base += len(corners)
    if not verts:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(verts), np.concatenate(tris)


def _frames(run: RunData, every: int) -> np.ndarray:
    return np.arange(0, len(run.t), max(1, every))


def quat_wxyz_to_xyzw(quat: np.ndarray) -> np.ndarray:
    """The trajectory's (w, x, y, z) quaternions in Rerun's (x, y, z, w) order."""
    return np.concatenate([quat[..., 1:], quat[..., :1]], axis=-1)


def rotation_matrices(quat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) body-to-world rotations of unit quaternions (..., 4) in (w, x, y, z)."""
    q = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def event_text(name: Any, agents: Any) -> str:
    """The event log's line for a scheduled event of kind ``name`` (``hover``, ``comm_loss``) of ``agents``."""
    what = {"hover": "failed (hovers in place)", "comm_loss": "lost its radio"}.get(str(name), str(name))
    return f"agent {', '.join(str(a) for a in agents)}: {what}"


def events(run: RunData) -> list[tuple[float, str, str]]:
    """(time s, level, text) of every event of the run, in time order (module docstring); an event's
    kind is its ``name``, or its ``kind`` in a run recorded until 0.6.0."""
    from ..core.spelling import recorded_name

    out: list[tuple[float, str, str]] = []
    for event in run.config.get("events") or []:
        if float(event["at"]) <= float(run.t[-1]) + 1e-9:
            out.append((float(event["at"]), "WARN", event_text(recorded_name(event), event.get("agents", []))))
    out += end_events(run)
    return sorted(out, key=lambda e: e[0])


def end_events(run: RunData) -> list[tuple[float, str, str]]:
    """(time s, level, text) known at the end of a run: each safety condition's first violation
    (``violations.*`` metrics) and the end (``stop_reason``)."""
    out: list[tuple[float, str, str]] = []
    for condition in ("separation", "clearance", "connectivity"):
        first = run.metrics.get(f"violations.{condition}.first_time")
        if isinstance(first, (int, float)):
            agents = run.metrics.get(f"violations.{condition}.agents") or []
            out.append((float(first), "ERROR", f"{condition} first violated (agents {agents})"))
    reason = run.metrics.get("stop_reason")
    if reason is not None:
        out.append((float(run.t[-1]), "INFO", f"run ended: {reason}"))
    return out


def blueprint(run: RunData) -> Any:
    """The default layout: the 3-D world, beside it the safety series and the event log."""
    import rerun.blueprint as rrb

    series = [rrb.TimeSeriesView(origin="safety/separation", name="separation (m)")]
    if run.obstacles:
        series.append(rrb.TimeSeriesView(origin="safety/clearance", name="clearance (m)"))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name=f"{run.name} seed {run.seed}"),
            rrb.Vertical(*series, rrb.TextLogView(origin="events", name="events"), row_shares=[2] * len(series) + [1]),
            column_shares=[3, 2],
        ),
        rrb.BlueprintPanel(state="expanded"),  # lists the recordings: one per run (seed)
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=TIMELINE),
    )


def log_static(rec: Any, run: RunData) -> None:
    """The static scene: the world's axes, the obstacles, the series' styles (the live view's too)."""
    import rerun as rr

    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    strips = obstacle_strips(run)
    if strips:
        rec.log("world/obstacles", rr.LineStrips3D(strips, colors=[OBSTACLE_RGB]), static=True)
        verts, tris = obstacle_mesh(run)
        rec.log("world/obstacles/solid", rr.Mesh3D(vertex_positions=verts, triangle_indices=tris,
                                                   albedo_factor=(150, 150, 150, 90)), static=True)
    for name in ("separation", "clearance"):
        rec.log(f"safety/{name}/min", rr.SeriesLines(colors=[(31, 119, 180)], names=[f"min {name} (m)"]), static=True)
        rec.log(f"safety/{name}/limit", rr.SeriesLines(colors=[LIMIT_RGB], names=[f"{name} limit (m)"]), static=True)
    rec.log("safety/separation/events", rr.SeriesPoints(colors=[(0, 0, 0)], names=["event"], marker_sizes=[5.0]),
            static=True)


def log_agents(rec: Any, run: RunData, frames: np.ndarray) -> None:
    """Points (and with attitude, boxes and body axes) of every agent at every frame, as columns."""
    import rerun as rr

    n, f = run.n, len(frames)
    index = [rr.TimeColumn(TIMELINE, duration=run.t[frames])]
    half = 0.5 * run.min_separation_limit if run.min_separation_limit > 0 else 0.1
    # Without attitude a sphere of half the separation limit (touching spheres: a violation); with
    # it a small point, so the oriented body and its axes stay visible.
    radius = half if run.quat is None else 0.25 * half
    healthy = run.healthy[frames]
    palette = agent_colors(n)
    colors = np.broadcast_to(palette, (f, n, 3)).reshape(-1, 3)
    labelled: dict[str, Any] = {}
    if n <= MAX_LABELLED:  # a label per agent per frame: affordable for small swarms only
        names = np.array([str(i) for i in range(n)], dtype=object)
        labels = np.where(healthy, names, np.char.add(names.astype(str), " failed").astype(object)).reshape(-1)
        labelled = {"labels": labels.tolist(), "show_labels": np.full(n * f, n <= SHOWN_LABELS)}
    rec.send_columns(
        "world/agents", indexes=index,
        columns=rr.Points3D.columns(positions=run.pos[frames].reshape(-1, 3), colors=colors,
                                    radii=np.full(n * f, radius), **labelled).partition([n] * f),
    )
    if run.quat is None:
        return
    arm = 0.5 * half  # a vehicle's drawn half-width (a Crazyflie's arm is 4.6 cm: enlarged to be seen)
    body_colors = np.where(healthy[..., None], palette[None], np.array(FAILED_RGB, np.uint8)).reshape(-1, 3)
    quat = np.asarray(run.quat[frames], float)
    rec.send_columns(
        "world/bodies", indexes=index,
        columns=rr.Boxes3D.columns(centers=run.pos[frames].reshape(-1, 3),
                                   half_sizes=np.tile([arm, arm, 0.25 * arm], (n * f, 1)),
                                   quaternions=quat_wxyz_to_xyzw(quat).reshape(-1, 4),
                                   colors=body_colors).partition([n] * f),
    )
    rot = rotation_matrices(quat)  # (F, N, 3, 3); column k is body axis k in the world
    vectors = 1.8 * arm * np.swapaxes(rot, -1, -2)  # (F, N, 3 axes, 3)
    origins = np.repeat(np.asarray(run.pos[frames])[:, :, None, :], 3, axis=2)
    rec.send_columns(
        "world/body_axes", indexes=index,
        columns=rr.Arrows3D.columns(vectors=vectors.reshape(-1, 3), origins=origins.reshape(-1, 3),
                                    colors=np.tile(AXIS_RGB, (n * f, 1))).partition([3 * n] * f),
    )


def _log_safety(rec: Any, run: RunData) -> None:
    """Safety series, their limits (two points each, at the first and last time) and event markers."""
    import rerun as rr

    series = safety_series(run)
    t = np.asarray(series["t"], float)
    ends = [rr.TimeColumn(TIMELINE, duration=np.array([t[0], t[-1]]))]
    for name, limit in (("separation", run.min_separation_limit), ("clearance", run.min_clearance_limit)):
        values = np.asarray(series[f"min_{name}"], float)
        keep = np.isfinite(values)
        if not keep.any():
            continue  # no obstacles (or a single agent): no series
        rec.send_columns(f"safety/{name}/min", indexes=[rr.TimeColumn(TIMELINE, duration=t[keep])],
                         columns=rr.Scalars.columns(scalars=values[keep]))
        rec.send_columns(f"safety/{name}/limit", indexes=ends, columns=rr.Scalars.columns(scalars=[limit, limit]))
    marks = events(run)
    sep = np.asarray(series["min_separation"], float)
    if marks and np.isfinite(sep).any():
        at = np.array([m[0] for m in marks])
        k = np.clip(np.searchsorted(t, at - 1e-9), 0, len(t) - 1)
        value = np.where(np.isfinite(sep[k]), sep[k], np.nanmin(np.where(np.isfinite(sep), sep, np.nan)))
        rec.send_columns("safety/separation/events", indexes=[rr.TimeColumn(TIMELINE, duration=at)],
                         columns=rr.Scalars.columns(scalars=value))
    for when, level, text in marks:
        rec.set_time(TIMELINE, duration=when)
        rec.log("events", rr.TextLog(text, level=level))


def _log_frames(rec: Any, run: RunData, frames: np.ndarray, trail_seconds: float) -> None:
    """Trails, failure markers, exclusion circles and comm edges, logged per recorded frame."""
    dt = float(np.median(np.diff(run.t))) if len(run.t) > 1 else 1.0
    trail = max(1, int(round(trail_seconds / dt)))
    zone = exclusion_radius(run.config, run.metrics)
    palette = agent_colors(run.n)
    for agent, when, where in run.failures():
        log_failure(rec, agent, when, where)
    for k in frames:  # per frame, vectorised over agents
        rec.set_time(TIMELINE, duration=float(run.t[k]))
        log_scene(rec, run.pos[max(0, k - trail) : k + 1], run.healthy[k], zone, palette, run.comm_range)


def log_failure(rec: Any, agent: int, when: float, where: np.ndarray) -> None:
    """A red marker where ``agent`` failed, from the time it failed."""
    import rerun as rr

    rec.set_time(TIMELINE, duration=when)
    rec.log(f"world/failures/{agent}", rr.Points3D([where], colors=[FAILED_RGB], radii=[0.06],
                                                   labels=[f"{agent} failed @ {when:.1f} s"]))


def log_scene(rec: Any, recent: np.ndarray, healthy: np.ndarray, zone: float | None, palette: np.ndarray,
              comm_range: float) -> None:
    """At the time set on ``rec``: the trails (``recent`` (K, N, 3), the last K positions, the
    current one last), the exclusion circles around failed vehicles and the comm edges."""
    import rerun as rr

    now = recent[-1]
    rec.log("world/trails", rr.LineStrips3D(np.transpose(recent, (1, 0, 2)), radii=0.008, colors=palette))
    if zone is not None:
        rec.log("world/exclusion", rr.LineStrips3D([_circle(now[i], zone) for i in np.flatnonzero(~healthy)],
                                                   colors=[FAILED_RGB]))
    pairs = comm_edges(now[:, :2], healthy, comm_range)
    rec.log("world/comm_edges", rr.LineStrips3D(now[pairs], colors=[EDGE_RGB], radii=0.01))


def export(run: RunData, path: Path | None, every: int = 1, trail_seconds: float = 3.0,
           connect: str | None = None) -> Path | None:
    """Write ``path`` (.rrd) from a run's data and/or stream it to the viewer at ``connect``
    (a ``rerun+http://...`` address); returns ``path``."""
    import rerun as rr

    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id(run))
    sinks = ([rr.FileSink(str(path))] if path is not None else []) + ([rr.GrpcSink(connect)] if connect else [])
    if not sinks:
        raise ValueError("export needs a path or a viewer address to connect to")
    rec.set_sinks(*sinks, default_blueprint=blueprint(run))
    rec.send_recording_name(f"{run.name} seed {run.seed}")
    log_static(rec, run)
    frames = _frames(run, every)
    log_agents(rec, run, frames)
    _log_safety(rec, run)
    _log_frames(rec, run, frames, trail_seconds)
    rec.flush()
    rec.disconnect()
    return None if path is None else Path(path)


def export_rerun(run_dir: Path, sim: Any = None, result: Any = None, every: int | None = None,
                 connect: str | None = None) -> Path:
    """``replay.rrd`` in ``run_dir``, from a finished simulation or from the directory's files.

    ``every`` thins the frames for the per-frame shapes (default: at most ~600 frames);
    ``connect`` also streams the recording to a running viewer at that address.
    """
    run_dir = Path(run_dir)
    run = from_simulation(sim, result) if sim is not None else load_run(run_dir)
    if every is None:
        every = max(1, len(run.t) // 600)
    target = run_dir / "replay.rrd"
    # Rerun opens its file by name: a private directory, so no planted link is written through
    with private_temp_dir(run_dir, target.name) as tmp:
        export(run, tmp, every=every, connect=connect)
        publish(tmp, target)  # atomic, like every other output
    return target


def read_recordings(paths: list[Path], index: str | None = TIMELINE,
                    contents: str | list[str] = "/**") -> dict[str, Any]:
    """Read ``.rrd`` files back: {recording id: pandas DataFrame} (one row per time of ``index``,
    one column per entity and component, e.g. ``/world/agents:Points3D:positions``).

    Uses Rerun's local catalog server and DataFusion (both installed by the ``rerun`` extra).
    """
    import rerun as rr

    with rr.server.Server(datasets={"replay": [str(p) for p in paths]}) as server:
        dataset = server.client().get_dataset("replay")
        ids = sorted(dataset.segment_ids())
        frame: Any = dataset.filter_contents(contents).reader(index=index).to_pandas() if ids else None
    out = {}
    for rid in ids:
        rows = frame[frame["rerun_segment_id"] == rid]
        out[rid] = rows.sort_values(index).reset_index(drop=True) if index else rows.reset_index(drop=True)
    return out


def main(argv: list[str] | None = None) -> None:
    """``python -m swarmscene.views.replay RUN_DIR [RUN_DIR ...] [--connect URL] [--every K]``."""
    parser = argparse.ArgumentParser(prog="python -m swarmscene.views.replay", description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", nargs="+", type=Path, help="run directories (config.yaml + trajectory.npz)")
    parser.add_argument("--connect", metavar="URL", default=None,
                        help="also stream to a running viewer, e.g. rerun+http://127.0.0.1:9876/proxy")
    parser.add_argument("--every", type=int, default=None, help="keep every K-th frame (default: <= ~600 frames)")
    args = parser.parse_args(argv)
    if args.every is not None and args.every < 1:
        parser.exit(2, f"{parser.prog}: --every: must be an integer >= 1 (got {args.every})\n")
    from ..runs.rundir import RunFileError

    for run_dir in args.run_dirs:
        try:
            print(export_rerun(run_dir, every=args.every, connect=args.connect))
        except RunFileError as exc:  # a missing or damaged file of the run: one line naming it
            parser.exit(2, f"{parser.prog}: {exc}\n")
        except OSError as exc:  # the directory cannot be written (read-only, full disk)
            parser.exit(2, f"{parser.prog}: {run_dir}: cannot write replay.rrd ({exc.strerror or exc})\n")


if __name__ == "__main__":
    main()
