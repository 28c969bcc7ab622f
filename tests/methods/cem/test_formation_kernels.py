"""The CEM plugin's after-hand-back kernels (kernels.path_clear, kernels.measure_formation) against
the NumPy code they replaced (flow.segment_clearance of the setpoint targets; core.vectors), to the
bit, over random swarms with every setpoint mode, failed agents and boundary values of a_p."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene.core.setpoint import Mode
from swarmscene.core.vectors import min_distance_between, min_pair_distance
from swarmscene.methods.cem import kernels as k
from swarmscene.methods.cem.flow import segment_clearance

HOLD, VELOCITY, TRACK, POSITION = int(Mode.HOLD), int(Mode.VELOCITY), int(Mode.TRACK), int(Mode.POSITION)


def random_tick(seed: int, n: int = 7, f: int = 2):
    rng = np.random.default_rng(seed)
    healthy = rng.random(n) < 0.8
    pos = rng.uniform(-20, 20, (n, 3))
    mode = rng.choice([HOLD, VELOCITY, TRACK, POSITION], n).astype(np.int8)
    sp_pos, sp_vel = rng.uniform(-20, 20, (n, 3)), rng.uniform(-2, 2, (n, 3))
    sp_pos[0, :2] = pos[0, :2]  # a zero-length path
    failed = rng.uniform(-10, 10, (f, 2))
    return healthy, pos, mode, sp_pos, sp_vel, failed


def numpy_gaps(healthy, pos, mode, sp_pos, sp_vel, failed, lookahead):
    """The plugin's former NumPy test: each healthy agent's setpoint target, then segment_clearance."""
    agents = np.flatnonzero(healthy)
    m = mode[agents]
    target = sp_pos[agents, :2]
    hold, vel = m == HOLD, m == VELOCITY
    target[hold] = pos[agents[hold], :2]
    target[vel] = pos[agents[vel], :2] + lookahead * sp_vel[agents[vel], :2]
    return segment_clearance(pos[agents, :2], target, failed)


@pytest.mark.parametrize("seed", range(40))
def test_path_clear_decides_as_the_numpy_test_even_at_a_p_on_the_boundary(seed):
    healthy, pos, mode, sp_pos, sp_vel, failed = random_tick(seed)
    lookahead = 2.5
    gaps = numpy_gaps(healthy, pos, mode, sp_pos, sp_vel, failed, lookahead)
    exact = float(gaps.min())
    for a_p in (exact, np.nextafter(exact, np.inf), np.nextafter(exact, -np.inf), 0.5, 40.0):
        want = bool((gaps >= a_p).all())
        assert k.path_clear(healthy, pos, mode, sp_pos, sp_vel, failed, HOLD, VELOCITY, lookahead, a_p) is want
    args = (healthy, pos, mode, sp_pos, sp_vel, failed, HOLD, VELOCITY, lookahead)
    assert k.path_clear(*args, exact) and not k.path_clear(*args, np.nextafter(exact, np.inf))  # the boundary


def test_path_clear_with_a_nan_setpoint_is_not_clear_as_numpys_min():
    healthy, pos, mode, sp_pos, sp_vel, failed = random_tick(3)
    mode[:] = TRACK
    sp_pos[np.flatnonzero(healthy)[0], 0] = np.nan
    assert not k.path_clear(healthy, pos, mode, sp_pos, sp_vel, failed, HOLD, VELOCITY, 1.0, 0.0)


@pytest.mark.parametrize("seed", range(40))
def test_measure_formation_equals_core_vectors_to_the_bit(seed):
    healthy, pos, mode, sp_pos, _, failed = random_tick(seed, n=int(np.random.default_rng(seed).integers(1, 12)))
    out = np.full(k.N_FORM, -1.0)
    n, placed_n = k.measure_formation(healthy, pos, mode, sp_pos, failed, TRACK, POSITION, out)
    agents = np.flatnonzero(healthy)
    placed = agents[(mode[agents] == TRACK) | (mode[agents] == POSITION)]
    assert (n, placed_n) == (agents.size, placed.size)
    if n == 0:
        return
    xy, cmd = pos[agents, :2], sp_pos[placed, :2]
    assert out[k.F_CLEAR] == min_distance_between(xy, failed)
    assert out[k.F_PAIR] == min_pair_distance(xy)
    assert out[k.F_MARGIN] == min_distance_between(cmd, failed)
    assert out[k.F_PAIR_CMD] == min_pair_distance(cmd)
