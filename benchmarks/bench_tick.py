"""The engine's fixed cost per tick for small swarms: ``api.build``, then timed ``Simulation.step``.

    python benchmarks/bench_tick.py                        # this checkout, --repeat 5 rounds
    python benchmarks/bench_tick.py --baseline af87771     # and that commit, round by round
    python benchmarks/bench_tick.py --profile default      # where one case's tick goes (cProfile)
    python benchmarks/bench_tick.py --json

Cases (each round builds each afresh, in its own process):
    cem_six_vehicle   ``scenario=cem_six_vehicle``: 6 agents, CEM avoidance, single integrator
    default           the default scenario: 5 double integrators, potential field, one pillar
    swap              ``scenario=swap swarm.n=16 swarm.start.radius=8``: 16 agents, ORCA

A case runs as ``Simulation.run`` does (run-start hooks, then ticks until the duration, a stop or
the mission's completion: the whole run unless ``--ticks`` stops it earlier); each ``step()`` is
timed with ``perf_counter``, the first ``WARMUP`` untimed, so a case's median is the run's
``step_ms_median`` without the first ticks. A round's figure is the median tick of each case;
the table shows the median over rounds, its spread and, with ``--baseline``, the baseline's
figures measured in the same rounds (the two trees alternate, so a noisy neighbour hits both) and
the ratio of the medians. ``--baseline REV`` exports that commit (``git archive``) into a temporary
folder and imports ``swarmscene`` from it (its folders mapped to the packages as setup.py maps them).

Goals (issue #25, on the project machine): ``cem_six_vehicle`` <= 30 us, default <= 60 us.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES: dict[str, list[str]] = {
    "cem_six_vehicle": ["scenario=cem_six_vehicle"],
    "default": [],
    "swap": ["scenario=swap", "swarm.n=16", "swarm.start.radius=8"],
}
GOALS_US = {"cem_six_vehicle": 30.0, "default": 60.0}
WARMUP = 5
"""untimed ticks at the start of each case (first calls, caches)"""
PACKAGES = {"core": "core", "methods": "methods", "plugins": "plugins", "scenarios": "scenarios"}
"""swarmscene.<key> lives in the folder <value> of a checkout (setup.py's mapping)."""


def tick_times(overrides: list[str], ticks: int) -> list[float]:
    """Seconds of each timed tick of one freshly built run of ``overrides``."""
    from swarmscene import api

    sim = api.build(overrides)
    sim.hook.swarmscene_run_start(sim=sim)
    times: list[float] = []
    done = 0
    while sim.step_count < sim.total_steps and sim.stop_reason is None and len(times) < ticks:
        start = time.perf_counter()
        sim.step()
        elapsed = time.perf_counter() - start
        done += 1
        if done > WARMUP:
            times.append(elapsed)
        if sim.config.termination.on_complete and sim.formation.complete(sim.world):
            break
    return times


def worker(cases: list[str], ticks: int) -> dict[str, dict[str, float]]:
    """Median tick (us) and tick count of each case, in this process."""
    out = {}
    for name in cases:
        times = tick_times(CASES[name], ticks)
        out[name] = {"median_us": statistics.median(times) * 1e6, "ticks": len(times)}
    return out


def baseline_tree(rev: str, into: Path) -> Path:
    """``rev`` exported into ``into``, with a ``swarmscene`` package folder importable from it."""
    src = into / "src"
    src.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
    shim = into / "path"
    package = shim / "swarmscene"
    package.mkdir(parents=True)
    for entry in (src / "swarmscene").iterdir():
        (package / entry.name).symlink_to(entry)
    for name, folder in PACKAGES.items():
        (package / name).symlink_to(src / folder)
    (shim / "hydra_plugins").symlink_to(src / "hydra_plugins")
    return shim


def run_worker(cases: list[str], ticks: int, pythonpath: Path | None) -> dict[str, dict[str, float]]:
    env = dict(os.environ)
    if pythonpath is not None:  # found before the editable install's finder, which comes last
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(pythonpath), env.get("PYTHONPATH")]))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", "--cases", ",".join(cases),
           "--ticks", str(ticks)]
    done = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"bench_tick: worker failed ({'baseline' if pythonpath else 'this checkout'}):\n"
                         f"{done.stderr.strip()}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def profile(case: str, ticks: int, top: int = 25) -> None:
    """cProfile of one case's ticks (a second run of it), sorted by own time."""
    import cProfile
    import pstats

    from swarmscene import api

    tick_times(CASES[case], ticks)  # a first run pays the imports and compiled-kernel loads
    sim = api.build(CASES[case])
    sim.hook.swarmscene_run_start(sim=sim)
    for _ in range(WARMUP):
        sim.step()
    prof = cProfile.Profile()
    count = 0
    prof.enable()
    while sim.step_count < sim.total_steps and sim.stop_reason is None and count < ticks:
        sim.step()
        count += 1
    prof.disable()
    print(f"{case}: {count} ticks under cProfile (its overhead inflates small calls)")
    pstats.Stats(prof).strip_dirs().sort_stats("tottime").print_stats(top)


