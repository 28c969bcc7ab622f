"""The compiled pass of SwarmLab's metrics (methods/swarmlab/kernels.py through swarm_metrics) against
the line-by-line transcription of compute_swarm_performance.m (tests/oracles/swarmlab.py), to 1e-9:
the neighbour lists exactly (ties at the cut, lists cut by the previous sample's, agents exactly at r),
safety, order, union, and lambda_2 with its certificate (a proof within CERT_RTOL ||L||, the dense
fallback when none is found, warm starts from another graph, the wrong shift, disconnected graphs)."""

from __future__ import annotations

import numpy as np
import pytest
from oracles.swarmlab import compute_neighborhood, distance_matrix, swarm_performance

from swarmscene.methods.swarmlab import kernels
from swarmscene.methods.swarmlab.metrics import SwarmSample, WarmStart, swarm_metrics

TOL = 1e-9


def assert_equal_to_definition(pos, vel, r, max_neig, r_coll, start=None) -> SwarmSample:
    got = swarm_metrics(pos, vel, r, max_neig, r_coll, start)
    want = swarm_performance(pos, vel, r, max_neig, r_coll)[:4]
    for name, g, w in zip(("safety", "order", "union", "alg_conn"), (got.safety, got.order, got.union, got.alg_conn),
                          want, strict=True):
        assert abs(g - w) <= TOL, f"{name}: {g} != {w}"
    return got


def listed_matrix(start: WarmStart) -> np.ndarray:
    """M from the lists a sample left in its warm start (M[i, j] = 1: i is a neighbour of j)."""
    n = len(start.count)
    m = np.zeros((n, n))
    for j in range(n):
        m[start.nbr[j, :start.count[j]], j] = 1
    return m


def graph(pos, r, max_neig):
    """The undirected graph (indptr, indices, degrees) of the definition's M, and its Laplacian."""
    m = compute_neighborhood(distance_matrix(pos), r, max_neig)
    a = (m + m.T) > 0
    indptr = np.concatenate([[0], np.cumsum(a.sum(axis=1))]).astype(np.int64)
    indices = np.concatenate([np.flatnonzero(row) for row in a]).astype(np.int64)
    lap = np.diag(a.sum(axis=1).astype(float)) - a
    return indptr, indices, a.sum(axis=1).astype(np.int64), lap


def certify(indptr, indices, deg, x0, sigma):
    """kernels.certified_lambda2 with fresh buffers and the identity as the previous row order."""
    n = len(deg)
    fwork, iwork = kernels.workspace(n, 1)
    return kernels.certified_lambda2(indptr, indices, deg, x0, float(sigma), np.arange(n), fwork, iwork)


def drifting_swarm(n, ticks, seed, extent=20.0, step=0.6):
    """States of a swarm in a random walk: each tick's neighbour graph differs from the last."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, extent, (n, 3))
    pos[:, 2] *= 0.1
    for _ in range(ticks):
        vel = rng.normal(size=(n, 3))
        yield pos.copy(), vel
        pos = pos + step * vel


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(("n", "r", "max_neig", "r_coll"), [(40, 150.0, 10, 0.5), (60, 4.0, 5, 0.8), (25, 3.0, 30, 1.0),
                                                            (100, 150.0, 10, 0.5)])
def test_a_run_of_samples_equals_the_definition_at_every_sample(seed, n, r, max_neig, r_coll):
    """One warm start through a drifting swarm: lists cut by the previous sample's, lambda_2 from the
    previous Fiedler vector and shift, every sample equal to the definition."""
    start = WarmStart()
    certified = 0
    for pos, vel in drifting_swarm(n, 12, seed):
        got = assert_equal_to_definition(pos, vel, r, max_neig, r_coll, start)
        np.testing.assert_array_equal(listed_matrix(start), compute_neighborhood(distance_matrix(pos), r, max_neig))
        certified += got.certified
    if r == 150.0:  # connected throughout: lambda_2 computed at every sample, certified at most
        assert certified >= 9


@pytest.mark.parametrize("max_neig", [1, 3, 4, 6, 8])
def test_ties_at_the_cut_go_to_the_lower_index_cold_and_warm(max_neig):
    """A cubic lattice (an inner agent has six neighbours at one distance), then the lattice shuffled,
    its lists cut by the unshuffled one's (every previous member at a tie with the new ones)."""
    g = np.arange(4) * 2.0
    pos = np.array([[x, y, z] for x in g for y in g for z in g]) + np.array([10.3, -4.7, 1.1])
    vel = np.random.default_rng(1).normal(size=pos.shape)
    start = WarmStart()
    for state in (pos, pos[np.random.default_rng(2).permutation(len(pos))]):
        assert_equal_to_definition(state, vel, 150.0, max_neig, 0.5, start)
        np.testing.assert_array_equal(listed_matrix(start), compute_neighborhood(distance_matrix(state), 150.0, max_neig))


