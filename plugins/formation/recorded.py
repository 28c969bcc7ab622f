"""Recorded: a flown show played back as the swarm's reference paths, from a ROS 2 recording.

A lab's flight log (an MCAP file or a rosbag2 folder with MCAP storage, read without ROS:
:mod:`swarmscene.methods.ros2.bag`) comes back in as a scenario: agent i tracks the recorded path
of vehicle i (TRACK setpoints: the cubic spline through its samples, with its velocity and
acceleration as feed-forward; :mod:`swarmscene.methods.ros2.playback`), so the show can be
re-flown under wind, failures and another avoidance method, and compared with the flight.

Mapping: on TF (``topic``, default ``/tf``) each vehicle is a child frame of ``world_frame``;
``frames`` lists them in agent order (empty: every child frame found, in natural order, the first
``swarm.n``). With ``topics`` (pose topics, one per agent: PoseStamped, Odometry or
TransformStamped) TF is not read. ``start`` / ``end`` choose the time window (s after the
recording's first sample) and ``offset`` shifts the recorded positions into the scenario's world.
``bag: null`` plays the example flight shipped with the package (eight Crazyflies ``cf1``..``cf8``
circling (2 m radius, 20 s a turn, 1.0 +- 0.3 m high), recorded by rosbags with TF in a ``world`` frame).

Choices: the heading is not played (yaw 0); orientation in the recording is ignored. A recording
with more vehicles than ``swarm.n`` plays the first ``swarm.n``; fewer is an error naming the
frames found. The mission is complete once the window has played and every healthy agent is
within ``arrival_tolerance`` of its last recorded point.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field

from swarmscene.methods.ros2.bag import EXAMPLE_FLIGHT, BagError, natural_key, pose_tracks, tf_tracks
from swarmscene.methods.ros2.playback import Playback
from swarmscene.plugin import BuildContext, Formation, Mode, PluginParams, Setpoints, WorldState, hookimpl


class Recorded(Formation):
    """Each agent tracks a recorded vehicle's path (a ROS 2 recording's TF or pose topics)."""

    name = "recorded"

    class Params(PluginParams):
        bag: str | None = Field(
            None, description="the recording: an .mcap file or a rosbag2 folder (MCAP storage); null: the "
            "example flight shipped with the package"
        )
        topic: str = Field("/tf", min_length=1, description="the TF topic (tf2_msgs/msg/TFMessage)")
        world_frame: str = Field("world", min_length=1, description="the TF parent frame of the vehicles")
        frames: list[str] = Field(
            default_factory=list, description="child frame of each agent, in agent order (empty: every child of "
            "world_frame, natural order, the first swarm.n)"
        )
        topics: list[str] = Field(
            default_factory=list, description="pose topics, one per agent (PoseStamped, Odometry or "
            "TransformStamped); given, TF is not read"
        )
        start: float = Field(0.0, ge=0, description="window start, s after the recording's first sample")
        end: float | None = Field(None, gt=0, description="window end, s after the first sample (null: the last)")
        offset: tuple[float, float, float] = Field(
            (0.0, 0.0, 0.0), description="[x, y, z] m added to every recorded position"
        )
        arrival_tolerance: float = Field(
            0.5, gt=0, description="distance to its last recorded point at which an agent has arrived, m"
        )

    params: Params

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        path = Path(params.bag).expanduser() if params.bag is not None else EXAMPLE_FLIGHT
        try:
            tracks = self._tracks(path, ctx.n)
        except BagError as exc:  # the recording itself: the engine prefixes "formation."
            raise ValueError(f"bag: {exc}") from None
        self.playback = Playback(tracks, params.start, params.end, params.offset)
        self.vehicles = [tr.name for tr in tracks]

    def _tracks(self, path: Path, n: int) -> list:
        p = self.params
        if p.topics:
            if len(p.topics) != n:
                raise ValueError(f"topics: {len(p.topics)} topics for swarm.n = {n} agents")
            found = pose_tracks(path, list(p.topics))
            missing = [t for t in p.topics if t not in found]
            if missing:
                raise ValueError(f"topics: {', '.join(missing)} not in {path} (or without messages)")
            return [found[t] for t in p.topics]
        found = tf_tracks(path, p.topic, p.world_frame)
        listed = ", ".join(sorted(found, key=natural_key)[:12]) or "none"
        if p.frames:
            if len(p.frames) != n:
                raise ValueError(f"frames: {len(p.frames)} frames for swarm.n = {n} agents")
            missing = [f for f in p.frames if f.lstrip("/") not in found]
            if missing:
                raise ValueError(f"frames: {', '.join(missing)} not under {p.world_frame!r} on {p.topic} in "
                                 f"{path} (found: {listed})")
            return [found[f.lstrip("/")] for f in p.frames]
        names = sorted(found, key=natural_key)
        if len(names) < n:
            raise ValueError(f"frames: {path} has {len(names)} vehicle frame(s) under {p.world_frame!r} on "
                             f"{p.topic} ({listed}) for swarm.n = {n}")
        return [found[name] for name in names[:n]]

    def setpoints(self, world: WorldState, sensing) -> Setpoints:
        """TRACK each agent's recorded path at the played time, with its velocity and acceleration."""
        pos, vel, acc = self.playback.at(world.t)
        n = world.n
        return Setpoints(np.full(n, int(Mode.TRACK), dtype=np.int8), pos, vel, acc, np.zeros(n))

    def complete(self, world: WorldState) -> bool:
        """True once the window has played and every healthy agent is within ``arrival_tolerance``
        of its last recorded point."""
        if world.t < self.playback.duration:
            return False
        last = self.playback.at(self.playback.duration)[0]
        error = np.linalg.norm(world.pos[world.healthy] - last[world.healthy], axis=1)
        return bool(np.all(error <= self.params.arrival_tolerance))


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Add :class:`Recorded` to the registry, so that ``formation=recorded`` chooses it."""
    register(Recorded)
