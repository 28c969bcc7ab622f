"""The Crazyflie export refuses an unsafe placed show (issue #37, #36): the keep-out ellipsoid, the
run's separation limit and the floor clearance, checked after --fit-box and --time-scale, in one
line naming the vehicles, the time and the scale, writing nothing; --allow-exceed writes it anyway.
A show that starts in the air is lifted to the floor clearance and taken off to; a non-finite
position names the file and the vehicle."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.setpoint import Setpoints
from swarmscene.views import export

PROG = "python -m swarmscene.views.export"
README_BOX = ["--fit-box", "-2", "-2", "0", "2", "2", "2"]


def _main(*argv, capsys):
    try:
        export.main(list(argv))
        code = 0
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out.splitlines(), captured.err.splitlines()


@pytest.fixture(scope="module")
def cem_six(tmp_path_factory):
    """The cem_six_vehicle preset, flown and written (in the air at z = 2 m, pairs 1.35 m apart at least)."""
    run_dir = tmp_path_factory.mktemp("cem") / "run"
    sim = api.build(["scenario=cem_six_vehicle", "output.summary=false"])
    api.write_outputs(sim, sim.run(), run_dir)
    return run_dir


@pytest.fixture(scope="module")
def stacked(tmp_path_factory):
    """Two vehicles hovering 0.2 m one above the other for 2 s (separation limit 0.1 m: only the
    keep-out ellipsoid, 0.3 m tall, is broken), written."""
    run_dir = tmp_path_factory.mktemp("stacked") / "run"
    sim = api.build(["swarm.n=2", "swarm.leader=null", "swarm.start.layout=explicit",
                     "swarm.start.positions=[[0,0,1],[0,0,1.2]]", "safety.separation_limit=0.1",
                     "avoidance=none", "dynamics=single_integrator", "clock.duration=2", "output.summary=false"])
    target = sim.world.pos.copy()
    sim.formation.setpoints = lambda world, sensing: Setpoints.hold(target)
    api.write_outputs(sim, sim.run(), run_dir)
    return run_dir


def test_the_readme_fit_of_cem_six_vehicle_is_refused_naming_the_scale(cem_six, tmp_path, capsys):
    out = tmp_path / "cf"
    code, stdout, err = _main(str(cem_six), "--crazyflie", str(out), *README_BOX, capsys=capsys)
    assert code == 1 and stdout == [] and not out.exists()
    assert err == [f"{PROG}: cf_0 and cf_1 come 0.412 m apart at t = 0.00 s (0.202 m at the closest), under the run's separation limit "
                   "0.56 m (scale 0.151, offset (-1.75285, 0, -0.0370237) m, time scale 1); refused, nothing "
                   "written (--allow-exceed writes it anyway)"]


def test_forced_it_is_lifted_to_the_floor_clearance_and_taken_off_to(cem_six, tmp_path, capsys):
    out = tmp_path / "cf"
    code, stdout, err = _main(str(cem_six), "--crazyflie", str(out), *README_BOX, "--allow-exceed", capsys=capsys)
    assert code == 0 and len(err) == 1 and "written because of --allow-exceed" in err[0]
    placed = next(line for line in stdout if line.strip().startswith("placed:"))
    assert placed.strip().startswith("placed: scale 0.151, offset (-1.75285, 0, -0.0370237) m, time scale 1; "
                                     "floor z = 0.01 m, height above the floor in the air (m) 0.255 (limit 0.25)")
    dense = np.linspace(0.0, 24.0, 2401)
    for i in range(6):
        z = export.Poly4D.from_csv(out / f"cf_{i}.csv").evaluate(dense)[:, 2]
        assert z.min() >= 0.01 + 0.25  # the whole show at least the clearance above the box's floor
    show = json.loads((out / "crazyswarm2_show.json").read_text())
    assert show["starts_on_floor"] is False  # the script takes off to each first point


def test_a_stacked_show_is_refused_for_the_keep_out_ellipsoid(stacked, tmp_path, capsys):
    out = tmp_path / "cf"
    code, stdout, err = _main(str(stacked), "--crazyflie", str(out), capsys=capsys)
    assert code == 1 and not out.exists()
    assert err == [f"{PROG}: cf_0 and cf_1 come inside each other's keep-out ellipsoid at t = 0.00 s "
                   "(||E^-1 (p_i - p_j)|| = 0.67 < 1) (scale 1, offset (0, 0, 0) m, time scale 1); refused, "
                   "nothing written (--allow-exceed writes it anyway)"]
    # a flatter ellipsoid (a vehicle whose downwash reaches 0.15 m) lets it through
    code, stdout, err = _main(str(stacked), "--crazyflie", str(out), "--keep-out", "0.12", "0.12", "0.15",
                              capsys=capsys)
    assert code == 0 and err == [] and (out / "cf_1.csv").exists()


def test_a_show_too_low_is_refused_and_its_take_off_excepted(capsys):
    t = np.linspace(0.0, 4.0, 401)
    low = np.zeros((t.size, 2, 4))
    low[:, 0, :3] = [0.0, 0.0, 0.1]  # hovers 10 cm up the whole show
    low[:, 1, 0] = 1.0
    low[:, 1, 2] = np.minimum(t, 1.0)  # takes off from the floor to 1 m, then stays
    show = export.crazyflie_trajectories((t, low))
    floor = [c for c in show.safety if c["name"].startswith("height")][0]
    assert not floor["holds"] and floor["first"]["vehicles"] == ["cf_0"]
    assert show.unsafe() == ["cf_0 flies 0.100 m above the floor (z = 0 m) at t = 0.00 s, under the floor "
                             "clearance 0.25 m"]
    low[:, 0, 2] = 0.5  # both fly high enough; the second one's climb through 0.25 m is its take-off
    assert export.crazyflie_trajectories((t, low)).unsafe() == []


def test_a_non_finite_position_names_the_file_and_the_vehicle(stacked, tmp_path, capsys):
    t = np.linspace(0.0, 1.0, 11)
    samples = np.zeros((11, 3, 4))
    samples[..., 2] = 1.0
    samples[5, 2, 0] = np.nan
    with pytest.raises(ValueError) as err:
        export.crazyflie_trajectories((t, samples))
    assert str(err.value) == ("samples: vehicle 2 has a non-finite position [nan, 0.0, 1.0] at t = 0.5 s "
                              "(1 vehicles); nothing written")
    import shutil

    broken = tmp_path / "run"
    shutil.copytree(stacked, broken)
    with np.load(broken / "trajectory.npz") as data:
        arrays = {k: data[k] for k in data.files}
    arrays["pos"] = arrays["pos"].copy()
    arrays["pos"][3, 1, 2] = np.inf
    np.savez(broken / "trajectory.npz", **arrays)
    code, _, err = _main(str(broken), "--crazyflie", str(tmp_path / "cf"), "--source", "flown", capsys=capsys)
    assert code == 2 and not (tmp_path / "cf").exists()
    assert err == [f"{PROG}: {broken / 'trajectory.npz'}: vehicle 1 has a non-finite position [0.0, 0.0, inf] at "
                   "t = 0.3 s (1 vehicles); nothing written"]


def test_the_runs_floor_is_where_an_unplaced_take_off_starts(tmp_path, capsys):
    import yaml

    run_dir = tmp_path / "run"
    sim = api.build(["swarm.n=2", "swarm.leader=null", "swarm.start.layout=explicit",
                     "swarm.start.positions=[[0,0,1.5],[1,0,1.5]]", "environment.floor=0.5", "avoidance=none",
                     "dynamics=single_integrator", "clock.duration=2", "output.summary=false"])
    target = sim.world.pos.copy()
    sim.formation.setpoints = lambda world, sensing: Setpoints.hold(target)
    api.write_outputs(sim, sim.run(), run_dir)
    out = tmp_path / "cf"
    code, stdout, err = _main(str(run_dir), "--crazyflie", str(out), "--takeoff", "3", capsys=capsys)
    assert code == 0 and err == []
    config = yaml.safe_load((out / "crazyflies.yaml").read_text())
    assert config["robots"]["cf_0"]["initial_position"] == pytest.approx([0.0, 0.0, 0.5], abs=1e-6)
    assert "floor z = 0.5 m" in next(line for line in stdout if "placed:" in line)
