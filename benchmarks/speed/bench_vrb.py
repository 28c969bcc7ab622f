"""Benchmark: planning one VRB transformation segment for three robots (goal <= 1 ms).

The paper's C/MEX code planned "a segment of trajectory in less than 5 ms for the three
quadrotors" (section IV). One segment here is what is done at a switch: the Hungarian target
assignment of the next formation's slots plus the transformation law (integration of the
repelling field and the end-flat spline fit), for the air show's Phi^1_2 (line -> triangle, the
segment where the field acts most). Also reported: planning the whole show, and evaluating every
robot's flat outputs (p..snap, yaw) for one guidance tick, for 3 and 100 robots.

Run: /work/venv/bin/python benchmarks/speed/bench_vrb.py [--repeat 2000]
"""

from __future__ import annotations

import os

# Tiny arrays: threaded BLAS only adds hand-off latency (and spin-waits on a shared machine).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from swarmscene.methods.vrb.airshow import (  # noqa: E402
    AIRSHOW_LAW,
    airshow_formations,
    airshow_keyframes,
    airshow_sequence,
)
from swarmscene.methods.vrb.trajectory import VRBTrajectory  # noqa: E402
from swarmscene.methods.vrb.transform import (  # noqa: E402
    FormationSequence,
    assign_targets,
    plan_flight,
    plan_transformation,
    robot_flat_outputs,
)


def timings(fn, repeat: int) -> tuple[list[float], float]:
    """Wall-clock seconds of each of ``repeat`` calls, and mean CPU seconds per call.

    CPU time (this process only) is reported beside wall time because the benchmark machine may be
    shared: other processes inflate wall time, not this process's CPU time.
    """
    fn()  # warm-up: caches of the grid operators
    out = []
    c0 = time.process_time()
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out, (time.process_time() - c0) / repeat


def report(name: str, measured: tuple[list[float], float], goal_ms: float | None = None) -> None:
    """Print one timing line: wall median, min and p90, CPU time, and the goal's verdict when one is given."""
    ts, cpu = measured
    ms = np.array(ts) * 1e3
    med = statistics.median(ms)
    line = (
        f"{name:<44s} wall median {med:8.3f} ms  min {ms.min():8.3f} ms  p90 "
        f"{np.percentile(ms, 90):8.3f} ms | cpu {cpu * 1e3:8.3f} ms"
    )
    if goal_ms is not None:
        line += f"  goal <= {goal_ms} ms: {'met' if min(med, cpu * 1e3) <= goal_ms else 'MISSED'}"
    print(line)


