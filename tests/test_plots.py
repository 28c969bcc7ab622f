"""Per-run pictures show what the arrays say: one path per agent, the failed vehicle where it failed,
the obstacles, separation and clearance against their limits, speeds, an animation with comm edges."""

from __future__ import annotations

import colorsys
import io
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgb
from matplotlib.patches import Polygon

from swarmscene import api
from swarmscene.views import plots

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
    colors = plots.agent_colors(5) / 255.0
    for i, path in enumerate(paths):  # each agent in its own colour; the failed one dashed
        np.testing.assert_allclose(to_rgb(path.get_color()), colors[i])
    assert paths[0].get_linestyle() == "--" and paths[1].get_linestyle() == "-"
    assert "failed (1)" in [text.get_text() for text in ax.get_legend().get_texts()]


def test_agent_colors_are_distinct_and_never_red():
    """One colour map for every picture, the animation and the replay; red marks failures only."""
    small = plots.agent_colors(9)
    assert len({tuple(c) for c in small}) == 9 and (214, 39, 40) not in {tuple(c) for c in small}
    np.testing.assert_array_equal(plots.agent_colors(4), small[:4])  # stable: agent i keeps its colour
    large = plots.agent_colors(200).astype(float) / 255.0
    assert large.shape == (200, 3) and len({tuple(c) for c in large.round(6)}) == 200
    hue = np.array([colorsys.rgb_to_hsv(*c)[0] * 360 for c in large])
    assert hue.min() >= 29.5 and hue.max() <= 330.5  # no red (hue near 0/360)


def test_bands_are_percentiles_over_agents_ignoring_nan():
    values = np.array([[1.0, 2.0, 3.0, 4.0, np.nan], [np.nan] * 5, [5.0, np.inf, 5.0, 5.0, 5.0]])
    b = plots.bands(values)
    assert b["median"][0] == 2.5 and b["min"][0] == 1.0 and b["max"][0] == 4.0
    assert b["p10"][0] == pytest.approx(np.percentile([1, 2, 3, 4], 10))
    assert np.isnan(b["median"][1]) and b["median"][2] == 5.0


def _band(ax, gid):
    """(lower, upper) of a fill_between collection drawn with ``gid``."""
    (poly,) = _by_gid(ax, gid)
    verts = poly.get_paths()[0].vertices  # start, lower 0..n-1, upper n-1..0 (doubled end), start, close
    n = (len(verts) - 3) // 2
    return verts[1 : n + 1, 1], verts[n + 2 : 2 * n + 2, 1][::-1]


def test_safety_figure_draws_distributions_minimum_and_limits(finished):
    """Median and bands of each agent's nearest-neighbour distance and clearance (an oracle from
    scipy's pdist), the monitor's minimum, and the limits."""
    from scipy.spatial.distance import pdist, squareform

    sim, result, _ = finished
    run = plots.from_simulation(sim, result)
    top, bottom = plots.safety_figure(run).axes
    assert top.get_ylabel() == "nearest neighbour (m)" and bottom.get_xlabel() == "time (s)"
    (sep_limit,) = _by_gid(top, "separation_limit")
    (clear_limit,) = _by_gid(bottom, "clearance_limit")
    assert set(sep_limit.get_ydata()) == {sim.config.safety.separation_limit}
    assert set(clear_limit.get_ydata()) == {sim.config.safety.clearance_limit}
    (minimum,) = _by_gid(top, "separation_min")
    assert np.nanmin(minimum.get_ydata()) == pytest.approx(result.metrics["min_separation"])
    (clearance,) = _by_gid(bottom, "clearance_min")
    assert np.nanmin(clearance.get_ydata()) == pytest.approx(result.metrics["min_clearance"])
    pos = result.trajectory["pos"]
    nearest = np.array([np.sort(squareform(pdist(frame)), axis=1)[:, 1] for frame in pos])
    (median,) = _by_gid(top, "separation_median")
    np.testing.assert_allclose(median.get_ydata(), np.median(nearest, axis=1), rtol=1e-12)
    low, high = _band(top, "separation_envelope")
    np.testing.assert_allclose(low, nearest.min(axis=1), rtol=1e-12)
    np.testing.assert_allclose(high, nearest.max(axis=1), rtol=1e-12)
    assert len([line for line in top.lines if (line.get_gid() or "").startswith("separation_agent")]) == 5


