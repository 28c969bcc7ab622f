"""recorded: a bag written by another tool (rosbags' rosbag2 writer, its own vehicle naming) played
back as reference paths within the cubic spline's published error bounds; the frame and topic
mappings, the time window; damaged and hostile recordings refused in one line naming the file."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.methods.ros2.bag import EXAMPLE_FLIGHT
from swarmscene.plugin import Mode, WorldState, build_context
from swarmscene.plugins.formation.recorded import Recorded

STORE = get_typestore(Stores.ROS2_HUMBLE)
EPOCH = 1_750_000_000  # s: a lab clock's stamps
H = 0.04  # s, 25 Hz, the recording's sample spacing
W = 2 * np.pi / 10.0  # rad/s
R, A = 2.0, 0.4  # m
NAMES = ["uav_a", "uav_b", "uav_c"]


def path(t, k):
    """Vehicle k's recorded path p_k(t) (T, 3), and its velocity and acceleration."""
    phase = W * t + 2 * np.pi * k / 3
    p = np.stack([R * np.cos(phase), R * np.sin(phase), 1.0 + A * np.sin(2 * phase)], axis=1)
    v = np.stack([-R * W * np.sin(phase), R * W * np.cos(phase), 2 * W * A * np.cos(2 * phase)], axis=1)
    a = np.stack([-R * W**2 * np.cos(phase), -R * W**2 * np.sin(phase), -4 * W**2 * A * np.sin(2 * phase)], axis=1)
    return p, v, a


M4 = np.array([R * W**4, R * W**4, A * (2 * W) ** 4])
"""max |p''''| per axis."""


def _header(ns, frame):
    Header, Time = STORE.types["std_msgs/msg/Header"], STORE.types["builtin_interfaces/msg/Time"]
    return Header(Time(sec=ns // 10**9, nanosec=ns % 10**9), frame)


def write_bag(folder, duration=12.0):
    """TF in frame ``map`` for uav_a..uav_c (all three in one TFMessage a sample), and vehicle 0's
    path also as PoseStamped on /uav_a/pose and Odometry on /uav_a/odom, by rosbags."""
    T = STORE.types
    t = np.arange(int(round(duration / H)) + 1) * H
    paths = [path(t, k)[0] for k in range(3)]
    with Writer(folder, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=STORE)
        pose = writer.add_connection("/uav_a/pose", "geometry_msgs/msg/PoseStamped", typestore=STORE)
        odom = writer.add_connection("/uav_a/odom", "nav_msgs/msg/Odometry", typestore=STORE)
        for j, now in enumerate(t):
            ns = EPOCH * 10**9 + int(round(now * 1e9))
            transforms = [T["geometry_msgs/msg/TransformStamped"](
                _header(ns, "map"), name, T["geometry_msgs/msg/Transform"](
                    T["geometry_msgs/msg/Vector3"](*paths[k][j]), T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)))
                for k, name in enumerate(NAMES)]
            writer.write(tf, ns, STORE.serialize_cdr(T["tf2_msgs/msg/TFMessage"](transforms), "tf2_msgs/msg/TFMessage"))
            p = T["geometry_msgs/msg/Pose"](T["geometry_msgs/msg/Point"](*paths[0][j]),
                                            T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0))
            writer.write(pose, ns, STORE.serialize_cdr(T["geometry_msgs/msg/PoseStamped"](_header(ns, "map"), p),
                                                       "geometry_msgs/msg/PoseStamped"))
            cov = np.zeros(36)
            twist = T["geometry_msgs/msg/Twist"](T["geometry_msgs/msg/Vector3"](0.0, 0.0, 0.0),
                                                  T["geometry_msgs/msg/Vector3"](0.0, 0.0, 0.0))
            msg = T["nav_msgs/msg/Odometry"](_header(ns, "map"), "uav_a/base_link",
                                            T["geometry_msgs/msg/PoseWithCovariance"](p, cov),
                                            T["geometry_msgs/msg/TwistWithCovariance"](twist, cov))
            writer.write(odom, ns, STORE.serialize_cdr(msg, "nav_msgs/msg/Odometry"))
    return folder


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    return write_bag(tmp_path_factory.mktemp("lab") / "flight")


