"""Rerun export, read back in Python as the user would (``replay.read_recordings``): one recording per
run (name, seed, config hash), agents in their colours with labels, attitude as oriented boxes and
body axes, safety series against their limits, events, obstacles, exclusion zones, comm edges."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from rerun.chunk import RrdReader

from swarmscene import api
from swarmscene.views import plots, replay

OVERRIDES = ["events=lead_fails", "events.0.at=3.0", "clock.duration=8.0"]
SHOW = ["scenario=vrb_airshow", "clock.duration=4.0"]  # 6-DOF quadrotors: attitude recorded


def _write(run_dir, overrides):
    sim = api.build(overrides)
    result = sim.run()
    api.write_outputs(sim, result, run_dir)
    return replay.export_rerun(run_dir)  # from the directory's files alone


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    """The default scenario with the leader failing at 3 s, seeds 0 and 1, read back together."""
    dirs = [tmp_path_factory.mktemp(f"seed{seed}") for seed in (0, 1)]
    paths = [_write(d, [*OVERRIDES, f"seed={seed}"]) for seed, d in zip((0, 1), dirs, strict=True)]
    return dirs, paths, replay.read_recordings(paths)


@pytest.fixture(scope="module")
def show(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("show")
    path = _write(run_dir, SHOW)
    (rid, frame), = replay.read_recordings([path]).items()
    return plots.load_run(run_dir), frame


def _column(frame, entity, component):
    """The non-null rows of one column: (times s, values)."""
    name = f"{entity}:{component}"
    rows = frame[frame[name].notna()]
    return rows["sim_time"].dt.total_seconds().to_numpy(), [_plain(v) for v in rows[name]]


def _plain(value):
    """Nested numpy object arrays (how pandas holds Arrow lists) as nested Python lists."""
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value]
    return value.item() if isinstance(value, np.generic) else value


def test_each_seed_is_its_own_recording_named_by_name_seed_and_config_hash(seeds):
    dirs, paths, recordings = seeds
    expected = []
    for seed, run_dir in zip((0, 1), dirs, strict=True):
        digest = json.loads((run_dir / "manifest.json").read_text())["config_hash"]
        expected.append(f"default-seed{seed}-{digest[:12]}")
    assert sorted(recordings) == sorted(expected) and expected[0] != expected[1]
    for path, rid in zip(paths, expected, strict=True):
        (recording,) = RrdReader(str(path)).recordings()
        assert recording.application_id == "swarmscene" and recording.recording_id == rid


def test_recording_holds_every_entity(seeds):
    _, _, recordings = seeds
    columns = set(next(iter(recordings.values())).columns)
    for entity in ("/world/agents:Points3D:positions", "/world/trails:LineStrips3D:strips",
                   "/world/obstacles:LineStrips3D:strips", "/world/obstacles/solid:Mesh3D:vertex_positions",
                   "/world/exclusion:LineStrips3D:strips", "/world/comm_edges:LineStrips3D:strips",
                   "/world/failures/0:Points3D:positions", "/safety/separation/min:Scalars:scalars",
                   "/safety/separation/limit:Scalars:scalars", "/safety/clearance/min:Scalars:scalars",
                   "/safety/clearance/limit:Scalars:scalars", "/safety/separation/events:Scalars:scalars",
                   "/events:TextLog:text"):
        assert entity in columns, entity
    assert not any("bodies" in c for c in columns)  # point-mass dynamics: no attitude to draw


def test_agents_read_back_with_positions_colours_and_labels(seeds):
    """The logged points are the recorded positions on sim_time, each agent in its colour
    (agent_colors, as in the pictures), labelled, "0 failed" once the leader has failed."""
    dirs, _, recordings = seeds
    run = plots.load_run(dirs[0])
    frame = recordings[replay.recording_id(run)]
    times, positions = _column(frame, "/world/agents", "Points3D:positions")
    np.testing.assert_allclose(times, run.t, atol=1e-9)
    np.testing.assert_allclose(np.array(positions, float), run.pos, atol=1e-5)  # stored as float32
    _, colors = _column(frame, "/world/agents", "Points3D:colors")
    rgba = plots.agent_colors(run.n).astype(np.uint32)
    packed = (rgba[:, 0] << 24) | (rgba[:, 1] << 16) | (rgba[:, 2] << 8) | 0xFF
    assert colors[0] == colors[-1] == packed.tolist()
    _, labels = _column(frame, "/world/agents", "Points3D:labels")
    assert labels[0] == ["0", "1", "2", "3", "4"]
    assert labels[-1] == ["0 failed", "1", "2", "3", "4"]
    k = int(np.argmax(~run.healthy[:, 0]))
    assert labels[k][0] == "0 failed" and labels[k - 1][0] == "0"


def test_safety_series_equal_the_trajectorys_and_limits_span_the_run(seeds):
    dirs, _, recordings = seeds
    run = plots.load_run(dirs[1])
    frame = recordings[replay.recording_id(run)]
    expected = plots.safety_series(run)
    for name in ("separation", "clearance"):
        times, values = _column(frame, f"/safety/{name}/min", "Scalars:scalars")
        np.testing.assert_allclose(times, run.t, atol=1e-9)
        np.testing.assert_allclose(np.array(values).ravel(), expected[f"min_{name}"], rtol=1e-12)
    times, values = _column(frame, "/safety/separation/limit", "Scalars:scalars")
    assert times.tolist() == pytest.approx([0.0, 8.0]) and np.ravel(values).tolist() == [0.5, 0.5]
    _, values = _column(frame, "/safety/clearance/limit", "Scalars:scalars")
    assert np.ravel(values).tolist() == [run.min_clearance_limit] * 2


def test_events_are_logged_and_marked_on_the_separation_series(seeds):
    dirs, _, recordings = seeds
    run = plots.load_run(dirs[0])
    frame = recordings[replay.recording_id(run)]
    times, texts = _column(frame, "/events", "TextLog:text")
    assert dict(zip(np.round(times, 9).tolist(), texts, strict=True)) == {3.0: ["agent 0: failed (hovers in place)"],
                                                              8.0: ["run ended: duration"]}
    times, values = _column(frame, "/safety/separation/events", "Scalars:scalars")
    assert times.tolist() == [3.0, 8.0]
    sep = plots.safety_series(run)["min_separation"]
    assert np.ravel(values).tolist() == pytest.approx([sep[np.searchsorted(run.t, 3.0 - 1e-9)], sep[-1]])
    times, where = _column(frame, "/world/failures/0", "Points3D:positions")
    assert times.tolist() == [3.0]
    np.testing.assert_allclose(where[0][0], run.failures()[0][2], atol=1e-6)


def test_attitude_as_oriented_boxes_and_body_axes(show):
    """Boxes carry the recorded quaternions (Rerun order x, y, z, w); the three arrows of each
    vehicle are the columns of its rotation matrix (body axes in the world)."""
    run, frame = show
    assert run.quat is not None
    times, quats = _column(frame, "/world/bodies", "Boxes3D:quaternions")
    np.testing.assert_allclose(times, run.t, atol=1e-9)
    q = np.array(quats, float)
    np.testing.assert_allclose(q, np.concatenate([run.quat[..., 1:], run.quat[..., :1]], -1), atol=1e-6)
    assert np.abs(run.quat[-1, :, 1:3]).max() > 1e-3  # the show really tilts the vehicles
    _, centers = _column(frame, "/world/bodies", "Boxes3D:centers")
    np.testing.assert_allclose(np.array(centers, float), run.pos, atol=1e-5)
    _, arrows = _column(frame, "/world/body_axes", "Arrows3D:vectors")
    vectors = np.array(arrows, float).reshape(len(run.t), run.n, 3, 3)
    from scipy.spatial.transform import Rotation

    k = len(run.t) - 1
    rot = Rotation.from_quat(run.quat[k], scalar_first=True).as_matrix()  # (N, 3, 3)
    length = np.linalg.norm(vectors[k, 0, 0])
    np.testing.assert_allclose(vectors[k] / length, np.swapaxes(rot, -1, -2), atol=1e-5)


def test_rotation_matrices_match_scipy():
    from scipy.spatial.transform import Rotation

    quat = Rotation.random(20, random_state=3).as_quat(scalar_first=True)
    np.testing.assert_allclose(replay.rotation_matrices(quat), Rotation.from_quat(quat, scalar_first=True).as_matrix(),
                               atol=1e-12)


def test_exclusion_radius_is_read_from_the_metrics_never_the_yaml():
    """#16: with the group default a_f: null the YAML holds no a_p; the metric does, or nothing."""
    cem = {"avoidance": {"name": "cem", "a_f": None, "delta": 0.4, "eps": 0.28}}
    assert replay.exclusion_radius(cem, {"cem.a_p": 1.36}) == 1.36
    assert replay.exclusion_radius(cem, {}) is None  # metric absent: no circle, no crash
    assert replay.exclusion_radius({"avoidance": {"name": "potential"}, "safety": {"min_separation": 0.5}}, {}) == 0.5


