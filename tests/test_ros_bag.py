"""ROS 2 bags (``output.mcap=true``, ``export --mcap``) read back by independent readers: the mcap
package with mcap-ros2-support's decoder, rosbags (the folder as a rosbag2 bag, its own CDR
decoder and its own copy of the message definitions) and Rerun (``rerun mcap convert``); /tf
positions equal trajectory.npz to the bit."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.hookspecs import hookimpl
from swarmscene.methods.ros2 import messages
from swarmscene.runs.rundir import RunDir
from swarmscene.views import mcap_bag, plots, replay

FAILING = ["events=lead_fails", "events.0.at=3.0", "clock.duration=6.0", "output.mcap=true", "output.summary=false"]
"""The default scenario (obstacles, five vehicles) with the leader failing at 3 s."""
SHOW = ["scenario=vrb_airshow", "clock.duration=2.0", "output.mcap=true", "output.summary=false"]
"""6-DOF quadrotors: attitude and body rates."""
HUMBLE = get_typestore(Stores.ROS2_HUMBLE)


@pytest.fixture(scope="module")
def failing(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("failing") / "run"
    api.run(FAILING, output_dir=run_dir)
    return run_dir


@pytest.fixture(scope="module")
def show(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("show") / "run"
    api.run(SHOW, output_dir=run_dir)
    return run_dir


def _mcap(run_dir):
    return run_dir / "bag" / "bag_0.mcap"


def _decoded(path, topics=None):
    """(topic, log time ns, decoded message) by mcap-ros2-support, in file order."""
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        return [(c.topic, m.log_time, msg) for _, c, m, msg in reader.iter_decoded_messages(topics=topics,
                                                                                              log_time_order=False)]


def _tf(path):
    """(log times ns (T,), parents, children, translations (T, N, 3), rotations (T, N, 4)) of /tf."""
    rows = _decoded(path, ["/tf"])
    t = np.array([ns for _, ns, _ in rows])
    tfs = [msg.transforms for _, _, msg in rows]
    parents = {tf.header.frame_id for msgs in tfs for tf in msgs}
    children = [tf.child_frame_id for tf in tfs[0]]
    trans = np.array([[[tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z]
                       for tf in msgs] for msgs in tfs])
    rot = np.array([[[tf.transform.rotation.x, tf.transform.rotation.y, tf.transform.rotation.z,
                      tf.transform.rotation.w] for tf in msgs] for msgs in tfs])
    return t, parents, children, trans, rot


# -- the message definitions ---------------------------------------------------------------------
@pytest.mark.parametrize("typename", sorted(set(mcap_bag.TOPICS.values())))
def test_each_schema_is_the_definition_rosbags_generates_for_humble(typename):
    assert messages.msgdef(typename) == HUMBLE.generate_msgdef(typename, ros_version=2)[0]


# -- the bag of a run ----------------------------------------------------------------------------
def test_the_run_directory_holds_a_rosbag2_folder_listed_in_the_manifest(failing):
    assert sorted(p.name for p in (failing / "bag").iterdir()) == ["bag_0.mcap", "metadata.yaml"]
    assert "bag" in RunDir(failing).manifest()["files"]
    assert not [p for p in failing.iterdir() if p.name.endswith(".tmp")]  # nothing left half-written
    info = yaml.safe_load((failing / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["storage_identifier"] == "mcap" and info["relative_file_paths"] == ["bag_0.mcap"]
    with open(_mcap(failing), "rb") as fh:
        stats = make_reader(fh).get_summary().statistics
    counted = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    assert info["message_count"] == stats.message_count == sum(counted.values())
    frames = len(np.load(failing / "trajectory.npz")["t"])
    assert counted["/tf"] == counted["/clock"] == counted["/agent_0/odom"] == frames
    assert counted["/swarmscene/obstacles"] == 1 and counted["/swarmscene/keep_out"] == 1


def test_every_message_decodes_with_mcap_ros2_support_and_rosbags_reads_the_same(failing):
    decoded = _decoded(_mcap(failing))
    with open(_mcap(failing), "rb") as fh:
        raw = [(c.topic, m.log_time, m.data) for _, c, m in make_reader(fh).iter_messages(log_time_order=False)]
    with AnyReader([failing / "bag"], default_typestore=HUMBLE) as reader:
        theirs = [(c.topic, t, bytes(data)) for c, t, data in reader.messages()]
        for conn, _, data in reader.messages():  # rosbags' own decoder and definitions, every message
            reader.deserialize(data, conn.msgtype)
    assert len(decoded) == len(raw)
    assert sorted(theirs) == sorted(raw)
    odom = {(topic, t): msg for topic, t, msg in decoded if topic == "/agent_1/odom"}
    with AnyReader([failing / "bag"], default_typestore=HUMBLE) as reader:
        conn = next(c for c in reader.connections if c.topic == "/agent_1/odom")
        for _, t, data in reader.messages(connections=[conn]):
            ours, msg = odom[("/agent_1/odom", t)], reader.deserialize(data, conn.msgtype)
            assert (msg.pose.pose.position.x, msg.pose.pose.position.y, msg.twist.twist.linear.z) == (
                ours.pose.pose.position.x, ours.pose.pose.position.y, ours.twist.twist.linear.z)
            assert msg.child_frame_id == ours.child_frame_id == "agent_1/base_link"


def test_tf_positions_equal_the_trajectory_exactly_in_rep_105_frames(failing):
    traj = np.load(failing / "trajectory.npz")
    t, parents, children, trans, rot = _tf(_mcap(failing))
    assert parents == {"world"}
    assert children == [f"agent_{i}/base_link" for i in range(traj["pos"].shape[1])]
    assert np.array_equal(t, np.round(traj["t"] * 1e9).astype(np.int64))  # stamps: the simulated time, in ns
    assert np.array_equal(trans, traj["pos"])  # bit for bit
    assert np.array_equal(rot, np.broadcast_to([0.0, 0.0, 0.0, 1.0], rot.shape))  # point masses: identity


def test_attitude_goes_to_ros_order_and_the_twist_to_the_body_frame(show):
    traj = np.load(show / "trajectory.npz")
    _, _, _, trans, rot = _tf(_mcap(show))
    assert np.array_equal(trans, traj["pos"])
    assert np.array_equal(rot, traj["quat"][..., [1, 2, 3, 0]])  # (w, x, y, z) -> (x, y, z, w)
    odom = [msg for _, _, msg in _decoded(_mcap(show), ["/agent_2/odom"])]
    linear = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z] for m in odom])
    body = np.einsum("tji,tj->ti", replay.rotation_matrices(traj["quat"][:, 2]), traj["vel"][:, 2])  # R^T v
    np.testing.assert_allclose(linear, body, rtol=0, atol=1e-12)
    assert np.linalg.norm(linear - traj["vel"][:, 2], axis=1).max() > 1e-3  # not the world velocity


def test_odometry_covariance_is_the_declared_sensing_noise(tmp_path):
    api.run(["disturbances=[mocap]", "clock.duration=0.3", "output.mcap=true", "output.summary=false"],
            output_dir=tmp_path / "run")
    msg = _decoded(_mcap(tmp_path / "run"), ["/agent_0/odom"])[0][2]
    pose, twist = np.reshape(msg.pose.covariance, (6, 6)), np.reshape(msg.twist.covariance, (6, 6))
    expected_pose, expected_twist = np.zeros((6, 6)), np.zeros((6, 6))
    expected_pose[:3, :3] = np.diag([0.001 ** 2] * 3)  # scenarios/disturbances/mocap.yaml pos_std
    expected_twist[:3, :3] = np.diag([0.1 ** 2] * 3)  # ... vel_std
    assert np.array_equal(pose, expected_pose) and np.array_equal(twist, expected_twist)


def test_events_failures_first_violations_and_verdicts_are_log_lines_on_the_timeline(failing):
    lines = [(ns * 1e-9, msg.level, msg.msg) for _, ns, msg in _decoded(_mcap(failing), ["/rosout"])]
    assert lines[0] == (3.0, 30, "agent 0: failed (hovers in place)")  # WARN at the event's time
    end = float(np.load(failing / "trajectory.npz")["t"][-1])
    metrics = RunDir(failing).metrics()
    assert (end, 20, f"run ended: {metrics['stop_reason']}") in lines
    verdicts = [text for t, _, text in lines if t == end and text.split(" ", 1)[0] in ("OK", "FAIL", "n/a")]
    assert [v.split(":")[0] for v in verdicts[:4]] == ["OK separation", "OK clearance", "OK connectivity",
                                                       verdicts[3].split(":")[0]]
    assert verdicts[0].startswith(f"OK separation: min {metrics['min_separation']:.2f} m")
    keep_out = _decoded(_mcap(failing), ["/swarmscene/keep_out"])
    (_, ns, msg), = keep_out
    marker = msg.markers[0]
    assert ns == 3_000_000_000 and marker.id == 0 and marker.type == 3  # a CYLINDER around agent 0
    assert marker.scale.x == 2 * replay.exclusion_radius(plots.load_run(failing).config, metrics)


def test_obstacles_are_one_latched_triangle_list_of_the_obstacle_prisms(failing):
    (_, ns, msg), = _decoded(_mcap(failing), ["/swarmscene/obstacles"])
    marker = msg.markers[0]
    run = plots.load_run(failing)
    verts, tris = replay.obstacle_mesh(plots.RunData(config={}, t=run.t[:1], pos=run.pos[:1], vel=run.vel[:1],
                                                     healthy=run.healthy[:1], obstacles=run.obstacles))
    points = np.array([[p.x, p.y, p.z] for p in marker.points])
    assert ns == 0 and marker.type == 11 and np.array_equal(points, verts[tris.reshape(-1)])
    info = yaml.safe_load((failing / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
           for t in info["topics_with_message_count"]}
    assert yaml.safe_load(qos["/swarmscene/obstacles"])[0]["durability"] == 1  # transient local


def test_formation_slots_are_the_formations_setpoints(tmp_path):
    sim = api.build(["clock.duration=0.5", "output.mcap=true", "output.summary=false"])
    writers = api.extra_writers(sim)
    seen = []
    original = sim.formation.setpoints  # the recorder's wrapper: what it records is what the kernel gets
    sim.formation.setpoints = lambda world, sensing: seen.append((world.t, original(world, sensing))) or seen[-1][1]
    result = sim.run()
    api.write_outputs(sim, result, tmp_path, [lambda d, w=w: w(d, sim=sim, result=result) for w in writers])
    slots = _decoded(_mcap(tmp_path), ["/swarmscene/formation_slots"])
    assert len(slots) == len(seen) == 5
    for (_, ns, msg), (t, sp) in zip(slots, seen, strict=True):
        points = np.array([[p.x, p.y, p.z] for p in msg.markers[0].points])
        assert np.array_equal(points, sp.pos) and ns == round(t * 1e9)  # stamped when the tick began


def test_rerun_opens_the_mcap_and_reads_the_same_transforms(failing, tmp_path):
    """Rerun's own MCAP loader (``rerun mcap convert``) turns each /tf transform into a Transform3D row
    (a row per child frame, float32) and each /rosout line into a TextLog."""
    from rerun.chunk import RrdReader

    from swarmscene.views.live import rerun_command

    rrd = tmp_path / "bag.rrd"
    proc = subprocess.run([*rerun_command(), "mcap", "convert", str(_mcap(failing)), "-o", str(rrd)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows, texts = [], []
    for chunk in RrdReader(str(rrd)).stream():
        if chunk.is_static or str(chunk.entity_path) not in ("/tf", "/rosout"):
            continue
        data = chunk.to_record_batch().to_pydict()
        if str(chunk.entity_path) == "/tf":
            rows += zip(data["message_log_time"], data["Transform3D:child_frame"],
                        data["Transform3D:parent_frame"], data["Transform3D:translation"], strict=True)
        else:
            texts += [t[0] for t in data["TextLog:text"]]
    traj = np.load(failing / "trajectory.npz")
    t, n = traj["t"], traj["pos"].shape[1]
    assert len(rows) == len(t) * n
    by_time = {}
    for when, child, parent, xyz in rows:
        assert parent == ["world"]
        by_time.setdefault(when.value, {})[child[0]] = xyz[0]
    assert sorted(by_time) == np.round(t * 1e9).astype(np.int64).tolist()
    translations = np.array([[by_time[k][f"agent_{i}/base_link"] for i in range(n)] for k in sorted(by_time)])
    assert np.array_equal(translations, traj["pos"].astype(np.float32))  # Rerun keeps float32
    assert "[swarmscene] agent 0: failed (hovers in place)" in texts  # Rerun prefixes the node name


# -- converted from a run directory --------------------------------------------------------------
def test_the_converter_writes_the_same_tf_and_odometry_from_the_run_directory(failing, tmp_path):
    out = mcap_bag.export_mcap(failing, tmp_path / "converted")
    assert sorted(p.name for p in out.iterdir()) == ["converted_0.mcap", "metadata.yaml"]
    ours = _tf(out / "converted_0.mcap")
    live = _tf(_mcap(failing))
    for a, b in zip(ours, live, strict=True):
        assert np.array_equal(np.asarray(a), np.asarray(b)) if not isinstance(a, set) else a == b
    for topic in ("/agent_1/odom", "/clock"):
        converted, streamed = _decoded(out / "converted_0.mcap", [topic]), _decoded(_mcap(failing), [topic])
        assert [ns for _, ns, _ in converted] == [ns for _, ns, _ in streamed]
    pose = [[(m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z, m.twist.twist.linear.x)
             for _, _, m in _decoded(path, ["/agent_1/odom"])] for path in (out / "converted_0.mcap", _mcap(failing))]
    assert pose[0] == pose[1]
    lines = {msg.msg for _, _, msg in _decoded(out / "converted_0.mcap", ["/rosout"])}
    assert "agent 0: failed (hovers in place)" in lines
    assert any(line.startswith("OK separation: min") for line in lines)
    with AnyReader([out], default_typestore=HUMBLE) as reader:
        assert reader.message_count == sum(1 for _ in _decoded(out / "converted_0.mcap"))


def test_the_export_command_writes_a_bag_and_refuses_what_it_cannot_write(failing, tmp_path):
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    cmd = [sys.executable, "-m", "swarmscene.views.export", str(failing), "--mcap", str(tmp_path / "out")]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0 and (tmp_path / "out" / "out_0.mcap").is_file(), done.stderr
    again = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert again.returncode == 2
    assert again.stderr == (f"python -m swarmscene.views.export: --mcap: {tmp_path / 'out'} exists (a bag is written "
                            "into a new folder, as ros2 bag record does)\n")
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    for name in ("config.yaml", "metrics.json", "manifest.json"):
        (damaged / name).write_bytes((failing / name).read_bytes())
    (damaged / "trajectory.npz").write_bytes((failing / "trajectory.npz").read_bytes()[:500])
    bad = subprocess.run([sys.executable, "-m", "swarmscene.views.export", str(damaged), "--mcap", str(tmp_path / "b")],
                         capture_output=True, text=True, env=env, timeout=300)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1
    assert bad.stderr.startswith(f"python -m swarmscene.views.export: {damaged / 'trajectory.npz'}: not a readable numpy")
    assert not (tmp_path / "b").exists() and not list(tmp_path.glob(".b.*"))


# -- safe writes ----------------------------------------------------------------------------------
def test_a_link_planted_at_the_bag_is_replaced_never_followed(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "keep.txt").write_text("mine")
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "bag").symlink_to(elsewhere, target_is_directory=True)
    api.run(["clock.duration=0.3", "output.mcap=true", "output.summary=false"], output_dir=run_dir)
    assert not (run_dir / "bag").is_symlink() and (run_dir / "bag" / "bag_0.mcap").is_file()
    assert [p.name for p in elsewhere.iterdir()] == ["keep.txt"]


def test_a_directory_written_again_keeps_no_bag_of_an_earlier_run(tmp_path):
    """A run without output.mcap, written into the directory of one with it, removes that run's
    bag: the new manifest listed it, and a replay of RUN_DIR/bag flew the earlier run."""
    run_dir = tmp_path / "run"
    api.run(["clock.duration=0.3", "output.mcap=true", "output.summary=false"], output_dir=run_dir)
    assert "bag" in RunDir(run_dir).manifest()["files"]
    api.run(["clock.duration=0.5", "output.summary=false"], output_dir=run_dir)
    assert not (run_dir / "bag").exists() and "bag" not in RunDir(run_dir).manifest()["files"]


def test_more_vehicles_than_a_bag_has_channels_is_one_line():
    """MCAP's channel ids are 16-bit, an odometry topic per vehicle: past the limit the writer says
    so instead of struct's 'ushort format requires 0 <= number <= 65535'."""
    import io

    with pytest.raises(ValueError, match=rf"^output.mcap: a bag holds at most {mcap_bag.MAX_VEHICLES} vehicles "):
        mcap_bag.BagWriter(io.BytesIO(), {}, mcap_bag.MAX_VEHICLES + 1)
    assert mcap_bag.MAX_VEHICLES + len(mcap_bag.TOPICS) - 1 == 0xFFFF


