"""Trajectory recorder: streaming to disk in chunks gives the in-memory arrays, with bounded memory."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.recorder import MIB, NpyAppender, npy_header

BASE = ["scenario=flocking", "swarm.n=30", "swarm.start.extent=30", "clock.duration=40"]
TINY = 0.01  # MiB: a few frames of 30 agents, so a 41-frame run needs many chunks


def run(*overrides: str, output_dir=None):
    return api.run([*BASE, *overrides], output_dir=output_dir)


def recorder(result):
    return result.recorder


@pytest.mark.parametrize("extra", [[], ["output.trajectory_every=3"], ["output.float32=true"]])
def test_streamed_arrays_equal_in_memory_arrays(extra, tmp_path):
    memory = run(*extra, "output.trajectory_stream=off")
    streamed = run(*extra, "output.trajectory_stream=on", f"output.trajectory_buffer_mb={TINY}",
                   output_dir=tmp_path)
    rec = recorder(streamed)
    assert rec.streaming and not recorder(memory).streaming
    assert 1 < rec.chunk < rec.count  # several chunks, the last one partial or full
    a, b = memory.trajectory, streamed.trajectory
    archive = np.load(tmp_path / "trajectory.npz")
    assert set(a) == set(b) == set(archive.files) == {"t", "pos", "vel", "healthy"}
    for key in a:
        assert a[key].dtype == b[key].dtype == archive[key].dtype
        np.testing.assert_array_equal(a[key], b[key])
        np.testing.assert_array_equal(a[key], archive[key])


def test_decimation_keeps_every_kth_tick():
    traj = run("output.trajectory_every=4", "output.trajectory_stream=on",
               f"output.trajectory_buffer_mb={TINY}").trajectory
    np.testing.assert_allclose(traj["t"], np.arange(0.0, 41.0, 4.0))
    assert traj["pos"].shape == (11, 30, 3)
    full = run("output.trajectory_stream=off").trajectory
    np.testing.assert_array_equal(traj["pos"], full["pos"][::4])


def test_float32_halves_the_frames():
    r64 = recorder(run("output.trajectory_stream=off"))
    r32 = recorder(run("output.trajectory_stream=off", "output.float32=true"))
    assert r32.buffer["pos"].dtype == np.float32 and r64.buffer["pos"].dtype == np.float64
    assert r32.buffer["pos"].nbytes * 2 == r64.buffer["pos"].nbytes


def test_memory_is_bounded_by_the_buffer_whatever_the_length():
    short = recorder(run("output.trajectory_stream=on", f"output.trajectory_buffer_mb={TINY}"))
    long = recorder(run("output.trajectory_stream=on", f"output.trajectory_buffer_mb={TINY}",
                        "clock.duration=400"))
    budget = TINY * MIB
    assert short.buffer_bytes() == long.buffer_bytes() <= budget
    frame_bytes = 30 * (3 * 8 + 3 * 8 + 1)
    assert long.count * frame_bytes > 50 * budget  # the record itself is far larger...
    on_disk = sum(f.path.stat().st_size for f in long.files.values())
    assert on_disk == 3 * 256 + long.count * frame_bytes  # ...and went to disk, headers aside


def test_auto_streams_only_when_the_record_exceeds_the_buffer():
    assert not recorder(run()).streaming  # 41 frames of 30 agents: well under 256 MiB
    rec = recorder(run(f"output.trajectory_buffer_mb={TINY}"))
    assert rec.streaming and rec.buffer_bytes() <= TINY * MIB


def test_spill_directory_is_removed_with_the_recorder():
    result = run("output.trajectory_stream=on")
    spill = recorder(result).spill_dir
    assert spill.is_dir() and {p.name for p in spill.iterdir()} == {"pos.npy", "vel.npy", "healthy.npy"}
    del result
    gc.collect()
    assert not spill.exists()


def test_spill_goes_where_asked(tmp_path):
    rec = recorder(run("output.trajectory_stream=on", f"output.trajectory_spill_dir={tmp_path / 'spill'}"))
    assert rec.spill_dir.parent == tmp_path / "spill"


def test_npy_appender_reads_back_as_one_array(tmp_path):
    frames = np.arange(5 * 4 * 3, dtype=np.float32).reshape(5, 4, 3)
    app = NpyAppender(tmp_path / "x.npy", (4, 3), np.float32)
    assert app.load().shape == (0, 4, 3)
    app.append(frames[:2])
    np.testing.assert_array_equal(app.load(), frames[:2])  # readable mid-way
    app.append(frames[2:])
    app.close()
    np.testing.assert_array_equal(np.load(tmp_path / "x.npy"), frames)
    assert len(npy_header(np.dtype(np.float64), (10**15, 10**6, 3))) == 256


def test_attitude_is_streamed_too():
    base = ["dynamics=quadrotor", "clock.duration=1", "clock.physics_step=0.005"]
    memory = api.run([*base, "output.trajectory_stream=off"]).trajectory
    streamed = api.run([*base, "output.trajectory_stream=on", "output.trajectory_buffer_mb=0.001"])
    assert recorder(streamed).chunk < recorder(streamed).count
    assert set(streamed.trajectory) == set(memory) == {"t", "pos", "vel", "healthy", "quat"}
    for key, value in memory.items():
        np.testing.assert_array_equal(value, streamed.trajectory[key])


def test_npz_copies_whole_spill_files_and_writes_other_arrays(tmp_path):
    from swarmscene.runs.outputs import _whole_npy_file, write_npz

    frames = np.arange(6 * 2 * 3, dtype=np.float32).reshape(6, 2, 3)
    app = NpyAppender(tmp_path / "pos.npy", (2, 3), np.float32)
    app.append(frames)
    mapped = app.load()
    assert _whole_npy_file(mapped) == str(tmp_path / "pos.npy")  # copied file to file
    assert _whole_npy_file(mapped[1:]) is None and _whole_npy_file(frames) is None  # written by numpy
    write_npz(tmp_path / "out.npz", {"pos": mapped, "tail": mapped[2:], "t": np.arange(6.0)})
    archive = np.load(tmp_path / "out.npz")
    np.testing.assert_array_equal(archive["pos"], frames)
    np.testing.assert_array_equal(archive["tail"], frames[2:])
    np.testing.assert_array_equal(archive["t"], np.arange(6.0))


def test_the_same_run_writes_the_same_bytes_streamed_or_not(tmp_path):
    """Same config, same seed: trajectory.npz is byte-identical run after run (every member has
    the same fixed timestamp), and the streamed archive equals the in-memory one."""
    import time

    files = []
    for k, stream in enumerate(("on", "on", "off")):
        if k:
            time.sleep(2.1)  # past the zip format's 2-second timestamp resolution
        run("clock.duration=4", "output.trajectory_stream=" + stream, f"output.trajectory_buffer_mb={TINY}",
            output_dir=tmp_path / str(k))
        files.append((tmp_path / str(k) / "trajectory.npz").read_bytes())
    assert files[0] == files[1] == files[2]


def test_a_planted_link_in_the_spill_directory_is_refused(tmp_path):
    from swarmscene.core.recorder import create_exclusive

    victim = tmp_path / "victim"
    victim.write_text("precious")
    (tmp_path / "pos.npy").symlink_to(victim)
    with pytest.raises(FileExistsError):
        create_exclusive(tmp_path / "pos.npy")
    assert victim.read_text() == "precious"