def test_obstacle_outlines_and_solid_follow_the_footprints(seeds):
    run = plots.load_run(seeds[0][0])
    strips = replay.obstacle_strips(run)
    ring = np.asarray(run.obstacles[0].exterior.coords)
    # ground and ceiling outlines, then one vertical edge per corner
    assert len(strips) == 2 + len(ring) - 1
    np.testing.assert_allclose(strips[0][:, :2], ring[:, :2])
    assert set(strips[0][:, 2]) == {0.0} and strips[1][0, 2] > run.pos[..., 2].max()
    verts, tris = replay.obstacle_mesh(run)
    m = len(ring) - 1
    assert len(tris) == 2 * m + (m - 2)  # two triangles per wall, a fan of m - 2 for the roof
    roof = verts[tris[2 * m:]]
    u, v = roof[:, 1, :2] - roof[:, 0, :2], roof[:, 2, :2] - roof[:, 0, :2]
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum()
    assert area == pytest.approx(run.obstacles[0].area)


def test_cli_output_rerun_true_with_cem_does_not_crash(tmp_path):
    """#16: ``avoidance=cem output.rerun=true`` crashed after the run (a_f: null in the YAML)."""
    env = {**os.environ}
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.run(
        [sys.executable, "-c", "from swarmscene.cli import main; main()", *OVERRIDES, "avoidance=cem",
         "output.rerun=true", f"hydra.run.dir={tmp_path}/run"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    run = plots.load_run(tmp_path / "run")
    ((rid, frame),) = replay.read_recordings([tmp_path / "run" / "replay.rrd"]).items()
    digest = json.loads((tmp_path / "run" / "manifest.json").read_text())["config_hash"]
    assert rid == f"default-seed{run.seed}-{digest[:12]}"  # exported during the run, before the manifest
    a_p = run.metrics["cem.a_p"]  # published by the cem plugin: a_f + delta + eps with a_f = eps + delta
    assert a_p == pytest.approx(2 * (0.28 + 0.40))
    _, strips = _column(frame, "/world/exclusion", "LineStrips3D:strips")
    circle = np.array([s for s in strips if s][-1][0])
    assert np.linalg.norm(circle[0] - circle[:-1].mean(axis=0)) == pytest.approx(a_p, rel=1e-3)  # closed ring


def test_links_planted_at_the_temporary_or_target_name_are_never_written_through(tmp_path):
    run_dir = tmp_path / "run"
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    sim = api.build(["clock.duration=1.0"])
    api.write_outputs(sim, sim.run(), run_dir)
    (run_dir / ".replay.rrd.tmp").symlink_to(victim)  # the temporary name of former versions
    (run_dir / "replay.rrd").symlink_to(victim)
    path = replay.export_rerun(run_dir)
    assert victim.read_bytes() == b"precious"
    assert not path.is_symlink() and path.stat().st_size > 1000
    assert sorted(p.name for p in run_dir.iterdir() if p.name.endswith(".tmp")) == [".replay.rrd.tmp"]  # left alone


def test_the_command_names_a_damaged_file_in_one_line(tmp_path, capsys):
    run_dir = tmp_path / "run"
    sim = api.build(["clock.duration=0.5"])
    api.write_outputs(sim, sim.run(), run_dir)
    (run_dir / "trajectory.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(SystemExit) as exit_:
        replay.main([str(run_dir)])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.startswith(
        f"python -m swarmscene.views.replay: {run_dir}/trajectory.npz: not a readable numpy archive (")
    assert not (run_dir / "replay.rrd").exists()
    with pytest.raises(SystemExit) as exit_:
        replay.main([str(run_dir), "--every", "0"])
    assert exit_.value.code == 2 and capsys.readouterr().err == \
        "python -m swarmscene.views.replay: --every: must be an integer >= 1 (got 0)\n"