def test_the_bag_is_streamed_to_a_private_spill_directory_and_moved_in(tmp_path):
    spill = tmp_path / "spill"
    sim = api.build(["clock.duration=0.3", "output.mcap=true", "output.summary=false",
                     f"output.trajectory_spill_dir={spill}"])
    (publish,) = api.extra_writers(sim)
    (private,) = list(spill.iterdir())
    assert private.name.startswith(".bag.") and oct(private.stat().st_mode & 0o777) == "0o700"
    result = sim.run()
    api.write_outputs(sim, result, tmp_path / "run", [lambda d: publish(d, sim=sim, result=result)])
    assert list(spill.iterdir()) == [] and (tmp_path / "run" / "bag" / "bag_0.mcap").is_file()


def test_a_run_without_a_directory_refuses_output_mcap():
    with pytest.raises(ConfigError) as err:
        api.run(["clock.duration=0.3", "output.mcap=true", "output.summary=false"])
    assert err.value.lines == ["output.mcap=true: writes files, so it needs a run directory: "
                               "api.run(..., output_dir=...)"]


def test_the_layout_shipped_names_topics_the_bag_holds():
    import json

    layout = json.loads(mcap_bag.LAYOUT.read_text())
    panels = layout["configById"]
    assert set(panels["3D!swarmscene"]["topics"]) <= set(mcap_bag.TOPICS)
    plotted = {p["value"].rsplit(".", 1)[0] for p in panels["Plot!separation"]["paths"]}
    assert plotted == {"/swarmscene/min_separation", "/swarmscene/separation_limit"}
    assert panels["3D!swarmscene"]["followTf"] == mcap_bag.WORLD_FRAME
    assert {layout["layout"]["first"], layout["layout"]["second"]["first"], layout["layout"]["second"]["second"]} == \
        set(panels)


