"""Engine benchmark runner: agents, steps/s, agent-steps/s, real-time factor, peak memory.

    python benchmarks/speed/run.py            # every case below
    python benchmarks/speed/run.py default    # cases whose name contains "default"

Each case is a scenario (Hydra overrides) run in a fresh process (so peak memory is the case's
own) pinned to one core where the OS allows it. Figures are measurements on this machine, printed
beside the goal of the issue that set it; nothing here is asserted in the test suite.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

ONE_K = [
    "swarm=grid", "swarm.n=1000", "environment=open", "formation.shape=grid",
    "formation.waypoints=[[500,0,2]]", "clock.physics_step=null", "clock.duration=20",
    "termination.on_complete=false", "output.trajectory=false",
]
CASES: dict[str, tuple[list[str], str]] = {
    "default": ([], ""),
    "1k_double_integrator_static_shape_potential": (ONE_K, ">= 500 guidance steps/s (issue 2)"),
    "cem_six_vehicle": (["scenario=cem_six_vehicle"], ""),
}

CHILD = r"""
import json, resource, sys, time
from swarmscene import api
sim = api.build(json.loads(sys.argv[1]))
start = time.perf_counter()
result = sim.run()
wall = time.perf_counter() - start
m = result.metrics
print(json.dumps({
    "agents": m["agents"], "steps": m["steps"], "wall": wall,
    "steps_per_s": m["steps"] / wall, "agent_steps_per_s": m["steps"] * m["agents"] / wall,
    "realtime_factor": m["duration"] / wall, "step_ms_median": m["step_ms_median"],
    "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
}))
"""


def run_case(overrides: list[str]) -> dict:
    """One case's figures (steps/s, real-time factor, peak memory), measured in a child process."""
    cmd = [sys.executable, "-c", CHILD, json.dumps(overrides)]
    if hasattr(os, "sched_setaffinity"):
        cmd = ["taskset", "-c", "0", *cmd] if _has_taskset() else cmd
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def _has_taskset() -> bool:
    return subprocess.run(["which", "taskset"], capture_output=True).returncode == 0


def cli_start_to_summary(repeats: int = 3) -> float:
    """Best wall time of `swarmscene` (default scenario) from command to summary, s."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(
            [sys.executable, "-c", "from swarmscene.cli import main; main()",
             "hydra.run.dir=/tmp/swarmscene-bench-run"],
            check=True, capture_output=True,
        )
        best = min(best, time.perf_counter() - start)
    return best


def main(selected: list[str]) -> None:
    """Print a row per case whose name contains a ``selected`` word (all when empty), then the CLI's time."""
    header = (f"{'case':48} {'agents':>7} {'steps/s':>9} {'agent-steps/s':>14} {'RTF':>8} {'ms/step':>8} "
              f"{'peak MiB':>9}  goal")
    print(header)
    for name, (overrides, goal) in CASES.items():
        if selected and not any(s in name for s in selected):
            continue
        r = run_case(overrides)
        print(
            f"{name:48} {r['agents']:7d} {r['steps_per_s']:9.0f} {r['agent_steps_per_s']:14.0f} "
            f"{r['realtime_factor']:8.1f} {r['step_ms_median']:8.3f} {r['peak_mib']:9.0f}  {goal}"
        )
    if not selected or any("cli" in s for s in selected):
        print(f"swarmscene (default scenario), command to summary: {cli_start_to_summary():.2f} s  "
              "(goal < 3 s, issue 2)")


if __name__ == "__main__":
    main(sys.argv[1:])
