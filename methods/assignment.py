"""Exact linear assignment for large swarms: scipy's solver warm-started by coarse-to-fine duals.

``scipy.optimize.linear_sum_assignment`` (shortest augmenting paths) starts from zero dual
potentials. On geometric costs where the whole swarm has to spread out (agents packed on a home
grid, slots on a wide hexagon) the augmenting paths then run through most of the matrix and an
N = 1,000 assignment takes about half a second. The optimal assignment of a square cost C is
unchanged when any u_i is subtracted from row i and any v_j from column j, so near-optimal
potentials can be handed to the solver as a reduced cost matrix: it then mostly confirms the
zeros and the paths are short.

The potentials come from the same problem at a coarser scale: every ``coarsen``-th row and
column (a spatially spread sample when rows and columns are in a sensible order), solved
recursively, its exact duals recovered (:func:`assignment_duals`), extended to the full matrix
by the c-transforms v_j = min_k (c_kj - u_k), u_i = min_j (c_ij - v_j), v_j = min_i (c_ij - u_i)
(which also make them feasible: every reduced cost is >= 0). The result is exactly optimal:
only the solver's starting point changes, never the problem. Integer costs stay integer, so ties
are exact and the answer is a deterministic function of the matrix.

Two row orders, both fixed functions of the matrix, keep the paths short: rows are sorted by their
cheapest column before sampling (a stratified coarse sample, hence better duals), and scipy takes
the rows of each reduced matrix with the fewest zeros first (tie-heavy rows last). At N = 1,000
(benchmarks/speed/bench_hex_assignment.py) every starting configuration then solves in under 50 ms.
"""

from __future__ import annotations

from functools import lru_cache
from itertools import permutations

import numpy as np
import scipy  # scipy.optimize and scipy.sparse load on first use (start-up of unrelated runs)

FEW = 6
"""Up to this many rows, :func:`min_cost_assignment` tries every assignment (at most 720 for six
agents on six slots) instead of importing scipy.optimize, which costs a quarter of a second of
the command line's start-up: the default scenario's five agents need nothing more."""


def min_cost_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and their columns in an assignment of least total cost, like scipy's
    ``linear_sum_assignment`` for a (k, m) ``cost`` with k <= m: every row gets a distinct column.

    Exact either way: with at most ``FEW`` rows by enumeration (of all ordered choices of k of
    the m columns; the first one of least cost in lexicographic order wins a tie), else by scipy.
    """
    k, m = cost.shape
    if k > FEW or m > FEW:
        return scipy.optimize.linear_sum_assignment(cost)
    rows = np.arange(k)
    if k == 0:
        return rows, rows
    choices = _column_choices(k, m)
    totals = cost[rows, choices].sum(axis=1)
    return rows, choices[int(np.argmin(totals))]


@lru_cache(maxsize=FEW * FEW)
def _column_choices(k: int, m: int) -> np.ndarray:
    """Every ordered choice of k distinct columns among m, (m! / (m - k)!, k), lexicographic."""
    return np.array(list(permutations(range(m), k)), dtype=np.intp)


def assignment_duals(
    cost: np.ndarray, cols: np.ndarray, v_start: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Dual potentials (u, v) of an optimal assignment ``row i -> cols[i]`` of a square ``cost``.

    They satisfy u_i + v_j <= c_ij everywhere with equality on the assignment (complementary
    slackness), which certifies optimality. v solves the difference constraints
    v_j <= v_cols(i) + c_ij - c_i,cols(i) by Bellman-Ford iterations (vectorised over the matrix),
    from ``v_start`` (default 0) downwards: the largest solution below the start.

    Raises:
        ValueError: when the iterations do not settle, i.e. the assignment is not optimal.
    """
    n = cost.shape[0]
    rows = np.arange(n)
    on_assignment = cost[rows, cols]
    slack = cost - on_assignment[:, None]  # slack[i, j]: edge from column cols[i] to column j
    v = np.zeros(n, dtype=cost.dtype) if v_start is None else v_start.astype(cost.dtype, copy=True)
    for _ in range(n + 1):
        relaxed = np.minimum(v, (v[cols][:, None] + slack).min(axis=0))
        if np.array_equal(relaxed, v):
            return on_assignment - v[cols], v
        v = relaxed
    raise ValueError("the assignment is not optimal (negative cycle in its residual graph)")


