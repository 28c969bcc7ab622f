"""reynolds_flocking: Mesa's BoidFlockers rule, vectorised; separation, alignment, cohesion, torus."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.environment import Environment
from swarmscene.core.plugin import BuildContext
from swarmscene.core.sensing import Sensing
from swarmscene.core.setpoint import Mode
from swarmscene.core.state import WorldState
from swarmscene.core.vectors import wrap
from swarmscene.methods.flocking.torus import minimum_image
from swarmscene.plugins.formation.reynolds_flocking import FlockingParams, ReynoldsFlocking, params_from_mesa

OPEN = Environment([])


def make(pos: np.ndarray, heading: np.ndarray | None = None, **options) -> tuple[ReynoldsFlocking, WorldState]:
    pos = np.asarray(pos, dtype=float)
    world = WorldState.at_rest(pos, leader=None)
    ctx = BuildContext(
        n=len(pos), guidance_period=1.0, physics_step=1.0, duration=100.0, separation_limit=0.0,
        clearance_limit=0.0, comm_range=10.0, environment=OPEN, rng=np.random.default_rng(1),
        initial=WorldState.at_rest(pos, leader=None),
    )
    flock = ReynoldsFlocking(FlockingParams(**options), ctx)
    if heading is not None:
        flock.heading = np.asarray(heading, dtype=float).copy()
    return flock, world


def tick(flock: ReynoldsFlocking, world: WorldState, dt: float = 1.0) -> None:
    """One guidance tick with perfect velocity tracking (a single integrator without saturation)."""
    sp = flock.setpoints(world, Sensing(world, OPEN, 10.0))
    world.pos += sp.vel * dt
    world.vel[:] = sp.vel
    box = flock.periodic_box()  # the kernel's wrap phase
    if box is not None:
        world.pos[:, : box[0].size] = wrap(world.pos[:, : box[0].size], *box)


def mesa_rule(pos: np.ndarray, d: np.ndarray, p: FlockingParams, size: np.ndarray) -> np.ndarray:
    """Mesa's Boid.step direction update, one boid at a time, all from the same snapshot (2-D)."""
    new = d.copy()
    for i in range(len(pos)):
        delta = minimum_image(pos - pos[i], size)
        dist = np.linalg.norm(delta, axis=1)
        seen = (dist <= p.vision) & (np.arange(len(pos)) != i)
        if not seen.any():
            continue
        cohere = delta[seen].sum(axis=0) * p.cohere
        separate = -delta[seen & (dist < p.separation)].sum(axis=0) * p.separate
        match = d[seen].sum(axis=0) * p.match
        v = d[i] + (cohere + separate + match) / seen.sum()
        new[i] = v / np.linalg.norm(v)
    return new


def polarization(heading: np.ndarray) -> float:
    unit = heading / np.linalg.norm(heading, axis=1, keepdims=True)
    return float(np.linalg.norm(unit.mean(axis=0)))


def radius_of_gyration(pos: np.ndarray) -> float:
    return float(np.sqrt(((pos - pos.mean(axis=0)) ** 2).sum(axis=1).mean()))


def test_one_tick_equals_mesa_rule_in_a_torus():
    rng = np.random.default_rng(7)
    n, size = 200, np.array([40.0, 40.0])
    pos = np.column_stack([rng.uniform(0, 40, (n, 2)), np.full(n, 2.0)])
    d = np.column_stack([rng.uniform(-1, 1, (n, 2)), np.zeros(n)])
    params = params_from_mesa(width=40.0, height=40.0, vision=5.0, separation=2.0)
    flock, world = make(pos, d, **params.model_dump())
    expected = mesa_rule(pos[:, :2], d[:, :2], params, size)
    sp = flock.setpoints(world, Sensing(world, OPEN, 10.0))
    np.testing.assert_allclose(flock.heading[:, :2], expected, atol=1e-12)
    np.testing.assert_allclose(sp.vel[:, :2], params.speed * expected, atol=1e-12)
    assert np.all(sp.mode == Mode.VELOCITY) and np.all(sp.vel[:, 2] == 0.0)
    assert 0 < flock.neighbour_count.mean() < n  # the torus seams were crossed, not everyone seen


