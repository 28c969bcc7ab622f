"""ROS 2 bags of a run, without ROS: ``output.mcap=true`` and ``python -m swarmscene.views.export RUN_DIR --mcap OUT``.

A bag is a rosbag2 folder: ``<name>_0.mcap`` (MCAP, ``ros2`` profile: CDR messages, ``ros2msg``
schemas) and the ``metadata.yaml`` that ``ros2 bag info`` and ``ros2 bag play`` read. A run with
``output.mcap=true`` gets ``bag/`` (``bag/bag_0.mcap``), streamed while it runs; the converter
writes the same topics from a run directory. Open it in Foxglove (the layout shipped beside this
module, :data:`LAYOUT`), with ``ros2 bag play bag``, or read it in Python with rosbags or
mcap-ros2-support (docs/ros.md).

Frames (REP 103, REP 105): one world frame ``world``, x east, y north, z up (the engine's frame),
and one ``agent_<i>/base_link`` per vehicle (x forward, y left, z up; the identity attitude for
point-mass dynamics), so a lab's per-vehicle namespaces map onto ``agent_<i>``. Stamps are the
simulated time (t = 0 is the epoch), the same in every message's header and in the MCAP log time.

Topics (each guidance tick unless told; "live only": not in a bag converted from a run directory):

    /clock                        rosgraph_msgs/msg/Clock             the simulated time
    /tf                           tf2_msgs/msg/TFMessage              world -> agent_<i>/base_link, every vehicle
    /agent_<i>/odom               nav_msgs/msg/Odometry               pose (frame world) and twist (frame
                                                                      agent_<i>/base_link; angular: the body
                                                                      rates, live only), covariances below
    /swarmscene/min_separation    std_msgs/msg/Float64                the smallest distance between two vehicles, m
    /swarmscene/separation_limit  std_msgs/msg/Float64                safety.separation_limit, m (a line to plot)
    /swarmscene/formation_slots   visualization_msgs/msg/MarkerArray  the formation's reference positions (its
                                                                      setpoints before avoidance; live only, and
                                                                      not for velocity-mode formations)
    /swarmscene/obstacles         visualization_msgs/msg/MarkerArray  the obstacle prisms, once at t = 0
                                                                      (transient local: latched on replay)
    /swarmscene/keep_out          visualization_msgs/msg/MarkerArray  a disc around each failed vehicle, of the
                                                                      replay's exclusion radius, at each failure
    /rosout                       rcl_interfaces/msg/Log              events and failures (WARN), each safety
                                                                      condition's first violation (ERROR), the
                                                                      end of the run and the verdict lines

Covariance: where the scenario declares sensing noise (``disturbances.<key>.name: sensing_noise``)
the pose covariance's x, y, z diagonal is the sum of the models' ``pos_std``^2 and the twist's
linear diagonal the sum of their ``vel_std``^2 (the body frame's when the three deviations are
equal, as in every shipped preset); orientation and angular entries are 0 (not modelled). The pose
itself is the true state, as on /tf: the covariance says how well a vehicle's own estimate knows it.

Streaming: the bag is written tick by tick into a private spill directory
(``output.trajectory_spill_dir`` or the system's temporary directory; memory stays two 4 MiB
chunks, one filling while the other is compressed, whatever the run's length) and moved into the
run directory with the other outputs, before the manifest, which lists it. A run stopped early
leaves no bag (its manifest is marked incomplete); its spill directory is removed.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
import weakref
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.hookspecs import hookimpl
from ..methods.ros2 import messages as msgs
from ..methods.ros2.cdr import CdrBuilder, CdrTemplate, split_time
from .mcap_file import McapWriter, RecordBlock

WORLD_FRAME = "world"
BAG_DIR = "bag"
"""The run directory's bag folder (``output.mcap=true``)."""
LAYOUT = Path(__file__).with_name("foxglove_layout.json")
"""The Foxglove layout shipped with the package: the 3-D panel with the frames and markers, a plot
of /swarmscene/min_separation against its limit, and the /rosout log."""
COMPRESSION = "zstd"
ROS_DISTRO = "humble"
"""The message definitions the bag's schemas carry (Humble's; Jazzy's are the same for these types)."""
TOPICS = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf": "tf2_msgs/msg/TFMessage",
    "odom": "nav_msgs/msg/Odometry",
    "/swarmscene/min_separation": "std_msgs/msg/Float64",
    "/swarmscene/separation_limit": "std_msgs/msg/Float64",
    "/swarmscene/formation_slots": "visualization_msgs/msg/MarkerArray",
    "/swarmscene/obstacles": "visualization_msgs/msg/MarkerArray",
    "/swarmscene/keep_out": "visualization_msgs/msg/MarkerArray",
    "/rosout": "rcl_interfaces/msg/Log",
}
MAX_VEHICLES = 0xFFFF - (len(TOPICS) - 1)
"""The most vehicles a bag holds: MCAP's channel ids are 16-bit, one odometry topic per vehicle
beside the other topics."""
LATCHED = ("/swarmscene/obstacles",)
"""Topics offered transient local (``ros2 bag play`` latches them)."""
LOG_NAME = "swarmscene"
FAILED_RGBA = (0.84, 0.15, 0.16, 0.35)
OBSTACLE_RGBA = (0.59, 0.59, 0.59, 0.6)
SLOT_RGBA = (0.1, 0.1, 0.1, 0.8)


