"""Exports: the VRB air show as Crazyflie poly4d trajectories (evaluated against the plan: under 1 cm,
C^3 joins, within the vehicle's memory and thrust limits, the PID controller's velocity cap found and
met by slowing the show), the Crazyswarm2 CSV read back as Crazyswarm2 reads it, and per-agent CSV."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from swarmscene import api
from swarmscene.methods.vrb.transform import robot_flat_outputs
from swarmscene.views import export, plots

SHOW = ["scenario=vrb_airshow"]
BUNDLE = ["cf_0.csv", "cf_1.csv", "cf_2.csv", "crazyflie.json", "crazyflies.yaml", "crazyswarm2_show.json",
          "crazyswarm2_show.py"]


@pytest.fixture(scope="module")
def plan():
    """The air show's plan (no simulation): the formation's flat outputs of the three vehicles."""
    formation = api.build(SHOW).formation

    def at(t):
        fo = robot_flat_outputs(formation.trajectory, formation.flight, t)
        return fo.p, fo.yaw  # (5, T, N, 3), (5, T, N)

    return at


@pytest.fixture(scope="module")
def fitted(plan):
    t = np.linspace(0.0, 71.0, 7101)
    p, yaw = plan(t)
    samples = np.concatenate([p[0], yaw[0][..., None]], axis=-1)
    return export.crazyflie_trajectories((t, samples)), samples


def test_memory_layout_is_the_firmwares():
    """struct poly4d { float p[4][8]; float duration; }: 132 bytes; 4096 bytes hold 31 pieces."""
    assert export.PIECE_BYTES == 132 and export.MAX_PIECES == 31
    assert export.CSV_HEADER.split(",")[:3] == ["Duration", "x^0", "x^1"]
    assert export.CSV_HEADER.split(",")[-1] == "yaw^7" and len(export.CSV_HEADER.split(",")) == 33


def test_fit_matches_the_plan_within_one_centimetre(plan, fitted):
    show, _ = fitted
    dense = np.linspace(0.0, 71.0, 71001)  # 1 kHz, ten times the fitted samples
    p, yaw = plan(dense)
    assert len(show.fits) == 3
    for i, fit in enumerate(show.fits):
        poly = fit.poly  # float32 coefficients, as the vehicle stores them
        assert poly.pieces <= export.MAX_PIECES and poly.nbytes <= export.TRAJECTORY_MEMORY_BYTES
        assert poly.duration == pytest.approx(71.0, abs=1e-5)
        position = np.linalg.norm(poly.evaluate(dense)[:, :3] - p[0][:, i], axis=1)
        assert position.max() < 0.01
        assert np.abs(poly.evaluate(dense)[:, 3] - yaw[0][:, i]).max() < 0.01  # rad
        velocity = np.linalg.norm(poly.evaluate(dense, 1)[:, :3] - p[1][:, i], axis=1)
        assert velocity.max() < 0.1  # m/s: the feed-forward the commander sends is the plan's


def test_joins_are_continuous_up_to_jerk(fitted):
    show, _ = fitted
    for fit in show.fits:
        poly = fit.poly
        joins = poly.t0 + np.cumsum(poly.durations)[:-1]
        for n, tol in ((0, 1e-5), (1, 1e-4), (2, 1e-3), (3, 1e-2)):  # float32 coefficients
            jump = np.abs(poly.evaluate(joins - 1e-9, n) - poly.evaluate(joins + 1e-9, n))
            assert jump.max() < tol, (n, jump.max())


def test_thrust_limits_hold_and_the_pid_velocity_cap_is_reported(fitted):
    """Mellinger (feed-forward, no velocity cap): thrust within 4 THRUST_MAX / CF_MASS. The PID
    controller's 1.0 m/s per-axis cap is exceeded by the show as planned (1.25 m/s)."""
    show, samples = fitted
    assert export.CRAZYFLIE["mellinger"].max_collective_acc == pytest.approx(4 * 0.1125 / 0.029)
    for checks in show.checks:
        assert all(c["holds"] for c in checks), checks
    t = np.linspace(0.0, 71.0, 7101)
    pid = export.crazyflie_trajectories((t, samples), controller="pid")
    speed = [next(c for c in checks if c["name"].startswith("axis speed")) for checks in pid.checks]
    assert max(c["value"] for c in speed) == pytest.approx(1.25, abs=0.01)
    assert [c["holds"] for c in speed] == [False, False, False]


