"""Time the hexagonal-formation slot assignment (thesis eq. 4.12-4.13) for a large swarm.

Usage:  python benchmarks/speed/bench_hex_assignment.py [--n 1000] [--repeat 5]

For each starting configuration it builds the pattern for N agents (d_r = 5 m), then times
``assign_offsets`` (cost matrix in decimetres + exact assignment) and, for reference, scipy's
``linear_sum_assignment`` on the same square matrix without the warm start. It checks that
both reach the same total cost. Goal (issue 5): N = 1,000 in at most 50 ms.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from functools import partial

import numpy as np
from scipy.optimize import linear_sum_assignment

from swarmscene.methods.outdoor.hex_pattern import DECIMETRE, assign_offsets, assignment_cost, hex_pattern

D_R, D_I = 5.0, 1.5  # Table 4.3: formation spacing, initial spacing


def configurations(n: int, pattern, rng: np.random.Generator) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(followers' xy (N-1, 2), leader xy (2,)) for each starting situation."""
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)[:n] * D_I
    centre = int(np.argmin(np.linalg.norm(grid - grid.mean(axis=0), axis=1)))
    # In steady state the penalty leaves outer-ring slots free: followers sit on the first N - 1
    # slots (pattern order is ring by ring), each shuffled to a random id.
    slots = pattern.offsets_xy[: n - 1][rng.permutation(n - 1)]
    return {
        "home grid, leader at a corner (cold FORM)": (grid[1:], grid[0]),
        "home grid, leader at the centre (cold FORM)": (np.delete(grid, centre, axis=0), grid[centre]),
        "uniform in a 200 m square": (rng.uniform(-100, 100, size=(n - 1, 2)), np.zeros(2)),
        "near their slots, 0.3 m noise (re-assignment each T_s)": (
            slots + rng.normal(0.0, 0.3, size=slots.shape), np.zeros(2)),
        "on a line d_i apart, leader second (thesis 4.5.2, scaled)": (
            np.c_[np.r_[0.0, np.arange(2, n) * D_I], np.zeros(n - 1)], np.array([D_I, 0.0])),
    }


def best_of(repeat: int, fn: Callable[[], object]) -> tuple[float, object]:
    """The shortest wall time (s) of ``repeat`` calls of ``fn`` and the last call's result."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> None:
    """Time assign_offsets and plain scipy on each starting configuration and print whether their costs agree."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="swarm size N (leader included)")
    parser.add_argument("--repeat", type=int, default=5, help="timed repetitions (best is reported)")
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    pattern = hex_pattern(args.n, D_R)
    ids = np.arange(1, args.n)
    penalty = np.rint(pattern.periphery_penalty / DECIMETRE).astype(np.int64)
    print(f"N = {args.n}: M = {pattern.m} offsets, rho_max = {pattern.rho_max}; best of {args.repeat}")
    print(f"{'configuration':58s} {'assign_offsets':>14s} {'plain scipy':>12s}  same cost")
    for name, (xy, leader) in configurations(args.n, pattern, rng).items():
        t_ours, slots = best_of(args.repeat, partial(assign_offsets, pattern, ids, xy, leader))
        cost = assignment_cost(pattern, xy, leader)
        square = np.vstack([cost - penalty, np.tile(-penalty, (pattern.m - cost.shape[0], 1))])
        t_plain, (rows, cols) = best_of(min(args.repeat, 2), partial(linear_sum_assignment, square))
        real = rows < cost.shape[0]
        same = cost[np.arange(cost.shape[0]), slots].sum() == cost[rows[real], cols[real]].sum()
        print(f"{name:58s} {t_ours * 1e3:11.1f} ms {t_plain * 1e3:9.1f} ms  {same}")


if __name__ == "__main__":
    main()
