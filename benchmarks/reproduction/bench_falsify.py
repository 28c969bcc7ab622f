"""The falsifier against random search with the same budget (issue #18, docs/sweeps.md).

For each search space (``full``: ``+sweep=falsify``, wind, packet loss and a failure; ``failure``:
``+sweep=falsify_failure``, the failure alone), scenario and sampler seed, one study with Optuna's
TPE (the falsifier) and one with Optuna's RandomSampler, each ``--trials`` runs, one after the
other in a child process (the machine's cores are shared: no two studies at once). Each study is
the command a user types; its worst case is read back from ``worst_case.json``. Reported per study:
the worst minimum separation found, its robustness rho = min_separation - separation_limit (m,
negative: a counter-example), how many trials it took to the first violation (the budget a sampler
needed to find a counter-example; TPE's first 10 trials are random, drawn as the RandomSampler of
the same seed draws them), how many of its trials violated, and its wall time; then per space,
scenario and sampler, over the seeds, the median and range of the worst case and how many seeds
found a violation.

    # 2 spaces x 2 scenarios x 3 seeds x 2 samplers x 100 trials:
    python benchmarks/reproduction/bench_falsify.py
    python benchmarks/reproduction/bench_falsify.py --spaces failure --seeds 0 --trials 20 --scenarios cem_six_vehicle
    python benchmarks/reproduction/bench_falsify.py --json results.json      # the rows, for docs/benchmarks.md

Studies are written under ``--out`` (default ``multirun/bench_falsify``); running the same command
again resumes them (every trial already complete for the same config is skipped, and the seeded
samplers ask for the same trials again).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
SPACES = {"full": "falsify", "failure": "falsify_failure"}
"""the search spaces: wind, packet loss and a failure (+sweep=falsify), or the failure alone"""
SAMPLERS = ("tpe", "random")
"""hydra/sweeper/sampler=...: the falsifier, and its baseline"""


def study(space: str, scenario: str, sampler: str, seed: int, trials: int, out: Path, extra: list[str]) -> dict:
    """Run one study (the command line, in a child process) and return its worst case record."""
    directory = out / space / scenario / f"{sampler}_seed{seed}"
    command = [*EXE, f"+sweep={SPACES[space]}", f"hydra/sweeper/sampler={sampler}", f"scenario={scenario}",
               f"hydra.sweeper.n_trials={trials}",
               f"hydra.sweeper.sampler.seed={seed}", f"hydra.sweep.dir={directory}", "output.trajectory=false",
               "hydra.callbacks.swarmscene_summary.progress=off", *extra]
    started = time.perf_counter()
    proc = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if proc.returncode != 0:
        raise SystemExit(f"bench_falsify: {' '.join(command[3:])} failed:\n{proc.stderr[-2000:]}")
    record = json.loads((directory / "worst_case.json").read_text())
    return {
        "space": space, "scenario": scenario, "sampler": sampler, "seed": seed, "trials": record["trials"],
        "worst_min_separation": record["min_separation"], "robustness": record["robustness"],
        "violated": record["violated"], "first_violating_trial": record["first_violating_trial"],
        "violating_trials": record["violating_trials"], "first_violation": record["first_violation"],
        "worst_overrides": [o for o in record["overrides"] if o.lstrip("+").startswith(("events.", "disturbances."))],
        "failed_trials": len(record["failed"]), "wall_s": round(wall, 1), "study": str(directory),
    }


def summary(rows: list[dict]) -> list[dict]:
    """Per scenario and sampler, over the seeds: the worst case's median and range, violations."""
    out = []
    for space, scenario in dict.fromkeys((r["space"], r["scenario"]) for r in rows):
        for sampler in SAMPLERS:
            group = [r for r in rows if (r["space"], r["scenario"], r["sampler"]) == (space, scenario, sampler)]
            if not group:
                continue
            worst = [r["worst_min_separation"] for r in group]
            firsts = [r["first_violating_trial"] + 1 for r in group if r["first_violating_trial"] is not None]
            out.append({
                "space": space, "scenario": scenario, "sampler": sampler, "seeds": len(group),
                "median_worst": statistics.median(worst), "min_worst": min(worst), "max_worst": max(worst),
                "seeds_violated": sum(r["violated"] for r in group),
                "median_trials_to_violation": statistics.median(firsts) if firsts else None,
                "mean_violating_trials": statistics.fmean(r["violating_trials"] for r in group),
            })
    return out