def _formation(n=3, **options):
    ctx = build_context(n, positions=np.column_stack([np.arange(n) * 3.0, np.zeros(n), np.ones(n)]))
    return Recorded(Recorded.Params(**options), ctx), ctx


def _played(formation, times):
    world = WorldState.at_rest(np.zeros((formation.playback.n, 3)))
    out = []
    for t in times:
        world.t = float(t)
        out.append(formation.setpoints(world, None))
    return out


def test_a_rosbags_bag_with_another_naming_plays_back_within_the_spline_error_bounds(bag):
    formation, _ = _formation(bag=str(bag), world_frame="map", frames=["uav_c", "uav_a", "uav_b"], start=2.0, end=10.0)
    times = np.arange(0.0, 8.0 + 1e-9, 0.01)  # 100 Hz guidance over the window
    sps = _played(formation, times)
    for agent, k in enumerate((2, 0, 1)):  # the mapping: agent 0 flies uav_c
        p, v, a = path(2.0 + times, k)
        pos = np.array([sp.pos[agent] for sp in sps])
        vel = np.array([sp.vel[agent] for sp in sps])
        acc = np.array([sp.acc[agent] for sp in sps])
        assert np.all(np.abs(pos - p) <= 5 / 384 * H**4 * M4)  # Hall and Meyer 1976
        assert np.all(np.abs(vel - v) <= 1 / 24 * H**3 * M4)
        assert np.all(np.abs(acc - a) <= 3 / 8 * H**2 * M4)
        assert np.abs(pos - p).max() > 0  # interpolated, not a copy of the samples
    assert all((sp.mode == int(Mode.TRACK)).all() for sp in sps)


def test_after_the_window_the_reference_holds_its_last_point_at_rest(bag):
    formation, _ = _formation(bag=str(bag), world_frame="map", start=2.0, end=10.0)
    (during,), (after,) = _played(formation, [8.0]), _played(formation, [9.5])
    np.testing.assert_array_equal(after.pos, during.pos)
    assert not after.vel.any() and not after.acc.any()
    world = WorldState.at_rest(during.pos.copy())
    world.t = 8.0
    assert formation.complete(world) is True
    world.pos[1] += [0.6, 0.0, 0.0]  # beyond arrival_tolerance = 0.5 m
    assert formation.complete(world) is False
    world.t = 7.9
    assert formation.complete(world) is False


def test_frames_default_to_every_child_of_the_world_frame_in_natural_order(bag):
    formation, _ = _formation(n=2, bag=str(bag), world_frame="map")
    assert formation.vehicles == ["uav_a", "uav_b"]  # the first swarm.n


def test_pose_and_odometry_topics_play_the_same_path_as_tf(bag):
    by_tf, _ = _formation(n=1, bag=str(bag), world_frame="map", frames=["uav_a"], start=1.0)
    by_pose, _ = _formation(n=1, bag=str(bag), topics=["/uav_a/pose"], start=1.0)
    by_odom, _ = _formation(n=1, bag=str(bag), topics=["/uav_a/odom"], start=1.0)
    times = [0.0, 0.37, 5.01]
    for a, b, c in zip(*(_played(f, times) for f in (by_tf, by_pose, by_odom)), strict=True):
        assert np.array_equal(a.pos, b.pos) and np.array_equal(a.pos, c.pos)


def test_offset_shifts_the_recording_into_the_world(bag):
    plain, _ = _formation(n=1, bag=str(bag), world_frame="map")
    moved, _ = _formation(n=1, bag=str(bag), world_frame="map", offset=(10.0, -5.0, 0.5))
    (a,), (b,) = _played(plain, [3.3]), _played(moved, [3.3])
    np.testing.assert_array_equal(b.pos, a.pos + [10.0, -5.0, 0.5])
    np.testing.assert_array_equal(a.vel, b.vel)


