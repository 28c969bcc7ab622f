"""Speed of one CEM guidance step (Algorithm 1 with CalcXY, papers/cem-fluid-flow-navigation.md).

The compiled step (methods/cem/kernels.py) side by side with the NumPy implementation it replaced
(tests/oracles/cem.py), alternating in one process, single thread:

1. Section V-A: five healthy agents around the failed lead of the six-vehicle formation, n = 20,
   through the whole manoeuvre (both saddle points, 1300 ticks), for K in {1, 2, 5} (Fig. 11: the
   paper's C++ took about 0.2 / 0.4 / 1 ms). The plugin's ``adjust`` (setpoint copy and write-back
   included) is timed too. Against a plain C++ implementation: benchmarks/speed/peers/bench_cem_cpp.py.
2. Scale: 1,000 healthy agents on a 4 m grid around 10 failed ones, K = 2, n = 20.

    OMP_NUM_THREADS=1 taskset -c 1 python benchmarks/speed/bench_cem.py [--ticks 300] [--rounds 5]

Goals (issue 4): median step <= 0.1 ms for six agents; <= 10 ms for 1,000 agents and 10 failures.
Per-tick figures are thread CPU time (a shared core's waits are not ours), mean over a whole
manoeuvre, median over alternating rounds.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from swarmscene.core.plugin import BuildContext  # noqa: E402
from swarmscene.core.setpoint import Mode, Setpoints  # noqa: E402
from swarmscene.core.state import WorldState  # noqa: E402
from swarmscene.methods.cem.flow import CEMNavigator  # noqa: E402
from swarmscene.plugins.avoidance.cem import CEM  # noqa: E402
from swarmscene.plugins.event.hover import Hover  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from oracles.cem import NumpyNavigator  # noqa: E402  (the NumPy step the kernel replaced)

A_P = 1.36
DT = 0.01


def six_vehicle() -> tuple[np.ndarray, np.ndarray]:
    """(failed lead (1, 2), healthy (5, 2)) of section V-A, nearest spacing 2.72 m."""
    d, s3 = 2.72, np.sqrt(3.0)
    healthy = np.array([[-s3 * d, 0], [-s3 / 2 * d, d / 2], [-s3 / 2 * d, -d / 2], [-s3 * d, d], [-s3 * d, -d]])
    return np.zeros((1, 2)), healthy


def per_tick(step, ticks: int) -> float:
    """Thread CPU seconds per call of ``step`` over ``ticks`` calls."""
    c0 = time.thread_time()
    for _ in range(ticks):
        step()
    return (time.thread_time() - c0) / ticks


def plugin_step(ticks: int, K: int = 2):
    """The plugin's adjust() on the six-vehicle world, perfect tracking; hand-back tested, never reached."""
    failed, healthy = six_vehicle()
    pos = np.column_stack([np.vstack([failed, healthy]), np.full(6, 2.0)])
    world = WorldState.at_rest(pos)
    ctx = BuildContext(n=6, guidance_period=DT, physics_step=DT, duration=ticks * DT, separation_limit=1.36,
                       clearance_limit=0.0, comm_range=50.0, environment=None, rng=np.random.default_rng(1),
                       initial=world)
    plugin = CEM(CEM.Params(K=K, handback_distance=1e6, direction=0.0), ctx)
    ev = Hover.event(0.0, (0,))
    ev.apply(world)
    plugin.swarmscene_event(sim=type("Sim", (), {"world": world})(), event=ev)
    sp = Setpoints.hold(world.pos)
    sp.mode[1:] = Mode.TRACK
    return lambda: plugin.adjust(world, None, sp)


def side_by_side(make, ticks: int, rounds: int) -> tuple[float, float]:
    """(kernel, NumPy) thread CPU s per tick, median over alternating rounds of fresh navigators."""
    kernel, numpy_ = [], []
    for _ in range(rounds):
        kernel.append(per_tick(make(1).step, ticks))
        numpy_.append(per_tick(NumpyNavigator(make(1), np.random.default_rng(1)).step, ticks))
    return float(np.median(kernel)), float(np.median(numpy_))


def large(n_healthy: int = 1000, n_failed: int = 10, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A 4 m grid of n_healthy + n_failed agents; n_failed of them, at least 10 m apart, fail."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n_healthy + n_failed)))
    g = np.array([[x, y] for x in range(side) for y in range(side)], dtype=float)[: n_healthy + n_failed] * 4.0
    failed: list[int] = []
    for i in rng.permutation(len(g)):
        if all(np.hypot(*(g[i] - g[j])) >= 10.0 for j in failed):
            failed.append(int(i))
        if len(failed) == n_failed:
            break
    mask = np.zeros(len(g), bool)
    mask[failed] = True
    return g[mask], g[~mask]


def main() -> None:
    """Print CEM's time per tick, the kernel beside NumPy: six vehicles, the plugin's adjust(), a large swarm."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=300, help="ticks of the 1,000-agent run")
    ap.add_argument("--rounds", type=int, default=5, help="alternating rounds")
    args = ap.parse_args()

    failed, healthy = six_vehicle()
    CEMNavigator(healthy, failed, a_p=A_P, rng=np.random.default_rng(0)).step()  # load the cached kernel
    print(f"six vehicles (section V-A), 5 healthy around 1 failure, n = 20, 1300 ticks; thread CPU per tick, "
          f"median of {args.rounds} alternating rounds:")
    for K in (1, 2, 5):
        def make(seed, K=K):
            return CEMNavigator(healthy, failed, a_p=A_P, K=K, n=20, sigma=1e-3, dT=DT, rng=np.random.default_rng(seed))

        kernel, numpy_ = side_by_side(make, 1300, args.rounds)
        paper = {1: 0.2, 2: 0.4, 5: 1.0}[K]
        print(f"  K={K}: kernel {kernel * 1e3:.4f} ms, NumPy {numpy_ * 1e3:.4f} ms ({numpy_ / kernel:.0f}x)"
              f"   (paper's C++: {paper} ms)")
    t = float(np.median([per_tick(plugin_step(1300), 1300) for _ in range(args.rounds)]))
    print(f"  plugin adjust(), K=2: {t * 1e3:.4f} ms   (goal <= 0.1 ms)")

    failed, healthy = large()

    def make_large(seed):
        return CEMNavigator(healthy, failed, a_p=A_P, K=2, n=20, sigma=1e-3, dT=DT, rng=np.random.default_rng(seed))

    kernel, numpy_ = side_by_side(make_large, args.ticks, max(1, args.rounds // 2))
    print(f"{len(healthy)} healthy around {len(failed)} failures, K=2, n=20, {args.ticks} ticks:")
    print(f"  kernel {kernel * 1e3:.3f} ms, NumPy {numpy_ * 1e3:.3f} ms ({numpy_ / kernel:.1f}x)   (goal <= 10 ms)")


if __name__ == "__main__":
    main()