SHORT = {"disturbances.constant_wind.speed": "wind {:.2f} m/s",
         "disturbances.constant_wind.heading": "toward {:.0f} deg",
         "disturbances.packet_loss.p": "loss {:.1%}", "events.0.agents.0": "agent {:.0f} fails",
         "events.0.at": "at {:.2f} s"}


def worst_case_text(overrides: list[str]) -> str:
    """The searched values of a worst case, short: ``wind 3.19 m/s, toward -83 deg, ...``."""
    values = dict(o.lstrip("+").split("=", 1) for o in overrides)
    text = ", ".join(SHORT[k].format(float(values[k])) if k in SHORT else f"{k}={values[k]}"
                     for k in sorted(values, key=lambda k: list(SHORT).index(k) if k in SHORT else len(SHORT)))
    return text.replace("fails, at", "fails at")


def markdown(rows: list[dict], groups: list[dict]) -> str:
    """The table of every study and the table of their groups (:func:`summary`), in markdown."""
    lines = ["| space | scenario | sampler | seed | worst min separation (mm) | robustness (m) "
             "| trials to the first violation | violating trials | worst case | wall (s) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        first = "-" if r["first_violating_trial"] is None else str(r["first_violating_trial"] + 1)
        lines.append(f"| {r['space']} | {r['scenario']} | {r['sampler']} | {r['seed']} "
                     f"| {1e3 * r['worst_min_separation']:.3g} | {r['robustness']:+.4f} | {first} "
                     f"| {r['violating_trials']}/{r['trials']} | {worst_case_text(r['worst_overrides'])} "
                     f"| {r['wall_s']:.0f} |")
    lines += ["", "| space | scenario | sampler | seeds | worst min separation: median (range), mm "
              "| seeds with a violation | median trials to the first violation | mean violating trials |",
              "|---|---|---|---|---|---|---|---|"]
    for g in groups:
        first = "-" if g["median_trials_to_violation"] is None else f"{g['median_trials_to_violation']:g}"
        lines.append(f"| {g['space']} | {g['scenario']} | {g['sampler']} | {g['seeds']} "
                     f"| {1e3 * g['median_worst']:.3g} ({1e3 * g['min_worst']:.3g} - {1e3 * g['max_worst']:.3g}) "
                     f"| {g['seeds_violated']}/{g['seeds']} "
                     f"| {first} | {g['mean_violating_trials']:.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Run every study (space x scenario x seed x sampler), print the markdown tables, write ``--json``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spaces", nargs="+", default=list(SPACES), choices=list(SPACES))
    parser.add_argument("--scenarios", nargs="+", default=["cem_six_vehicle", "outdoor_square"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--trials", type=int, default=100, help="budget of every study")
    parser.add_argument("--samplers", nargs="+", default=list(SAMPLERS), choices=SAMPLERS)
    parser.add_argument("--out", type=Path, default=Path("multirun/bench_falsify"))
    parser.add_argument("--json", type=Path, help="write the rows and the summary here")
    parser.add_argument("overrides", nargs="*", help="more overrides for every study (e.g. avoidance=orca)")
    args = parser.parse_args(argv)
    rows = []
    for space in args.spaces:
        for scenario in args.scenarios:
            for seed in args.seeds:
                for sampler in args.samplers:
                    rows.append(study(space, scenario, sampler, seed, args.trials, args.out, args.overrides))
                    print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    groups = summary(rows)
    print(markdown(rows, groups))
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "summary": groups}, indent=2) + "\n")


if __name__ == "__main__":
    main()
