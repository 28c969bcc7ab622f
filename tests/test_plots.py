"""Per-run pictures show what the arrays say: one path per agent, the failed vehicle where it failed,
the obstacles, separation and clearance against their limits, speeds, an animation with comm edges."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.patches import Polygon

from swarmscene import api, plots

OVERRIDES = ["events=lead_fails", "events.0.at=3.0", "clock.duration=12.0"]


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """The default scenario (five agents around a pillar), the leader failing at t = 3 s."""
    run_dir = tmp_path_factory.mktemp("run")
    sim = api.build(OVERRIDES)
    result = sim.run()
    api.write_outputs(sim, result, run_dir)
    return sim, result, run_dir


def _by_gid(ax, gid):
    return [a for a in [*ax.lines, *ax.collections] if a.get_gid() == gid]


def test_trajectory_figure_shows_paths_obstacles_and_failure(finished):
    sim, result, _ = finished
    run = plots.from_simulation(sim, result)
    ax = plots.trajectory_figure(run).axes[0]
    assert ax.get_xlabel() == "x (m, east)" and ax.get_ylabel() == "y (m, north)"
    paths = [line for line in ax.lines if (line.get_gid() or "").startswith("agent")]
    assert len(paths) == 5
    np.testing.assert_allclose(paths[2].get_xydata(), result.trajectory["pos"][:, 2, :2])
    assert len([p for p in ax.patches if isinstance(p, Polygon)]) == len(sim.environment.obstacles) == 1
    (failed,) = _by_gid(ax, "failed")
    t, pos, healthy = (result.trajectory[k] for k in ("t", "pos", "healthy"))
    k = int(np.argmax(~healthy[:, 0]))  # first frame showing the failure (recorded after the tick)
    assert t[k - 1] == pytest.approx(3.0) and healthy[k - 1, 0]
    np.testing.assert_allclose(failed.get_offsets(), pos[k, :1, :2])
    np.testing.assert_allclose(pos[k:, 0], np.broadcast_to(pos[k, 0], pos[k:, 0].shape))  # hovers there
    assert run.failures()[0][:2] == (0, 3.0)
    assert paths[0].get_color() == plots.FAILED_COLOR and paths[1].get_color() == plots.HEALTHY_COLOR
    assert "failed (1)" in [text.get_text() for text in ax.get_legend().get_texts()]


def test_safety_figure_draws_series_against_limits(finished):
    sim, result, _ = finished
    run = plots.from_simulation(sim, result)
    top, bottom = plots.safety_figure(run).axes
    assert top.get_ylabel() == "min separation (m)" and bottom.get_xlabel() == "time (s)"
    (sep_limit,) = _by_gid(top, "separation_limit")
    (clear_limit,) = _by_gid(bottom, "clearance_limit")
    assert set(sep_limit.get_ydata()) == {sim.config.safety.min_separation}
    assert set(clear_limit.get_ydata()) == {sim.config.safety.min_clearance}
    series = [line for line in top.lines if line.get_gid() is None][0]
    assert np.nanmin(series.get_ydata()) == pytest.approx(result.metrics["min_separation"])
    clearance = [line for line in bottom.lines if line.get_gid() is None][0]
    assert np.nanmin(clearance.get_ydata()) == pytest.approx(result.metrics["min_clearance"])


def test_series_recomputed_from_directory_match_the_monitor(finished):
    """From a run directory (trajectory every tick here) the recomputed series equal the monitor's."""
    _, result, run_dir = finished
    from_dir = plots.safety_series(plots.load_run(run_dir))
    live = result.series
    np.testing.assert_allclose(from_dir["t"], live["t"])
    np.testing.assert_allclose(from_dir["min_separation"], live["min_separation"], rtol=1e-9)
    np.testing.assert_allclose(from_dir["min_clearance"], live["min_clearance"], rtol=1e-9)


