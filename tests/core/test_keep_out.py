"""The keep-out ellipsoid as a safety condition of the monitor (``safety.keep_out``, issue #37).

Crazyswarm's planners keep every pair of vehicles out of each other's ellipsoid, ||E^-1 (p_i - p_j)|| >= 1
with E = diag(0.12, 0.12, 0.3) m (Preiss et al., IROS 2017). The monitor's numbers are held to an
independent transcription that visits every pair at every recorded tick in plain Python.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.vectors import ellipsoid_norm
from swarmscene.views.summary import FAIL, OK, verdicts

CRAZYFLIE = [0.12, 0.12, 0.3]
"""m: the Crazyflie's keep-out radii (methods/physics/crazyflie.py KEEP_OUT_RADII)."""
STACKED = [[0.0, 0.0, 1.0], [0.0, 0.0, 1.25]]
"""0.25 m apart vertically: 0.25 / 0.3 < 1, inside."""
SIDE_BY_SIDE = [[5.0, 0.0, 1.0], [5.0, 0.2, 1.0]]
"""0.2 m apart side by side: 0.2 / 0.12 > 1, outside (but within the largest radius, 0.3 m)."""


def brute_force(t: np.ndarray, pos: np.ndarray, radii: list[float]) -> dict:
    """Every pair (i < j) at every tick: the smallest norm over the pairs within the largest radius
    (per tick and overall; inf: none), the distinct pairs with a norm under 1, and the first of
    them: its time and agents."""
    rx, ry, rz = radii
    reach = max(radii)
    per_tick, pairs, first = [], set(), None
    for k in range(len(t)):
        p = pos[k].tolist()
        best, inside = math.inf, []
        for i in range(len(p)):
            for j in range(i + 1, len(p)):
                dx, dy, dz = p[j][0] - p[i][0], p[j][1] - p[i][1], p[j][2] - p[i][2]
                norm = math.sqrt((dx / rx) * (dx / rx) + (dy / ry) * (dy / ry) + (dz / rz) * (dz / rz))
                if norm < 1.0:
                    inside.append((i, j))
                if dx * dx + dy * dy + dz * dz <= reach * reach:
                    best = min(best, norm)
        per_tick.append(best)
        pairs.update(inside)
        if inside and first is None:
            first = (float(t[k]), sorted({a for pair in inside for a in pair}))
    return {"per_tick": np.array(per_tick), "min": min(per_tick, default=math.inf), "pairs": pairs,
            "first": first}


def explicit(data: dict, positions: list[list[float]], keep_out: list[float] | None, duration: float) -> dict:
    """The default scenario with agents at ``positions``, no obstacles, no avoidance, the keep-out
    ellipsoid ``keep_out`` and a separation limit under every pair's distance (no collision)."""
    data["swarm"].update(n=len(positions), start={"layout": "explicit", "positions": positions})
    data["environment"]["obstacles"] = []
    data["avoidance"] = {"name": "none"}
    data["safety"].update(separation_limit=0.01, keep_out=keep_out)
    data["clock"]["duration"] = duration
    data["termination"]["on_complete"] = False
    data["output"]["summary"] = False
    return data


def assert_monitor_is_brute_force(result, radii: list[float]) -> dict:
    """The run's keep-out metrics and series equal the transcription's over its trajectory."""
    traj, m = result.trajectory, result.metrics
    assert np.array_equal(result.series["t"], traj["t"])  # the same ticks sampled
    expected = brute_force(traj["t"], traj["pos"], radii)
    assert np.array_equal(result.series["min_keep_out"], expected["per_tick"])
    assert m["min_keep_out"] == (expected["min"] if math.isfinite(expected["min"]) else None)
    assert m["keep_out_conflicts"] == len(expected["pairs"])
    if expected["first"] is None:
        assert "violations.keep_out.first_time" not in m and "violations.keep_out.agents" not in m
    else:
        assert (m["violations.keep_out.first_time"], m["violations.keep_out.agents"]) == expected["first"]
    return expected


def test_the_norm_is_the_scalar_formula_to_the_bit():
    rng = np.random.default_rng(3)
    d, radii = rng.normal(size=(200, 3)), np.array([0.12, 0.17, 0.3])
    expected = [math.sqrt((x / radii[0]) * (x / radii[0]) + (y / radii[1]) * (y / radii[1])
                          + (z / radii[2]) * (z / radii[2])) for x, y, z in d.tolist()]
    assert ellipsoid_norm(d, radii).tolist() == expected


def test_a_stacked_pair_is_inside_and_a_side_by_side_pair_is_not(data):
    result = api.run(explicit(data, STACKED + SIDE_BY_SIDE, CRAZYFLIE, 0.5))
    expected = assert_monitor_is_brute_force(result, CRAZYFLIE)
    m = result.metrics
    assert expected["pairs"] == {(0, 1)}  # the side-by-side pair (2, 3) never inside
    assert m["keep_out_conflicts"] == 1
    assert m["violations.keep_out.first_time"] == 0.0 and m["violations.keep_out.agents"] == [0, 1]
    assert result.series["min_keep_out"][0] == math.sqrt((0.25 / 0.3) * (0.25 / 0.3))  # tick 0: the start
    assert m["collisions"] == 0 and m["success"] is False  # the conflict alone fails the run


