"""The observation of B worlds at once (methods/policy/observation.observe_batch) against each
world's own (``observe``), to the bit."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from swarmscene.core.environment import Environment
from swarmscene.core.sensing import NEAR_K, Sensing
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.methods.policy.observation import ObservationLayout, observe, observe_batch


def worlds(rng: np.random.Generator, b: int, n: int, env: Environment) -> tuple[list[Sensing], list[Setpoints]]:
    """B worlds of N agents over a 12 m square (some near the map's box, some beyond the sensing
    range of the others), random velocities, a failed agent, references of every mode."""
    sensings, refs = [], []
    for _ in range(b):
        world = WorldState.at_rest(np.column_stack([rng.uniform(-6, 6, (n, 2)), rng.uniform(0.5, 3, n)]))
        world.vel[:] = rng.normal(size=(n, 3))
        world.healthy[rng.integers(n)] = False
        ref = Setpoints.hold(world.pos + rng.normal(size=(n, 3)))
        ref.mode[:] = rng.integers(0, 4, n)
        ref.vel[:] = rng.normal(size=(n, 3))
        sensings.append(Sensing(world, env, comm_range=4.0))
        refs.append(ref)
    return sensings, refs


@pytest.mark.parametrize("n", [2, 3, 6, 9])
@pytest.mark.parametrize("k", [0, 1, NEAR_K, NEAR_K + 2])
@pytest.mark.parametrize("open_map", [True, False])
def test_the_batched_observation_is_each_worlds_own(n, k, open_map):
    rng = np.random.default_rng(100 * n + k)
    env = Environment() if open_map else Environment([shapely.box(2.0, -1.0, 4.0, 1.0)])
    layout = ObservationLayout(k)
    for _ in range(5):
        sensings, refs = worlds(rng, 7, n, env)
        refs[2] = None  # t = 0: no reference yet
        batched = observe_batch(sensings, refs, layout, radius=5.0, obstacle_radius=3.0)
        assert batched.shape == (7, n, layout.size) and batched.dtype == np.float32
        for b, (sensing, ref) in enumerate(zip(sensings, refs, strict=True)):
            own = observe(Sensing(sensing.world, env, comm_range=4.0), ref, layout, radius=5.0, obstacle_radius=3.0)
            assert batched[b].tobytes() == own.tobytes()
        assert k == 0 or layout.split(batched)["nbr_mask"].any()  # neighbours seen
        assert open_map or layout.split(batched)["obs_mask"].any()  # and an obstacle


def test_worlds_with_no_obstacle_in_range_are_observed_without_a_query():
    """Worlds 40 m from the map's box whose tick has found no obstacle within 5 m (their obstacle
    features are constants, no query made) beside worlds near it: every world's rows its own."""
    rng = np.random.default_rng(5)
    env = Environment([shapely.box(2.0, -1.0, 4.0, 1.0)])
    layout = ObservationLayout(NEAR_K)
    sensings, refs = worlds(rng, 6, 5, env)
    for s in sensings[:3]:
        s.world.pos[:, 0] += 40.0
        s.obstacle_nearest(5.0)  # the tick's own query: nothing within 5 m
    assert [s.nothing_within(3.0) for s in sensings] == [True] * 3 + [False] * 3
    batched = observe_batch(sensings, refs, layout, radius=5.0, obstacle_radius=3.0)
    for b, (sensing, ref) in enumerate(zip(sensings, refs, strict=True)):
        own = observe(Sensing(sensing.world, env, comm_range=4.0), ref, layout, radius=5.0, obstacle_radius=3.0)
        assert batched[b].tobytes() == own.tobytes()
    assert not layout.split(batched[:3])["obs_mask"].any() and layout.split(batched[3:])["obs_mask"].any()


def test_worlds_of_different_sizes_are_refused_in_one_line():
    rng = np.random.default_rng(6)
    sensings = worlds(rng, 2, 4, Environment())[0] + worlds(rng, 1, 5, Environment())[0]
    with pytest.raises(ValueError, match=r"^observe_batch: worlds of \[4, 5\] agents cannot be stacked$"):
        observe_batch(sensings, [None] * 3, ObservationLayout(2), radius=5.0, obstacle_radius=3.0)


def test_every_world_with_a_reference_is_observed_from_the_stacked_references():
    rng = np.random.default_rng(9)
    sensings, refs = worlds(rng, 5, 6, Environment())
    refs[3].mode[:] = Mode.TRACK
    refs[0].mode[:] = Mode.HOLD
    sensings[1].world.pos[:2] = [(0.0, 0.0, 1.0), (3.0, 4.0, 1.0)]  # 5 m apart: at the sensing range
    sensings[1].world.pos[2:, 0] += 20.0  # the others beyond it
    layout = ObservationLayout(3)
    batched = observe_batch(sensings, refs, layout, radius=5.0, obstacle_radius=3.0)
    for b, (sensing, ref) in enumerate(zip(sensings, refs, strict=True)):
        assert batched[b].tobytes() == observe(sensing, ref, layout, radius=5.0, obstacle_radius=3.0).tobytes()
    parts = layout.split(batched)
    assert parts["ref_mask"][3].all() and not parts["ref_mask"][0].any()
    assert parts["nbr_mask"][1, 0].tolist() == parts["nbr_mask"][1, 1].tolist() == [1, 0, 0]  # d <= R is seen