def test_the_bag_changes_no_number_of_the_run_nor_its_config_hash(failing, tmp_path):
    api.run([o for o in FAILING if o != "output.mcap=true"], output_dir=tmp_path / "plain")
    ours, plain = np.load(failing / "trajectory.npz"), np.load(tmp_path / "plain" / "trajectory.npz")
    assert all(np.array_equal(ours[k], plain[k]) for k in ("t", "pos", "vel", "healthy"))
    assert RunDir(failing).manifest()["config_hash"] == RunDir(tmp_path / "plain").manifest()["config_hash"]


class StopAt:
    """Asks the run to stop (as Ctrl-C does) at its fifth tick."""

    @hookimpl
    def swarmscene_step_end(self, sim):
        from swarmscene.core import interrupts

        if sim.step_count == 5:
            interrupts.request()


def _stopped_run(run_dir, spill):
    from swarmscene.core import interrupts

    sim = api.build(["clock.duration=2.0", "output.mcap=true", "output.summary=false",
                     f"output.trajectory_spill_dir={spill}"])
    (publish,) = api.extra_writers(sim)
    sim.pm.register(StopAt(), name="stop_at")
    try:
        result = sim.run()
        api.write_outputs(sim, result, run_dir, [lambda d: publish(d, sim=sim, result=result)])
    finally:
        interrupts.clear()


