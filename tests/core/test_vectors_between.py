"""core.vectors.min_distance_between: the closest pair across two point sets (CEM's clearance to the
failed vehicles after a hand-back), the same distance to the bit as a k-d tree query."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swarmscene.core.vectors import min_distance_between


@pytest.mark.parametrize("seed", range(5))
def test_equals_the_k_d_tree_query_to_the_bit(seed):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-50, 50, (int(rng.integers(1, 12)), 2))
    b = rng.uniform(-50, 50, (int(rng.integers(1, 4)), 2))
    assert min_distance_between(a, b) == float(cKDTree(b).query(a)[0].min())
    assert min_distance_between(a, b) == min_distance_between(b, a)


def test_a_known_distance_and_an_empty_set():
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[3.0, 4.0], [13.0, 4.5]])
    assert min_distance_between(a, b) == 5.0
    assert min_distance_between(a, np.empty((0, 2))) == math.inf
    assert min_distance_between(np.empty((0, 2)), b) == math.inf