def main() -> None:
    """Time the VRB planning and flat outputs for 3 and 100 robots, then the 100-quadrotor flight."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2000)
    ap.add_argument("--flight", type=float, default=30.0,
                    help="simulated seconds of the 100-quadrotor flight at 240 Hz (0: skip)")
    args = ap.parse_args()

    slots = airshow_formations()
    seq = airshow_sequence()
    t0, t1 = seq.phase_bounds()[1:3]
    r_from = slots[0]

    def one_segment():
        perm = assign_targets(r_from, slots[1])
        return plan_transformation(r_from, slots[1][perm], t0, t1, AIRSHOW_LAW)

    seg = one_segment()
    print(f"segment Phi^1_2: {seg.duration:.1f} s, {AIRSHOW_LAW.steps(seg.duration)} steps, "
          f"min distance {seg.min_distance():.3f} m (s_i + s_j = 0.6 m)")
    report("plan one transformation segment, 3 robots", timings(one_segment, args.repeat), 1.0)
    report("plan the whole show (5 segments)", timings(lambda: plan_flight(seq, AIRSHOW_LAW), 200))
    report("build the VRB trajectory (30 keyframes)", timings(lambda: VRBTrajectory(airshow_keyframes()), 20))

    traj = VRBTrajectory(airshow_keyframes())
    flight = plan_flight(seq, AIRSHOW_LAW)
    tick = np.array([3.3])  # inside Phi^1_2
    report("flat outputs, one tick, 3 robots", timings(lambda: robot_flat_outputs(traj, flight, tick), args.repeat))

    # 100 robots: a 10 x 10 grid morphing into a ring in the VRB frame, spacing 0.7 m
    g = 0.7 * np.stack(np.meshgrid(np.arange(10.0), np.arange(10.0)), -1).reshape(-1, 2)
    grid = np.c_[g - g.mean(0), np.zeros(100)]
    ang = 2 * np.pi * np.arange(100) / 100
    ring = np.c_[12.0 * np.cos(ang), 12.0 * np.sin(ang), np.zeros(100)]
    big = FormationSequence(np.stack([grid, ring]), np.array([5.0, 5.0]), np.array([8.0]), 0.0)
    big_flight = plan_flight(big, AIRSHOW_LAW)
    report("plan one segment, 100 robots", timings(lambda: plan_flight(big, AIRSHOW_LAW), 20))
    big_tick = np.array([9.0])
    ts = timings(lambda: robot_flat_outputs(traj, big_flight, big_tick), 500)
    report("flat outputs, one tick, 100 robots", ts)
    print(f"  -> setpoint generation alone allows {1.0 / max(ts[1], 1e-9):.0f} ticks/s of CPU "
          f"(240 Hz guidance needs 240)")
    if args.flight > 0:
        flight_100(args.flight)


SHOW_100 = {
    # A 10 x 10 grid 1.5 m apart: horizontal -> vertical wall (x-z plane of the body) -> horizontal,
    # while the body climbs, turns 90 degrees and banks 30 degrees (sized for 100 small quadrotors).
    "name": "virtual_rigid_body",
    "preset": "custom",
    "keyframes": [
        {"t": 0.0, "pos": [0.0, 0.0, 10.0], "euler_deg": [0.0, 0.0, 0.0]},
        {"t": 10.0, "pos": [8.0, 2.0, 12.0], "euler_deg": [30.0, 0.0, 45.0]},
        {"t": 20.0, "pos": [12.0, 10.0, 12.0], "euler_deg": [0.0, 0.0, 90.0]},
        {"t": 30.0, "pos": [12.0, 20.0, 10.0], "euler_deg": [0.0, 0.0, 90.0]},
    ],
    "formations": [
        {"shape": "grid", "spacing": 1.5, "plane": "xy", "duration": 4.0},
        {"shape": "grid", "spacing": 1.5, "plane": "xz", "duration": 6.0},
        {"shape": "grid", "spacing": 1.5, "plane": "xy", "duration": 4.0},
    ],
    "transformation_duration": 8.0,
}


def flight_100(duration: float) -> None:
    """100 quadrotors fly a VRB show (``SHOW_100``) at 240 Hz through the API."""
    from swarmscene import api
    from swarmscene.builtins import BUILTIN_PLUGINS
    from swarmscene.core.registry import make_plugin_manager
    from swarmscene.core.simulation import Simulation

    modules = tuple(dict.fromkeys((*BUILTIN_PLUGINS, "swarmscene.plugins.formation.virtual_rigid_body",
                                   "swarmscene.plugins.dynamics.quadrotor")))
    pm, registry = make_plugin_manager(modules, load_entry_points=False)
    data = api.compose(["swarm=grid", "swarm.n=100", "swarm.start.spacing=1.5",
                        "swarm.start.center=[0.0,0.0,10.0]", "environment=open", "avoidance=none"])
    data["formation"] = SHOW_100
    data["dynamics"] = {"name": "quadrotor"}
    data["clock"] = {"guidance_period": 1.0 / 240.0, "physics_step": 1.0 / 240.0, "duration": duration}
    data["output"]["progress"] = "off"
    sim = Simulation(api.load(data, registry), pm, registry.observers)
    c0 = time.process_time()
    m = sim.run().metrics
    cpu = time.process_time() - c0
    print(f"100 quadrotors, VRB show, 240 Hz, {m['duration']:.0f} s simulated: wall {m['wall_time']:.1f} s, "
          f"real-time factor {m['realtime_factor']:.2f} (cpu-time factor {m['duration'] / cpu:.2f}), "
          f"tick median {m['step_ms_median']:.2f} ms, tracking rms {m['vrb.tracking_rms'] * 1e3:.3f} mm, "
          f"min distance in transformations {m['vrb.min_transformation_distance']:.2f} m")


if __name__ == "__main__":
    main()