def test_agents_exactly_at_r_and_at_twice_r_coll():
    """d <= r lists an agent exactly at r (the roots are the definition's, the sums only pre-select);
    a pair exactly 2 r_coll apart does not collide (d < 2 r_coll)."""
    pos = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0], [6.0, 8.0, 0.0], [0.0, 0.0, 5.0]])  # distances 5 and 10
    vel = np.ones_like(pos)
    start = WarmStart()
    for _ in range(2):  # cold, then cut by its own lists
        got = assert_equal_to_definition(pos, vel, 5.0, 2, 2.5, start)
        np.testing.assert_array_equal(listed_matrix(start), compute_neighborhood(distance_matrix(pos), 5.0, 2))
    assert got.safety == 1.0


def test_coincident_agents_and_agents_at_rest():
    rng = np.random.default_rng(3)
    pos = rng.uniform(-2, 2, (12, 3))
    pos[[5, 9]] = pos[4]
    vel = rng.normal(size=(12, 3))
    vel[[0, 4]] = 0.0
    start = WarmStart()
    for _ in range(2):
        got = assert_equal_to_definition(pos, vel, 150.0, 3, 0.5, start)
    assert 0.0 < got.order < 1.0
    at_rest = assert_equal_to_definition(pos, np.zeros_like(pos), 150.0, 3, 0.5)
    assert at_rest.order == 0.0  # every cosine with a zero velocity counts 0


@pytest.mark.parametrize("n", [0, 1, 2, 3])
def test_tiny_swarms(n):
    """No agent, one (S = U = Phi = 1, lambda_2 = 0), two (lambda_2 = 2, one vector: the dense
    eigenvalues), three."""
    pos = np.arange(3.0 * n).reshape(n, 3)
    vel = np.ones((n, 3))
    got = swarm_metrics(pos, vel, 150.0, 10, 0.5)
    if n < 2:
        assert (got.safety, got.order, got.union, got.alg_conn) == (1.0, 1.0, 1.0, 0.0)
    else:
        assert_equal_to_definition(pos, vel, 150.0, 10, 0.5)


def test_a_split_swarm_has_no_connectivity_and_keeps_its_warm_start():
    rng = np.random.default_rng(4)
    pos = np.vstack([rng.uniform(0, 3, (10, 3)), rng.uniform(100, 103, (7, 3))])
    vel = rng.normal(size=pos.shape)
    start = WarmStart()
    joined = assert_equal_to_definition(pos, vel, 500.0, 10, 0.5, start)
    x = start.x.copy()
    split = assert_equal_to_definition(pos, vel, 10.0, 10, 0.5, start)
    assert split.components == 2 and split.alg_conn == 0.0 and split.union == pytest.approx(15 / 16)
    np.testing.assert_array_equal(start.x, x)  # a disconnected sample leaves the Fiedler vector as it was
    assert joined.components == 1