def solve_square(cost: np.ndarray, coarsen: int = 3, direct_size: int = 100) -> np.ndarray:
    """Column of each row in a minimal-cost assignment of a square ``cost`` (exact).

    Args:
        cost: (n, n) costs (integers keep ties exact).
        coarsen: sampling step between scales (every ``coarsen``-th row and column).
        direct_size: below this size the problem is handed to scipy as it is.

    Returns:
        (n,) int, the column assigned to each row.
    """
    if cost.shape[0] <= direct_size:
        return _solve_with_duals_hint(cost, coarsen, direct_size)[0]
    cheapest = cost.argmin(axis=1)  # column of each row's minimum
    cols = _matching_on_reduction_zeros(cost, cheapest)
    if cols is not None:
        return cols
    # The coarse scales take every ``coarsen``-th row: with the rows sorted by their cheapest
    # column (its slot, for a formation whose slots are listed ring by ring) that sample is
    # stratified over the pattern instead of over the agents' ids, so its duals extend better to
    # the full matrix (agents uniform in a square, N = 1,000: solve 54 -> 40-47 ms). A stable
    # sort keeps the answer a deterministic function of the matrix.
    row_order = np.argsort(cheapest, kind="stable")
    return _solve_with_duals_hint(cost, coarsen, direct_size, row_order)[0]


def _matching_on_reduction_zeros(cost: np.ndarray, cheapest: np.ndarray | None = None) -> np.ndarray | None:
    """An optimal assignment when row then column reduction already leaves one, else None.

    After u_i = min_j c_ij and v_j = min_i (c_ij - u_i) every reduced cost is >= 0; a perfect
    matching on the zeros then has reduced cost 0, which is optimal (complementary slackness).
    That is the common case of a formation re-assigned every tick with each agent near its slot,
    and Hopcroft-Karp on the zero graph finds it in a few milliseconds.
    """
    # Cheap pre-test: a perfect matching on the zeros needs (nearly) distinct row minima.
    if cheapest is None:
        cheapest = cost.argmin(axis=1)
    if np.unique(cheapest).size < 0.9 * cost.shape[0]:
        return None
    reduced = cost - cost.min(axis=1, keepdims=True)
    reduced -= reduced.min(axis=0)
    rows, cols = np.nonzero(reduced == 0)
    zeros = scipy.sparse.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=cost.shape)
    match = scipy.sparse.csgraph.maximum_bipartite_matching(zeros, perm_type="column")
    return match if np.all(match >= 0) else None


def _solve_with_duals_hint(cost, coarsen, direct_size, row_order=None):
    """Solve ``cost``; also return the column potentials used, as a start for its own duals.

    The coarse problem takes every ``coarsen``-th row of ``row_order`` (default: as given) and
    every ``coarsen``-th column; its rows stay in that order at the coarser scales.
    """
    n = cost.shape[0]
    if n <= direct_size:
        return scipy.optimize.linear_sum_assignment(cost)[1], np.zeros(n, dtype=cost.dtype)
    sample_cols = np.arange(0, n, coarsen)
    sample = sample_cols if row_order is None else row_order[::coarsen]
    coarse = cost[np.ix_(sample, sample_cols)]
    coarse_cols, coarse_hint = _solve_with_duals_hint(coarse, coarsen, direct_size)
    u_coarse, _ = assignment_duals(coarse, coarse_cols, coarse_hint)
    # Extend to every column and row by c-transforms; the last two make (u, v) feasible.
    v = (cost[sample] - u_coarse[:, None]).min(axis=0)
    reduced = cost - v
    reduced -= reduced.min(axis=1, keepdims=True)  # u
    v_shift = reduced.min(axis=0)
    reduced -= v_shift
    return _solve_reduced(reduced), v + v_shift


def _solve_reduced(reduced: np.ndarray) -> np.ndarray:
    """scipy's solver on a reduced cost matrix, rows taken in order of their number of zeros.

    The solver augments one row at a time in the order given. A row with few zero reduced costs
    has little choice, so settling those rows first leaves the flexible ones (a far agent ties on
    hundreds of slots) to fill the remaining gaps, instead of taking slots that the constrained rows
    then have to win back along long alternating paths: on the line start of the benchmark this
    halves the solve. The order is a fixed function of the matrix (stable sort), so the answer
    stays deterministic; the optimum does not depend on the order.
    """
    order = np.argsort(np.count_nonzero(reduced == 0, axis=1), kind="stable")
    cols = np.empty(reduced.shape[0], dtype=np.intp)
    cols[order] = scipy.optimize.linear_sum_assignment(reduced[order])[1]
    return cols