def test_the_example_flight_plays_through_the_preset(tmp_path):
    result = api.run(["scenario=recorded_flight", "dynamics=double_integrator", "output.summary=false"],
                     output_dir=tmp_path / "run")
    assert result.metrics["stop_reason"] == "complete" and result.metrics["success"] is True
    formation, _ = _formation(n=8)  # bag: null, the example
    assert formation.vehicles == [f"cf{k}" for k in range(1, 9)]
    assert EXAMPLE_FLIGHT.is_dir()


# -- mapping errors and hostile files: one line naming the option and the file --------------------
def _error(tmp_path, bag, *options):
    with pytest.raises(ConfigError) as err:
        api.build(["formation=recorded", f"formation.bag={bag}", "swarm.n=3", *options,
                   "output.summary=false"])
    (line,) = err.value.lines
    return line


def test_missing_frames_and_too_few_vehicles_name_what_the_bag_has(bag, tmp_path):
    line = _error(tmp_path, bag, "formation.world_frame=map", "formation.frames=[uav_a,uav_x,uav_b]")
    assert line == f"formation.frames: uav_x not under 'map' on /tf in {bag} (found: uav_a, uav_b, uav_c)"
    line = _error(tmp_path, bag, "formation.world_frame=world")
    assert line == f"formation.frames: {bag} has 0 vehicle frame(s) under 'world' on /tf (none) for swarm.n = 3"
    line = _error(tmp_path, bag, "formation.topics=[/uav_a/pose,/nope,/uav_a/odom]")
    assert line == f"formation.topics: /nope not in {bag} (or without messages)"
    line = _error(tmp_path, bag, "formation.world_frame=map", "formation.start=20")
    assert line == "formation.start: 20 s is past the recording's last sample (12 s after its first)"
    line = _error(tmp_path, bag, "formation.world_frame=map", "formation.start=5", "formation.end=4")
    assert line == "formation.end: must be after start (got 4 s <= 5 s)"


