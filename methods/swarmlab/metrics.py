"""SwarmLab's performance metrics of one swarm state, from neighbour lists and sparse graphs.

Source: E. Soria, F. Schiano, D. Floreano, "SwarmLab: a Matlab drone swarm simulator", IROS 2020,
section IV-C, as computed by ``math_tools/compute_swarm_performance.m`` and
``math_tools/compute_neighborhood.m`` of github.com/lis-epfl/swarmlab. For N agents at positions
p_i with velocities v_i, at one time step:

* **neighbourhood** M (``compute_neighborhood``): agent j's neighbours are the others within the
  metric radius r (d_ij <= r), cut to the ``max_neig`` nearest when there are more (the
  topological distance; ties at the cut go to the lower index, as MATLAB's stable ``sort``);
  M may be asymmetric;
* **safety** S = 1 - n_coll / (N (N - 1) / 2), n_coll the pairs closer than 2 r_coll (r_coll:
  the radius of the sphere that approximates one drone); 1 for fewer than two agents;
* **order** Phi = (1/N) sum_j (1/|N_j|) sum_{i in N_j} v_j . v_i / (|v_j| |v_i|), an agent
  without neighbours counting 1;
* **union** U = (N - n_cc) / (N - 1), n_cc the connected components of the undirected graph
  A = (M + M^T) > 0 (1 for a single agent);
* **algebraic connectivity** lambda_2(L) / N, L = D - A the graph Laplacian, lambda_2 its second
  smallest eigenvalue (0 for a disconnected graph, and for a single agent);
* **obstacle safety** S_obs = 1 - n_obs / (N n_o), n_obs the (agent, obstacle) pairs with the
  agent strictly inside the obstacle, n_o the obstacles; **min_d_obs** each agent's signed
  distance to the nearest obstacle (SwarmLab: to the cylinders' surfaces, in the horizontal
  plane; here to the obstacles' footprints, the engine's obstacles being vertical prisms).

Choices where the source is silent or breaks:

* an agent at rest has no direction: a cosine with a zero velocity counts 0 (SwarmLab divides by
  zero and returns NaN, e.g. for every swarm at its start);
* SwarmLab's defaults (``parameters/param_swarm/param_swarm.m``): r = 150 m, max_neig = 10,
  r_coll = 0.5 m; SwarmLab writes S_obs = 0 and min_d_obs = 0 when no obstacle is active, here
  they are left undefined (None) so a mean over the run is not dragged to 0.

Up to ``COMPILED_LIMIT`` agents (:func:`swarm_metrics`) one compiled pass
(:mod:`swarmscene.methods.swarmlab.kernels`) takes every pair's distance, the neighbour lists (cut
by the previous sample's lists, exactly), safety, order and the components, and lambda_2 comes
from a Krylov space of the shift-inverted Laplacian started from the previous sample's Fiedler
vector, with a proof (Temple's inequality and a Sylvester inertia count) that it is within
1e-12 ||L||_inf of the true value; when no proof is found, from the dense eigenvalues. Above, the
neighbour lists come from a k-d tree query of the ``max_neig + 2`` nearest points (the agent
itself, ``max_neig`` others, and one more that shows a tie at the cut: such an agent is listed by
the definition's full sort instead), and the graph quantities from a sparse adjacency
(``scipy.sparse.csgraph``; lambda_2 by shift-invert Lanczos for large connected graphs). Both
equal the definition's all-pairs matrices (tests/methods/swarmlab against
tests/oracles/swarmlab.py, a line-by-line transcription of the MATLAB).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from scipy.sparse import csr_matrix
    from scipy.spatial import cKDTree

R_DEFAULT = 150.0
"""SwarmLab's metric radius of influence r, m (``p_swarm.r``)."""
MAX_NEIG_DEFAULT = 10
"""SwarmLab's topological limit on neighbours (``p_swarm.max_neig``)."""
R_COLL_DEFAULT = 0.5
"""SwarmLab's collision radius r_coll, m (``p_swarm.r_coll``): a pair collides closer than 2 r_coll."""
DENSE_EIGEN_LIMIT = 400
"""Up to this many agents lambda_2 is taken from the dense Laplacian (LAPACK, one eigenvalue);
above, by shift-invert Lanczos on the sparse one (the dense cost grows as N^3)."""
COMPILED_LIMIT = 400
"""Up to this many agents :func:`swarm_metrics` takes the compiled pass (every pair: N^2 / 2
distances); above, the k-d tree's neighbour lists and the sparse graph."""