def test_the_side_by_side_pair_alone_holds(data):
    result = api.run(explicit(data, SIDE_BY_SIDE, CRAZYFLIE, 0.5))
    assert_monitor_is_brute_force(result, CRAZYFLIE)
    m = result.metrics
    assert m["keep_out_conflicts"] == 0 and m["min_keep_out"] > 1.0
    assert not any(k.startswith("violations.keep_out") for k in m)
    assert result.series["min_keep_out"][0] == math.sqrt((0.2 / 0.12) * (0.2 / 0.12))


@pytest.mark.parametrize("n", [7, 40])  # every pair at once, and the compiled cell list (> 32 agents)
def test_a_moving_swarm_equals_the_transcription_at_every_tick(data, n):
    """Agents packed into a small box fly a formation apart: pairs come inside, leave, and come
    within the largest radius of each other without coming inside (radii unequal on every axis)."""
    rng = np.random.default_rng(n)
    start = rng.uniform([-0.6, -0.6, 1.0], [0.6, 0.6, 1.6], size=(n, 3))
    radii = [0.25, 0.15, 0.45]
    result = api.run(explicit(data, start.tolist(), radii, 2.0))
    expected = assert_monitor_is_brute_force(result, radii)
    assert expected["pairs"] and expected["first"] is not None  # not vacuous
    assert np.isinf(expected["per_tick"]).any() or expected["min"] < 1.0


def test_off_by_default_no_metrics_no_record_and_the_flight_unchanged():
    """Through api.run with the option on: only the verdict changes (the same flight to the bit);
    the default scenario's closest pair, 1.54 m apart side by side, is inside a 2 m-wide ellipsoid."""
    off = api.run(["output.summary=false"])
    on = api.run(["safety.keep_out=[2.0,2.0,0.5]", "output.summary=false"])
    for key, value in off.trajectory.items():
        assert np.array_equal(on.trajectory[key], value), key
    assert "min_keep_out" not in off.metrics and "keep_out_conflicts" not in off.metrics
    assert "keep_out" not in api.build(api.compose([])).config.model_dump(mode="json")["safety"]  # config_hash kept
    assert "min_keep_out" not in off.series and off.metrics["success"] is True
    assert not any(k.startswith("violations.keep_out") for k in off.metrics)
    assert on.metrics["keep_out_conflicts"] > 0 and on.metrics["success"] is False
    assert_monitor_is_brute_force(on, [2.0, 2.0, 0.5])
    same = {k for k in off.metrics if k not in ("wall_time", "realtime_factor", "step_ms_median", "success",
                                                 "min_keep_out", "keep_out_conflicts")}
    assert {k: on.metrics[k] for k in same} == {k: off.metrics[k] for k in same}


def test_the_summary_prints_a_keep_out_line_only_when_set(data):
    sim = api.build(explicit(data, STACKED + SIDE_BY_SIDE, CRAZYFLIE, 0.3))
    metrics = sim.run().metrics
    lines = {name: (status, detail) for name, status, detail in verdicts(sim, metrics)}
    status, detail = lines["keep_out"]
    assert status == FAIL and detail.startswith(f"min {metrics['min_keep_out']:.3g} vs 1, ||E^-1 (p_i - p_j)|| "
                                                "with E = diag(0.12, 0.12, 0.3) m")
    assert detail.endswith("1 pair(s) inside; first at 0.00 s (agents 0, 1)")
    sim = api.build(explicit(data, SIDE_BY_SIDE, CRAZYFLIE, 0.3))
    assert verdicts(sim, sim.run().metrics)[3][:2] == ("keep_out", OK)
    sim = api.build(explicit(data, SIDE_BY_SIDE, None, 0.3))
    assert "keep_out" not in {name for name, _, _ in verdicts(sim, sim.run().metrics)}


def test_the_radii_are_validated():
    assert api.load(["safety.keep_out=[0.12,0.12,0.3]"]).config.safety.keep_out == (0.12, 0.12, 0.3)
    for value in ("[0.12,0.3]", "[0.12,0,0.3]", "[0.12,-0.1,0.3]", "[0.1,0.1,0.1,0.1]", "0.3", "abc",
                  "[true,1,1]", "[1e9,1,1]"):
        with pytest.raises(ConfigError) as err:
            api.load([f"safety.keep_out={value}"])
        assert len(err.value.lines) == 1, err.value.lines
        assert err.value.lines[0].startswith("safety.keep_out: must be three radii [rx, ry, rz], each > 0"), value