def test_auto_time_scale_brings_the_show_within_the_pid_limits(plan, fitted):
    _, samples = fitted
    t = np.linspace(0.0, 71.0, 7101)
    slow = export.crazyflie_trajectories((t, samples), controller="pid", time_scale="auto")
    assert slow.time_scale == pytest.approx(1.3)
    for fit, checks in zip(slow.fits, slow.checks, strict=True):
        assert {c["name"]: c["holds"] for c in checks} == {
            "collective thrust |a + g e3| (m/s^2)": True, "downward acceleration -a_z (m/s^2)": True,
            "axis speed max(|vx|, |vy|, |vz|) (m/s)": True, "tilt (deg)": True}
        assert fit.poly.duration == pytest.approx(71.0 * 1.3, abs=1e-4)
    p, _ = plan(np.array([10.0]))  # the same path, later: the plan at t is the slowed show at 1.3 t
    np.testing.assert_allclose(slow.fits[0].poly.evaluate([13.0])[0, :3], p[0][0, 0], atol=0.01)


def test_crazyswarm_csv_round_trip(fitted, tmp_path):
    """Each row is a piece: duration then x, y, z, yaw coefficients in ascending powers, evaluated
    by Horner's rule as Crazyswarm2's uav_trajectory.Polynomial.eval does."""
    show, samples = fitted
    poly = show.fits[1].poly
    path = tmp_path / "cf_1.csv"
    poly.to_csv(path)
    assert path.read_text().splitlines()[0] == export.CSV_HEADER
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    assert data.shape == (poly.pieces, 33)
    np.testing.assert_array_equal(data[:, 0].astype(np.float32), poly.durations.astype(np.float32))
    start = np.concatenate([[0.0], np.cumsum(data[:, 0])])
    t = 12.345
    j = int(np.searchsorted(start, t, side="right") - 1)
    tau = t - start[j]
    x = 0.0
    for c in data[j, 1:9][::-1]:  # Horner, highest power first
        x = x * tau + c
    assert x == pytest.approx(poly.evaluate([t])[0, 0], abs=1e-6)
    assert abs(x - float(np.interp(t, np.linspace(0, 71, 7101), samples[:, 1, 0]))) < 0.01
    back = export.Poly4D.from_csv(path)
    np.testing.assert_allclose(back.coeffs, poly.coeffs, rtol=1e-7, atol=1e-12)


@pytest.fixture(scope="module")
def short_show(tmp_path_factory):
    """The first 3 s of the show (take-off), simulated and written: a run directory."""
    run_dir = tmp_path_factory.mktemp("show")
    sim = api.build([*SHOW, "clock.duration=3.0"])
    api.write_outputs(sim, sim.run(), run_dir)
    return run_dir


def test_cli_crazyflie_export_from_a_run_directory(short_show, tmp_path):
    out = tmp_path / "cf"
    proc = subprocess.run([sys.executable, "-m", "swarmscene.views.export", str(short_show), "--crazyflie", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0] == "crazyflie: 3 vehicles from the plan, time scale 1, controller mellinger"
    assert sorted(p.name for p in out.iterdir()) == BUNDLE
    summary = json.loads((out / "crazyflie.json").read_text())
    assert summary["source"] == "plan" and summary["max_pieces"] == 31
    for vehicle in summary["vehicles"]:
        assert vehicle["duration"] == pytest.approx(3.0, abs=1e-6)
        assert vehicle["max_position_error"] < 0.005 and vehicle["bytes"] == 132 * vehicle["pieces"]
    poly = export.Poly4D.from_csv(out / "cf_2.csv")
    run = plots.load_run(short_show)
    # the plan starts where the vehicle stands on the ground
    np.testing.assert_allclose(poly.evaluate([0.0])[0, :3], run.pos[0, 2], atol=0.005)


def test_trajectory_csv_one_file_per_agent(short_show, tmp_path):
    written = export.trajectory_csv(short_show, tmp_path)
    assert [p.name for p in written] == ["agent_0.csv", "agent_1.csv", "agent_2.csv"]
    header = written[0].read_text().splitlines()[0]
    assert header == "t,x,y,z,vx,vy,vz,healthy,yaw,qw,qx,qy,qz"
    run = plots.load_run(short_show)
    table = np.loadtxt(written[1], delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 0], run.t, rtol=1e-9)
    np.testing.assert_allclose(table[:, 1:4], run.pos[:, 1], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(table[:, 4:7], run.vel[:, 1], rtol=1e-8, atol=1e-12)
    assert set(table[:, 7]) == {1.0}
    np.testing.assert_allclose(table[:, 9:], run.quat[:, 1], rtol=1e-8, atol=1e-12)
    w, x, y, z = run.quat[:, 1].T
    np.testing.assert_allclose(np.cos(table[:, 8]), np.cos(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))),
                               atol=1e-8)