def table(rows: dict[str, dict[str, list[float]]], baseline: str | None) -> str:
    head = "| case | ticks | median tick, us (min-max over rounds) |"
    rule = "|---|---|---|"
    if baseline:
        head += f" baseline {baseline}, us | ratio |"
        rule += "---|---|"
    lines = [head, rule]
    for name, row in rows.items():
        this = row["this"]
        cells = [name, str(int(statistics.median(row["ticks"]))),
                 f"{statistics.median(this):.1f} ({min(this):.1f}-{max(this):.1f})"]
        if baseline:
            base = row["base"]
            cells += [f"{statistics.median(base):.1f} ({min(base):.1f}-{max(base):.1f})",
                      f"{statistics.median(base) / statistics.median(this):.1f}x"]
        goal = GOALS_US.get(name)
        if goal is not None:
            cells[2] += f", goal <= {goal:g}: {'met' if statistics.median(this) <= goal else 'NOT met'}"
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="rounds (fresh processes) per tree")
    ap.add_argument("--ticks", type=int, default=1_000_000, help="at most this many timed ticks per case "
                    "(default: the whole run)")
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated subset of " + ", ".join(CASES))
    ap.add_argument("--baseline", metavar="REV", help="also measure this git revision, round by round")
    ap.add_argument("--profile", metavar="CASE", help="print a cProfile of one case instead")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    cases = [c for c in args.cases.split(",") if c]
    unknown = [c for c in cases + ([args.profile] if args.profile else []) if c not in CASES]
    if unknown:
        raise SystemExit(f"bench_tick: unknown case {unknown[0]!r} (cases: {', '.join(CASES)})")
    if args.repeat < 1 or args.ticks < 1:
        raise SystemExit("bench_tick: --repeat and --ticks must be >= 1")
    if args.worker:
        print(json.dumps(worker(cases, args.ticks)))
        return
    if args.profile:
        profile(args.profile, args.ticks)
        return
    rows = {c: {"this": [], "base": [], "ticks": []} for c in cases}
    with tempfile.TemporaryDirectory(prefix="bench_tick_") as tmp:
        shim = baseline_tree(args.baseline, Path(tmp)) if args.baseline else None
        for r in range(args.repeat):
            trees = [("this", None)] + ([("base", shim)] if shim else [])
            for label, path in trees if r % 2 == 0 else trees[::-1]:  # alternate who goes first
                result = run_worker(cases, args.ticks, path)
                for name, fig in result.items():
                    rows[name][label].append(fig["median_us"])
                    if label == "this":
                        rows[name]["ticks"].append(fig["ticks"])
            print(f"round {r + 1}/{args.repeat} done", file=sys.stderr, flush=True)
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        print(table(rows, args.baseline))


if __name__ == "__main__":
    main()
