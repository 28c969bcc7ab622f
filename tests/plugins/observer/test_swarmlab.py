"""The ``swarmlab`` observer on real runs: its per-tick series (swarmlab.npz) equal SwarmLab's
definitions recomputed from the recorded trajectory (tests/oracles/swarmlab.py) to 1e-9, obstacles
included; its means are the metrics; it adds nothing unless asked for; its options are validated."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
from oracles.swarmlab import swarm_performance

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.plugins.observer.swarmlab import SERIES, SwarmLab
from swarmscene.testing import check_observer

TOL = 1e-9
BOXES = ["task=nav_boxes", "avoidance=none", "clock.duration=12", "output.summary=false"]


def signed_clearance(geoms, x, y):
    """Each obstacle's signed distance (negative inside: minus the depth to its boundary)."""
    point = shapely.Point(x, y)
    return min(-g.boundary.distance(point) if g.contains(point) else g.distance(point) for g in geoms)


def test_series_equal_the_definition_recomputed_from_the_trajectory(tmp_path):
    """nav_boxes without avoidance: the V flies into the boxes, so obstacle safety drops below 1."""
    result = api.run(["observers.swarmlab.max_neig=3", "observers.swarmlab.r=4.0", *BOXES], output_dir=tmp_path)
    series = np.load(tmp_path / "swarmlab.npz")
    traj = np.load(tmp_path / "trajectory.npz")
    geoms = api.load(["observers.swarmlab.max_neig=3", *BOXES]).obstacles
    np.testing.assert_allclose(series["t"], traj["t"], rtol=0, atol=1e-12)
    for k in range(len(traj["t"])):
        pos, vel = traj["pos"][k], traj["vel"][k]
        inside = np.array([[shapely.contains_xy(g, x, y) for g in geoms] for x, y, _ in pos])
        want = swarm_performance(pos, vel, 4.0, 3, 0.5, inside)
        for name, value in zip(SERIES[:5], want, strict=True):
            assert abs(series[name][k] - value) <= TOL, f"t = {traj['t'][k]}: {name}"
        want_min = min(signed_clearance(geoms, x, y) for x, y, _ in pos)
        assert abs(series["min_d_obs"][k] - want_min) <= TOL
    assert series["safety_obs"].min() < 1.0  # the case with agents inside was met
    for name in SERIES:
        assert result.metrics[f"swarmlab.{name}"] == pytest.approx(series[name].mean(), abs=1e-12)
    assert result.metrics["swarmlab.min_d_obs_min"] == pytest.approx(series["min_d_obs"].min(), abs=1e-12)
    assert "swarmlab.npz" in json.loads((tmp_path / "manifest.json").read_text())["files"]


def test_a_flocking_run_equals_the_definition_at_every_tick(tmp_path):
    """The issue's case: 100 boids with SwarmLab's defaults, a neighbour graph that changes every tick
    and boids that wrap around the torus; every sample (lists cut by the previous ones, lambda_2 warm
    started and certified, or dense) equal to the definition recomputed from the trajectory."""
    api.run(["scenario=flocking", "observers=[swarmlab]", "clock.duration=40", "output.summary=false"],
            output_dir=tmp_path)
    series = np.load(tmp_path / "swarmlab.npz")
    traj = np.load(tmp_path / "trajectory.npz")
    p = SwarmLab.Params()
    for k in range(len(traj["t"])):
        want = swarm_performance(traj["pos"][k], traj["vel"][k], p.r, p.max_neig, p.r_coll)[:4]
        for name, value in zip(SERIES[:4], want, strict=True):
            assert abs(series[name][k] - value) <= TOL, f"t = {traj['t'][k]}: {name}"
    assert series["alg_conn"].max() > 0  # connected samples were met


def test_held_states_measured_in_chunks_equal_a_sample_at_every_tick(tmp_path, monkeypatch):
    """The observer holds the states (copies) and measures them CHUNK at a time, the last ones at the
    run's end: every sample bit for bit what measuring each at its own tick gives (a run of 101
    samples, not a multiple of CHUNK)."""
    from swarmscene.plugins.observer import swarmlab

    run = ["scenario=flocking", "observers=[swarmlab]", "clock.duration=100", "output.summary=false"]
    assert 101 % swarmlab.CHUNK
    chunked = api.run(run, output_dir=tmp_path / "chunked")
    monkeypatch.setattr(swarmlab, "CHUNK", 1)
    each = api.run(run, output_dir=tmp_path / "each")
    series, want = np.load(tmp_path / "chunked" / "swarmlab.npz"), np.load(tmp_path / "each" / "swarmlab.npz")
    assert len(series["t"]) == 101
    for name in ("t", *SERIES[:4]):
        np.testing.assert_array_equal(series[name], want[name])
    assert {k: v for k, v in chunked.metrics.items() if k.startswith("swarmlab.")} == {
        k: v for k, v in each.metrics.items() if k.startswith("swarmlab.")}


def test_every_sample_step_and_swarmlab_defaults(tmp_path):
    """``every=5`` samples the start and every fifth tick; the defaults are SwarmLab's."""
    params = SwarmLab.Params()
    assert (params.r, params.max_neig, params.r_coll, params.every) == (150.0, 10, 0.5, 1)
    api.run(["scenario=swap", "observers=[swarmlab]", "observers.swarmlab.every=5", "clock.duration=2",
             "output.summary=false"], output_dir=tmp_path)
    t = np.load(tmp_path / "swarmlab.npz")["t"]
    np.testing.assert_allclose(t, np.arange(0, 21, 5) * 0.1, atol=1e-12)


def test_not_asked_for_it_adds_nothing(tmp_path):
    result = api.run(["scenario=swap", "clock.duration=2", "output.summary=false"], output_dir=tmp_path)
    assert not [k for k in result.metrics if k.startswith("swarmlab.")]
    assert not (tmp_path / "swarmlab.npz").exists()
    assert "observers" not in result.run_dir.joinpath("config.yaml").read_text()


def test_the_observer_keeps_the_contract():
    check_observer(SwarmLab, ["observers=[swarmlab]"])


@pytest.mark.parametrize(("override", "line"), [
    ("observers.swarmlab.r=-1", "observers.swarmlab.r: must be > 0.0 (got -1)"),
    ("observers.swarmlab.max_neig=0", "observers.swarmlab.max_neig: must be >= 1 (got 0)"),
    ("+observers.nope.x=1", "observers.nope: unknown observer with options (valid: swarmlab)"),
])
def test_bad_options_are_one_line_naming_the_key(override, line):
    with pytest.raises(ConfigError) as err:
        api.load(["scenario=swap", "observers=[swarmlab]", override])
    assert err.value.lines == [line]


def test_the_options_are_recorded_and_reproduce_the_run(tmp_path):
    import yaml

    first = api.run(["scenario=swap", "observers=[swarmlab]", "observers.swarmlab.r=3", "clock.duration=2",
                     "output.summary=false"], output_dir=tmp_path / "a")
    config = yaml.safe_load((tmp_path / "a" / "config.yaml").read_text())
    assert config["observers"] == {"swarmlab": {"r": 3.0, "max_neig": 10, "r_coll": 0.5, "every": 1}}
    again = api.run({**config, "output": {**config["output"], "summary": False}}, output_dir=tmp_path / "b")
    assert {k: v for k, v in again.metrics.items() if k.startswith("swarmlab.")} == {
        k: v for k, v in first.metrics.items() if k.startswith("swarmlab.")}
