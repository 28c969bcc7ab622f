"""The Crazyswarm2 bundle's script (``crazyswarm2_show.py``), run without ROS 2: Crazyswarm2's
``crazyflie_py`` API (``Crazyswarm``, ``allcfs.crazyfliesByName``, ``cf.uploadTrajectory``,
``cf.takeoff``, ``cf.goTo``, ``allcfs.startTrajectory``, ``allcfs.land``, ``timeHelper.sleep``;
IMRCLab/crazyswarm2, crazyflie_py/crazyflie.py) stands in as a recorder with a simulated clock, so
the test reads what the script would ask of the vehicles and when."""

from __future__ import annotations

import json
import runpy
import sys
import types

import numpy as np
import pytest
import yaml

from swarmscene import api
from swarmscene.views import export

SHOW = ["scenario=vrb_airshow", "clock.duration=3.0"]


@pytest.fixture(scope="module")
def short_show(tmp_path_factory):
    """The first 3 s of the VRB air show (the take-off from the ground), simulated and written."""
    run_dir = tmp_path_factory.mktemp("show")
    sim = api.build(SHOW)
    api.write_outputs(sim, sim.run(), run_dir)
    return run_dir


class Recorder:
    """Crazyswarm2's API as a log of (time s, robot or "all", call, arguments) on a simulated clock."""

    def __init__(self, names):
        self.clock, self.calls, self.names = 0.0, [], names

    def log(self, who, what, **args):
        self.calls.append((round(self.clock, 9), who, what, args))

    def modules(self):
        recorder = self

        class Trajectory:  # uav_trajectory.Trajectory.loadcsv: 33 columns after a header line
            def loadcsv(self, filename):
                data = np.loadtxt(filename, delimiter=",", skiprows=1, usecols=range(33), ndmin=2)
                self.filename, self.pieces, self.duration = str(filename), data, float(np.sum(data[:, 0]))

        class Crazyflie:
            def __init__(self, name):
                self.name = name

            def uploadTrajectory(self, trajectoryId, pieceOffset, trajectory):
                recorder.log(self.name, "upload", id=trajectoryId, offset=pieceOffset, file=trajectory.filename,
                             duration=trajectory.duration)

            def takeoff(self, targetHeight, duration, groupMask=0):
                recorder.log(self.name, "takeoff", height=targetHeight, duration=duration)

            def goTo(self, goal, yaw, duration, relative=False, groupMask=0):
                recorder.log(self.name, "goTo", goal=[goal[0], goal[1], goal[2]], yaw=yaw, duration=duration)

        class Server:
            crazyfliesByName = {name: Crazyflie(name) for name in recorder.names}

            def startTrajectory(self, trajectoryId, timescale=1.0, reverse=False, relative=True, groupMask=0):
                recorder.log("all", "start", id=trajectoryId, timescale=timescale, reverse=reverse, relative=relative)

            def land(self, targetHeight, duration, groupMask=0):
                recorder.log("all", "land", height=targetHeight, duration=duration)

        class TimeHelper:
            def sleep(self, duration):
                recorder.clock += duration

        class Crazyswarm:
            def __init__(self):
                self.allcfs, self.timeHelper = Server(), TimeHelper()

        package = types.ModuleType("crazyflie_py")
        package.Crazyswarm = Crazyswarm
        reader = types.ModuleType("crazyflie_py.uav_trajectory")
        reader.Trajectory = Trajectory
        return {"crazyflie_py": package, "crazyflie_py.uav_trajectory": reader}


def fly(out, monkeypatch, names=None):
    """Run the bundle's script against the recorder (robots: crazyflies.yaml's unless ``names``)."""
    config = yaml.safe_load((out / "crazyflies.yaml").read_text())
    recorder = Recorder(list(config["robots"]) if names is None else names)
    for name, module in recorder.modules().items():
        monkeypatch.setitem(sys.modules, name, module)
    runpy.run_path(str(out / export.LAUNCH_SCRIPT), run_name="__main__")
    return recorder, config, json.loads((out / "crazyflie.json").read_text())


def export_show(run_dir, out, *options):
    export.main([str(run_dir), "--crazyflie", str(out), *options])


def test_the_script_compiles_and_uploads_exactly_the_written_trajectories(short_show, tmp_path, monkeypatch):
    out = tmp_path / "cf"
    export_show(short_show, out)
    source = (out / export.LAUNCH_SCRIPT).read_text()
    compile(source, export.LAUNCH_SCRIPT, "exec")
    recorder, config, summary = fly(out, monkeypatch)
    uploads = [(who, args) for _, who, what, args in recorder.calls if what == "upload"]
    written = sorted(p.name for p in out.glob("cf_*.csv"))
    assert [who for who, _ in uploads] == list(config["robots"]) == ["cf_0", "cf_1", "cf_2"]
    assert sorted(args["file"].rsplit("/", 1)[-1] for _, args in uploads) == written
    for who, args in uploads:  # each robot gets its own file, as trajectory 0 at piece 0
        assert args["file"] == str((out / f"{who}.csv").resolve()) and (args["id"], args["offset"]) == (0, 0)
        vehicle = summary["vehicles"][int(who.split("_")[1])]
        assert args["duration"] == pytest.approx(vehicle["duration"], abs=1e-6)


