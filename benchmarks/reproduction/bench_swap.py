"""Every built-in avoidance on the antipodal swap (issue #14): collisions, separation, arrival, speed.

The swap preset (scenarios/scenario/swap.yaml): N agents on a ring fly to the opposite slot through
the centre at 1 m/s, safety.separation_limit = 0.56 m. Each avoidance runs with its own defaults
(nothing tuned here), for N in {8, 16, 32, 100} under single_integrator and double_integrator, and
N = 8 under quadrotor. The ring radius is the preset's R = 6 m, except R = 16 m for N = 100 (at
6 m the start slots would be 0.38 m apart, closer than the safety distance; at 16 m they are 1.0 m).

Columns: collisions (distinct pairs ever closer than 0.56 m), minimum separation (m), completion
time (s; "no" when not every agent reached its goal within the duration, 120 s), median wall
time of one guidance tick (ms, the whole tick: sensing, formation, avoidance, control, physics,
monitors), and the fallback count of orca and cbf (agent-ticks where their programme was infeasible).

    OMP_NUM_THREADS=1 python benchmarks/reproduction/bench_swap.py [--n 8 16 32 100] [--avoidance orca cbf]
"""

from __future__ import annotations

import argparse
import os
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from swarmscene import api  # noqa: E402

AVOIDANCES = ("none", "potential", "cem", "apf_navigation", "potential_barrier", "orca", "cbf")
NOTES = {
    "none": "pass-through",
    "cem": "acts around failed vehicles only (none here): pass-through",
    "apf_navigation": "thesis ch. 4 navigation, its d_c = 1.65 m",
    "potential_barrier": "thesis ch. 5 terms, tuned for T_s = 10 ms",
}
DURATION = 120.0


def ring_radius(n: int) -> float:
    """The start ring's radius (m) for ``n`` agents: a wider ring above 32."""
    return 6.0 if n <= 32 else 16.0


def run(avoidance: str, dynamics: str, n: int) -> dict:
    """One swap run's metrics and its wall time (``wall``), or its ``error`` when the method cannot run it."""
    overrides = ["scenario=swap", f"avoidance={avoidance}", f"dynamics={dynamics}", f"swarm.n={n}",
                 f"swarm.start.radius={ring_radius(n)}", f"clock.duration={DURATION}",
                 "output.progress=off", "output.trajectory=false"]
    t0 = time.perf_counter()
    try:
        m = api.run(overrides).metrics
    except Exception as exc:  # noqa: BLE001 - a method that cannot run the swap is a row too
        return {"error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    m["wall"] = time.perf_counter() - t0
    return m


def row(avoidance: str, dynamics: str, n: int, m: dict) -> str:
    """The swap table's markdown row of one run: its outcome, or why it could not run."""
    if "error" in m:
        return f"| {avoidance} | {dynamics} | {n} | {ring_radius(n):g} | cannot run: {m['error']} | | | | |"
    done = f"{m['duration']:.1f}" if m["stop_reason"] == "complete" else "no"
    fallback = m.get(f"{avoidance}.fallback_ticks", "")
    note = NOTES.get(avoidance, "")
    return (f"| {avoidance} | {dynamics} | {n} | {ring_radius(n):g} | {m['collisions']} | "
            f"{m['min_separation']:.3f} | {done} | {m['step_ms_median']:.2f} | {fallback} | {note} |")


def time_adjust(avoidance: str, n: int, calls: int = 50) -> tuple[float, float]:
    """Median ms of one ``adjust`` (neighbour table, half-planes, the lock-step programmes, setpoint
    copy) on a jammed crowd (a jittered lattice 0.9 m apart), random velocities; and the
    share of agents whose programme was infeasible (fallback) there."""
    import numpy as np

    from swarmscene.core.sensing import Sensing
    from swarmscene.core.setpoint import Mode

    sim = api.build(["scenario=swap", f"avoidance={avoidance}", f"swarm.n={n}",
                     f"swarm.start.radius={max(6.0, n * 0.7 / 6.0)}", "output.progress=off"])
    rng = np.random.default_rng(0)
    # a hexagonal lattice 0.9 m apart, the n sites nearest the centre, each jittered by up to 0.1 m
    # per axis: neighbours 0.62 m apart at least, about one agent per 0.7 m^2 (a jam)
    k = int(np.sqrt(n)) + 3
    a, b = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1))
    lattice = 0.9 * np.column_stack([a.ravel() + 0.5 * b.ravel(), np.sqrt(3) / 2 * b.ravel()])
    pos = lattice[np.argsort(np.hypot(*lattice.T))[:n]] + rng.uniform(-0.1, 0.1, (n, 2))
    sim.world.pos[:, :2] = pos
    sim.world.vel[:, :2] = rng.uniform(-0.7, 0.7, (n, 2))
    sensing = Sensing(sim.world, sim.environment, sim.config.comm.range)
    sp = sim.formation.setpoints(sim.world, sensing)
    assert (sp.mode == Mode.VELOCITY).all()
    plugin = sim.avoidance
    samples = []
    for _ in range(calls):
        t0 = time.perf_counter()
        plugin.adjust(sim.world, sensing, sp)
        samples.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(samples)), plugin.fallback_ticks / (calls * n)


def main() -> None:
    """Print the swap table over methods, dynamics and sizes (or only the adjust() timings, ``--adjust-only``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[8, 16, 32, 100])
    parser.add_argument("--avoidance", nargs="+", default=list(AVOIDANCES))
    parser.add_argument("--no-quadrotor", action="store_true", help="skip the N = 8 quadrotor rows")
    parser.add_argument("--adjust-only", action="store_true",
                        help="only time orca's and cbf's adjust() on a jammed crowd of 100 and 1000")
    args = parser.parse_args()
    if args.adjust_only:
        print("| avoidance | N | adjust (ms, median) | agents in fallback |")
        print("|---|---|---|---|")
        for avoidance in ("orca", "cbf"):
            for n in (100, 1000):
                ms, share = time_adjust(avoidance, n)
                print(f"| {avoidance} | {n} | {ms:.2f} | {100 * share:.0f} % |", flush=True)
        return
    cases = [(d, n) for d in ("single_integrator", "double_integrator") for n in args.n]
    if not args.no_quadrotor:
        cases.append(("quadrotor", 8))
    print("| avoidance | dynamics | N | R (m) | collisions | min separation (m) | complete at (s) "
          "| tick (ms) | fallbacks | note |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for dynamics, n in cases:
        for avoidance in args.avoidance:
            print(row(avoidance, dynamics, n, run(avoidance, dynamics, n)), flush=True)


if __name__ == "__main__":
    main()
