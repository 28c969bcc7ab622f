"""Exact assignment warm-started by coarse-to-fine duals (used for eq. 4.12-4.13 at large N)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from swarmscene.methods.assignment import assignment_duals, min_cost_assignment, solve_square


def _optimum(cost):
    rows, cols = linear_sum_assignment(cost)
    return cost[rows, cols].sum()


@pytest.mark.parametrize("seed", range(4))
def test_duals_certify_an_optimal_assignment(seed):
    rng = np.random.default_rng(seed)
    cost = rng.integers(0, 50, size=(40, 40))
    cols = linear_sum_assignment(cost)[1]
    u, v = assignment_duals(cost, cols)
    reduced = cost - u[:, None] - v
    assert reduced.min() == 0
    np.testing.assert_array_equal(reduced[np.arange(40), cols], 0)


def test_duals_refuse_a_suboptimal_assignment():
    cost = np.array([[0, 10], [10, 0]])
    with pytest.raises(ValueError):
        assignment_duals(cost, np.array([1, 0]))


@pytest.mark.parametrize("seed", range(3))
def test_multiscale_solution_is_optimal_on_geometric_and_random_costs(seed):
    rng = np.random.default_rng(seed)
    n = 260
    packed = rng.uniform(0, 20, size=(n, 2))  # agents packed, slots spread: long augmenting paths
    slots = rng.uniform(-60, 60, size=(n, 2))
    for cost in (np.rint(cdist(packed, slots) * 10), rng.integers(0, 1000, size=(n, n)).astype(float)):
        cols = solve_square(cost, coarsen=3, direct_size=20)  # three scales
        assert np.array_equal(np.sort(cols), np.arange(n))
        assert cost[np.arange(n), cols].sum() == _optimum(cost)


def test_multiscale_solution_is_deterministic():
    rng = np.random.default_rng(9)
    cost = np.rint(cdist(rng.uniform(0, 5, (150, 2)), rng.uniform(0, 40, (150, 2))))  # many ties
    first = solve_square(cost, direct_size=10)
    assert all(np.array_equal(first, solve_square(cost.copy(), direct_size=10)) for _ in range(3))
    assert cost[np.arange(150), first].sum() == _optimum(cost)


def test_steady_state_is_certified_by_the_reduction_zeros():
    # Agents each near their own slot (the re-assignment of a formed swarm): row and column
    # reduction already leave a perfect matching of zeros, which is returned as it is.
    from swarmscene.methods.assignment import _matching_on_reduction_zeros

    rng = np.random.default_rng(4)
    slots = np.stack(np.meshgrid(np.arange(15.0), np.arange(15.0)), axis=-1).reshape(-1, 2) * 5
    agents = slots[rng.permutation(len(slots))] + rng.normal(0, 0.3, size=slots.shape)
    cost = np.rint(cdist(agents, slots) * 10)
    cols = _matching_on_reduction_zeros(cost)
    assert cols is not None
    assert cost[np.arange(len(cost)), cols].sum() == _optimum(cost)
    np.testing.assert_array_equal(solve_square(cost), cols)
    # A packed start has no such matching: the multiscale path takes over, still optimal.
    packed = np.rint(cdist(rng.uniform(0, 10, size=slots.shape), slots) * 10)
    assert _matching_on_reduction_zeros(packed) is None
    assert packed[np.arange(len(packed)), solve_square(packed)].sum() == _optimum(packed)


def test_tie_heavy_line_start_is_optimal_and_deterministic():
    # Agents on a long line, slots on a compact disc: far agents tie on many slots (the case the
    # fewest-zeros-first row order speeds up); the optimum must still be scipy's, deterministically.
    from swarmscene.methods.assignment import _solve_reduced

    n = 240
    agents = np.c_[np.arange(n) * 1.5, np.zeros(n)]
    rng = np.random.default_rng(5)
    slots = rng.uniform(-20, 20, size=(n, 2))
    cost = np.rint(cdist(agents, slots) * 10).astype(np.int32)
    cols = solve_square(cost, coarsen=3, direct_size=20)
    assert np.array_equal(np.sort(cols), np.arange(n))
    assert cost[np.arange(n), cols].sum() == _optimum(cost)
    np.testing.assert_array_equal(cols, solve_square(cost.copy(), coarsen=3, direct_size=20))
    reduced = cost - cost.min(axis=1, keepdims=True)
    direct = _solve_reduced(reduced)
    assert reduced[np.arange(n), direct].sum() == _optimum(reduced)


@pytest.mark.parametrize("k, m", [(1, 1), (2, 5), (3, 3), (5, 5), (4, 6), (6, 6), (7, 7), (3, 8)])
@pytest.mark.parametrize("seed", range(3))
def test_min_cost_assignment_matches_scipys_optimum(k, m, seed):
    """Small problems are enumerated (no scipy.optimize at start-up), larger go to scipy: either
    way a valid assignment of scipy's least total cost, also with many tied costs."""
    rng = np.random.default_rng(seed)
    for cost in (rng.uniform(0, 10, (k, m)), rng.integers(0, 3, (k, m)).astype(float)):
        rows, cols = min_cost_assignment(cost)
        np.testing.assert_array_equal(rows, np.arange(k))
        assert len(set(cols.tolist())) == k and cols.max() < m
        assert cost[rows, cols].sum() == pytest.approx(_optimum(cost), abs=1e-12)


def test_min_cost_assignment_breaks_ties_by_the_first_choice():
    rows, cols = min_cost_assignment(np.zeros((3, 3)))
    np.testing.assert_array_equal(cols, [0, 1, 2])