def test_a_run_stopped_early_leaves_no_bag_and_no_spill(tmp_path):
    """Ctrl-C mid-run: the directory is marked incomplete, the extras (the bag among them) are left
    out, and the bag's private spill directory goes with the recorder."""
    import gc

    _stopped_run(tmp_path / "run", tmp_path / "spill")
    assert RunDir(tmp_path / "run").manifest()["complete"] is False
    assert not (tmp_path / "run" / "bag").exists()
    gc.collect()
    assert list((tmp_path / "spill").iterdir()) == []


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
def test_the_mcap_writer_makes_files_the_mcap_reader_and_rosbags_read_in_each_compression(tmp_path, compression):
    from swarmscene.methods.ros2.cdr import CdrTemplate, split_time
    from swarmscene.views.mcap_file import McapWriter, RecordBlock

    frames = ["a/base_link", "bb/base_link"]
    (tmp_path / "b").mkdir()
    with open(tmp_path / "b" / "b_0.mcap", "wb") as fh:
        writer = McapWriter(fh, "ros2", "test", compression, chunk_bytes=2000)  # many chunks
        schema = writer.add_schema("tf2_msgs/msg/TFMessage", "ros2msg", messages.msgdef("tf2_msgs/msg/TFMessage").encode())
        channel = writer.add_channel("/tf", schema, "cdr")
        block = RecordBlock([channel], CdrTemplate([messages.tf_message("world", frames)]))
        expected = []
        for k in range(50):
            pose = np.column_stack([np.full((2, 3), k + 0.5) + [[0, 1, 2]], np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))])
            writer.write_block(block, k * 10**8, stamp=split_time(k * 0.1), transform=pose)
            expected.append(pose[:, :3].copy())
        writer.finish()
    got = np.array([[[t.transform.translation.x, t.transform.translation.y, t.transform.translation.z]
                     for t in msg.transforms] for _, _, msg in _decoded(tmp_path / "b" / "b_0.mcap")])
    assert np.array_equal(got, np.array(expected))
    with open(tmp_path / "b" / "b_0.mcap", "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert len(summary.chunk_indexes) > 5 and {c.compression for c in summary.chunk_indexes} == {compression}
    from rosbags.rosbag2.storage_mcap import McapReader

    reader = McapReader(tmp_path / "b" / "b_0.mcap")  # rosbags' own MCAP reader
    reader.open()
    assert sum(1 for _ in reader.messages(reader.connections)) == 50
    reader.close()