class WarmStart:
    """What a sample hands the next (one per run; :func:`swarm_metrics` updates it): the
    neighbour lists, whose furthest members bound the next lists, the Fiedler vector and shift
    lambda_2 starts from and the row order its factorisation sorts from, and the compiled pass's
    buffers (allocated with the first sample of a size). The lists do not depend on it; lambda_2
    only within its certified bound (a warm start changes the last digits, never more than
    1e-12 ||L||_inf); the cost does."""

    def __init__(self) -> None:
        self.fit(0, 0)

    def fit(self, n: int, listed: int) -> None:
        """Empty the state for N agents of ``listed`` neighbours at most."""
        self.n, self.listed_max = n, listed
        self.nbr = np.zeros((n, listed), dtype=np.int64)
        self.count = np.zeros(n, dtype=np.int64)
        self.listed = False
        self.x = np.zeros(n)
        self.sigma = 0.0
        self.order = np.arange(n)
        self.fwork: np.ndarray | None = None  # kernels.workspace(n, listed), with the first sample
        self.iwork: np.ndarray | None = None

    def again(self, pos: np.ndarray, vel: np.ndarray, r: float, r_coll: float) -> tuple:
        """The compiled pass of a swarm this state has sampled before (``listed``): the kernel's
        tuple, S, Phi, U and lambda_2 / N first (:func:`kernels.swarm_sample`).

        :func:`swarm_metrics` without its checks and conversions, which the first sample settled
        (the size, the buffers, the kernels): ``pos`` and ``vel`` must be (N, dim) float64 arrays of
        that N (the engine's state), ``r`` and ``r_coll`` floats. A hundred boids' sample is short
        enough that the checks' Python, out of the caches between two flocking ticks, was ~7 % of it.
        """
        assert self.listed and _kernels is not None
        out = _kernels.swarm_sample(pos, vel, r, r_coll, self.nbr, self.count, True, self.x, self.sigma, self.order,
                                    self.fwork, self.iwork)
        self.sigma = out[6]
        return out


class SwarmSample(NamedTuple):
    """One sample's metrics (SwarmLab's S, Phi, U, lambda_2 / N), the components, and whether
    lambda_2 was certified from the warm start (False: the dense eigenvalues, or none needed)."""

    safety: float
    order: float
    union: float
    alg_conn: float
    components: int
    certified: bool = False


@dataclass(frozen=True)
class Neighbourhood:
    """SwarmLab's neighbourhood M as directed edges: ``source[k]`` is a neighbour of ``target[k]``
    (M[source, target] = 1), each agent's neighbours listed together."""

    n: int
    source: np.ndarray
    target: np.ndarray


def neighbourhood(pos: np.ndarray, r: float, max_neig: int, tree: cKDTree | None = None) -> Neighbourhood:
    """M of ``compute_neighborhood.m`` for positions ``pos`` (N, 3), m, from a k-d tree over them.

    Args:
        pos: positions, (N, 3), m.
        r: metric radius, m (neighbours at d <= r).
        max_neig: most neighbours per agent (the nearest; the lower index first at a tie).
        tree: a ``scipy.spatial.cKDTree`` over ``pos`` (the engine's shared one), or None to build it.
    """
    from scipy.spatial import cKDTree

    n = len(pos)
    if n < 2 or max_neig < 1:
        empty = np.zeros(0, dtype=np.intp)
        return Neighbourhood(n, empty, empty)
    if tree is None:
        tree = cKDTree(pos)
    k = min(n, max_neig + 2)
    # a hair beyond r: the tree's bound is strict, and d <= r is decided on our own distances below
    _, idx = tree.query(pos, k=k, distance_upper_bound=r * (1.0 + 1e-9) + 1e-12)
    idx = idx.reshape(n, k)
    rows = np.repeat(np.arange(n), k).reshape(n, k)
    found = (idx < n) & (idx != rows)
    safe = np.where(found, idx, 0)
    dist = np.sqrt(((pos[safe] - pos[:, None, :]) ** 2).sum(axis=2))  # pdist's sum, then its root
    dist = np.where(found & (dist <= r), dist, np.inf)
    # per row: the others by (distance, index), the definition's stable sort
    order = np.lexsort((np.where(np.isfinite(dist), safe, n), dist), axis=1)
    dist = np.take_along_axis(dist, order, axis=1)
    safe = np.take_along_axis(safe, order, axis=1)
    count = np.isfinite(dist).sum(axis=1)
    keep = min(max_neig, k)
    listed = np.isfinite(dist[:, :keep])
    # a row with more than max_neig candidates has a cut; a tie at the cut, or a row whose query was
    # full (a further tie could lie beyond it), is listed by the definition's full sort
    cut = count > max_neig
    if k > max_neig:
        last, next_ = dist[:, max_neig - 1], dist[:, min(max_neig, k - 1)]
        # within a few ulps: the tree may round a distance otherwise than the definition's sum
        with np.errstate(invalid="ignore"):  # inf - inf in rows without a cut
            tie = cut & (next_ - last <= 1e-12 * np.maximum(next_, 1.0))
    else:
        tie = np.zeros(n, dtype=bool)
    target = np.repeat(np.arange(n), keep).reshape(n, keep)
    source, target = safe[:, :keep][listed & ~tie[:, None]], target[listed & ~tie[:, None]]
    tied = np.flatnonzero(tie)
    if tied.size:
        extra = [_full_sort_row(pos, int(j), r, max_neig) for j in tied]
        source = np.concatenate([source, *extra])
        target = np.concatenate([target, *[np.full(len(e), j) for e, j in zip(extra, tied, strict=True)]])
    return Neighbourhood(n, source.astype(np.intp), target.astype(np.intp))


