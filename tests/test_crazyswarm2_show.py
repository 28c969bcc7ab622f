"""The Crazyswarm2 script of the export's bundle as a module (``swarmscene.views.crazyswarm2_show``), run
against a stand-in for Crazyswarm2's ``crazyflie_py`` (IMRCLab/crazyswarm2, crazyflie_py/crazyflie.py:
``Crazyswarm``, ``allcfs.crazyfliesByName``, ``cf.uploadTrajectory``, ``cf.takeoff``, ``cf.goTo``,
``allcfs.startTrajectory``, ``allcfs.land``, ``timeHelper.sleep``; ``uav_trajectory.Trajectory``)
that records every call in order, on hand-written show data: the exact calls and arguments of a
show that starts in the air and of one that starts and ends on the floor, and a missing or damaged
``crazyswarm2_show.json`` stopped in one line before anything is sent. The bundle as the export
writes it, flown end to end, is tests/test_export_crazyswarm2.py's."""

from __future__ import annotations

import ast
import json
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from swarmscene.views import crazyswarm2_show, export


def fake_crazyflie_py(names: list[str]) -> tuple[list[tuple], dict[str, types.ModuleType]]:
    """(the call log, the modules ``crazyflie_py`` and ``crazyflie_py.uav_trajectory``): each call
    as (who, what, arguments), ``who`` a robot's name, "all" or "time"."""
    calls: list[tuple] = []

    class Trajectory:
        def loadcsv(self, filename):
            self.filename = filename
            calls.append(("traj", "loadcsv", {"filename": filename}))

    class Crazyflie:
        def __init__(self, name):
            self.name = name

        def uploadTrajectory(self, trajectoryId, pieceOffset, trajectory):
            calls.append((self.name, "uploadTrajectory",
                          {"trajectoryId": trajectoryId, "pieceOffset": pieceOffset, "file": trajectory.filename}))

        def takeoff(self, targetHeight, duration, groupMask=0):
            calls.append((self.name, "takeoff", {"targetHeight": targetHeight, "duration": duration}))

        def goTo(self, goal, yaw, duration, relative=False, groupMask=0):
            calls.append((self.name, "goTo", {"goal": goal, "yaw": yaw, "duration": duration}))

    class Server:
        def __init__(self):
            self.crazyfliesByName = {name: Crazyflie(name) for name in names}

        def startTrajectory(self, trajectoryId, timescale=1.0, reverse=False, relative=True, groupMask=0):
            calls.append(("all", "startTrajectory",
                          {"trajectoryId": trajectoryId, "timescale": timescale, "relative": relative}))

        def land(self, targetHeight, duration, groupMask=0):
            calls.append(("all", "land", {"targetHeight": targetHeight, "duration": duration}))

    class TimeHelper:
        def sleep(self, duration):
            calls.append(("time", "sleep", {"duration": duration}))

    class Crazyswarm:
        def __init__(self):
            calls.append(("all", "Crazyswarm", {}))
            self.allcfs, self.timeHelper = Server(), TimeHelper()

    package = types.ModuleType("crazyflie_py")
    package.Crazyswarm = Crazyswarm  # type: ignore[attr-defined]
    reader = types.ModuleType("crazyflie_py.uav_trajectory")
    reader.Trajectory = Trajectory  # type: ignore[attr-defined]
    return calls, {"crazyflie_py": package, "crazyflie_py.uav_trajectory": reader}


AIR = {
    "version": 1,
    "robots": [{"name": "cf_0", "trajectory": "cf_0.csv", "start": [0.5, -0.5, 1.25, 0.3]},
               {"name": "cf_1", "trajectory": "cf_1.csv", "start": [-0.5, 0.5, 0.75, -1.5]}],
    "show_seconds": 6.5, "starts_on_floor": False, "ends_on_floor": False, "floor": 0.0, "landing_height": 0.06,
}


def bundle(folder: Path, data: dict) -> Path:
    """A bundle's folder with ``data`` as crazyswarm2_show.json and a file for each robot's trajectory."""
    folder.mkdir()
    for robot in data["robots"]:
        (folder / robot["trajectory"]).write_text("Duration\n")
    (folder / crazyswarm2_show.DATA).write_text(json.dumps(data))
    return folder


def fly(folder: Path, monkeypatch, names=("cf_0", "cf_1")) -> list[tuple]:
    calls, modules = fake_crazyflie_py(list(names))
    for name, module in modules.items():
        monkeypatch.setitem(sys.modules, name, module)
    crazyswarm2_show.main(folder)
    return calls


