"""The engine's fixed cost per tick for small swarms: ``api.build``, then timed ``Simulation.step``.

    python benchmarks/speed/bench_tick.py                        # this checkout, --repeat 5 rounds
    python benchmarks/speed/bench_tick.py --baseline af87771     # and that commit, round by round
    python benchmarks/speed/bench_tick.py --phases default       # each phase's median share of the tick
    python benchmarks/speed/bench_tick.py --profile default      # where one case's tick goes (cProfile)
    python benchmarks/speed/bench_tick.py --json

Cases (each round builds each afresh, in its own process):
    cem_six_vehicle   ``scenario=cem_six_vehicle``: 6 agents, CEM avoidance, single integrator
    default           the default scenario: 5 double integrators, potential field, one pillar
    swap              ``scenario=swap swarm.n=16 swarm.start.radius=8``: 16 agents, ORCA
    flocking          ``scenario=flocking``: 100 boids in Mesa's 100 m torus, single integrator

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

ROOT = Path(__file__).resolve().parents[2]  # benchmarks/speed/ -> the repository
CASES: dict[str, list[str]] = {
    "cem_six_vehicle": ["scenario=cem_six_vehicle"],
    "default": [],
    "swap": ["scenario=swap", "swarm.n=16", "swarm.start.radius=8"],
    "flocking": ["scenario=flocking"],
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
    done = subprocess.run(["git", "-C", str(ROOT), "archive", rev], capture_output=True)
    if done.returncode != 0:
        reason = (done.stderr.decode(errors="replace").strip().splitlines() or ["git archive failed"])[-1]
        raise SystemExit(f"bench_tick: --baseline {rev}: cannot export it ({reason})")
    subprocess.run(["tar", "-x", "-C", str(src)], input=done.stdout, check=True)
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
    """The median tick figures of ``cases`` from a worker process on ``pythonpath`` (None: this checkout)."""
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


PHASES = ("events", "sense", "formation", "avoidance", "control", "physics", "hold", "finite",
          "snapshot", "observers")


def phases(case: str, ticks: int) -> dict[str, float]:
    """Median microseconds of each phase of one case's ticks, and of the whole tick ("tick").

    The kernel's collaborators are wrapped in timers on this one simulation (its step() runs as
    written): formation.setpoints, avoidance.adjust, dynamics.control, the physics sub-steps
    (dynamics.step and the wind calls around it), events.hold, the finite check, the Sensing
    snapshot and the step-end hooks (every observer, through pluggy; then each observer's own call,
    indented). Each timer adds ~0.1 us.
    """
    from swarmscene import api
    from swarmscene.core import simulation

    tick_times(CASES[case], ticks)  # imports and compiled-kernel loads paid first
    sim = api.build(CASES[case])
    spent = dict.fromkeys(PHASES, 0.0)

    def timed(phase: str, func):
        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return func(*args, **kwargs)
            finally:
                spent[phase] += time.perf_counter() - start
        return call

    sim._apply_due_events = timed("events", sim._apply_due_events)
    sim.disturbances.perceive = timed("sense", sim.disturbances.perceive)
    sim.formation.setpoints = timed("formation", sim.formation.setpoints)
    sim.avoidance.adjust = timed("avoidance", sim.avoidance.adjust)
    sim.dynamics.control = timed("control", sim.dynamics.control)
    for name in ("blow", "push"):
        setattr(sim.disturbances, name, timed("physics", getattr(sim.disturbances, name)))
    sim.dynamics.step = timed("physics", sim.dynamics.step)
    sim.events.hold = timed("hold", sim.events.hold)
    sim._check_finite = timed("finite", sim._check_finite)
    sim._step_end = timed("observers", sim._step_end)  # the observers' call (Simulation._step_end)
    for impl in sim.hook.swarmscene_step_end.get_hookimpls():  # each observer's own share
        name = f"  {type(impl.plugin).__name__}"
        spent[name] = 0.0
        impl.function = timed(name, impl.function)
    snapshot, simulation.Sensing = simulation.Sensing, timed("snapshot", simulation.Sensing)
    rows: dict[str, list[float]] = {name: [] for name in (*spent, "tick")}
    try:
        sim.hook.swarmscene_run_start(sim=sim)
        done = 0
        while sim.step_count < sim.total_steps and sim.stop_reason is None and done < ticks:
            for name in spent:
                spent[name] = 0.0
            start = time.perf_counter()
            sim.step()
            rows["tick"].append(time.perf_counter() - start)
            for name, seconds in spent.items():
                rows[name].append(seconds)
            done += 1
            if sim.config.termination.on_complete and sim.formation.complete(sim.world):
                break
    finally:
        simulation.Sensing = snapshot
    return {name: statistics.median(v[WARMUP:]) * 1e6 for name, v in rows.items()}


def table(rows: dict[str, dict[str, list[float]]], baseline: str | None) -> str:
    """The markdown table of each case's median tick over the rounds, the baseline's beside it, and the goal."""
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
    """Print the cases' tick times (this tree and ``--baseline`` alternated), one case's phases, or its profile."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="rounds (fresh processes) per tree")
    ap.add_argument("--ticks", type=int, default=1_000_000, help="at most this many timed ticks per case "
                    "(default: the whole run)")
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated subset of " + ", ".join(CASES))
    ap.add_argument("--baseline", metavar="REV", help="also measure this git revision, round by round")
    ap.add_argument("--phases", metavar="CASE", help="print each phase's median tick time of one case")
    ap.add_argument("--profile", metavar="CASE", help="print a cProfile of one case instead")
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    cases = [c for c in args.cases.split(",") if c]
    unknown = [c for c in [*cases, args.profile, args.phases] if c and c not in CASES]
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
    if args.phases:
        medians = phases(args.phases, args.ticks)
        rest = medians["tick"] - sum(medians[name] for name in PHASES)
        print(f"| {args.phases}: phase | median, us |\n|---|---|")
        for name, us in medians.items():
            print(f"| {name} | {us:.1f} |")
        print(f"| (tick less the phases' medians: the kernel's own lines, timers) | {rest:.1f} |")
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
