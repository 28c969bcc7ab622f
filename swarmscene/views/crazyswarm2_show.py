#!/usr/bin/env python3
"""Fly a swarmscene show of Crazyflies with Crazyswarm2 (crazyflie_py).

Copied unchanged by ``python -m swarmscene.views.export --crazyflie DIR`` beside the trajectories
(cf_<i>.csv), crazyflies.yaml and the show's data, crazyswarm2_show.json: the robots, each one's
trajectory file and first point, the show's duration, whether it starts and ends on the floor, and
the floor's height. Start Crazyswarm2's server on this folder's crazyflies.yaml, then run this
script in a shell where the Crazyswarm2 workspace is sourced:

    # in Crazyswarm2's simulator:
    ros2 launch crazyflie launch.py crazyflies_yaml_file:=$PWD/crazyflies.yaml backend:=sim
    python3 crazyswarm2_show.py --ros-args -p use_sim_time:=True
    # real vehicles (put your radio uris into crazyflies.yaml first):
    ros2 launch crazyflie launch.py crazyflies_yaml_file:=$PWD/crazyflies.yaml
    python3 crazyswarm2_show.py

Positions are absolute, in the frame of the motion capture (x east, y north, z up, metres): place
each vehicle at its initial_position of crazyflies.yaml.

What it asks of the vehicles (:func:`fly`): it uploads each robot's trajectory as trajectory 0,
brings the vehicles to the trajectories' first points (a take-off to each one's first height and a
go-to, unless every trajectory starts on the floor: then the trajectory is the take-off), starts all
trajectories at once with the positions absolute (``relative=False``) and the time scale 1 (the
export's time scale is already in the durations), waits the trajectories' duration, and lands
(in place when every trajectory ends on the floor: that landing ends the high-level commander's
plan). A robot the server does not know, or a missing or damaged crazyswarm2_show.json, stops it
with one line before anything is sent.

This file is also the module ``swarmscene.views.crazyswarm2_show`` (linted, type-checked and tested with
the package). It imports the standard library only, and Crazyswarm2's ``crazyflie_py`` inside
:func:`main`, so the workspace's python3 runs it without swarmscene installed.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

DATA = "crazyswarm2_show.json"
"""The show's data file, beside this script (written by the export with it)."""
VERSION = 1
"""The data file's ``version`` this script reads."""
TRAJECTORY_ID = 0
TIMESCALE = 1.0
"""startTrajectory's timescale: 1, the export's time scale is already in the durations."""
TAKEOFF_SECONDS = 3.0
GOTO_SECONDS = 2.0
LAND_SECONDS = 3.0
TOUCHDOWN_SECONDS = 1.0
"""s: the landing in place that ends the commander's plan after a show that ends on the floor."""
SETTLE_SECONDS = 1.0


@dataclass(frozen=True)
class Robot:
    """A robot of crazyflies.yaml and its part of the show.

    Attributes:
        name: the robot's name in crazyflies.yaml (``cf_<i>``).
        trajectory: the file of its trajectory in this folder (``cf_<i>.csv``).
        start: its trajectory's first point: x, y, z (m) and yaw (rad).
    """

    name: str
    trajectory: str
    start: tuple[float, float, float, float]


@dataclass(frozen=True)
class Show:
    """What crazyswarm2_show.json holds.

    Attributes:
        robots: every robot of the show, in the order the export numbered them.
        show_seconds: the trajectories' duration (s), the export's time scale and take-off/landing
            segments included.
        starts_on_floor: every trajectory starts on the floor: it is the take-off (no separate one).
        ends_on_floor: every trajectory ends on the floor: it is the landing.
        floor: the floor's height, m.
        landing_height: m, where a landing from the air ends (a few centimetres above the floor).
    """

    robots: tuple[Robot, ...]
    show_seconds: float
    starts_on_floor: bool
    ends_on_floor: bool
    floor: float
    landing_height: float


class ShowFileError(ValueError):
    """crazyswarm2_show.json is missing or damaged: the message is one line naming the file."""


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ShowFileError(f"{where}: must be a finite number (got {value!r})")
    return float(value)


def _flag(value: Any, where: str) -> bool:
    if not isinstance(value, bool):
        raise ShowFileError(f"{where}: must be true or false (got {value!r})")
    return value


def _robot(value: Any, k: int, folder: Path) -> Robot:
    where = f"robots[{k}]"
    if not isinstance(value, dict) or set(value) != {"name", "trajectory", "start"}:
        raise ShowFileError(f"{where}: must be an object with the keys name, trajectory and start (got {value!r})")
    name, trajectory, start = value["name"], value["trajectory"], value["start"]
    if not isinstance(name, str) or not name:
        raise ShowFileError(f"{where}.name: must be a robot's name (got {name!r})")
    # a file of this folder only: the data file may have been edited, and the script reads what it names
    if not isinstance(trajectory, str) or Path(trajectory).name != trajectory or trajectory in ("", ".", ".."):
        raise ShowFileError(f"{where}.trajectory: must be a file name in {folder} (got {trajectory!r})")
    if not (folder / trajectory).is_file():
        raise ShowFileError(f"{where}.trajectory: {trajectory} is not a file in {folder}")
    if not isinstance(start, list) or len(start) != 4:
        raise ShowFileError(f"{where}.start: must be 4 numbers x, y, z (m) and yaw (rad) (got {start!r})")
    x, y, z, yaw = (_number(v, f"{where}.start[{i}]") for i, v in enumerate(start))
    return Robot(name, trajectory, (x, y, z, yaw))


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    keys = [key for key, _ in pairs]
    twice = sorted({key for key in keys if keys.count(key) > 1})
    if twice:
        raise ShowFileError(f"the key {twice[0]!r} is given twice")
    return dict(pairs)