@pytest.mark.parametrize("damage", ["missing", "random", "truncated", "footer", "sqlite", "escape", "not_tf"])
def test_a_damaged_or_hostile_recording_is_one_line_naming_the_file(bag, tmp_path, damage):
    mcap = next(bag.glob("*.mcap"))
    data = mcap.read_bytes()
    target = tmp_path / "x.mcap"
    extra = ["formation.world_frame=map"]
    if damage == "missing":
        named = tmp_path / "nothing.mcap"
        target = named
    elif damage == "random":
        target.write_bytes(np.random.default_rng(0).bytes(5000))
        named = target
    elif damage == "truncated":
        target.write_bytes(data[: len(data) // 2])
        named = target
    elif damage == "footer":  # the footer and closing magic zeroed: no summary to seek by
        target.write_bytes(data[:-40] + bytes(40))
        named = target
    elif damage == "sqlite":
        target = tmp_path / "sq"
        target.mkdir()
        (target / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n"
                                              "  relative_file_paths: [sq_0.db3]\n")
        named = target / "metadata.yaml"
    elif damage == "escape":
        target = tmp_path / "esc"
        target.mkdir()
        (target / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  storage_identifier: mcap\n"
                                              f"  relative_file_paths: [../{bag.name}/{mcap.name}]\n")
        named = target / "metadata.yaml"
    else:  # a pose topic on the TF option
        target = bag
        named = bag
        extra = ["formation.topic=/uav_a/pose"]
    line = _error(tmp_path, target, *extra)
    assert line.startswith(f"formation.bag: {named}: ") and "\n" not in line
    expected = {"missing": "missing (give an .mcap file or a rosbag2 folder)",
                "sqlite": "storage_identifier is 'sqlite3': only MCAP storage is read",
                "escape": f"relative_file_paths names '../{bag.name}/{mcap.name}', outside the folder",
                "not_tf": "topic /uav_a/pose holds geometry_msgs/msg/PoseStamped, not tf2_msgs/msg/TFMessage"}
    if damage in expected:
        assert line[len(f"formation.bag: {named}: "):].startswith(expected[damage])
    else:
        assert "not a readable MCAP recording" in line


def _one_chunk(path, compression, declared, data):
    """An MCAP file of one chunk record declaring ``declared`` bytes uncompressed, holding ``data``,
    and no summary (the MCAP specification's records: Header, Chunk, Data End, Footer)."""
    import struct

    def string(text):
        return struct.pack("<I", len(text)) + text.encode()

    def record(opcode, content):
        return struct.pack("<BQ", opcode, len(content)) + content

    magic = b"\x89MCAP0\r\n"
    chunk = struct.pack("<QQQI", 0, 0, declared, 0) + string(compression) + struct.pack("<Q", len(data)) + data
    path.write_bytes(magic + record(0x01, string("ros2") + string("test")) + record(0x06, chunk)
                     + record(0x0F, struct.pack("<I", 0)) + record(0x02, struct.pack("<QQI", 0, 0, 0)) + magic)
    return path


def test_a_chunk_larger_than_the_limit_is_refused_before_it_is_decompressed(tmp_path):
    """A decompression bomb: a chunk declaring more than MAX_CHUNK_BYTES (checked on the chunk's own
    record: a file without a summary, or whose index understates it, was read whole), and an lz4
    chunk inflating past what it declares (lz4's decoder trusts no size: ~2 GiB from a 4 MB file)."""
    import lz4.frame

    from swarmscene.methods.ros2.bag import MAX_CHUNK_BYTES, BagError, tf_tracks

    big = _one_chunk(tmp_path / "big.mcap", "zstd", MAX_CHUNK_BYTES + 1, b"not even zstd")
    with pytest.raises(BagError, match=rf"^{big}: a chunk of {MAX_CHUNK_BYTES + 1} bytes \(at most "):
        tf_tracks(big, "/tf", "world")
    inflating = _one_chunk(tmp_path / "lz4.mcap", "lz4", 1000, lz4.frame.compress(bytes(5000)))
    with pytest.raises(BagError, match=rf"^{inflating}: an lz4 chunk decompresses past the 1000 bytes it declares$"):
        tf_tracks(inflating, "/tf", "world")


def test_a_folder_whose_mcap_is_a_pipe_or_behind_a_linked_folder_is_refused(bag, tmp_path):
    """A named pipe called x.mcap in a folder without metadata.yaml blocked the reader forever
    (deaf to SIGTERM); metadata.yaml naming sub/x.mcap, sub a link, read a file outside the folder."""
    import os

    from swarmscene.methods.ros2.bag import BagError, mcap_files

    piped = tmp_path / "piped"
    piped.mkdir()
    os.mkfifo(piped / "x.mcap")
    with pytest.raises(BagError, match=r"not a rosbag2 folder \(no metadata.yaml, and not one plain .mcap file in it\)$"):
        mcap_files(piped)
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "sub").symlink_to(bag, target_is_directory=True)
    name = next(bag.glob("*.mcap")).name
    (linked / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  storage_identifier: mcap\n"
                                          f"  relative_file_paths: [sub/{name}]\n")
    with pytest.raises(BagError, match=r"listed in metadata.yaml but not a plain file inside the folder$"):
        mcap_files(linked)


def test_a_stamp_from_another_clock_and_a_position_that_is_not_finite_are_refused(tmp_path):
    """One sample stamped 0 among a lab clock's (~1.75e9 s) made a 1.75e9 s window and a reference
    ~1e9 m away; a NaN position failed in the spline without naming the file."""
    from swarmscene.methods.ros2.bag import BagError, _tracks

    lab = EPOCH * 1_000_000_000
    with pytest.raises(BagError, match=r"^rec: its stamps span 1.75e\+09 s \(0 to 1750000000100000000 ns\), wider"):
        _tracks("rec", {"cf1": [(0, 0.0, 0.0, 1.0), (lab, 0.0, 0.0, 1.0), (lab + 10**8, 0.1, 0.0, 1.0)]})
    with pytest.raises(BagError, match=r"^rec: cf2: a position that is not finite \(\(nan, 0.0, 1.0\)\) at stamp"):
        _tracks("rec", {"cf1": [(lab, 0.0, 0.0, 1.0)], "cf2": [(lab, float("nan"), 0.0, 1.0)]})