# -- what the export refuses ----------------------------------------------------------------------
def _main(*argv: str, capsys) -> tuple[int, list[str]]:
    try:
        export.main(list(argv))
        code = 0
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("option, value, line", [
    ("--time-scale", "0", "--time-scale: must be a number > 0 or 'auto' (got '0')"),
    ("--time-scale", "-2", "--time-scale: must be a number > 0 or 'auto' (got '-2')"),
    ("--time-scale", "inf", "--time-scale: must be a number > 0 or 'auto' (got 'inf')"),
    ("--time-scale", "fast", "--time-scale: must be a number > 0 or 'auto' (got 'fast')"),
    ("--tolerance", "nan", "--tolerance: must be a finite number of metres > 0 (got nan)"),
    ("--tolerance", "0", "--tolerance: must be a finite number of metres > 0 (got 0.0)"),
])
def test_a_bad_option_is_one_line_naming_it_and_writes_nothing(short_show, tmp_path, capsys, option, value, line):
    code, err = _main(str(short_show), "--crazyflie", str(tmp_path / "cf"), option, value, capsys=capsys)
    assert code == 2 and err == [f"python -m swarmscene.views.export: {line}"]
    assert not (tmp_path / "cf").exists()


def _with(run_dir, tmp_path, manifest=None, metrics=None, error=None):
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    if manifest is not None:
        (copy / "manifest.json").write_text(json.dumps({**json.loads((copy / "manifest.json").read_text()), **manifest}))
    if metrics is not None:
        (copy / "metrics.json").write_text(json.dumps({**json.loads((copy / "metrics.json").read_text()), **metrics}))
    if error is not None:
        (copy / "error.json").write_text(json.dumps(error))
    return copy


@pytest.mark.parametrize("change, words", [
    ({"manifest": {"complete": False}}, "did not complete (manifest.json: complete is not true)"),
    ({"metrics": {"collisions": 2}}, "collided (collisions = 2, stop_reason = duration)"),
    ({"metrics": {"stop_reason": "collision"}}, "collided (collisions = 0, stop_reason = collision)"),
    ({"manifest": {"complete": False, "status": "failed"}, "error": {"error": "RunFailed: non-finite state"}},
     "failed (RunFailed: non-finite state)"),
])
def test_a_run_that_failed_collided_or_did_not_complete_is_refused_unless_forced(
        short_show, tmp_path, capsys, change, words):
    run = _with(short_show, tmp_path, **change)
    code, err = _main(str(run), "--csv", str(tmp_path / "csv"), capsys=capsys)
    assert code == 2
    assert err == [f"python -m swarmscene.views.export: {run}: the run {words}; refused (--force exports it anyway)"]
    assert not (tmp_path / "csv").exists()
    code, err = _main(str(run), "--csv", str(tmp_path / "csv"), "--force", capsys=capsys)
    assert code == 0 and err == [f"python -m swarmscene.views.export: warning: {run}: the run {words}; exported because "
                                 "of --force"]
    assert len(list((tmp_path / "csv").glob("agent_*.csv"))) == 3


def test_a_run_without_a_manifest_is_unfinished(short_show, tmp_path, capsys):
    run = _with(short_show, tmp_path)
    (run / "manifest.json").unlink()
    code, err = _main(str(run), "--csv", str(tmp_path / "csv"), capsys=capsys)
    assert code == 2 and err[0].endswith("the run did not complete (no manifest.json: the run was stopped before "
                                         "its end); refused (--force exports it anyway)")
    assert export.run_problem(short_show) is None


