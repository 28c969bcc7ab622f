"""Start geometry: the vectorised random sampler against the one-by-one loop it replaces."""

from __future__ import annotations

import subprocess
import sys

import networkx as nx
import numpy as np
import pytest

from swarmscene.core import geometry
from swarmscene.core.geometry import component_count, max_spread, random_spread


def one_by_one_spread(n: int, extent: float, spacing: float, rng: np.random.Generator) -> np.ndarray:
    """The oracle: the sequential O(N^2) sampler the engine used before (commit 6a54d6c)."""
    points = np.empty((0, 2))
    for _ in range(200):
        candidates = rng.uniform(-extent / 2, extent / 2, size=(4 * n, 2))
        for c in candidates:
            if len(points) == n:
                break
            if len(points) == 0 or np.min(np.hypot(*(points - c).T)) >= spacing:
                points = np.vstack([points, c])
        if len(points) == n:
            break
    if len(points) < n:
        raise ValueError(f"swarm.start: cannot place {n} agents {spacing} m apart in a {extent} m square")
    return np.column_stack([points, np.zeros(n)])


CASES = [  # (n, extent, spacing): sparse, dense (several rounds), the indoor presets' starts
    (1, 10.0, 2.0), (5, 10.0, 2.0), (30, 10.0, 1.0), (60, 10.0, 1.0), (12, 9.0, 0.6), (30, 2.5, 0.3),
    (200, 30.0, 1.5), (25, 6.0, 1.0),
]


@pytest.mark.parametrize(("n", "extent", "spacing"), CASES)
def test_vectorised_sampler_draws_the_same_positions_as_the_loop(n, extent, spacing):
    for seed in range(6):
        try:
            expected = one_by_one_spread(n, extent, spacing, np.random.default_rng(seed))
        except ValueError:
            expected = None
        rng = np.random.default_rng(seed)
        if expected is None:
            with pytest.raises(ValueError, match="cannot place"):
                random_spread(n, extent, spacing, rng)
            continue
        got = random_spread(n, extent, spacing, rng)
        assert np.array_equal(got, expected)
        # and the generator is left where the loop left it (later draws of the run agree)
        oracle_rng = np.random.default_rng(seed)
        one_by_one_spread(n, extent, spacing, oracle_rng)
        assert rng.random() == oracle_rng.random()


def test_blocks_of_a_round_resolve_like_one_block(monkeypatch):
    """A round split into blocks (memory budget) takes the same candidates in the same order."""
    whole = random_spread(150, 20.0, 1.0, np.random.default_rng(3))
    monkeypatch.setattr(geometry, "PAIR_BUDGET", 1)  # blocks of 1,024 candidates
    assert np.array_equal(random_spread(400, 40.0, 1.0, np.random.default_rng(4)),
                          one_by_one_spread(400, 40.0, 1.0, np.random.default_rng(4)))
    monkeypatch.undo()
    assert np.array_equal(whole, one_by_one_spread(150, 20.0, 1.0, np.random.default_rng(3)))


def test_a_packing_that_cannot_fit_is_refused_without_drawing():
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    with pytest.raises(ValueError) as info:
        random_spread(1_000_000, 10.0, 2.0, rng)
    assert str(info.value) == ("swarm.start: cannot place 1000000 agents 2.0 m apart in a 10.0 m square "
                               "(at most 39 fit; raise swarm.start.extent)")
    assert rng.bit_generator.state == state
    # The bound never refuses a packing that exists: a 6 x 6 grid 2 m apart fits a 10 m square.
    assert max_spread(10.0, 2.0) == 39 >= 36 and max_spread(0.0, 1.0) == 1


def test_the_maximum_swarm_spreads_in_one_round():
    """The documented maximum N (MAX_AGENTS) in a square with room: one round of 4 N candidates."""
    from swarmscene.core.config import MAX_AGENTS

    pos = random_spread(MAX_AGENTS, 4000.0, 1.0, np.random.default_rng(0))
    assert pos.shape == (MAX_AGENTS, 3)
    from scipy.spatial import cKDTree

    assert cKDTree(pos[:, :2]).query_pairs(1.0 - 1e-12).__len__() == 0


def test_component_count_agrees_with_networkx():
    rng = np.random.default_rng(1)
    for n in (1, 2, 7, 40):
        pos = rng.uniform(0, 10, size=(n, 2))
        d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
        i, j = np.nonzero(np.triu(d <= 3.0, k=1))
        expected = nx.number_connected_components(nx.from_numpy_array((d <= 3.0).astype(int)))
        got = component_count(n, np.column_stack([i, j]))
        assert got == expected or (expected > 1 and got > 1)


def test_geometry_does_not_import_the_config_module():
    """core.config calls geometry during validation; geometry must not import it back."""
    code = "import sys, swarmscene.core.geometry; print('swarmscene.core.config' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