def _full_sort_row(pos: np.ndarray, j: int, r: float, max_neig: int) -> np.ndarray:
    """Agent j's neighbours by the definition: every other within r, the ``max_neig`` lowest by
    (distance, index)."""
    d = np.sqrt(((pos - pos[j]) ** 2).sum(axis=1))
    d[j] = np.inf
    within = np.flatnonzero(d <= r)
    ranked = within[np.lexsort((within, d[within]))]
    return ranked[:max_neig]


def safety(pos: np.ndarray, r_coll: float, tree: cKDTree | None = None) -> float:
    """S = 1 - (pairs closer than 2 r_coll) / (N (N - 1) / 2); 1 for fewer than two agents."""
    from scipy.spatial import cKDTree

    n = len(pos)
    if n < 2:
        return 1.0
    if tree is None:
        tree = cKDTree(pos)
    limit = 2.0 * r_coll
    # the tree lists pairs at d <= 2 r_coll; the definition counts d < 2 r_coll
    pairs = tree.query_pairs(limit, output_type="ndarray")
    if len(pairs):
        d = np.sqrt(((pos[pairs[:, 0]] - pos[pairs[:, 1]]) ** 2).sum(axis=1))
        close = int((d < limit).sum())
    else:
        close = 0
    return 1.0 - close / (n * (n - 1) / 2)


def order(vel: np.ndarray, hood: Neighbourhood) -> float:
    """Phi = (1/N) sum_j mean_{i in N_j} cos(v_j, v_i); an agent without neighbours counts 1, a
    cosine with a zero velocity 0."""
    n = hood.n
    if n == 0:
        return 1.0
    speed = np.sqrt((vel**2).sum(axis=1))
    dot = (vel[hood.source] * vel[hood.target]).sum(axis=1)
    norm = speed[hood.source] * speed[hood.target]
    cos = np.divide(dot, norm, out=np.zeros_like(dot), where=norm > 0)
    count = np.bincount(hood.target, minlength=n)
    total = np.bincount(hood.target, weights=cos, minlength=n)
    per_agent = np.where(count > 0, total / np.maximum(count, 1), 1.0)
    return float(per_agent.sum() / n)


def adjacency(hood: Neighbourhood) -> csr_matrix:
    """A = (M + M^T) > 0, the undirected graph, as a sparse boolean-valued (0/1) matrix."""
    from scipy.sparse import coo_matrix

    n = hood.n
    ones = np.ones(len(hood.source))
    m = coo_matrix((ones, (hood.source, hood.target)), shape=(n, n)).tocsr()
    a = (m + m.T).tocsr()
    a.data[:] = 1.0
    return a


def graph_metrics(hood: Neighbourhood, dense_limit: int = DENSE_EIGEN_LIMIT) -> tuple[float, float, int]:
    """Union, lambda_2 / N and the component count of the graph (M + M^T) > 0: for at most
    ``dense_limit`` agents from a dense boolean matrix (reachability sweeps, LAPACK's eigenvalues,
    no sparse construction: a hundred agents' sparse matrices cost more than the answer), above
    from the sparse graph (:func:`union_and_connectivity`)."""
    n = hood.n
    if n > dense_limit:
        return union_and_connectivity(adjacency(hood), dense_limit)
    if n < 2:
        return 1.0, 0.0, n
    a = np.zeros((n, n), dtype=bool)
    a[hood.source, hood.target] = True
    a |= a.T
    unseen = np.ones(n, dtype=bool)
    n_cc = 0
    while unseen.any():
        reached = np.zeros(n, dtype=bool)
        reached[int(np.argmax(unseen))] = True
        count = 0
        while (new := int(reached.sum())) != count:
            count = new
            reached |= a[reached].any(axis=0)
        unseen &= ~reached
        n_cc += 1
    union = (n - n_cc) / (n - 1)
    if n_cc > 1:
        return union, 0.0, n_cc
    lap = np.diag(a.sum(axis=1).astype(float)) - a
    return union, float(np.linalg.eigvalsh(lap)[1]) / n, n_cc


