"""What ``output.mcap=true`` costs: run wall time with and without the bag, and its memory.

Overhead: the same scenario run with and without ``output.mcap=true`` (``api.run`` into a fresh run
directory, outputs written: the run's wall time as a user sees it), in alternating pairs so a noisy
neighbour hits both alike; the ratio of the medians, of wall time and of the process's CPU time
(every thread: the bag's writer thread included; steadier than wall time on a loaded machine).
/tf, /clock, every vehicle's odometry and the separation go into the bag at every guidance tick.
Also the bag writer's own cost per tick (``BagWriter.frame`` alone, N vehicles).

Memory: Python's peak allocations (tracemalloc) of a run with and without the bag, for two run
lengths (the trajectory off, so the record does not grow either): the bag's share must not grow
with the run (it is streamed to disk a 4 MiB chunk at a time).

    python benchmarks/speed/bench_mcap.py [--pairs 5] [--n 100] [--json]

Goal (issue #39): overhead <= 5 % of the run's wall time at N = 100, /tf at the guidance rate;
memory flat in the run's length.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np


def scenarios(n: int) -> dict[str, list[str]]:
    """The runs timed: the antipodal swap with ORCA (10 Hz guidance) and the default mission."""
    quiet = ["output.summary=false", "output.progress=off"]
    return {
        "swap + orca, 60 s at 10 Hz": ["scenario=swap", f"swarm.n={n}", "swarm.start.radius=30",
                                       "clock.duration=60", *quiet],
        "default mission, 60 s at 10 Hz": [f"swarm.n={n}", "clock.duration=60", *quiet],
    }


def timed_run(overrides: list[str], base: Path, bag: bool) -> tuple[float, float]:
    """(wall s, CPU s of this process, every thread) of one run with its outputs."""
    from swarmscene import api

    run_dir = Path(tempfile.mkdtemp(dir=base))
    start, cpu = time.perf_counter(), time.process_time()
    api.run([*overrides, f"output.mcap={str(bag).lower()}"], output_dir=run_dir / "run")
    return time.perf_counter() - start, time.process_time() - cpu


def overhead(overrides: list[str], pairs: int) -> dict[str, float]:
    """Medians of wall and CPU time with and without the bag, and their ratios (module docstring)."""
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        timed_run(overrides, base, True)  # kernels compiled, caches warm
        plain, bagged = [], []
        for k in range(pairs):  # alternating, the order flipped each pair
            first = k % 2 == 0
            for bag in (first, not first):
                (bagged if bag else plain).append(timed_run(overrides, base, bag))
    wall = [statistics.median(w for w, _ in runs) for runs in (plain, bagged)]
    cpu = [statistics.median(c for _, c in runs) for runs in (plain, bagged)]
    return {"plain_median_s": wall[0], "bag_median_s": wall[1], "ratio": wall[1] / wall[0],
            "plain_cpu_s": cpu[0], "bag_cpu_s": cpu[1], "cpu_ratio": cpu[1] / cpu[0], "pairs": pairs}


def writer_per_tick(n: int, ticks: int = 2000) -> float:
    """us per ``BagWriter.frame`` of N vehicles (clock, /tf, odometry, separation)."""
    from swarmscene.views.mcap_bag import BagWriter

    rng = np.random.default_rng(0)
    pos, vel = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    with tempfile.TemporaryFile() as fh:
        writer = BagWriter(fh, {"safety": {"separation_limit": 0.5}}, n)
        start = time.perf_counter()
        for k in range(ticks):
            writer.frame(0.1 * k, pos, vel, None, 1.0)
        writer.finish()
        return (time.perf_counter() - start) / ticks * 1e6


def peak_memory(n: int, duration: float, bag: bool) -> tuple[int, int]:
    """(tracemalloc's peak during one run (trajectory off), bytes; the bag's size, bytes)."""
    from swarmscene import api

    overrides = ["scenario=swap", f"swarm.n={n}", "swarm.start.radius=30", f"clock.duration={duration}",
                 "termination.on_complete=false",  # the whole duration, however soon the swap ends
                 "output.summary=false", "output.progress=off", "output.trajectory=false",
                 f"output.mcap={str(bag).lower()}"]
    with tempfile.TemporaryDirectory() as tmp:
        tracemalloc.start()
        api.run(overrides, output_dir=Path(tmp) / "run")
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        size = sum(p.stat().st_size for p in (Path(tmp) / "run" / "bag").glob("*")) if bag else 0
    return peak, size


def main() -> None:
    """Time runs with and without ``output.mcap``, pairs alternately, and measure memory over run length."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--n", type=int, default=100)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    out: dict[str, object] = {"n": args.n, "load": os.getloadavg()}
    for name, overrides in scenarios(args.n).items():
        out[name] = overhead(overrides, args.pairs)
        print(f"{name}: {out[name]}", file=sys.stderr)
    out["writer_us_per_tick"] = writer_per_tick(args.n)
    print(f"BagWriter.frame, N = {args.n}: {out['writer_us_per_tick']:.0f} us", file=sys.stderr)
    memory = {}
    peak_memory(args.n, 5.0, True)  # compiled, imported
    for duration in (60.0, 240.0):
        (with_bag, size), (without, _) = peak_memory(args.n, duration, True), peak_memory(args.n, duration, False)
        memory[f"{duration:g} s"] = {"with_bag_mib": with_bag / 2**20, "without_mib": without / 2**20,
                                     "bag_share_mib": (with_bag - without) / 2**20, "bag_file_mib": size / 2**20}
        print(f"peak memory, {duration:g} s: {memory[f'{duration:g} s']}", file=sys.stderr)
    out["memory"] = memory
    out["load_after"] = os.getloadavg()
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for name in scenarios(args.n):
            r = out[name]
            print(f"{name}: wall {r['plain_median_s']:.2f} s plain, {r['bag_median_s']:.2f} s with the bag "  # type: ignore[index]
                  f"(x{r['ratio']:.3f}); CPU {r['plain_cpu_s']:.2f} s, {r['bag_cpu_s']:.2f} s "  # type: ignore[index]
                  f"(x{r['cpu_ratio']:.3f})")  # type: ignore[index]
        for duration, m in memory.items():
            print(f"peak memory {duration}: {m['with_bag_mib']:.1f} MiB with the bag, {m['without_mib']:.1f} without "
                  f"(the bag's share {m['bag_share_mib']:.1f} MiB; the bag {m['bag_file_mib']:.0f} MiB on disk)")


if __name__ == "__main__":
    main()