def test_a_show_from_the_ground_takes_off_with_its_trajectory_and_runs_its_full_duration(
        short_show, tmp_path, monkeypatch):
    """The air show starts on the ground: no separate take-off; the trajectories start at once,
    absolute, at time scale 1; the landing comes after their whole duration (3 s)."""
    out = tmp_path / "cf"
    export_show(short_show, out)
    recorder, config, summary = fly(out, monkeypatch)
    after = [(t, who, what, args) for t, who, what, args in recorder.calls if what != "upload"]
    assert [what for _, _, what, _ in after] == ["start", "land"]
    (t_start, _, _, start), (t_land, _, _, land) = after
    assert start == {"id": 0, "timescale": 1.0, "reverse": False, "relative": False}
    duration = summary["vehicles"][0]["duration"]
    assert duration == pytest.approx(3.0, abs=1e-6)
    assert duration <= t_land - t_start <= duration + 1.0
    assert land["height"] == pytest.approx(0.06)  # it ends in the air: a landing a few cm above the floor
    assert recorder.clock == pytest.approx(t_land + land["duration"] + 1.0)


def test_a_show_in_the_air_takes_off_to_each_first_point_and_keeps_the_time_scale(short_show, tmp_path,
                                                                                   monkeypatch):
    """Raised 0.5 m and slowed down twice: each vehicle rises to its own first height, goes to its
    first point and yaw (crazyflies.yaml's initial_position), then the 6 s show runs."""
    out = tmp_path / "cf"
    export_show(short_show, out, "--offset", "0", "0", "0.5", "--time-scale", "2")
    recorder, config, summary = fly(out, monkeypatch)
    calls = [(t, who, what, args) for t, who, what, args in recorder.calls if what != "upload"]
    assert [what for _, _, what, _ in calls] == ["takeoff"] * 3 + ["goTo"] * 3 + ["start", "land"]
    for i in range(3):
        poly = export.Poly4D.from_csv(out / f"cf_{i}.csv")
        first = poly.evaluate([0.0])[0]
        _, who, _, takeoff = calls[i]
        _, who_goto, _, goto = calls[3 + i]
        assert who == who_goto == f"cf_{i}"
        assert takeoff["height"] == pytest.approx(first[2], abs=1e-6) and takeoff["height"] > 0.45
        np.testing.assert_allclose(goto["goal"], config["robots"][f"cf_{i}"]["initial_position"], atol=1e-6)
        assert goto["yaw"] == pytest.approx(first[3], abs=1e-6)
        assert calls[3 + i][0] >= takeoff["duration"]  # after the take-off
    t_goto = calls[3][0]
    (t_start, _, _, start), (t_land, _, _, land) = calls[6:]
    assert t_start >= t_goto + calls[3][3]["duration"] and start["timescale"] == 1.0 and start["relative"] is False
    assert summary["time_scale"] == 2.0 and summary["vehicles"][0]["duration"] == pytest.approx(6.0, abs=1e-5)
    assert 6.0 <= t_land - t_start <= 7.0


def test_take_off_and_landing_segments_replace_the_scripts_own(short_show, tmp_path, monkeypatch):
    out = tmp_path / "cf"
    export_show(short_show, out, "--offset", "0", "0", "0.5", "--takeoff", "2", "--land", "3", "--floor", "0.1")
    recorder, _, summary = fly(out, monkeypatch)
    calls = [(t, what, args) for t, _, what, args in recorder.calls if what != "upload"]
    assert [what for _, what, _ in calls] == ["start", "land"]
    assert summary["vehicles"][0]["duration"] == pytest.approx(8.0, abs=1e-5)
    assert 8.0 <= calls[1][0] - calls[0][0] <= 9.0
    assert calls[1][2]["height"] == 0.1  # already on the floor: a landing in place ends the plan


def test_a_server_without_a_robot_of_the_bundle_stops_the_script_naming_it(short_show, tmp_path, monkeypatch):
    out = tmp_path / "cf"
    export_show(short_show, out)
    with pytest.raises(SystemExit) as stop:
        fly(out, monkeypatch, names=["cf_0", "cf_2"])
    assert str(stop.value) == ("crazyswarm2_show.py: the Crazyswarm2 server has no cf_1: start it on this folder's "
                               "crazyflies.yaml")