def union_and_connectivity(a: csr_matrix, dense_limit: int = DENSE_EIGEN_LIMIT) -> tuple[float, float, int]:
    """Union U = (N - n_cc) / (N - 1), algebraic connectivity lambda_2(L) / N and n_cc of graph ``a``.

    lambda_2 is 0 for a disconnected graph (the Laplacian has one zero eigenvalue per component)
    and computed otherwise: from the dense Laplacian up to ``dense_limit`` agents, else by
    shift-invert Lanczos on the sparse one (sigma = -1: L + I is positive definite, and the two
    eigenvalues nearest -1 are the two smallest, 0 and lambda_2).
    """
    from scipy.sparse.csgraph import connected_components, laplacian

    n = a.shape[0]
    if n < 2:
        return 1.0, 0.0, n
    n_cc = int(connected_components(a, directed=False, return_labels=False))
    union = (n - n_cc) / (n - 1)
    if n_cc > 1:
        return union, 0.0, n_cc
    lap = laplacian(a)
    if n <= dense_limit:
        from scipy.linalg import eigh

        lam2 = float(eigh(lap.toarray(), eigvals_only=True, subset_by_index=[1, 1])[0])
    else:
        from scipy.sparse.linalg import eigsh

        values = eigsh(lap.tocsc(), k=2, sigma=-1.0, which="LM", return_eigenvectors=False, tol=0)
        lam2 = float(np.sort(values)[1])
    return union, lam2 / n, n_cc


def swarm_metrics(pos: np.ndarray, vel: np.ndarray, r: float, max_neig: int, r_coll: float,
                  start: WarmStart | None = None, tree: cKDTree | None = None) -> SwarmSample:
    """S, Phi, U and lambda_2 / N of one swarm state (compute_swarm_performance.m): for at most
    ``COMPILED_LIMIT`` agents by one compiled pass with the certified lambda_2 (starting from and
    updating ``start``), above by :func:`neighbourhood`, :func:`safety`, :func:`order` and
    :func:`graph_metrics` over the k-d tree ``tree`` (built when None)."""
    n = len(pos)
    if n > COMPILED_LIMIT:
        from scipy.spatial import cKDTree

        tree = cKDTree(pos) if tree is None else tree
        hood = neighbourhood(pos, r, max_neig, tree)
        union, alg_conn, n_cc = graph_metrics(hood)
        return SwarmSample(safety(pos, r_coll, tree), order(vel, hood), union, alg_conn, n_cc)
    if n < 2:  # no pair, no neighbour: SwarmLab's values of a lone agent
        return SwarmSample(1.0, 1.0, 1.0, 0.0, n)
    state = WarmStart() if start is None else start
    listed = min(max_neig, n - 1)
    if state.n != n or state.listed_max != listed:
        state.fit(n, listed)
    kernels = _kernels or _load_kernels()
    if state.fwork is None or state.iwork is None:
        state.fwork, state.iwork = kernels.workspace(n, listed)
    out = kernels.swarm_sample(
        np.ascontiguousarray(pos, dtype=float), np.ascontiguousarray(vel, dtype=float), float(r), float(r_coll),
        state.nbr, state.count, state.listed, state.x, state.sigma, state.order, state.fwork, state.iwork)
    state.listed, state.sigma = True, out[6]
    return SwarmSample(*out[:6])


_kernels: ModuleType | None = None
"""The compiled kernels, imported with the first compiled sample (numba's import is not free: a
run without the observer, or listing the plugins, never pays it)."""


def _load_kernels() -> ModuleType:
    """Import :mod:`swarmscene.methods.swarmlab.kernels` and keep it in ``_kernels``."""
    global _kernels
    from swarmscene.methods.swarmlab import kernels

    _kernels = kernels
    return kernels


def obstacle_safety(inside_pairs: int, n: int, n_obstacles: int) -> float | None:
    """S_obs = 1 - n_obs / (N n_o) (None without obstacles or agents)."""
    if n_obstacles == 0 or n == 0:
        return None
    return 1.0 - inside_pairs / (n * n_obstacles)