def test_a_show_in_the_air_takes_off_goes_to_each_first_point_flies_and_lands_above_the_floor(tmp_path, monkeypatch):
    folder = bundle(tmp_path / "cf", AIR)
    calls = fly(folder, monkeypatch)
    here = folder.resolve()
    assert calls == [
        ("all", "Crazyswarm", {}),
        ("traj", "loadcsv", {"filename": here / "cf_0.csv"}),
        ("cf_0", "uploadTrajectory", {"trajectoryId": 0, "pieceOffset": 0, "file": here / "cf_0.csv"}),
        ("traj", "loadcsv", {"filename": here / "cf_1.csv"}),
        ("cf_1", "uploadTrajectory", {"trajectoryId": 0, "pieceOffset": 0, "file": here / "cf_1.csv"}),
        ("cf_0", "takeoff", {"targetHeight": 1.25, "duration": 3.0}),  # straight up to each one's first height
        ("cf_1", "takeoff", {"targetHeight": 0.75, "duration": 3.0}),
        ("time", "sleep", {"duration": 4.0}),  # the take-off and a second to settle
        ("cf_0", "goTo", {"goal": (0.5, -0.5, 1.25), "yaw": 0.3, "duration": 2.0}),
        ("cf_1", "goTo", {"goal": (-0.5, 0.5, 0.75), "yaw": -1.5, "duration": 2.0}),
        ("time", "sleep", {"duration": 3.0}),
        ("all", "startTrajectory", {"trajectoryId": 0, "timescale": 1.0, "relative": False}),
        ("time", "sleep", {"duration": 7.5}),  # the whole show and a second
        ("all", "land", {"targetHeight": 0.06, "duration": 3.0}),  # a few cm above the floor
        ("time", "sleep", {"duration": 4.0}),
    ]


def test_a_show_from_and_to_the_floor_is_its_own_take_off_and_landing(tmp_path, monkeypatch):
    data = {**AIR, "robots": [{**r, "start": [*r["start"][:2], 0.1, 0.0]} for r in AIR["robots"]],
            "starts_on_floor": True, "ends_on_floor": True, "floor": 0.1, "landing_height": 0.16}
    calls = fly(bundle(tmp_path / "cf", data), monkeypatch)
    assert [(who, what) for who, what, _ in calls[:5]] == [
        ("all", "Crazyswarm"), ("traj", "loadcsv"), ("cf_0", "uploadTrajectory"), ("traj", "loadcsv"),
        ("cf_1", "uploadTrajectory")]
    assert calls[5:] == [
        ("all", "startTrajectory", {"trajectoryId": 0, "timescale": 1.0, "relative": False}),
        ("time", "sleep", {"duration": 7.5}),
        ("all", "land", {"targetHeight": 0.1, "duration": 1.0}),  # in place: it ends the commander's plan
        ("time", "sleep", {"duration": 2.0}),
    ]


def test_a_show_from_the_floor_that_ends_in_the_air_lands_at_the_landing_height(tmp_path, monkeypatch):
    calls = fly(bundle(tmp_path / "cf", {**AIR, "starts_on_floor": True}), monkeypatch)
    assert [what for _, what, _ in calls[5:]] == ["startTrajectory", "sleep", "land", "sleep"]
    assert calls[7] == ("all", "land", {"targetHeight": 0.06, "duration": 3.0})


def test_a_robot_the_server_does_not_know_stops_the_script_before_anything_is_sent(tmp_path, monkeypatch):
    folder = bundle(tmp_path / "cf", AIR)
    with pytest.raises(SystemExit) as stop:
        fly(folder, monkeypatch, names=["cf_1"])
    assert str(stop.value) == ("crazyswarm2_show.py: the Crazyswarm2 server has no cf_0: start it on this folder's "
                               "crazyflies.yaml")


@pytest.mark.parametrize("damage, problem", [
    (None, "missing (python -m swarmscene.views.export --crazyflie writes it beside this script)"),
    ("{", "not a JSON file (Expecting property name enclosed in double quotes: line 1 column 2 (char 1))"),
    (b"\xff\xfe", "not a JSON file (not UTF-8 text)"),
    ([1, 2], "must be an object with the keys ends_on_floor, floor, landing_height, robots, show_seconds, "
             "starts_on_floor, version (got list)"),
    ({**AIR, "version": 2}, "version: this script reads version 1 (got 2): export the show again"),
    ({**AIR, "show_seconds": "6.5"}, "show_seconds: must be a finite number (got '6.5')"),
    ({**AIR, "show_seconds": -1.0}, "show_seconds: must be >= 0 (got -1.0)"),
    ({**AIR, "ends_on_floor": 1}, "ends_on_floor: must be true or false (got 1)"),
    ({**AIR, "robots": []}, "robots: must be a list of at least one robot (got [])"),
    ({**AIR, "robots": [{**AIR["robots"][0], "start": [0.0, 0.0, 1.0]}]},
     "robots[0].start: must be 4 numbers x, y, z (m) and yaw (rad) (got [0.0, 0.0, 1.0])"),
    ({**AIR, "robots": [{**AIR["robots"][0], "start": [0.0, None, 1.0, 0.0]}]},
     "robots[0].start[1]: must be a finite number (got None)"),
    ({**AIR, "robots": [AIR["robots"][0], AIR["robots"][0]]}, "robots: cf_0 is given twice"),
    ({**AIR, "robots": [{**AIR["robots"][0], "trajectory": "../cf_0.csv"}]},
     "robots[0].trajectory: must be a file name in FOLDER (got '../cf_0.csv')"),
    ({**AIR, "robots": [{**AIR["robots"][0], "trajectory": "cf_9.csv"}]},
     "robots[0].trajectory: cf_9.csv is not a file in FOLDER"),
    ('{"version": 1, "version": 1}', "the key 'version' is given twice"),
])
def test_a_missing_or_damaged_show_file_is_one_line_naming_it_before_anything_is_sent(
        damage, problem, tmp_path, monkeypatch):
    folder = bundle(tmp_path / "cf", AIR).resolve()
    path = folder / crazyswarm2_show.DATA
    if damage is None:
        path.unlink()
    elif isinstance(damage, bytes):
        path.write_bytes(damage)
    else:
        path.write_text(damage if isinstance(damage, str) else json.dumps(damage))
    calls, modules = fake_crazyflie_py(["cf_0", "cf_1"])
    for name, module in modules.items():
        monkeypatch.setitem(sys.modules, name, module)
    with pytest.raises(SystemExit) as stop:
        crazyswarm2_show.main(folder)
    assert str(stop.value) == f"crazyswarm2_show.py: {path}: {problem.replace('FOLDER', str(folder))}"
    assert calls == []  # not even connected


