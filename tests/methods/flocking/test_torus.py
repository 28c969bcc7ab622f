"""The flock's periodic space (methods/flocking/torus.py): minimum image, seam pairs, the neighbours."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swarmscene.core.vectors import wrap
from swarmscene.methods.flocking.kernels import seam_pairs
from swarmscene.methods.flocking.torus import in_box, minimum_image, periodic_shifts, torus_neighbours


def test_wrap_and_minimum_image():
    size = np.array([10.0, 10.0])
    np.testing.assert_allclose(wrap(np.array([[-0.5, 10.5], [3.0, 20.0]]), np.zeros(2), size),
                               [[9.5, 0.5], [3.0, 0.0]])
    assert np.all(wrap(np.array([[-1e-18, 0.0]]), np.zeros(2), size) < size)
    np.testing.assert_allclose(minimum_image(np.array([[9.0, -6.0]]), size), [[-1.0, 4.0]])


@pytest.mark.parametrize("axes", [2, 3])
def test_shared_tree_plus_seam_pairs_equal_the_periodic_neighbours(axes):
    rng = np.random.default_rng(11)
    lo, hi = np.array([-5.0, 0.0, 1.0]), np.array([15.0, 30.0, 21.0])
    pos = rng.uniform(lo, hi, size=(400, 3))
    radius = 3.0
    inner = cKDTree(pos).query_pairs(radius, output_type="ndarray")
    si, sj, sdelta = seam_pairs(pos, lo[:axes], hi[:axes], radius, periodic_shifts(axes).astype(float))
    found = {tuple(sorted(p)) for p in inner.tolist()} | {tuple(sorted(p)) for p in zip(si.tolist(), sj.tolist(), strict=True)}
    assert len(found) == len(inner) + len(si)  # no pair twice
    size = hi[:axes] - lo[:axes]
    expected = cKDTree(np.column_stack([pos[:, :axes] - lo[:axes], pos[:, axes:]]),
                       boxsize=np.r_[size, np.full(3 - axes, 1e9)]).query_pairs(radius)
    assert found == expected and len(si) > 0
    direct = pos[sj, :axes] - pos[si, :axes]
    np.testing.assert_allclose(sdelta.T, minimum_image(direct, size), atol=1e-9)
    assert len(periodic_shifts(axes)) == (3**axes - 1) // 2


@pytest.mark.parametrize("axes", [2, 3])
def test_torus_neighbours_are_the_periodic_pairs_with_their_minimum_image(axes):
    rng = np.random.default_rng(5)
    lo, hi = np.array([0.0, -10.0, 2.0]), np.array([20.0, 10.0, 22.0])
    pos = rng.uniform(lo, hi, size=(300, 3))
    assert in_box(pos, lo[:axes], hi[:axes]) and not in_box(pos + (hi - lo), lo[:axes], hi[:axes])
    radius = 2.5
    inner = cKDTree(pos).query_pairs(radius, output_type="ndarray")
    i, j, delta = torus_neighbours(pos, inner, lo[:axes], hi[:axes], radius,
                                   periodic_shifts(axes).astype(float))
    size = hi[:axes] - lo[:axes]
    expected = cKDTree(np.column_stack([pos[:, :axes] - lo[:axes], pos[:, axes:]]),
                       boxsize=np.r_[size, np.full(3 - axes, 1e9)]).query_pairs(radius)
    assert {tuple(sorted(p)) for p in zip(i.tolist(), j.tolist(), strict=True)} == expected
    assert len(i) == len(expected) > len(inner)  # seam pairs added, none twice
    assert delta.shape == (axes, len(i))
    np.testing.assert_allclose(delta.T, minimum_image(pos[j, :axes] - pos[i, :axes], size), atol=1e-9)