# -- a show the vehicles cannot fly ---------------------------------------------------------------
EXCEEDS_LINE = (
    "the show exceeds the mellinger controller's limits ("
    "cf_0: collective thrust |a + g e3| (m/s^2) 21.2 > 15.5, downward acceleration -a_z (m/s^2) 10.2 > 9.81; "
    "cf_1: collective thrust |a + g e3| (m/s^2) 21.2 > 15.5, downward acceleration -a_z (m/s^2) 13.1 > 9.81; "
    "cf_2: collective thrust |a + g e3| (m/s^2) 21.2 > 15.5, downward acceleration -a_z (m/s^2) 11.7 > 9.81)")


def test_a_show_beyond_the_limits_is_refused_with_status_1_and_nothing_written(short_show, tmp_path, capsys):
    """The take-off played four times faster (--time-scale 0.25: accelerations x 16) needs 21.2
    m/s^2 of collective thrust per unit mass, beyond 4 THRUST_MAX / CF_MASS = 15.5."""
    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--time-scale", "0.25", capsys=capsys)
    assert code == 1
    assert err == [f"python -m swarmscene.views.export: {EXCEEDS_LINE}; refused, nothing written "
                   "(--time-scale auto slows it down; --allow-exceed writes it anyway)"]
    assert not out.exists()
    csv = tmp_path / "csv"  # with --csv too: the show was refused after the CSVs were written
    code, err = _main(str(short_show), "--csv", str(csv), "--crazyflie", str(out), "--time-scale", "0.25",
                      capsys=capsys)
    assert code == 1 and "nothing written" in err[0] and not csv.exists() and not out.exists()


def test_allow_exceed_writes_the_show_with_a_warning(short_show, tmp_path, capsys):
    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--time-scale", "0.25", "--allow-exceed",
                      capsys=capsys)
    assert code == 0
    assert err == [f"python -m swarmscene.views.export: warning: {EXCEEDS_LINE}; written because of --allow-exceed"]
    assert sorted(p.name for p in out.iterdir()) == BUNDLE
    summary = json.loads((out / "crazyflie.json").read_text())
    assert summary["time_scale"] == 0.25
    assert [c["holds"] for c in summary["vehicles"][0]["limits"]] == [False, False]
    assert export.Poly4D.from_csv(out / "cf_0.csv").duration == pytest.approx(0.75, abs=1e-6)


# -- placing the show in a lab volume, the geofence ------------------------------------------------
def test_a_show_leaving_the_geofence_is_refused_naming_vehicle_time_and_face(short_show, tmp_path, capsys):
    """cf_0 climbs out to the left (x from -0.7 to -1.197 m in 3 s): with xmin = -1 it leaves
    through the x min face between the plan's samples at 2.58 s and 2.59 s."""
    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--geofence", "-1", "-1", "-0.1", "1", "1", "2",
                      capsys=capsys)
    assert code == 1
    assert err == ["python -m swarmscene.views.export: cf_0 leaves the geofence at t = 2.59 s through the x min face "
                   "(x = -1.001 m < -1 m); refused, nothing written (--fit-box scales the show into a box)"]
    assert not out.exists()
    t, samples, _ = export.show_samples(short_show)
    crossing = t[np.flatnonzero(samples[:, 0, 0] < -1.0)[0]]
    assert crossing == pytest.approx(2.59) and samples[:, 1:, 0].min() > -1.0  # only cf_0 leaves
    # --allow-exceed is for the controller's limits; a geofence is never overridden
    code, err = _main(str(short_show), "--crazyflie", str(out), "--geofence", "-1", "-1", "-0.1", "1", "1", "2",
                      "--allow-exceed", capsys=capsys)
    assert code == 1 and "leaves the geofence" in err[0] and not out.exists()