def test_params_from_mesa_map_every_argument():
    p = params_from_mesa(width=120, height=80, speed=2.0, vision=7, separation=3, cohere=0.1,
                         separate=0.2, match=0.3, guidance_period=0.5)
    assert (p.vision, p.separation, p.cohere, p.separate, p.match) == (7, 3, 0.1, 0.2, 0.3)
    assert p.speed == 4.0  # Mesa's 2 units per step over a 0.5 s tick
    assert p.space == "toroidal" and p.planar
    assert p.box_min[:2] == (0.0, 0.0) and p.box_max[:2] == (120, 80)
    defaults = FlockingParams()  # the plugin's own defaults are Mesa's BoidFlockers defaults
    mesa = params_from_mesa()
    for key in ("vision", "separation", "cohere", "separate", "match", "speed"):
        assert getattr(defaults, key) == getattr(mesa, key)


def test_separation_turns_close_boids_apart():
    # Two boids 1 m apart (inside separation = 2 m) flying straight at each other.
    def distance_after(separate: float) -> float:
        flock, world = make([[0, 0, 2], [1, 0, 2]], [[1, 0.01, 0], [-1, 0.01, 0]],
                            separate=separate, cohere=0.0, match=0.0, space="open")
        tick(flock, world, dt=0.25)
        if separate > 0:  # s_i = -2 (p_j - p_i) outweighs the unit heading: they turn away
            toward = world.pos[1] - world.pos[0]
            assert np.dot(flock.heading[0], toward) < 0 and np.dot(flock.heading[1], -toward) < 0
        return float(np.linalg.norm(world.pos[1] - world.pos[0]))

    assert distance_after(2.0) > 1.0 > distance_after(0.0)


def test_separation_keeps_a_packed_flock_further_apart_than_without_it():
    rng = np.random.default_rng(3)
    xy = np.stack(np.meshgrid(np.arange(6.0), np.arange(6.0)), -1).reshape(-1, 2) * 0.5
    pos = np.column_stack([xy, np.full(len(xy), 2.0)])
    d = np.column_stack([rng.uniform(-1, 1, (len(xy), 2)), np.zeros(len(xy))])

    def min_distance_after(separate: float) -> float:
        flock, world = make(pos, d, vision=0.8, separation=0.8, separate=separate, cohere=0.0,
                            match=0.0, space="open")
        for _ in range(10):
            tick(flock, world, dt=0.1)
        return Sensing(world, OPEN, 10.0).nearest[0].min()

    assert min_distance_after(5.0) > min_distance_after(0.0) + 0.05


def test_alignment_aligns_headings():
    rng = np.random.default_rng(4)
    n = 40
    pos = np.column_stack([rng.uniform(0, 5, (n, 2)), np.full(n, 2.0)])
    d = np.column_stack([rng.uniform(-1, 1, (n, 2)), np.zeros(n)])
    flock, world = make(pos, d, vision=1000.0, cohere=0.0, separate=0.0, match=0.5, space="open")
    start = polarization(d[:, :2])
    for _ in range(20):
        tick(flock, world)
    assert start < 0.5 and polarization(flock.heading[:, :2]) > 0.999


def test_cohesion_pulls_a_spread_flock_together():
    rng = np.random.default_rng(5)
    xy = np.stack(np.meshgrid(np.arange(10.0), np.arange(10.0)), -1).reshape(-1, 2) * 4.0
    pos = np.column_stack([xy, np.full(len(xy), 2.0)])
    d = np.column_stack([rng.uniform(-1, 1, (len(xy), 2)), np.zeros(len(xy))])

    def spread_after(cohere: float) -> float:
        flock, world = make(pos, d, vision=1000.0, cohere=cohere, separate=0.0, match=0.0,
                            speed=1.0, space="open")
        for _ in range(15):
            tick(flock, world)
        return radius_of_gyration(world.pos)

    start = radius_of_gyration(pos)
    assert spread_after(0.5) < 0.6 * start < start < spread_after(0.0)