def read_show(path: Path) -> Show:
    """The show of ``path`` (crazyswarm2_show.json), checked; a ShowFileError names what is wrong."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"), object_pairs_hook=_unique_keys)
    except FileNotFoundError:
        raise ShowFileError("missing (python -m swarmscene.views.export --crazyflie writes it beside this script)"
                            ) from None
    except OSError as exc:
        raise ShowFileError(f"cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise ShowFileError("not a JSON file (not UTF-8 text)") from None
    except json.JSONDecodeError as exc:
        raise ShowFileError(f"not a JSON file ({exc})") from None
    keys = {"version", "robots", "show_seconds", "starts_on_floor", "ends_on_floor", "floor", "landing_height"}
    if not isinstance(data, dict) or set(data) != keys:
        got = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise ShowFileError(f"must be an object with the keys {', '.join(sorted(keys))} (got {got})")
    if data["version"] != VERSION or isinstance(data["version"], bool):
        raise ShowFileError(f"version: this script reads version {VERSION} (got {data['version']!r}): "
                            "export the show again")
    if not isinstance(data["robots"], list) or not data["robots"]:
        raise ShowFileError(f"robots: must be a list of at least one robot (got {data['robots']!r})")
    robots = tuple(_robot(value, k, path.parent) for k, value in enumerate(data["robots"]))
    names = [robot.name for robot in robots]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise ShowFileError(f"robots: {twice[0]} is given twice")
    seconds = _number(data["show_seconds"], "show_seconds")
    if seconds < 0:
        raise ShowFileError(f"show_seconds: must be >= 0 (got {seconds!r})")
    return Show(robots, seconds, _flag(data["starts_on_floor"], "starts_on_floor"),
                _flag(data["ends_on_floor"], "ends_on_floor"), _number(data["floor"], "floor"),
                _number(data["landing_height"], "landing_height"))


def fly(show: Show, folder: Path, swarm: Any, trajectory_type: Any) -> None:
    """Fly ``show`` with Crazyswarm2's ``swarm`` (``crazyflie_py.Crazyswarm``), loading each robot's
    trajectory from ``folder`` with ``trajectory_type`` (``crazyflie_py.uav_trajectory.Trajectory``).

    Exits with one line naming the robots of the show the server does not know, before anything is
    sent."""
    time_helper = swarm.timeHelper
    allcfs = swarm.allcfs
    missing = sorted({robot.name for robot in show.robots} - set(allcfs.crazyfliesByName))
    if missing:
        sys.exit(f"{Path(__file__).name}: the Crazyswarm2 server has no {', '.join(missing)}: "
                 "start it on this folder's crazyflies.yaml")
    cfs = [(robot, allcfs.crazyfliesByName[robot.name]) for robot in show.robots]
    for robot, cf in cfs:
        trajectory = trajectory_type()
        trajectory.loadcsv(folder / robot.trajectory)
        cf.uploadTrajectory(TRAJECTORY_ID, 0, trajectory)
    if not show.starts_on_floor:  # the show starts in the air: rise straight up, then go to each first point
        for robot, cf in cfs:
            cf.takeoff(targetHeight=robot.start[2], duration=TAKEOFF_SECONDS)
        time_helper.sleep(TAKEOFF_SECONDS + SETTLE_SECONDS)
        for robot, cf in cfs:
            cf.goTo(robot.start[:3], robot.start[3], GOTO_SECONDS)
        time_helper.sleep(GOTO_SECONDS + SETTLE_SECONDS)
    allcfs.startTrajectory(TRAJECTORY_ID, timescale=TIMESCALE, relative=False)
    time_helper.sleep(show.show_seconds * TIMESCALE + SETTLE_SECONDS)
    if show.ends_on_floor:  # already down: a short landing in place ends the commander's plan
        allcfs.land(targetHeight=show.floor, duration=TOUCHDOWN_SECONDS)
        time_helper.sleep(TOUCHDOWN_SECONDS + SETTLE_SECONDS)
    else:
        allcfs.land(targetHeight=show.landing_height, duration=LAND_SECONDS)
        time_helper.sleep(LAND_SECONDS + SETTLE_SECONDS)


def main(folder: Path | None = None) -> None:
    """Read the show beside this script (or in ``folder``), connect to Crazyswarm2 and fly it.

    The command line is Crazyswarm2's (``--ros-args ...``, read by rclpy), not this script's."""
    folder = Path(__file__).resolve().parent if folder is None else Path(folder).resolve()
    path = folder / DATA
    try:
        show = read_show(path)
    except ShowFileError as exc:
        sys.exit(f"{Path(__file__).name}: {path}: {exc}")
    from crazyflie_py import Crazyswarm  # Crazyswarm2's, in its sourced ROS 2 workspace
    from crazyflie_py.uav_trajectory import Trajectory

    fly(show, folder, Crazyswarm(), Trajectory)


if __name__ == "__main__":
    main()