def test_fit_box_scales_and_shifts_the_show_into_the_box(short_show, tmp_path, capsys):
    """Box 1 m x 1 m x 1 m; margin 2 x 5 mm: room 0.98 m per axis. The show spans 1.908 m in x,
    0.310 m in y, 1.499 m in z, so x sets the scale 0.98 / 1.908; x, y centred, the floor on zmin + 1 cm
    (the show starts on the ground). At that scale the vehicles, 0.7 m apart on the ground, stand
    0.36 m apart, under the run's 0.6 m separation limit: refused, written only with --allow-exceed."""
    out = tmp_path / "cf"
    box = ["--fit-box", "-0.5", "-0.5", "0", "0.5", "0.5", "1"]
    code, err = _main(str(short_show), "--crazyflie", str(out), *box, capsys=capsys)
    assert code == 1 and not out.exists()
    assert err == ["python -m swarmscene.views.export: cf_0 and cf_1 come 0.359 m apart at t = 0.00 s (0.337 m at the closest), under the run's "
                   "separation limit 0.6 m (scale 0.514, offset (0.124995, 0.0774017, 0.01) m, time scale 1); "
                   "refused, nothing written (--allow-exceed writes it anyway)"]
    code, err = _main(str(short_show), "--crazyflie", str(out), *box, "--allow-exceed", capsys=capsys)
    assert code == 0 and len(err) == 1 and err[0].endswith("written because of --allow-exceed")
    t, samples, _ = export.show_samples(short_show)
    lo, hi = samples[..., :3].min(axis=(0, 1)), samples[..., :3].max(axis=(0, 1))
    scale = 0.98 / (hi[0] - lo[0])
    assert scale == pytest.approx(0.98 / (0.71063275 + 1.19734309), rel=1e-7)
    summary = json.loads((out / "crazyflie.json").read_text())
    assert summary["placement"]["scale"] == pytest.approx(scale, rel=1e-12)
    offset = np.array(summary["placement"]["offset"])
    np.testing.assert_allclose(offset, [-scale * (lo[0] + hi[0]) / 2, -scale * (lo[1] + hi[1]) / 2,
                                        0.01 - scale * lo[2]],
                               atol=1e-12)
    assert summary["geofence"] == {"min": [-0.5, -0.5, 0.0], "max": [0.5, 0.5, 1.0], "breach": None}
    dense = np.linspace(0.0, 3.0, 3001)
    for i in range(3):
        poly = export.Poly4D.from_csv(out / f"cf_{i}.csv")
        np.testing.assert_allclose(poly.evaluate([0.0])[0, :3], scale * samples[0, i, :3] + offset, atol=0.005)
        pos = poly.evaluate(dense)[:, :3]
        assert pos.min(axis=0).min() >= -0.5 and (pos.min(axis=0)[2]) >= 0.0 and pos.max() <= 1.0
        yaw = poly.evaluate(dense)[:, 3]
        np.testing.assert_allclose(yaw, np.interp(dense, t, samples[:, i, 3]), atol=0.01)  # yaw is not scaled


def test_scaling_applies_before_the_limits(short_show, tmp_path, capsys):
    """Twice as fast (--time-scale 0.5) the take-off needs 1.67 m/s along an axis, beyond the PID
    controller's 1.0 m/s cap; the same show at half size needs half: 0.83 m/s, within it (and its
    vehicles stand 0.35 m apart, under the run's 0.6 m: the separation alone is warned of)."""
    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--controller", "pid", "--time-scale", "0.5",
                      capsys=capsys)
    assert code == 1 and err[0].startswith("python -m swarmscene.views.export: the show exceeds the pid controller's limits "
                                           "(cf_0: axis speed max(|vx|, |vy|, |vz|) (m/s) 1.67 > 1")
    code, err = _main(str(short_show), "--crazyflie", str(out), "--controller", "pid", "--time-scale", "0.5",
                      "--scale", "0.5", "--offset", "0", "0", "0.2", "--allow-exceed", capsys=capsys)
    # at half size the vehicles stand closer than the run's separation limit: written only with a warning
    assert code == 0 and err == [
        "python -m swarmscene.views.export: warning: cf_0 and cf_1 come 0.350 m apart at t = 0.00 s (0.328 m at the closest), under the run's "
        "separation limit 0.6 m (scale 0.5, offset (0, 0, 0.2) m, time scale 0.5); written because of --allow-exceed"]
    summary = json.loads((out / "crazyflie.json").read_text())
    assert summary["placement"] == {"scale": 0.5, "offset": [0.0, 0.0, 0.2]}
    speed = [c for c in summary["vehicles"][0]["limits"] if c["name"].startswith("axis speed")][0]
    assert speed["value"] == pytest.approx(1.6667 / 2, abs=2e-3) and speed["holds"]
    t, samples, _ = export.show_samples(short_show)
    poly = export.Poly4D.from_csv(out / "cf_2.csv")
    np.testing.assert_allclose(poly.evaluate([0.0])[0, :3], 0.5 * samples[0, 2, :3] + [0, 0, 0.2], atol=0.005)


