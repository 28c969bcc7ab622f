"""Paper scenarios under declared disturbances (issue #18): safety, separation, tracking, seeds.

    python benchmarks/reproduction/bench_resilience.py                 # every table, 30 seeds, 2 processes
    python benchmarks/reproduction/bench_resilience.py --only wind --seeds 5
    python benchmarks/reproduction/bench_resilience.py --markdown      # tables for docs/benchmarks.md

Tables:

* ``wind``: cem_six_vehicle under Dryden turbulence (``+disturbances=[dryden]``) at a mean wind of
  0 / 2 / 5 / 8 m/s (``disturbances.dryden.speed``), with single_integrator and quadrotor dynamics.
* ``loss``: cem_six_vehicle with Bernoulli packet loss (``+disturbances=[packet_loss]``) of
  0 / 10 / 30 % (``disturbances.packet_loss.p``), both dynamics models.
* ``delay``: outdoor_square with the engine's hop-proportional delay model (``comm_delay``) at
  tau_com = 0.1 / 0.2 / 0.5 s: formation (tracking) error and completion time.

Each cell runs seeds 0..n-1 through ``swarmscene.api.run`` (worker processes, each distinct run
once: the runner of benchmarks/reproduction/reproduce.py) and reports the safe fraction (no collision, no
clearance violation: the monitors judge the true state), the success rate, the worst and mean
minimum separation and the tracking error with its 95 % interval.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from reproduce import Job, run_jobs  # noqa: E402  (the report's runner: one process per worker)

from swarmscene.sweeps.stats import mean_ci, wilson  # noqa: E402

DYNAMICS = ("single_integrator", "quadrotor")
CEM = ["scenario=cem_six_vehicle"]


def cases(only: list[str]) -> dict[str, list[tuple[str, list[str]]]]:
    """Table name -> [(row label, overrides)]."""
    tables = {
        "wind": [(f"{dyn}, Dryden {v:g} m/s", [*CEM, f"dynamics={dyn}", "+disturbances=[dryden]",
                                                f"disturbances.dryden.speed={v}"])
                 for dyn in DYNAMICS for v in (0, 2, 5, 8)],
        "loss": [(f"{dyn}, loss {p:.0%}", [*CEM, f"dynamics={dyn}", "+disturbances=[packet_loss]",
                                           f"disturbances.packet_loss.p={p}"])
                 for dyn in DYNAMICS for p in (0.0, 0.1, 0.3)],
        "delay": [(f"tau_com {tau:g} s", ["scenario=outdoor_square", "+disturbances=[comm_delay]",
                                          f"disturbances.comm_delay.tau={tau}"])
                  for tau in (0.1, 0.2, 0.5)],
    }
    return {k: v for k, v in tables.items() if not only or k in only}


def row(label: str, runs: list[dict]) -> dict:
    """One table row from the runs of one cell."""
    safe = [m.get("collisions", 0) == 0 and m.get("clearance_violations", 0) == 0 for m in runs]
    success = [bool(m.get("success")) for m in runs]
    sep = [m["min_separation"] for m in runs if m.get("min_separation") is not None]
    track_key = "cem.tracking_error_max" if "cem.tracking_error_max" in runs[0] else "outdoor.tracking_error_max"
    track = [m[track_key] for m in runs if m.get(track_key) is not None]
    done = [m["duration"] for m in runs if m.get("success")]
    return {
        "label": label, "runs": len(runs),
        "safe": (sum(safe), wilson(sum(safe), len(runs))),
        "success": (sum(success), wilson(sum(success), len(runs))),
        "min_sep_worst": min(sep) if sep else math.nan,
        "min_sep_mean": mean_ci(sep),
        "tracking": mean_ci(track),
        "tracking_worst": max(track) if track else math.nan,
        "completion": mean_ci(done),
    }


def _rate(count_ci: tuple[int, tuple[float, float]], n: int) -> str:
    count, (lo, hi) = count_ci
    return f"{count}/{n} [{100 * lo:.0f}, {100 * hi:.0f} %]"


def _mean(ci: tuple[float, float, int], digits: int = 3) -> str:
    mean, half, n = ci
    if n == 0:
        return "n/a"
    return f"{mean:.{digits}f}" + (f" ± {half:.{digits}f}" if math.isfinite(half) and half > 0 else "")


def markdown(table: str, rows: list[dict]) -> str:
    """One case table's rows (:func:`row`) as a markdown table headed by the table's name."""
    lines = [f"| {table} | runs | safe (95 % CI) | success | worst min sep (m) | mean min sep (m) | "
             "tracking error max (m), mean ± CI | worst tracking (m) | completion (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['label']} | {r['runs']} | {_rate(r['safe'], r['runs'])} | {_rate(r['success'], r['runs'])} | "
            f"{r['min_sep_worst']:.3f} | {_mean(r['min_sep_mean'])} | {_mean(r['tracking'])} | "
            f"{r['tracking_worst']:.3f} | {_mean(r['completion'], 1)} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run every case's seeds (cached, in parallel) and print each table; the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", nargs="*", default=[], choices=["wind", "loss", "delay"])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--cache", type=Path, default=None, help="directory keeping finished runs")
    parser.add_argument("--markdown", action="store_true", help="print markdown tables")
    args = parser.parse_args(argv)
    tables = cases(args.only)
    jobs = {label: [Job(overrides=tuple(o), seed=s) for s in range(args.seeds)]
            for cells in tables.values() for label, o in cells}
    results = run_jobs([j for js in jobs.values() for j in js], args.jobs, args.cache)
    for name, cells in tables.items():
        rows = [row(label, [results[j.key] for j in jobs[label]]) for label, _ in cells]
        if args.markdown:
            print(markdown(name, rows), end="\n\n")
        else:
            for r in rows:
                print(name, r)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