def test_speed_figure_one_line_per_agent(finished):
    sim, result, _ = finished
    ax = plots.speed_figure(plots.from_simulation(sim, result)).axes[0]
    assert ax.get_ylabel() == "speed (m/s)" and len(ax.lines) == 5
    speed = np.linalg.norm(result.trajectory["vel"][:, 4], axis=1)
    np.testing.assert_allclose(ax.lines[4].get_ydata(), speed)
    assert ax.lines[0].get_linestyle() == "--"  # the failed leader
    assert ax.lines[0].get_ydata()[-1] == 0.0  # it hovers


def test_comm_edges_are_healthy_pairs_within_range():
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [2.5, 0.0], [0.0, 0.9]])
    healthy = np.array([True, True, True, False])
    edges = {tuple(sorted(e)) for e in plots.comm_edges(xy, healthy, 1.5).tolist()}
    assert edges == {(0, 1), (1, 2)}


def test_write_run_plots_and_gif_animation(finished, tmp_path):
    sim, result, _ = finished
    written = plots.write_run_plots(tmp_path, sim=sim, result=result, plots=True, animation=False)
    assert [p.name for p in written] == ["trajectories.png", "safety.png", "speed.png"]
    from PIL import Image

    for path in written:
        with Image.open(path) as image:
            assert image.format == "PNG" and image.size[0] > 500
    run = plots.from_simulation(sim, result)
    path = plots.write_animation(run, tmp_path, frames=8, edges=True)
    assert path.suffix in (".gif", ".mp4") and path.stat().st_size > 0
    if path.suffix == ".gif":
        with Image.open(path) as image:
            assert image.n_frames == 8
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left


def test_animation_draws_comm_edges(finished, monkeypatch, tmp_path):
    """The edge collection of the last frame holds exactly the healthy in-range pairs."""
    sim, result, _ = finished
    run = plots.from_simulation(sim, result)
    captured = {}
    original = LineCollection.set_segments

    def spy(self, segments):
        if self.get_colors().size and np.allclose(self.get_colors()[0][:3], (0.17254902, 0.62745098, 0.17254902)):
            captured["last"] = [np.asarray(s) for s in segments]
        return original(self, segments)

    monkeypatch.setattr(LineCollection, "set_segments", spy)
    plots.write_animation(run, tmp_path, frames=3, edges=True)
    k = len(run.t) - 1
    pairs = plots.comm_edges(run.pos[k, :, :2], run.healthy[k], run.comm_range)
    assert len(captured["last"]) == len(pairs) > 0
    assert not run.healthy[k, 0] and all(0 not in p for p in pairs.tolist())


def test_cli_output_plots_true_writes_pictures(tmp_path):
    env = {**os.environ}
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.run(
        [sys.executable, "-c", "from swarmscene.cli import main; main()", *OVERRIDES, "output.plots=true",
         f"hydra.run.dir={tmp_path}/run"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "run"
    assert {"trajectories.png", "safety.png", "speed.png"} <= {p.name for p in run.iterdir()}
    assert not (run / "animation.gif").exists()  # only on output.animation=true
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["complete"] is True
    assert {"trajectories.png", "safety.png", "speed.png"} <= set(manifest["files"])  # written before it


def test_missing_extra_fails_before_the_run_and_leaves_no_run_directory(tmp_path):
    env = {**os.environ}
    env.pop("HYDRA_FULL_ERROR", None)
    hide = "import sys; sys.modules['matplotlib'] = None; from swarmscene.cli import main; main()"
    proc = subprocess.run(
        [sys.executable, "-c", hide, *OVERRIDES, "output.plots=true", f"hydra.run.dir={tmp_path}/run"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "swarmscene: output.plots/output.animation=true needs the 'plots' extra: pip install 'swarmscene[plots]'"
    ]
    assert not (tmp_path / "run").exists()


def test_missing_extra_is_named_in_one_line():
    from swarmscene import cli

    from swarmscene.core.errors import ConfigError

    with pytest.raises(ConfigError, match=r"output.plots=true needs the 'plots' extra: pip install 'swarmscene\[plots\]'"):
        cli._require("no_such_module_for_swarmscene", "output.plots", "plots")
    cli._require("matplotlib", "output.plots", "plots")  # installed: no error