@pytest.mark.parametrize("argv, line", [
    (["--scale", "0"], "--scale: must be a finite number > 0 (got '0')"),
    (["--scale", "nan"], "--scale: must be a finite number > 0 (got 'nan')"),
    (["--offset", "0", "x", "0"], "--offset: must be finite numbers of metres (got 'x')"),
    (["--fit-box", "0", "0", "0", "1", "-1", "1"], "--fit-box: ymin must be below ymax (got 0 and -1)"),
    (["--geofence", "0", "0", "inf", "1", "1", "1"], "--geofence: must be finite numbers of metres (got 'inf')"),
    (["--fit-box", "0", "0", "0", "1", "1", "1", "--scale", "2"],
     "--fit-box: computes the scale and offset itself: give it without --scale and --offset"),
    (["--fit-box", "0", "0", "0", "0.005", "1", "1"], "--fit-box: the box leaves no room inside its 1 cm margin"),
])
def test_a_bad_placement_option_is_one_line_naming_it(short_show, tmp_path, capsys, argv, line):
    code, err = _main(str(short_show), "--crazyflie", str(tmp_path / "cf"), *argv, capsys=capsys)
    assert code == 2 and err == [f"python -m swarmscene.views.export: {line}"]
    assert not (tmp_path / "cf").exists()


def test_placement_without_a_crazyflie_export_is_refused(short_show, tmp_path, capsys):
    code, err = _main(str(short_show), "--csv", str(tmp_path / "csv"), "--scale", "0.5", capsys=capsys)
    assert code == 2
    assert err == ["python -m swarmscene.views.export: --scale: places the Crazyflie show: give --crazyflie DIR"]
    assert not (tmp_path / "csv").exists()


# -- the Crazyswarm2 bundle ------------------------------------------------------------------------
@pytest.mark.parametrize("placement, controller", [([], "mellinger"),
                                                   (["--fit-box", "-1", "-1", "0", "1", "1", "1.5"], "pid")])
def test_crazyflies_yaml_places_each_vehicle_at_the_start_of_its_trajectory(short_show, tmp_path, capsys,
                                                                            placement, controller):
    import yaml

    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--controller", controller, *placement, capsys=capsys)
    assert code == 0 and err == []
    config = yaml.safe_load((out / "crazyflies.yaml").read_text())
    assert list(config["robots"]) == ["cf_0", "cf_1", "cf_2"]
    assert config["all"]["firmware_params"]["stabilizer"]["controller"] == {"mellinger": 2, "pid": 1}[controller]
    assert config["all"]["firmware_params"]["commander"]["enHighLevel"] == 1
    t, samples, _ = export.show_samples(short_show)
    scale = json.loads((out / "crazyflie.json").read_text())["placement"]
    for i in range(3):
        robot = config["robots"][f"cf_{i}"]
        assert robot["enabled"] is True and robot["type"] in config["robot_types"]
        assert robot["uri"] == f"radio://0/80/2M/E7E7E7E70{i}"
        start = export.Poly4D.from_csv(out / f"cf_{i}.csv").evaluate([0.0])[0, :3]
        np.testing.assert_array_equal(np.float32(robot["initial_position"]), np.float32(start))
        # where the vehicle stands in the (placed) scenario, within the fit's 5 mm
        np.testing.assert_allclose(robot["initial_position"],
                                   scale["scale"] * samples[0, i, :3] + scale["offset"], atol=0.005)


