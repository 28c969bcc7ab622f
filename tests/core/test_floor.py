"""The floor (environment.floor, issue #37): a vehicle that meets it lands or crashes; none by default."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.floor import Floor
from swarmscene.core.state import WorldState


def falling(data: dict, floor, drifts: dict[int, float], duration: float = 8.0) -> dict:
    """The default scenario with agents drifting straight down from z = 2 m (a coasting failure)."""
    data["environment"]["floor"] = floor
    data["events"] = [{"at": 0.5, "agents": [a], "name": "drift", "velocity": [0.0, 0.0, -v]}
                      for a, v in drifts.items()]
    data["clock"]["duration"] = duration
    data["termination"]["on_complete"] = False
    return data


def test_without_a_floor_a_falling_vehicle_falls_forever(data):
    sim = api.build(falling(data, None, {0: 1.0}))
    result = sim.run()
    assert sim.world.pos[0, 2] == pytest.approx(2.0 - 1.0 * 7.5, abs=1e-9)  # under z = 0, still falling
    assert not any(k.startswith("floor.") for k in result.metrics)


def test_a_fast_vehicle_crashes_a_slow_one_lands_and_both_stay(data):
    sim = api.build(falling(data, 0.0, {0: 1.0, 1: 0.3}))
    result = sim.run()
    m = result.metrics
    assert sim.world.pos[[0, 1], 2].tolist() == [0.0, 0.0]
    assert np.all(sim.world.vel[[0, 1]] == 0.0)
    assert m["floor.crashes"] == 1 and m["violations.floor.agents"] == [0]
    # from 2 m at 1 m/s from t = 0.5 s: under the floor during the tick ending at 2.5 s
    assert m["violations.floor.first_time"] == pytest.approx(2.5)
    assert m["success"] is False  # a crash is a failure of the run
    assert m["floor.height"] == 0.0 and m["floor.min_height"] >= 0.0


def test_a_healthy_vehicle_lands_below_the_touchdown_speed_and_may_lift_off():
    world = WorldState.at_rest(np.array([[0.0, 0.0, -0.01], [1.0, 0.0, -0.2], [2.0, 0.0, 1.0]]))
    world.vel[:] = [[0.0, 0.0, -0.4], [0.0, 0.0, -2.0], [0.0, 0.0, -3.0]]
    floor = Floor(0.0, 0.5, 0.1)
    floor.on_ground = np.zeros(3, dtype=bool)
    events = floor.meet(world)
    assert [(e.name, e.agents) for e in events] == [("crash", (1,))]
    assert world.pos[:, 2].tolist() == [0.0, 0.0, 1.0]
    assert world.vel[2].tolist() == [0.0, 0.0, -3.0]  # in the air: untouched
    assert floor.landings == 1 and floor.crashed == {1}
    # resting there is not a new landing; a second meeting of the crashed vehicle is no new crash
    world.pos[:2, 2] = -0.001
    assert floor.meet(world) == [] and floor.landings == 1


def test_a_start_below_the_floor_is_refused(data):
    data["environment"]["floor"] = 2.5
    with pytest.raises(ConfigError) as err:
        api.build(data)
    assert err.value.lines == ["swarm.start: agents [0, 1, 2, 3, 4] start below environment.floor = 2.5 m"]


@pytest.mark.parametrize("value, line", [
    ("x", "environment.floor: must be a number"),
    (True, "environment.floor: must be a number, not true/false"),
])
def test_a_bad_floor_is_one_line(data, value, line):
    data["environment"]["floor"] = value
    with pytest.raises(ConfigError) as err:
        api.load(data)
    assert err.value.lines[0].startswith(line)
