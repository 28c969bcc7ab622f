"""The command line's fixed cost: ``swarmscene clock.duration=0.1`` beside a bare Hydra app.

Three commands, each a fresh process, run in turn (alternating, so a noisy neighbour hits all
three alike), ``--repeat`` times; the best wall time of each is shown, and the ratios:

    interpreter   python -c pass
    bare Hydra    an empty @hydra.main task over the same config tree (pkg://swarmscene.scenarios,
                  config.yaml with its defaults list, overrides and callbacks), as Hydra alone costs
    swarmscene    the default scenario for 0.1 s: compose, validate, build, one tick, write outputs

    python benchmarks/speed/bench_startup.py [--repeat 15] [--json]

Goal (issue #20): swarmscene <= 0.6 s. The run directories go to a temporary folder.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

BARE_HYDRA = """
import hydra
@hydra.main(version_base=None, config_path="pkg://swarmscene.scenarios", config_name="config")
def app(cfg):
    pass
app()
"""


def commands(run_dir: str) -> dict[str, list[str]]:
    """The commands timed: an empty interpreter, a bare Hydra app and a 0.1 s swarmscene run."""
    swarmscene = os.path.join(os.path.dirname(sys.executable), "swarmscene")
    return {
        "interpreter": [sys.executable, "-c", "pass"],
        "bare Hydra": [sys.executable, "-c", BARE_HYDRA, f"hydra.run.dir={run_dir}/hydra"],
        "swarmscene": [swarmscene, "clock.duration=0.1", f"hydra.run.dir={run_dir}/swarmscene"],
    }


def measure(repeat: int) -> dict[str, float]:
    """Each command's shortest wall time (s) over ``repeat`` alternating rounds, after one untimed run each."""
    best: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as run_dir:
        cmds = commands(run_dir)
        for cmd in cmds.values():  # one untimed run each: .pyc files and disk caches warm
            subprocess.run(cmd, check=True, capture_output=True)
        for _ in range(repeat):
            for name, cmd in cmds.items():
                start = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True)
                best[name] = min(best.get(name, float("inf")), time.perf_counter() - start)
    return best


def main() -> None:
    """Print each command's best start-up time and swarmscene's ratio to bare Hydra (or them as JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    best = measure(args.repeat)
    result = {
        **{f"{k}_s": round(v, 4) for k, v in best.items()},
        "swarmscene_over_bare_hydra": round(best["swarmscene"] / best["bare Hydra"], 3),
        "goal_s": 0.6,
    }
    if args.json:
        print(json.dumps(result))
        return
    print(f"best of {args.repeat}, alternating:")
    for name, seconds in best.items():
        print(f"  {name:<12} {seconds:6.3f} s")
    print(f"  swarmscene / bare Hydra = {result['swarmscene_over_bare_hydra']:.2f} (goal: swarmscene <= 0.6 s)")


if __name__ == "__main__":
    main()