# -- take-off and landing --------------------------------------------------------------------------
def test_takeoff_and_landing_join_a_show_that_starts_in_the_air(short_show, tmp_path, capsys):
    """The take-off raised 0.5 m (--offset 0 0 0.5: the show now starts in the air): a 2 s piece
    from rest on the floor below the first point, a 3 s piece to rest on the floor below the last;
    both join the show with position to jerk continuous, as the fit's own joins."""
    import yaml

    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--offset", "0", "0", "0.5", "--takeoff", "2",
                      "--land", "3", "--geofence", "-2", "-2", "-0.05", "2", "2", "3", capsys=capsys)
    assert code == 0 and err == []
    summary = json.loads((out / "crazyflie.json").read_text())
    assert summary["segments"] == {"takeoff": 2.0, "land": 3.0, "floor": 0.0}
    t, samples, _ = export.show_samples(short_show)
    config = yaml.safe_load((out / "crazyflies.yaml").read_text())
    for i, vehicle in enumerate(summary["vehicles"]):
        assert vehicle["start_time"] == -2.0 and vehicle["duration"] == pytest.approx(8.0, abs=1e-5)
        poly = export.Poly4D.from_csv(out / f"cf_{i}.csv", t0=-2.0)
        assert poly.pieces == vehicle["pieces"] and poly.durations[0] == 2.0 and poly.durations[-1] == 3.0
        first, last = samples[0, i, :3] + [0, 0, 0.5], samples[-1, i, :3] + [0, 0, 0.5]
        start, end = poly.evaluate([0.0, 3.0])[:, :3]  # the fitted show's first and last points
        np.testing.assert_allclose(start, first, atol=0.005)  # the show starts on time
        np.testing.assert_allclose(end, last, atol=0.005)
        np.testing.assert_allclose(poly.evaluate([-2.0])[0, :3], [start[0], start[1], 0.0], atol=1e-5)
        np.testing.assert_allclose(poly.evaluate([6.0])[0, :3], [end[0], end[1], 0.0], atol=1e-5)
        for n in (1, 2, 3):  # at rest on the floor at both ends
            assert np.abs(poly.evaluate([-2.0, 6.0], n)).max() < 1e-4, n
        joins = [(j, n, tol) for j in (0.0, 3.0) for n, tol in ((0, 1e-5), (1, 1e-4), (2, 1e-3), (3, 1e-2))]
        for join, n, tol in joins:
            jump = np.abs(poly.evaluate([join - 1e-9], n) - poly.evaluate([join + 1e-9], n))
            assert jump.max() < tol, (join, n, jump.max())
        np.testing.assert_allclose(config["robots"][f"cf_{i}"]["initial_position"], [start[0], start[1], 0.0],
                                   atol=1e-5)


def test_a_takeoff_too_short_for_the_vehicle_is_refused(short_show, tmp_path, capsys):
    """1.5 m in 0.3 s: the 7th-degree rise needs 51.4 m/s^2 of collective thrust."""
    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--offset", "0", "0", "0.5", "--takeoff", "0.3",
                      capsys=capsys)
    assert code == 1 and "cf_0: collective thrust |a + g e3| (m/s^2) 51.4 > 15.5" in err[0]
    assert err[0].endswith("(--time-scale auto or a longer --takeoff/--land slows it down; --allow-exceed writes "
                           "it anyway)") and len(err) == 1
    assert not out.exists()


def test_with_a_fit_box_the_floor_is_the_placed_shows_floor(short_show, tmp_path, capsys):
    """The take-off ends 1.5 m up, still climbing; placed in the box (scale 1: it fits) its landing ends
    on zmin + 2 x 5 mm, where the
    placed show started. A take-off into a show that starts on that floor already climbing has to
    dip below it first (rest to upward speed at one height): the geofence refuses it."""
    out = tmp_path / "cf"
    code, err = _main(str(short_show), "--crazyflie", str(out), "--fit-box", "-2", "-2", "0", "2", "2", "2.5",
                      "--land", "4", capsys=capsys)
    assert code == 0 and err == []
    summary = json.loads((out / "crazyflie.json").read_text())
    assert summary["segments"] == {"takeoff": None, "land": 4.0, "floor": pytest.approx(0.01)}
    assert summary["geofence"]["breach"] is None
    poly = export.Poly4D.from_csv(out / "cf_1.csv")
    assert poly.evaluate([7.0])[0, 2] == pytest.approx(0.01, abs=1e-5)  # landed on the floor
    assert poly.evaluate([0.0])[0, 2] == pytest.approx(0.01, abs=0.005)  # the placed show's start, within the fit
    code, err = _main(str(short_show), "--crazyflie", str(out / "up"), "--fit-box", "-2", "-2", "0", "2", "2", "2.5",
                      "--takeoff", "3", capsys=capsys)
    assert code == 1 and err[0].startswith("python -m swarmscene.views.export: cf_0 leaves the geofence at t = -")
    assert "through the z min face" in err[0] and not (out / "up").exists()


