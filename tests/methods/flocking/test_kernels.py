"""The compiled boids' steer against its NumPy form (tests/oracles/flocking.py): bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from oracles.flocking import flocking_steer as numpy_steer
from scipy.spatial import cKDTree

from swarmscene.methods.flocking.kernels import flocking_steer
from swarmscene.plugins.formation.reynolds_flocking import FlockingParams


@pytest.mark.parametrize("axes", [2, 3])
@pytest.mark.parametrize("failed", [0, 7])
@pytest.mark.parametrize("seed", range(3))
def test_compiled_steer_equals_the_numpy_form_bit_for_bit(axes, failed, seed):
    rng = np.random.default_rng(seed)
    n = 400
    pos = rng.uniform(0, 40, (n, 3))
    if axes == 2:
        pos[:, 2] = 2.0
    pairs = cKDTree(pos).query_pairs(3.0, output_type="ndarray")
    i, j = np.ascontiguousarray(pairs[:, 0]), np.ascontiguousarray(pairs[:, 1])
    delta = np.ascontiguousarray((pos[j, :axes] - pos[i, :axes]).T)
    heading = rng.uniform(-1, 1, (n, 3))
    follow = np.ones(n, dtype=bool)
    follow[rng.choice(n, failed, replace=False)] = False
    p = FlockingParams(separation=1.0)
    want = numpy_steer(i, j, delta, heading, follow, p)
    got = flocking_steer(i, j, delta, heading, follow, p.cohere, p.match, p.separate, p.separation)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert (want[0][:, axes:] == 0).all() and want[1].max() > 0  # the case has neighbours


def test_no_pairs_no_steer():
    empty = np.zeros(0, dtype=np.intp)
    steer, count = flocking_steer(empty, empty, np.zeros((2, 0)), np.ones((5, 3)), np.ones(5, bool), 1.0, 1.0, 1.0, 1.0)
    assert not steer.any() and not count.any()


@pytest.mark.parametrize("axes", [2, 3])
@pytest.mark.parametrize("seed", range(3))
def test_compiled_seam_pairs_equal_the_tree_form(axes, seed):
    """The same seam-crossing pairs as the NumPy + k-d tree form, each with the same minimum-image
    vector to the bit (the order may differ: the compiled one lists shift by shift, i, then j)."""
    from oracles.flocking import seam_pairs as tree_seam_pairs

    from swarmscene.methods.flocking.kernels import seam_pairs
    from swarmscene.methods.flocking.torus import periodic_shifts

    rng = np.random.default_rng(seed)
    lo, hi = np.array([-5.0, 0.0, 1.0]), np.array([15.0, 30.0, 21.0])
    pos = rng.uniform(lo, hi, size=(500, 3))
    want = tree_seam_pairs(pos, cKDTree(pos), lo[:axes], hi[:axes], 3.0)
    got = seam_pairs(pos, lo[:axes], hi[:axes], 3.0, periodic_shifts(axes).astype(float))
    def as_dict(i, j, d):
        return {(a, b): tuple(v) for a, b, v in zip(i.tolist(), j.tolist(), d.T.tolist(), strict=True)}
    assert len(got[0]) == len(want[0]) > 0
    assert as_dict(*got) == as_dict(*want)