def vehicle_name(i: int) -> str:
    """The vehicle's namespace: ``agent_<i>``."""
    return f"agent_{i}"


def odom_topic(i: int) -> str:
    """The vehicle's odometry topic."""
    return f"/{vehicle_name(i)}/odom"


def child_frame(i: int) -> str:
    """The vehicle's body frame (REP 105 ``base_link`` in its namespace)."""
    return f"{vehicle_name(i)}/base_link"


def noise_deviations(config: dict[str, Any]) -> tuple[np.ndarray, np.ndarray] | None:
    """(position variances (3,), velocity variances (3,)) summed over the scenario's
    ``sensing_noise`` models, or None when it declares none."""
    from ..core.spelling import recorded_name  # a model's name, or its kind as recorded until 0.6.0

    found = [d for key, d in (config.get("disturbances") or {}).items()
             if isinstance(d, dict) and recorded_name(d, key) == "sensing_noise"]
    if not found:
        return None
    pos = sum((np.asarray(d.get("pos_std", [0, 0, 0]), float) ** 2 for d in found), np.zeros(3))
    vel = sum((np.asarray(d.get("vel_std", [0, 0, 0]), float) ** 2 for d in found), np.zeros(3))
    return pos, vel


def covariances(config: dict[str, Any]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The odometry's 6 x 6 pose and twist covariances (module docstring), or None, None."""
    variances = noise_deviations(config)
    if variances is None:
        return None, None
    pose, twist = np.zeros((6, 6)), np.zeros((6, 6))
    pose[:3, :3] = np.diag(variances[0])
    twist[:3, :3] = np.diag(variances[1])
    return pose, twist


def quat_xyzw(quat: np.ndarray | None, n: int) -> np.ndarray:
    """(N, 4) ROS order (x, y, z, w) of the engine's (w, x, y, z); the identity without attitude."""
    if quat is None:
        return np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    quat = np.asarray(quat, float)
    return np.concatenate([quat[:, 1:], quat[:, :1]], axis=1)


def body_velocity(vel: np.ndarray, quat: np.ndarray | None) -> np.ndarray:
    """(N, 3) world velocities in each vehicle's body frame, v_b = R^T v (R body to world)."""
    vel = np.asarray(vel, float)
    if quat is None:
        return vel
    from .replay import rotation_matrices

    return np.einsum("nji,nj->ni", rotation_matrices(np.asarray(quat, float)), vel)


def _ns(t: float) -> int:
    sec, nsec = split_time(t)
    return sec * 1_000_000_000 + nsec


class BagWriter:
    """Writes a run's topics (module docstring) into an open MCAP file, tick by tick.

    Args:
        fh: the .mcap file, open for binary writing.
        config: the run's effective configuration (``Scenario.data``, a run directory's config.yaml).
        n: number of vehicles.
        slots: whether the run gives formation slots (``/swarmscene/formation_slots``).
    """

    def __init__(self, fh: Any, config: dict[str, Any], n: int, slots: bool = False) -> None:
        from .. import __version__

        if n > MAX_VEHICLES:
            raise ValueError(f"output.mcap: a bag holds at most {MAX_VEHICLES} vehicles (an odometry topic each, "
                             f"and MCAP's channel ids are 16-bit); this run has {n}")
        self.n = n
        self.config = config
        self.mcap = McapWriter(fh, "ros2", f"swarmscene {__version__}", COMPRESSION)
        schemas = {name: self.mcap.add_schema(name, "ros2msg", msgs.msgdef(name).encode())
                   for name in sorted(set(TOPICS.values()))}
        self.channel: dict[str, int] = {}
        topics = [t for t in TOPICS if t != "odom" and (slots or t != "/swarmscene/formation_slots")]
        topics[2:2] = [odom_topic(i) for i in range(n)]  # after /clock and /tf
        self.types = {topic: TOPICS.get(topic, TOPICS["odom"]) for topic in topics}
        for topic in topics:  # the channel's QoS as rosbag2 records it (readers match it to metadata.yaml's)
            qos = {"offered_qos_profiles": _latched_qos() if topic in LATCHED else ""}
            self.channel[topic] = self.mcap.add_channel(topic, schemas[self.types[topic]], "cdr", qos)
        pose_cov, twist_cov = covariances(config)
        limit = float((config.get("safety") or {}).get("separation_limit", 0.0))
        frames = [child_frame(i) for i in range(n)]
        tick = [msgs.clock_message(), msgs.tf_message(WORLD_FRAME, frames),
                *(msgs.odometry_message(WORLD_FRAME, frames[i], pose_cov, twist_cov) for i in range(n)),
                msgs.float64_message(), msgs.float64_message(limit, slot=None)]
        order = ["/clock", "/tf", *(odom_topic(i) for i in range(n)), "/swarmscene/min_separation",
                 "/swarmscene/separation_limit"]
        self.block = RecordBlock([self.channel[t] for t in order], CdrTemplate(tick))
        self.pose = np.concatenate([np.zeros((n, 3)), quat_xyzw(None, n)], axis=1)  # point masses: identity
        self.twist = np.zeros((n, 6))  # ... and no body rates
        self.slot_block: RecordBlock | None = None
        if slots:
            b = CdrBuilder()
            b.sequence(1)
            msgs.put_marker(b, WORLD_FRAME, "formation_slots", 0, "SPHERE_LIST", scale=(0.1, 0.1, 0.1),
                            rgba=SLOT_RGBA, points=np.zeros((n, 3)), stamp_slot="stamp", points_slot="points")
            self.slot_block = RecordBlock([self.channel["/swarmscene/formation_slots"]], CdrTemplate([b]))
        self.failed: dict[int, np.ndarray] = {}

    # -- what is written ----------------------------------------------------------------------
    def frame(self, t: float, pos: np.ndarray, vel: np.ndarray, quat: np.ndarray | None, min_separation: float,
              omega: np.ndarray | None = None) -> None:
        """The tick's clock, transforms, odometry and separation (one block)."""
        pose, twist = self.pose, self.twist  # (N, 7) position and attitude, (N, 6) body twist
        pose[:, :3] = pos
        if quat is not None:
            pose[:, 3:] = quat_xyzw(quat, self.n)
        twist[:, :3] = body_velocity(vel, quat)
        if omega is not None:
            twist[:, 3:] = omega
        self.mcap.write_block(self.block, _ns(t), stamp=split_time(t), transform=pose, pose=pose, twist=twist,
                              data=min_separation)

    def slots(self, t: float, positions: np.ndarray) -> None:
        """The formation's reference positions (N, 3) at ``t``."""
        if self.slot_block is not None:
            self.mcap.write_block(self.slot_block, _ns(t), stamp=split_time(t), points=positions)

    def obstacles(self, obstacles: Sequence[Any], top: float) -> None:
        """The obstacle prisms (from the ground to ``top``, m) as one triangle-list marker, at t = 0."""
        from .plots import RunData
        from .replay import obstacle_mesh

        ground = RunData(config={}, t=np.zeros(1), pos=np.array([[[0.0, 0.0, top - 0.5]]]), vel=np.zeros((1, 1, 3)),
                         healthy=np.ones((1, 1), bool), obstacles=list(obstacles))
        verts, tris = obstacle_mesh(ground)  # prisms up to max(z + 0.5, 1): top
        b = CdrBuilder()
        b.sequence(1)
        msgs.put_marker(b, WORLD_FRAME, "obstacles", 0, "TRIANGLE_LIST", rgba=OBSTACLE_RGBA,
                        points=verts[tris.reshape(-1)] if len(tris) else np.zeros((0, 3)))
        self.mcap.write_message(self.channel["/swarmscene/obstacles"], 0, b.bytes())

    def fail(self, t: float, agents: Sequence[int], positions: np.ndarray, radius: float | None) -> None:
        """Vehicles failed at ``t``: the keep-out discs of every failed vehicle so far (radius m;
        None: the avoidance plans no zone, none drawn)."""
        for agent, where in zip(agents, np.asarray(positions, float), strict=True):
            self.failed.setdefault(int(agent), where)
        if radius is None or radius <= 0:
            return
        b = CdrBuilder()
        b.sequence(len(self.failed))
        for agent, (x, y, z) in sorted(self.failed.items()):
            msgs.put_marker(b, WORLD_FRAME, "keep_out", agent, "CYLINDER", t=t, pose=(x, y, z, 0, 0, 0, 1),
                            scale=(2 * radius, 2 * radius, 0.05), rgba=FAILED_RGBA)
        self.mcap.write_message(self.channel["/swarmscene/keep_out"], _ns(t), b.bytes())

    def log(self, t: float, level: str, text: str) -> None:
        """A /rosout line (``level``: DEBUG, INFO, WARN, ERROR, FATAL)."""
        self.mcap.write_message(self.channel["/rosout"], _ns(t), msgs.log_message(t, level, LOG_NAME, text))

    def finish(self) -> None:
        """Close the MCAP container (the file itself stays open: the caller's)."""
        self.mcap.finish()

    def metadata(self, file_name: str) -> dict[str, Any]:
        """rosbag2's ``metadata.yaml`` content (version 5, what Humble writes and every later
        distribution reads) for this bag, written as ``file_name``."""
        start = self.mcap.start_time or 0
        duration = self.mcap.end_time - start
        counts = self.mcap.counts
        topics = [{"topic_metadata": {"name": topic, "type": self.types[topic], "serialization_format": "cdr",
                                      "offered_qos_profiles": _latched_qos() if topic in LATCHED else ""},
                   "message_count": int(counts[ch])} for topic, ch in self.channel.items()]
        return {"rosbag2_bagfile_information": {
            "version": 5, "storage_identifier": "mcap", "duration": {"nanoseconds": int(duration)},
            "starting_time": {"nanoseconds_since_epoch": int(start)}, "message_count": int(self.mcap.message_count),
            "topics_with_message_count": topics, "compression_format": "", "compression_mode": "",
            "relative_file_paths": [file_name],
            "files": [{"path": file_name, "starting_time": {"nanoseconds_since_epoch": int(start)},
                       "duration": {"nanoseconds": int(duration)}, "message_count": int(self.mcap.message_count)}],
        }}


def yaml_text(value: Any, indent: int = 0) -> str:
    """Block-style YAML of plain data (mappings, lists of mappings, strings, numbers), strings as
    JSON strings (valid YAML double-quoted scalars): metadata.yaml without PyYAML's emitter, which
    takes 0.1-0.3 s for a hundred topics, a fixed cost of every run."""
    import json

    pad = " " * indent
    lines = []
    for key, item in value.items():
        if isinstance(item, dict):
            lines.append(f"{pad}{key}:\n" + yaml_text(item, indent + 2).rstrip("\n"))
        elif isinstance(item, list):
            lines.append(f"{pad}{key}:")
            for entry in item:
                if isinstance(entry, dict):
                    body = yaml_text(entry, indent + 4)
                    lines.append(f"{pad}  - " + body[indent + 4:].rstrip("\n"))
                else:
                    lines.append(f"{pad}  - {json.dumps(entry)}")
        else:
            lines.append(f"{pad}{key}: {json.dumps(item)}")
    return "\n".join(lines) + "\n"


def _latched_qos() -> str:
    """rosbag2's offered_qos_profiles (a YAML string, rmw enum values): keep last 1, reliable,
    transient local, automatic liveliness, default deadline and lifespan."""
    import yaml

    zero = {"sec": 0, "nsec": 0}
    profile = {"history": 1, "depth": 1, "reliability": 1, "durability": 1, "deadline": zero, "lifespan": zero,
               "liveliness": 1, "liveliness_lease_duration": zero, "avoid_ros_namespace_conventions": False}
    return yaml.safe_dump([profile], sort_keys=False)


def obstacle_top(pos0: np.ndarray) -> float:
    """Height of the drawn obstacle prisms: half a metre above the highest vehicle at t = 0, at
    least 1 m (the replay's rule, from the first frame so a live bag and a converted one agree)."""
    top = float(np.max(np.asarray(pos0)[..., 2])) if np.size(pos0) else 0.5
    return max(top + 0.5, 1.0)


def verdict_lines(lines: Sequence[tuple[str, str, str]]) -> list[tuple[str, str]]:
    """(level, text) of the summary's verdict lines: FAIL is ERROR, ``not met`` WARN, else INFO."""
    level = {"FAIL": "ERROR", "not met": "WARN"}
    return [(level.get(status, "INFO"), f"{status} {name}" + (f": {detail}" if detail else ""))
            for name, status, detail in lines]


# -- the bag folder -------------------------------------------------------------------------------
class BagFolder:
    """A rosbag2 folder being written in a private directory (``mkdtemp``: mode 0700, a fresh name,
    its file created exclusively, so nothing planted is written through) and published by one
    rename. Removed when garbage-collected or at exit if never published."""

    def __init__(self, where: Path | str | None, name: str) -> None:
        if where is not None:
            Path(where).mkdir(parents=True, exist_ok=True)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", suffix=".tmp", dir=where))
        self.folder = self.tmp / name
        self.folder.mkdir()
        self.file_name = f"{name}_0.mcap"
        from ..core.recorder import create_exclusive

        self.fh = os.fdopen(create_exclusive(self.folder / self.file_name), "wb")
        self._cleanup = weakref.finalize(self, _remove, self.fh, self.tmp)

    def publish(self, writer: BagWriter, target: Path) -> Path:
        """Finish the bag, write metadata.yaml and move the folder to ``target`` (named as the
        folder; a directory or a link already there is replaced, never followed)."""
        from ..runs.outputs import atomic_write_bytes, user_file_mode

        target = Path(target)
        if target.name != self.folder.name:
            raise ValueError(f"{target}: the bag folder is named {self.folder.name!r}")
        writer.finish()
        self.fh.close()
        text = yaml_text(writer.metadata(self.file_name))
        atomic_write_bytes(self.folder / "metadata.yaml", text.encode())
        mode = user_file_mode()
        os.chmod(self.folder / self.file_name, mode)
        os.chmod(self.folder, mode | ((mode & 0o444) >> 2))  # rwx where the files are rw
        target.parent.mkdir(parents=True, exist_ok=True)
        staged = self.tmp
        if self.tmp.parent.resolve() != target.parent.resolve():  # another directory, maybe another disk
            staged = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
            shutil.move(str(self.folder), str(staged / target.name))
        try:
            if target.is_symlink() or target.is_file():
                target.unlink()
            elif target.is_dir():
                shutil.rmtree(target)
            os.replace(staged / target.name, target)  # a rename within one directory
        finally:
            shutil.rmtree(staged, ignore_errors=True)
            self._cleanup()
        return target

    def discard(self) -> None:
        """Remove the unfinished bag."""
        self._cleanup()


def _remove(fh: Any, tmp: Path) -> None:
    fh.close()
    shutil.rmtree(tmp, ignore_errors=True)


# -- streamed while the run goes (output.mcap=true) ----------------------------------------------
def attach(sim: Any) -> Any:
    """Stream ``sim``'s run into a bag: the observer is registered on the run's plugin manager;
    returns the writer that publishes the bag into the run directory (``api.extra_writers``)."""
    recorder = McapRecorder(sim)
    sim.pm.register(recorder, name="mcap_bag")
    return recorder.publish


class McapRecorder:
    """An observer writing the run's bag tick by tick (lifecycle hooks: core/hookspecs.py).

    Args:
        sim: the :class:`~swarmscene.core.simulation.Simulation`, before its run.
    """

    def __init__(self, sim: Any) -> None:
        from .replay import exclusion_radius

        data = sim.scenario.data
        self.folder = BagFolder(sim.config.output.trajectory_spill_dir, BAG_DIR)
        self.writer = BagWriter(self.folder.fh, data, sim.world.n, slots=True)
        self.zone = exclusion_radius(data, {})  # cem's a_p is a metric: known at the end only, so none
        self.obstacles = list(sim.environment.obstacles)
        self.reference: tuple[float, np.ndarray] | None = None
        self._watch_formation(sim.formation)

    def _watch_formation(self, formation: Any) -> None:
        """See each tick's formation setpoints (the slots): the formation's own ``setpoints`` is
        wrapped on this instance only; the setpoints pass through untouched."""
        from ..core.setpoint import Mode

        original = formation.setpoints

        def setpoints(world: Any, sensing: Any) -> Any:
            sp = original(world, sensing)
            if not np.all(sp.mode == int(Mode.VELOCITY)):  # velocity commands have no place to be
                self.reference = (float(world.t), np.array(sp.pos, float))
            return sp

        try:
            formation.setpoints = setpoints
        except AttributeError:  # a plugin with __slots__: no slots topic
            pass

    def _frame(self, sim: Any) -> None:
        world = sim.world
        if self.reference is not None:  # stamped at the tick's start, so before the frame at its end
            self.writer.slots(*self.reference)
            self.reference = None
        self.writer.frame(float(world.t), world.pos, world.vel, world.quat, float(sim.sensing.min_separation),
                          world.omega if world.quat is not None else None)
        if not world.healthy.all():
            self._failures(float(world.t), world.pos, world.healthy)

    def _failures(self, t: float, pos: np.ndarray, healthy: np.ndarray) -> None:
        new = [int(i) for i in np.flatnonzero(~np.asarray(healthy)) if int(i) not in self.writer.failed]
        if new:
            self.writer.fail(t, new, np.asarray(pos, float)[new], self.zone)

    @hookimpl
    def swarmscene_run_start(self, sim: Any) -> None:
        """The obstacles and the first frame."""
        if self.obstacles:
            self.writer.obstacles(self.obstacles, obstacle_top(sim.world.pos))
        self._frame(sim)

    @hookimpl
    def swarmscene_step_end(self, sim: Any) -> None:
        """The tick's frame (and the formation's slots)."""
        self._frame(sim)

    @hookimpl
    def swarmscene_event(self, sim: Any, event: Any) -> None:
        """The event's /rosout line and the keep-out of any vehicle it failed."""
        from .replay import event_text

        at = float(event.at)
        self.writer.log(at, "WARN", event_text(event.name, event.agents))
        self._failures(at, sim.world.pos, sim.world.healthy)

    def publish(self, run_dir: Path, sim: Any = None, result: Any = None) -> Path:
        """The end of the run on /rosout (first violations, the stop, the verdict lines), then the
        bag moved into ``run_dir`` as ``bag/`` (an ``extra`` of the run directory's writer)."""
        from .summary import verdicts

        end = float(sim.world.t)
        metrics = dict(result.metrics)
        for t, level, text in end_lines(sim.scenario.data, end, metrics):
            self.writer.log(t, level, text)
        for level, text in verdict_lines(verdicts(sim, metrics)):
            self.writer.log(end, level, text)
        return self.folder.publish(self.writer, Path(run_dir) / BAG_DIR)


def end_lines(config: dict[str, Any], end: float, metrics: dict[str, Any]) -> list[tuple[float, str, str]]:
    """(time, level, text) known at the end: each condition's first violation and the stop
    (the replay's event log lines)."""
    from .plots import RunData
    from .replay import end_events

    final = RunData(config=config, t=np.array([end]), pos=np.zeros((1, 0, 3)), vel=np.zeros((1, 0, 3)),
                    healthy=np.zeros((1, 0), bool), metrics=metrics)
    return end_events(final)


# -- converted from a run directory ----------------------------------------------------------------
def export_mcap(run_dir: Path, out: Path) -> Path:
    """Write the bag folder ``out`` (``out/<name>_0.mcap`` and metadata.yaml) from a run directory,
    read through the checked reader (:func:`swarmscene.views.plots.load_run`). ``out`` must not exist."""
    from .plots import load_run, nearest_neighbour
    from .replay import events, exclusion_radius

    out = Path(out)
    if out.exists() or out.is_symlink():
        raise ValueError(f"--mcap: {out} exists (a bag is written into a new folder, as ros2 bag record does)")
    run = load_run(run_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    folder = BagFolder(out.parent, out.name)
    try:
        writer = BagWriter(folder.fh, run.config, run.n, slots=False)
        if run.obstacles:
            writer.obstacles(run.obstacles, obstacle_top(run.pos[0]))
        separation = nearest_neighbour(run).min(axis=1) if run.n > 1 else np.full(len(run.t), np.inf)
        zone = exclusion_radius(run.config, run.metrics)
        lines = events(run)  # (time, level, text), in time order, the end's included
        fails = sorted(run.failures(), key=lambda f: f[1])
        for k, t in enumerate(np.asarray(run.t, float)):
            while lines and lines[0][0] <= t:
                writer.log(*lines.pop(0))
            while fails and fails[0][1] <= t:
                agent, when, where = fails.pop(0)
                writer.fail(when, [agent], where[None], zone)
            quat = None if run.quat is None else run.quat[k]
            writer.frame(float(t), run.pos[k], run.vel[k], quat, float(separation[k]))
        for line in lines:
            writer.log(*line)
        end = float(run.t[-1]) if len(run.t) else 0.0
        for level, text in verdict_lines(_recorded_verdicts(run.config, run.metrics)):
            writer.log(end, level, text)
        return folder.publish(writer, out)
    except BaseException:
        folder.discard()
        raise


def _recorded_verdicts(config: dict[str, Any], metrics: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The safety verdicts a run directory's files give (the summary's engine and plugin lines; the
    mission's needs the run's last state, so its line is the stop and success instead)."""
    from types import SimpleNamespace

    from ..core.config import ScenarioConfig
    from ..core.errors import SwarmsceneDeprecationWarning
    from ..core.registry import installed_registry
    from .summary import engine_verdicts, plugin_verdicts

    context = {"registry": installed_registry()}  # the installed plugins choose a recorded map generator
    try:
        with warnings.catch_warnings():  # a record's old spelling is read silently: the user typed none of it
            warnings.simplefilter("ignore", SwarmsceneDeprecationWarning)
            engine = SimpleNamespace(config=ScenarioConfig.model_validate(config, context=context))
    except ValueError:
        return []
    lines = [*engine_verdicts(engine, metrics)] if metrics else []
    lines.append(("success", "OK" if metrics.get("success") else "FAIL",
                  f"stopped by {metrics.get('stop_reason', 'unknown')}"))
    return lines + plugin_verdicts(engine, metrics)



def export_main(parser: Any, run_dir: Path, out: Path) -> None:
    """``python -m swarmscene.views.export RUN_DIR --mcap OUT``: the bag, or one line and exit status 2
    (a damaged or missing file of the run, named; OUT already there; OUT not writable)."""
    from ..runs.rundir import RunFileError

    try:
        written = export_mcap(run_dir, out)
    except (RunFileError, ValueError) as exc:
        parser.exit(2, f"{parser.prog}: {' '.join(str(exc).split())}\n")
    except OSError as exc:
        parser.exit(2, f"{parser.prog}: {exc.filename or out}: cannot be written ({exc.strerror or exc})\n")
    print(f"ROS 2 bag in {written} ({written.name}_0.mcap, metadata.yaml): ros2 bag info {written}; "
          f"Foxglove layout {LAYOUT}")