@pytest.mark.parametrize("argv, line", [
    (["--takeoff", "0"], "--takeoff: must be a finite number of seconds > 0 (got '0')"),
    (["--land", "soon"], "--land: must be a finite number of seconds > 0 (got 'soon')"),
    (["--floor", "0.1"], "--floor: is where --takeoff starts and --land ends: give one of them"),
    (["--land", "2", "--floor", "nan"], "--floor: must be finite numbers of metres (got 'nan')"),
])
def test_a_bad_segment_option_is_one_line_naming_it(short_show, tmp_path, capsys, argv, line):
    code, err = _main(str(short_show), "--crazyflie", str(tmp_path / "cf"), *argv, capsys=capsys)
    assert code == 2 and err == [f"python -m swarmscene.views.export: {line}"]
    assert not (tmp_path / "cf").exists()


def test_a_flown_fit_keeps_its_pieces_determined_and_is_checked_between_samples():
    """A path with corners sampled at 10 Hz: the worst piece was halved with no lower bound, down
    to pieces shorter than the sample spacing, whose least squares held inf coefficients or swung
    hundreds of metres between two samples while the error at the samples read millimetres. Now
    every piece holds at least MIN_PIECE_SAMPLES samples, the coefficients are finite, and the
    reported error covers the points midway between samples (against the samples' cubic)."""
    from scipy.interpolate import CubicSpline

    from swarmscene.views.export import MIN_PIECE_SAMPLES, fit_poly4d

    t = np.arange(0.0, 6.0 + 1e-9, 0.1)
    corner = np.abs((t % 2.0) - 1.0)  # a zigzag: corners every second, beyond any polynomial's reach
    samples = np.column_stack([t, corner, 1.0 + 0.5 * corner, np.zeros_like(t)])
    fit = fit_poly4d(t, samples)
    poly = fit.poly
    assert np.isfinite(poly.coeffs).all()
    breaks = poly.t0 + np.concatenate([[0.0], np.cumsum(poly.durations)])
    held = np.diff(np.searchsorted(t, breaks, side="left"))
    assert held.min() >= MIN_PIECE_SAMPLES - 1  # halves of at least MIN_PIECE_SAMPLES (a break's own sample aside)
    mid = 0.5 * (t[:-1] + t[1:])
    between = np.abs(poly.evaluate(mid)[:, :3] - CubicSpline(t, samples)(mid)[:, :3]).max()
    assert between <= fit.max_position_error + 1e-12 and fit.max_position_error < 0.5


def test_a_plan_show_ends_where_the_run_ended():
    """A VRB run stopped at 71 s by its completed mission (clock 90 s) made a 90 s show, the plan
    past the stop never flown; a clock of 1e6 s asked for 1e8 samples."""
    from swarmscene.views.export import plan_span

    assert plan_span({"clock": {"duration": 90.0}}, 71.0) == (0.0, 71.0)
    assert plan_span({"clock": {"duration": 1e6}}, 14.0) == (0.0, 14.0)
    assert plan_span({"clock": {"duration": 20.0}}, 20.0) == (0.0, 20.0)


def test_a_show_of_fewer_samples_than_a_piece_needs_is_one_line():
    """A 0.2 s run (3 frames) failed with scipy's 'Need more x points.', naming nothing."""
    t = np.array([0.0, 0.1, 0.2])
    samples = np.zeros((3, 2, 4))
    samples[..., 2] = 1.0
    with pytest.raises(ValueError, match=r"^samples: 3 samples, fewer than the 8 a degree-7 piece needs"):
        export.crazyflie_trajectories((t, samples))


def test_auto_time_scale_slows_a_flown_show_until_its_fitted_polynomials_hold_the_limits():
    """--time-scale auto chose its scale from the samples' finite differences; a fit of 10 Hz flown
    samples turning sharp corners asks for more (22.9 m/s^2 of thrust at that scale), and the
    refusal then advised the option already given. It now raises the scale until the fitted
    polynomials hold every limit."""
    t = np.arange(0.0, 8.0 + 1e-9, 0.1)
    corner = np.abs((t % 2.0) - 1.0)
    samples = np.zeros((len(t), 2, 4))
    samples[:, 0, 0], samples[:, 1, 0], samples[..., 2] = corner, corner + 3.0, 1.0
    first = export._auto_time_scale(samples, t, export.CRAZYFLIE["mellinger"])
    assert export.crazyflie_trajectories((t, samples), time_scale=first).exceeded()  # the samples' guess fails
    show = export.crazyflie_trajectories((t, samples), time_scale="auto")
    assert show.time_scale > first and not show.exceeded()