def test_toroidal_neighbours_across_the_seam_and_wrap():
    # Boids at x = 0.5 and x = 99.5 are 1 m apart through the seam: they repel across it.
    flock, world = make([[0.5, 50, 2], [99.5, 50, 2]], [[0, 1, 0], [0, 1, 0]],
                        separate=1.0, cohere=0.0, match=0.0, space="toroidal")
    tick(flock, world)
    assert flock.neighbour_count.tolist() == [1, 1]
    assert flock.heading[0, 0] > 0 and flock.heading[1, 0] < 0  # apart, through the seam
    # Positions not yet folded into the box (setpoints called outside a run): same neighbours.
    flock, world = make([[-0.5, 50, 2], [99.0, 50, 2]], [[0, 1, 0], [0, 1, 0]], space="toroidal")
    flock.setpoints(world, Sensing(world, OPEN, 10.0))
    assert flock.neighbour_count.tolist() == [1, 1]
    # A lone boid crossing x = 100 reappears at the other side.
    flock, world = make([[99.8, 50, 2]], [[1, 0, 0]], space="toroidal")
    tick(flock, world)
    np.testing.assert_allclose(world.pos[0], [0.8, 50, 2], atol=1e-12)


def test_bounded_space_turns_boids_back():
    flock, world = make([[98.0, 50, 2]], [[1, 0, 0]], space="bounded", boundary_weight=2.0)
    for _ in range(20):
        tick(flock, world)
    assert world.pos[0, 0] < 100.0 and flock.heading[0, 0] < 0


def test_failed_boids_hold_and_are_not_followed():
    flock, world = make([[0, 0, 2], [3, 0, 2]], [[0, 1, 0], [1, 0, 0]], match=1.0, space="open")
    world.healthy[1] = False
    sp = flock.setpoints(world, Sensing(world, OPEN, 10.0))
    assert sp.mode[1] == Mode.HOLD and np.all(sp.vel[1] == 0)
    assert flock.neighbour_count[0] == 0 and np.allclose(flock.heading[0], [0, 1, 0])
    # ...but a failed boid closer than `separation` still repels.
    flock, world = make([[0, 0, 2], [1, 0, 2]], [[1, 0, 0], [1, 0, 0]], separate=2.0, space="open")
    world.healthy[1] = False
    flock.setpoints(world, Sensing(world, OPEN, 10.0))
    assert flock.neighbour_count[0] == 0 and flock.heading[0, 0] < 0


def test_flocking_scenario_runs_in_the_box_and_flocks():
    result = api.run(["scenario=flocking", "clock.duration=300"])
    pos = result.trajectory["pos"]
    assert pos.shape == (301, 100, 3)
    assert np.all((pos[..., :2] >= 0) & (pos[..., :2] < 100)) and np.all(pos[..., 2] == 2.0)
    vel = result.trajectory["vel"][1, :, :2]
    assert polarization(vel) < 0.2 < 0.5 < result.metrics["flocking.polarization"]
    assert result.metrics["flocking.mean_neighbours"] > 3.0  # Mesa's density alone: ~3


def test_goal_seeking_reaches_the_goal():
    result = api.run([
        "scenario=flocking", "swarm.n=20", "swarm.start.extent=20", "formation.space=open",
        "formation.goal=[80,50,2]", "formation.goal_weight=2.0", "formation.goal_tolerance=10",
        "clock.duration=200", "termination.on_complete=true",
    ])
    assert result.stop_reason == "complete" and result.metrics["steps"] < 200


@pytest.mark.parametrize("bad", [
    {"box_max": (0.0, 10.0, 10.0)}, {"vision": 0.0}, {"space": "sphere"},
    {"space": "toroidal", "vision": 50.0},  # seams need vision below half the box
])
def test_bad_params_are_rejected(bad):
    with pytest.raises(ValueError):
        FlockingParams(**bad)
