"""Rerun export: the recording read back holds agents over time, trails, obstacles, exclusion zones
around the failed vehicle and communication edges (the rerun extra)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np
import pytest
from rerun.chunk import RrdReader

from swarmscene import api, plots, replay

OVERRIDES = ["events=lead_fails", "events.0.at=3.0", "clock.duration=8.0"]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("run")
    sim = api.build(OVERRIDES)
    result = sim.run()
    api.write_outputs(sim, result, run_dir)
    path = replay.export_rerun(run_dir)  # from the directory's files alone
    return run_dir, path, plots.load_run(run_dir)


def _rows(summary: str, entity: str) -> int:
    """Rows logged for ``entity`` (chunks summed) in the store summary."""
    return sum(int(m) for m in re.findall(rf"^{re.escape(entity)} rows=(\d+)", summary, flags=re.M))


def test_recording_holds_every_entity(exported):
    _, path, run = exported
    assert path.name == "replay.rrd"
    reader = RrdReader(str(path))
    (recording,) = reader.recordings()
    assert recording.application_id == "swarmscene"
    store = reader.store()
    paths = set(store.schema().entity_paths())
    assert {"/world/agents", "/world/trails", "/world/obstacles", "/world/exclusion", "/world/comm_edges"} <= paths
    summary = store.summary()
    frames = len(run.t)
    assert _rows(summary, "/world/agents") == frames  # one row of N points per recorded frame
    assert _rows(summary, "/world/trails") == frames
    assert re.search(r"^/world/obstacles rows=1 static=True", summary, flags=re.M)
    assert "sim_time" in summary


def test_exclusion_radius_follows_the_avoidance():
    assert replay.exclusion_radius({"avoidance": {"name": "cem", "a_f": 0.68, "delta": 0.4, "eps": 0.28}}) == pytest.approx(1.36)
    assert replay.exclusion_radius({"avoidance": {"name": "potential"}, "safety": {"min_separation": 0.5}}) == 0.5


def test_obstacle_outlines_follow_the_footprints(exported):
    _, _, run = exported
    strips = replay.obstacle_strips(run)
    ring = np.asarray(run.obstacles[0].exterior.coords)
    # ground and ceiling outlines, then one vertical edge per corner
    assert len(strips) == 2 + len(ring) - 1
    np.testing.assert_allclose(strips[0][:, :2], ring[:, :2])
    assert set(strips[0][:, 2]) == {0.0} and strips[1][0, 2] > run.pos[..., 2].max()


def test_cli_output_rerun_true(tmp_path):
    env = {**os.environ}
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.run(
        [sys.executable, "-c", "from swarmscene.cli import main; main()", *OVERRIDES, "output.rerun=true",
         f"hydra.run.dir={tmp_path}/run"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    store = RrdReader(str(tmp_path / "run" / "replay.rrd")).store()
    assert "/world/agents" in set(store.schema().entity_paths())


def test_agent_positions_and_colours_read_back(exported):
    """The logged points are the recorded positions, on the sim_time timeline, red once failed."""
    _, path, run = exported
    batches = [ch.to_record_batch() for ch in RrdReader(str(path)).store().stream() if ch.entity_path == "/world/agents"]
    times, positions, colors = [], [], []
    for rb in batches:
        names = rb.schema.names
        times += rb.column(names.index("sim_time")).to_pylist()
        positions += rb.column(names.index("Points3D:positions")).to_pylist()
        colors += rb.column(names.index("Points3D:colors")).to_pylist()
    order = np.argsort([t.total_seconds() if hasattr(t, "total_seconds") else t for t in times])
    pos = np.array([positions[i] for i in order])
    assert pos.shape == run.pos.shape
    np.testing.assert_allclose(pos, run.pos, atol=1e-5)  # stored as float32
    last = [colors[i] for i in order][-1]
    assert len(set(last)) == 2 and last[0] != last[1]  # agent 0 failed: a colour of its own
    assert last[1:] == [last[1]] * (run.n - 1)