def test_series_recomputed_from_directory_match_the_monitor(finished):
    """From a run directory (trajectory every tick here) the recomputed series equal the monitor's."""
    _, result, run_dir = finished
    from_dir = plots.safety_series(plots.load_run(run_dir))
    live = result.series
    np.testing.assert_allclose(from_dir["t"], live["t"])
    np.testing.assert_allclose(from_dir["min_separation"], live["min_separation"], rtol=1e-9)
    np.testing.assert_allclose(from_dir["min_clearance"], live["min_clearance"], rtol=1e-9)


def test_speed_figure_is_a_distribution_over_healthy_agents(finished):
    sim, result, _ = finished
    run = plots.from_simulation(sim, result)
    ax = plots.speed_figure(run).axes[0]
    assert ax.get_ylabel() == "speed (m/s)"
    speed = np.linalg.norm(result.trajectory["vel"], axis=2)
    healthy = result.trajectory["healthy"]
    (median,) = _by_gid(ax, "speed_median")
    np.testing.assert_allclose(median.get_ydata(), np.nanmedian(np.where(healthy, speed, np.nan), axis=1))
    low, high = _band(ax, "speed_band")
    k = len(speed) - 1  # at the end the failed leader (speed 0) is out of the distribution
    assert low[k] == pytest.approx(np.percentile(speed[k, 1:], 10)) and high[k] == pytest.approx(np.percentile(speed[k, 1:], 90))
    (leader,) = _by_gid(ax, "speed_agent0")
    assert np.isnan(leader.get_ydata()[-1]) and leader.get_ydata()[0] == speed[0, 0]
    assert _by_gid(ax, "speed_limit") == []  # no plugin publishes a speed limit here


def test_speed_limit_is_drawn_from_a_published_metric(finished):
    sim, result, _ = finished
    run = plots.from_simulation(sim, result)
    run.metrics["single_integrator.speed_limit"] = 1.5
    (limit,) = _by_gid(plots.speed_figure(run).axes[0], "speed_limit")
    assert set(limit.get_ydata()) == {1.5}


def test_altitude_figure_for_the_vrb_show(tmp_path):
    """The air show climbs to its 2 m circle: median and envelope of z over the three vehicles."""
    sim = api.build(["scenario=vrb_airshow", "clock.duration=6.0"])
    result = sim.run()
    run = plots.from_simulation(sim, result)
    ax = plots.altitude_figure(run).axes[0]
    z = result.trajectory["pos"][..., 2]
    (median,) = _by_gid(ax, "altitude_median")
    np.testing.assert_allclose(median.get_ydata(), np.median(z, axis=1))
    low, high = _band(ax, "altitude_envelope")
    np.testing.assert_allclose(high, z.max(axis=1))
    assert z[0].max() == pytest.approx(0.0, abs=1e-9) and high.max() > 1.0  # takes off from the ground


def test_progress_line_reports_the_time_left():
    from swarmscene.views.summary import Progress, format_duration

    progress = Progress(stream=io.StringIO(), delay=0.0)
    assert progress.line(25, 100, "frame 25/100", elapsed=10.0) == (
        "  [#######-----------------------] frame 25/100, 30 s left ")
    assert format_duration(185) == "3 min 05 s" and format_duration(3720) == "1 h 02 min"
    assert Progress.maybe("auto") is None  # stderr is not a terminal under pytest: quiet
    assert isinstance(Progress.maybe("on"), Progress) and Progress.maybe("off") is None


def test_comm_edges_are_healthy_pairs_within_range():
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [2.5, 0.0], [0.0, 0.9]])
    healthy = np.array([True, True, True, False])
    edges = {tuple(sorted(e)) for e in plots.comm_edges(xy, healthy, 1.5).tolist()}
    assert edges == {(0, 1), (1, 2)}