def test_a_warm_start_from_another_swarm_and_a_wrong_shift_still_give_the_definition():
    """The warm start only steers the cost: the Fiedler vector and shift of another swarm (same N), a
    shift far above lambda_3 and one far below 0 are all corrected (or refused to the dense path)."""
    states = [s for s, _ in drifting_swarm(50, 1, 11)] + [s for s, _ in drifting_swarm(50, 1, 12)]
    vel = np.random.default_rng(0).normal(size=(50, 3))
    for sigma in (None, 1e3, -5.0, 1e-300):
        start = WarmStart()
        assert_equal_to_definition(states[0], vel, 150.0, 10, 0.5, start)
        if sigma is not None:
            start.sigma = sigma
        assert_equal_to_definition(states[1], vel, 150.0, 10, 0.5, start)


@pytest.mark.parametrize("seed", range(6))
def test_the_certificate_is_a_proof(seed):
    """Wherever certified_lambda2 says CERTIFIED, theta is within CERT_RTOL ||L||_inf of LAPACK's
    lambda_2 (which errs by far less): from cold starts, warm starts and shifts on both sides."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 15, (80, 3))
    indptr, indices, deg, lap = graph(pos, 150.0, 6)
    exact = np.linalg.eigvalsh(lap)
    for x0, sigma in ((rng.normal(size=80), 0.0), (rng.normal(size=80), 0.5 * (exact[1] + exact[2])),
                      (np.linalg.eigh(lap)[1][:, 1] + 0.1 * rng.normal(size=80), exact[1] * 0.9),
                      (rng.normal(size=80), exact[3] + 1.0)):
        theta, status, sigma_next, factorisations, _ = certify(indptr, indices, deg, x0.copy(), sigma)
        assert 1 <= factorisations <= kernels.FACTORISATIONS_MAX
        if status == kernels.CERTIFIED:
            assert abs(theta - exact[1]) <= kernels.CERT_RTOL * 2 * deg.max()
            assert exact[1] < sigma_next <= exact[2] + 1e-9  # the next shift: between lambda_2 and lambda_3


@pytest.mark.parametrize("shape", ["cycle", "cube"])
def test_no_certificate_for_a_double_lambda_2(shape):
    """The 4-cycle (lambda_2 = lambda_3 = 2) and the cube graph (lambda_2 = lambda_3 = lambda_4 = 2): no
    shift has exactly lambda_2 below it, so from a start that is not an eigenvector the kernel refuses;
    swarm_metrics still gives the definition's value (certified only where its start vector happens to
    be an eigenvector, whose quotient is then a shift at lambda_2 itself)."""
    if shape == "cycle":
        pos, max_neig = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), 2
    else:
        pos, max_neig = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]), 3
    indptr, indices, deg, lap = graph(pos, 1.0, max_neig)
    x0 = np.random.default_rng(6).normal(size=len(pos))
    theta, status, *_ = certify(indptr, indices, deg, x0, 0.0)
    assert status == kernels.REFUSED
    got = assert_equal_to_definition(pos, np.ones_like(pos), 1.0, max_neig, 0.1)
    assert got.alg_conn == pytest.approx(2.0 / len(pos), abs=1e-12)


def test_without_a_certificate_the_dense_eigenvalues_are_taken():
    """A sample whose certificate fails (the 4-cycle, lambda_2 = lambda_3, from a start that is no
    eigenvector) takes lambda_2 from the dense Laplacian, equal to the definition, and says so; so does
    dense_lambda2 on any graph."""
    pos = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    start = WarmStart()
    start.fit(4, 2)
    start.x[:] = np.random.default_rng(8).normal(size=4)
    got = assert_equal_to_definition(pos, np.ones_like(pos), 1.0, 2, 0.1, start)
    assert not got.certified and got.alg_conn == pytest.approx(2.0 / 4, abs=1e-12)
    for pos, _ in drifting_swarm(30, 3, 7):
        indptr, indices, deg, lap = graph(pos, 150.0, 5)
        assert kernels.dense_lambda2(indptr, indices, deg) == pytest.approx(np.linalg.eigvalsh(lap)[1], abs=1e-12)


def test_above_the_compiled_limit_the_tree_path_gives_the_definition():
    """401 agents: swarm_metrics takes the k-d tree's lists and the sparse graph (no warm start used)."""
    from swarmscene.methods.swarmlab.metrics import COMPILED_LIMIT

    rng = np.random.default_rng(9)
    pos = rng.uniform(0, 20, (COMPILED_LIMIT + 1, 3))
    vel = rng.normal(size=pos.shape)
    start = WarmStart()
    got = assert_equal_to_definition(pos, vel, 150.0, 6, 0.5, start)
    assert not got.certified and start.n == 0