def test_the_script_needs_the_standard_library_only_and_crazyflie_py_inside_main():
    """The lab's python3 runs the bundle's copy without swarmscene (or numpy) installed."""
    tree = ast.parse(Path(crazyswarm2_show.__file__).read_text())
    top = {alias.name.split(".")[0] for node in tree.body if isinstance(node, ast.Import) for alias in node.names}
    top |= {node.module.split(".")[0] for node in tree.body if isinstance(node, ast.ImportFrom) and node.module}
    assert top - {"__future__"} <= set(sys.stdlib_module_names), top
    main = next(node for node in tree.body if isinstance(node, ast.FunctionDef) and node.name == "main")
    assert {node.module for node in ast.walk(main) if isinstance(node, ast.ImportFrom)} == {
        "crazyflie_py", "crazyflie_py.uav_trajectory"}


def synthetic_show(lift: float) -> export.ShowExport:
    """Two vehicles 1 m apart climbing 0.5 m in 4 s from ``lift`` m above the floor z = 0."""
    t = np.linspace(0.0, 4.0, 401)
    samples = np.zeros((t.size, 2, 4))
    samples[:, 1, 0] = 1.0
    samples[:, :, 2] = lift + 0.5 * (t / 4.0)[:, None] ** 2
    return export.crazyflie_trajectories((t, samples), floor_clearance=0.0)


def test_the_bundle_holds_the_module_byte_for_byte_and_the_show_it_flies(tmp_path):
    show = synthetic_show(lift=1.0)
    show.write(tmp_path / "cf")
    assert (tmp_path / "cf" / export.LAUNCH_SCRIPT).read_bytes() == Path(crazyswarm2_show.__file__).read_bytes()
    read = crazyswarm2_show.read_show(tmp_path / "cf" / export.LAUNCH_DATA)
    first = [fit.poly.evaluate([fit.poly.t0])[0] for fit in show.fits]
    assert [r.name for r in read.robots] == ["cf_0", "cf_1"] and [r.trajectory for r in read.robots] == [
        "cf_0.csv", "cf_1.csv"]
    for robot, point in zip(read.robots, first, strict=True):  # float32, as the vehicle stores it
        assert robot.start == tuple(float(np.float32(v)) for v in point)
    assert read.show_seconds == float(np.float32(4.0)) and (read.starts_on_floor, read.ends_on_floor) == (False, False)
    assert (read.floor, read.landing_height) == (0.0, 0.06)
    on_floor = crazyswarm2_show.read_show(_written(synthetic_show(lift=0.0), tmp_path / "floor") / export.LAUNCH_DATA)
    assert (on_floor.starts_on_floor, on_floor.ends_on_floor) == (True, False)  # ends 0.5 m up


def _written(show: export.ShowExport, folder: Path) -> Path:
    show.write(folder)
    return folder


def test_the_script_is_written_over_a_link_never_through_it(tmp_path):
    outside = tmp_path / "elsewhere.py"
    outside.write_text("kept\n")
    folder = tmp_path / "cf"
    folder.mkdir()
    (folder / export.LAUNCH_SCRIPT).symlink_to(outside)
    (folder / export.LAUNCH_DATA).symlink_to(outside)
    synthetic_show(lift=1.0).write(folder)
    assert outside.read_text() == "kept\n"
    assert not (folder / export.LAUNCH_SCRIPT).is_symlink() and not (folder / export.LAUNCH_DATA).is_symlink()
    assert (folder / export.LAUNCH_SCRIPT).read_bytes() == export.crazyswarm2_program()
