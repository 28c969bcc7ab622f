"""Time the thesis' outdoor mission (scenario ``outdoor_square``, section 4.5.2) with N = 100.

Goal (issue 5): at least 50x real time on one core, the whole mission (INIT, FORM, following
the square path, every follower home) through the engine (kernel, double-integrator dynamics
with the thesis controllers, safety monitors), the run ending on ``termination.on_complete``.

N = 100 do not fit on the thesis' 1.5 m line sensibly (150 m long), so they start on a grid
d_i = 1.5 m apart (still closer than d_c: the hard start), the leader at a corner (agent 0),
with the communication range covering the swarm (``--comm-range``; a shorter one makes the
maps multi-hop). Wall time (``perf_counter``) and this process's CPU time (``process_time``,
robust when other processes share the cores) are both reported for the run alone.

    python benchmarks/speed/bench_outdoor.py [--n 100] [--comm-range 200] [--start grid]
"""

from __future__ import annotations

import argparse
import time

from swarmscene import api


def main() -> None:
    """Fly outdoor_square once and print its mission times, safety figures and real-time factor."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100)
    parser.add_argument("--comm-range", type=float, default=200.0)
    parser.add_argument("--start", default="grid", choices=["grid", "line"])
    parser.add_argument("--duration", type=float, default=900.0, help="upper bound, s")
    args = parser.parse_args()

    sim = api.build([
        "scenario=outdoor_square", f"swarm.n={args.n}", "swarm.leader=0",
        f"swarm.start.layout={args.start}", f"comm.range={args.comm_range}",
        f"clock.duration={args.duration}", "output.progress=off", "output.summary=false",
        "output.trajectory=false",
    ])
    wall0, cpu0 = time.perf_counter(), time.process_time()
    result = sim.run()
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    m = result.metrics
    simulated = m["duration"]
    print(f"outdoor_square, N = {args.n} ({args.start} start, d_com = {args.comm_range:g} m)")
    print(f"  simulated {simulated:.1f} s in {m['steps']} ticks, stop: {result.stop_reason}, "
          f"mission complete: {m['outdoor.mission_complete']}")
    print(f"  formed/departed {m['outdoor.departed_at']:.1f} s, path done {m['outdoor.path_done_at']:.1f} s, "
          f"last home {m['outdoor.last_home_at']:.1f} s, ignored {len(m['outdoor.ignored'])}")
    print(f"  min separation {m['min_separation']:.2f} m, collisions {m['collisions']}, "
          f"mean neighbour distance {m['outdoor.mean_neighbour_distance']:.2f} m, "
          f"tracking error {m['outdoor.tracking_error_mean']:.2f} m")
    print(f"  assignment solves {m['outdoor.assignment_solves']}")
    print(f"  wall {wall:.2f} s -> {simulated / wall:.1f}x real time; "
          f"CPU {cpu:.2f} s -> {simulated / cpu:.1f}x real time (goal >= 50x)")


if __name__ == "__main__":
    main()