@pytest.mark.parametrize("seed", range(5))
def test_the_row_order_is_the_stable_argsort_from_any_previous_order(seed):
    """sort_by gives np.argsort(x, kind="mergesort") (equal values in index order) whatever order it
    starts from: the identity, the previous sample's, a reversed one (x's sign flipped), a random one;
    with ties and signed zeros."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=60)
    x[rng.integers(0, 60, 15)] = 0.5  # ties
    x[[3, 7]] = 0.0, -0.0
    want = np.argsort(x, kind="mergesort")
    for start in (np.arange(60), want.copy(), want[::-1].copy(), rng.permutation(60),
                  np.argsort(x + 0.05 * rng.normal(size=60), kind="mergesort")):
        perm = start.copy()
        kernels.sort_by(x, perm)
        np.testing.assert_array_equal(perm, want)


def test_the_buffers_are_allocated_once_and_the_row_order_stays_a_permutation():
    """A run's samples reuse the warm start's two buffers (kernels.workspace, allocated with the first
    sample) and leave its row order a permutation of the agents; a new size refits them."""
    start = WarmStart()
    buffers = None
    for pos, vel in drifting_swarm(50, 6, 21):
        assert_equal_to_definition(pos, vel, 150.0, 8, 0.5, start)
        if buffers is None:
            buffers = (start.fwork, start.iwork)
        assert start.fwork is buffers[0] and start.iwork is buffers[1]
        np.testing.assert_array_equal(np.sort(start.order), np.arange(50))
    assert_equal_to_definition(pos[:30], vel[:30], 150.0, 8, 0.5, start)
    assert start.fwork is not buffers[0] and len(start.order) == 30


def test_a_warm_start_sampled_again_is_swarm_metrics_bit_for_bit():
    """WarmStart.again (the observer's call after its first sample: no checks, no conversions) gives
    every sample's metrics, lists and Fiedler vector exactly as swarm_metrics does from the same state."""
    through, direct = WarmStart(), WarmStart()
    for k, (pos, vel) in enumerate(drifting_swarm(40, 8, 5)):
        want = swarm_metrics(pos, vel, 150.0, 6, 0.5, through)
        got = swarm_metrics(pos, vel, 150.0, 6, 0.5, direct) if k == 0 else direct.again(pos, vel, 150.0, 0.5)
        assert tuple(got[:6]) == tuple(want), k
        np.testing.assert_array_equal(direct.nbr, through.nbr)
        np.testing.assert_array_equal(direct.x, through.x)
        assert direct.sigma == through.sigma


@pytest.mark.parametrize("r_coll", [1e-150, 1e-163, 1e-300])
def test_a_collision_radius_whose_square_underflows_still_counts_coincident_agents(r_coll):
    """Two agents at one place collide for any r_coll > 0 (0 < 2 r_coll). The compiled
    pre-selection bound, 4 r_coll^2, underflowed to 0 below about 1e-154 m and the pair went
    uncounted (safety 1 instead of the definition's 2/3)."""
    pos = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [5.0, 2.0, 3.0]])
    got = assert_equal_to_definition(pos, np.ones((3, 3)), 150.0, 10, r_coll)
    assert got.safety == pytest.approx(2.0 / 3.0, abs=1e-15)
