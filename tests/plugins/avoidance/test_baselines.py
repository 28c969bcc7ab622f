"""orca and cbf on the engine: the swap goal of issue #14 (RVO2's circle example and the
Robotarium's barrier-certificate demos: no collision, everyone arrives), failed vehicles and
obstacles respected, the setpoint contract."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.vectors import clip_norm

QUIET = ["output.progress=off", "output.trajectory=false", "output.summary=false"]
METHODS = ["orca", "cbf"]


def swap(method: str) -> list[str]:
    # R = 4 m instead of the preset's 6 m keeps the runs short; the crossing is the same conflict.
    return ["scenario=swap", f"avoidance={method}", "swarm.start.radius=4", *QUIET]


def assert_swap_succeeded(metrics: dict) -> None:
    assert metrics["collisions"] == 0
    assert metrics["min_separation"] >= 0.56  # safety.separation_limit of the preset
    assert metrics["stop_reason"] == "complete"  # every healthy agent within 0.1 m of its antipode
    assert metrics["success"] is True


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(
    ("n", "dynamics"),
    [(8, "single_integrator"), (16, "single_integrator"), (8, "double_integrator"),
     (16, "double_integrator"), (8, "quadrotor")],
)
def test_swap_without_collision_everyone_arrives(method, n, dynamics):
    ring = ["swarm.start.radius=3"] if dynamics == "quadrotor" else []  # 240 Hz physics: keep it short
    metrics = api.run([*swap(method), f"swarm.n={n}", f"dynamics={dynamics}", *ring]).metrics
    assert_swap_succeeded(metrics)
    if method == "orca":
        assert metrics["orca.max_neighbours_used"] == min(n - 1, 10)  # the whole ring meets at the centre
    else:
        assert metrics["cbf.fallback_ticks"] == 0  # h >= 0 throughout: every QP feasible


@pytest.mark.parametrize("method", METHODS)
def test_failed_vehicle_is_a_static_obstacle(method):
    data = api.compose([*swap(method), "swarm.n=8"])
    data["events"] = [{"at": 1.5, "agents": [0], "name": "hover"}]  # on its way to the centre
    metrics = api.run(data).metrics
    assert metrics["healthy_at_end"] == 7
    assert_swap_succeeded(metrics)


@pytest.mark.parametrize("method", METHODS)
def test_pillar_in_the_middle_is_kept_clear(method):
    metrics = api.run([*swap(method), "environment.obstacles=[{type:circle,center:[0.0,0.0],radius:1.0}]",
                       "safety.clearance_limit=0.3"]).metrics
    assert metrics["clearance_violations"] == 0
    assert metrics["min_clearance"] >= 0.3
    assert_swap_succeeded(metrics)


@pytest.mark.parametrize("method", METHODS)
def test_setpoints_become_velocities_and_failed_agents_pass_through(method):
    sim = api.build(["scenario=swap", f"avoidance={method}", "swarm.n=4", "swarm.start.radius=20",
                     "avoidance.perturbation=0.0", *QUIET])
    world, p = sim.world, sim.avoidance.params
    world.healthy[3] = False
    sp = Setpoints.hold(world.pos)
    sp.mode[:] = [Mode.POSITION, Mode.TRACK, Mode.VELOCITY, Mode.POSITION]
    sp.pos[:] = world.pos + [[3.0, 0.0, 0.5], [0.2, 0.1, 0.0], [0.0, 0.0, 0.0], [5.0, 5.0, 0.0]]
    sp.vel[:] = [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, -0.4, 0.0], [1.0, 0.0, 0.0]]
    before = sp.copy()
    out = sim.avoidance.adjust(world, sim.sensing, sp)
    # agents 20 m apart meet no constraint: the preferred velocity is flown as it is
    expected = clip_norm(np.array([[3.0, 0.0, 0.5], [0.5, 0.1, 0.0], [0.0, -0.4, 0.0]]), p.v_max)
    np.testing.assert_allclose(out.vel[:3], expected, atol=1e-12)
    np.testing.assert_array_equal(out.mode[:3], Mode.VELOCITY)
    np.testing.assert_array_equal(out.acc[:3], 0.0)
    # the failed agent's row and the input record are untouched
    assert out.mode[3] == Mode.POSITION
    np.testing.assert_array_equal(out.pos[3], before.pos[3])
    np.testing.assert_array_equal(out.vel[3], before.vel[3])
    for name in ("mode", "pos", "vel", "acc", "yaw"):
        np.testing.assert_array_equal(getattr(sp, name), getattr(before, name))


@pytest.mark.parametrize("method, deviations", [("orca", {"detour": 30.0}), ("cbf", {"detour": 30.0, "deadlock_turn": 90.0})])
def test_the_published_method_is_the_default_and_the_swap_preset_tunes_its_deadlock_remedy(method, deviations):
    """The plugins' defaults are the papers' methods; only the swap preset turns on the right-hand
    rule (and cbf's deadlock turn), through its tuning of that method."""
    from swarmscene import api

    elsewhere = api.load(["scenario=cem_six_vehicle", f"avoidance={method}"]).plugin_params["avoidance"]
    swap = api.load(["scenario=swap", f"avoidance={method}"]).plugin_params["avoidance"]
    for key, value in deviations.items():
        assert getattr(elsewhere, key) == 0.0
        assert getattr(swap, key) == value