def test_write_run_plots_and_gif_animation(finished, tmp_path):
    sim, result, _ = finished
    written = plots.write_run_plots(tmp_path, sim=sim, result=result, plots=True, animation=False)
    assert [p.name for p in written] == ["trajectories.png", "safety.png", "speed.png", "altitude.png"]
    from PIL import Image

    for path in written:
        with Image.open(path) as image:
            assert image.format == "PNG" and image.size[0] > 500
    run = plots.from_simulation(sim, result)
    from swarmscene.views.summary import Progress

    stream = io.StringIO()
    path = plots.write_animation(run, tmp_path, frames=8, edges=True, progress=Progress(stream=stream, delay=0.0))
    assert path.suffix in (".gif", ".mp4") and path.stat().st_size > 0
    last = stream.getvalue().split("\r")[-1]  # the writer reports frames written and the time left
    assert last.startswith(f"  [{'#' * 30}] {path.name}: frame 8/8, 0 s left") and stream.getvalue().endswith("\n")
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
    assert {"trajectories.png", "safety.png", "speed.png", "altitude.png"} <= {p.name for p in run.iterdir()}
    assert not (run / "animation.gif").exists()  # only on output.animation=true
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["complete"] is True
    assert {"trajectories.png", "safety.png", "speed.png", "altitude.png"} <= set(manifest["files"])  # written before it


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
    from swarmscene.core.errors import ConfigError
    from swarmscene.views import writers

    with pytest.raises(ConfigError, match=r"output.plots=true needs the 'plots' extra: pip install 'swarmscene\[plots\]'"):
        writers._require("no_such_module_for_swarmscene", "output.plots", "plots")
    writers._require("matplotlib", "output.plots", "plots")  # installed: no error


def test_load_run_names_a_damaged_file(finished, tmp_path):
    """load_run (pictures, replay, export, report re-runs) reads through swarmscene.runs.rundir."""
    import shutil

    from swarmscene.runs.rundir import RunFileError

    copy = tmp_path / "run"
    shutil.copytree(finished[2], copy)
    (copy / "config.yaml").write_text("environment: {obstacles: [{kind: circle, radius: -1}]}\n")
    with pytest.raises(RunFileError, match=rf"^{copy}/config.yaml: its environment cannot be built \("):
        plots.load_run(copy)
    (copy / "config.yaml").write_text("events: 3\n")
    with pytest.raises(RunFileError, match=rf"^{copy}/config.yaml: 'events' should be a list of mappings$"):
        plots.load_run(copy)


def test_paths_are_not_drawn_across_a_torus_seam():
    """An agent folded back into a periodic box (the engine's wrap) is not joined across the map:
    its path is split where it jumped, and a path that never wraps is drawn whole."""
    from swarmscene.views.plots import RunData, trajectory_figure, wrap_steps

    t = np.arange(0.0, 30.0, 0.5)
    x_wrapped = (1.0 * t) % 10.0  # 1 m/s along x in a 10 m torus: folds at t = 10 and 20 s
    pos = np.zeros((len(t), 2, 3))
    pos[:, 0, 0] = x_wrapped
    pos[:, 1, 0] = 0.2 * t  # never wraps
    pos[:, :, 1] = [2.0, 6.0]
    run = RunData(config={"name": "torus"}, t=t, pos=pos, vel=np.zeros_like(pos), healthy=np.ones((len(t), 2), bool))
    steps = wrap_steps(run)
    assert np.flatnonzero(steps[:, 0]).tolist() == [19, 39] and not steps[:, 1].any()
    line = [ln for ln in trajectory_figure(run).axes[0].lines if ln.get_gid() == "agent0"][0]
    xs = np.asarray(line.get_xdata(), dtype=float)
    assert np.isnan(xs).sum() == 2 and np.nanmax(np.abs(np.diff(xs))) < 1.0
