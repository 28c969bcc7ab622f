"""The cost of the disturbance phases (issue #18), side by side with the code before them.

1. No disturbances declared: each scenario runs under the engine before the disturbances group
   existed (``--baseline``, default: the parent of the commit that added core/disturbances) and
   under ``--candidate`` (default HEAD), alternately, ``--rounds`` times each, in fresh processes.
   Both trees come from ``git archive`` (uncommitted edits of the working tree are not measured),
   imported through a throw-away package root that maps the folders as setup.py does. Columns:
   the median over rounds of the run's median tick time (ms) and of its wall time (s), their
   ratio, and whether the trajectories are bit-identical (sha256 of every recorded array).
2. With disturbances (candidate only): the same scenarios with ``dryden``, ``gps``,
   ``packet_loss`` and all three, as a ratio of the median tick time to no disturbances. These
   include the algorithms' reaction (ORCA with 2 m GPS noise sees overlapping neighbours and works
   harder), not only the phases' own cost.

    OMP_NUM_THREADS=1 python benchmarks/speed/bench_disturbances.py [--rounds 5] [--json out.json]

Not a timed test: numbers depend on the machine; read the ratio, measured in one run.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[2]  # benchmarks/speed/ -> the repository
SCENARIOS = {
    "cem_six_vehicle": ["scenario=cem_six_vehicle"],                       # 4,000 ticks of 10 ms, CEM
    "default": ["scenario=default"],                                        # double integrator, 50 Hz
    "swap_100": ["scenario=swap", "swarm.n=100", "swarm.start.radius=16", "clock.duration=30"],
    "outdoor_square": ["scenario=outdoor_square"],                           # swarm maps
    "quadrotor": ["scenario=cem_six_vehicle", "dynamics=quadrotor", "clock.duration=10"],
}
DISTURBED = {
    "dryden": ["disturbances=[dryden]"],
    "gps": ["disturbances=[gps]"],
    "packet_loss": ["disturbances=[packet_loss]"],
    "all three": ["disturbances=[dryden,gps,packet_loss]"],
}
COMMON = ["output.summary=false", "output.progress=off"]


def worker(cases: dict[str, list[str]]) -> None:
    """Run each case once in this process and print one JSON line of results."""
    import warnings

    import numpy as np

    from swarmscene import api
    from swarmscene.composition.searchpath import register_search_path

    warnings.simplefilter("ignore")
    register_search_path()
    # only the disturbed runs are timed phase by phase (the wrappers would tax the "none" column)
    disturbed = any(any(o.startswith("disturbances=") for o in overrides) for overrides in cases.values())
    spent = _time_phases() if disturbed else [0.0]
    out = {}
    for name, overrides in cases.items():
        spent[0] = 0.0
        result = api.run([*overrides, *COMMON])
        digest = hashlib.sha256()
        for key in sorted(result.trajectory):
            digest.update(key.encode())
            digest.update(np.ascontiguousarray(result.trajectory[key]).tobytes())
        m = result.metrics
        out[name] = {"step_ms": m["step_ms_median"], "wall": m["wall_time"], "steps": m["steps"],
                     "sha": digest.hexdigest(), "min_separation": m.get("min_separation"),
                     "phases_ms": spent[0] * 1e3 / max(m["steps"], 1)}
    print(json.dumps(out))


def _time_phases() -> list[float]:
    """Wrap the disturbance phases (when the tree has them) to add their own time to ``spent[0]``."""
    import time

    spent = [0.0]
    try:
        from swarmscene.core.disturbances import Disturbances
    except ImportError:  # the code before the disturbances
        return spent
    for method in ("perceive", "blow", "push"):
        original = getattr(Disturbances, method)

        def timed(self, *args, _original=original):
            t0 = time.perf_counter()
            try:
                return _original(self, *args)
            finally:
                spent[0] += time.perf_counter() - t0

        setattr(Disturbances, method, timed)
    return spent


def tree(rev: str, where: Path) -> Path:
    """``rev`` extracted under ``where``, with a package root mapping the folders as setup.py does."""
    src = where / "src"
    src.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev], check=True, capture_output=True).stdout
    with tempfile.TemporaryFile() as fh:
        fh.write(archive)
        fh.seek(0)
        tarfile.open(fileobj=fh).extractall(src, filter="data")
    package = where / "root" / "swarmscene"
    package.mkdir(parents=True)
    for entry in (src / "swarmscene").iterdir():
        (package / entry.name).symlink_to(entry)
    for folder in ("core", "methods", "plugins", "scenarios"):
        (package / folder).symlink_to(src / folder)
    return where / "root"


def measure(root: Path, cases: dict[str, list[str]]) -> dict:
    """One round of ``cases`` timed in a child process on the source tree ``root`` (its JSON figures)."""
    env = dict(os.environ, PYTHONPATH=str(root))
    done = subprocess.run([sys.executable, __file__, "--worker", json.dumps(cases)], env=env, cwd=root,
                          check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def first_disturbance_commit() -> str:
    """The parent of the commit that added core/disturbances/ (the default baseline)."""
    log = subprocess.run(["git", "-C", str(ROOT), "log", "--diff-filter=A", "--format=%H", "--",
                          "core/disturbances/__init__.py"], check=True, capture_output=True, text=True)
    first = log.stdout.split()[-1]
    parent = subprocess.run(["git", "-C", str(ROOT), "rev-parse", first + "~1"], check=True,
                            capture_output=True, text=True)
    return parent.stdout.strip()


def main() -> None:
    """Time both trees alternately without disturbances, then each disturbance, and print the markdown tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--baseline", default=None, help="git revision before the disturbances")
    parser.add_argument("--candidate", default="HEAD")
    parser.add_argument("--json", default=None)
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        worker(json.loads(args.worker))
        return
    baseline = args.baseline or first_disturbance_commit()
    with tempfile.TemporaryDirectory() as tmp:
        roots = {"baseline": tree(baseline, Path(tmp) / "a"), "candidate": tree(args.candidate, Path(tmp) / "b")}
        runs: dict[str, list[dict]] = {"baseline": [], "candidate": []}
        for _ in range(args.rounds):  # alternate, so drifts of the machine hit both alike
            for label in ("baseline", "candidate"):
                runs[label].append(measure(roots[label], SCENARIOS))
        disturbed_cases = {f"{s}+{d}": [*o, *extra] for s, o in SCENARIOS.items() for d, extra in DISTURBED.items()}
        disturbed = [measure(roots["candidate"], disturbed_cases) for _ in range(max(1, args.rounds // 2))]
    report = {"baseline": baseline, "candidate": args.candidate, "rounds": args.rounds, "none": {}, "disturbed": {}}
    print(f"No disturbances declared: {baseline[:12]} (before) vs {args.candidate} (after), "
          f"median of {args.rounds} alternating rounds\n")
    print("| scenario | ticks | tick ms before | tick ms after | ratio | wall s before | wall s after "
          "| bit-identical |")
    print("|---|---|---|---|---|---|---|---|")
    for name in SCENARIOS:
        a = [r[name] for r in runs["baseline"]]
        b = [r[name] for r in runs["candidate"]]
        ms_a, ms_b = statistics.median(x["step_ms"] for x in a), statistics.median(x["step_ms"] for x in b)
        w_a, w_b = statistics.median(x["wall"] for x in a), statistics.median(x["wall"] for x in b)
        same = len({x["sha"] for x in a + b}) == 1
        report["none"][name] = {"ticks": a[0]["steps"], "step_ms_before": ms_a, "step_ms_after": ms_b,
                                "wall_before": w_a, "wall_after": w_b, "bit_identical": same}
        print(f"| {name} | {a[0]['steps']} | {ms_a:.3f} | {ms_b:.3f} | {ms_b / ms_a:.3f} | {w_a:.2f} | "
              f"{w_b:.2f} | {'yes' if same else 'NO'} |")
    print("\nWith disturbances (after): median tick time relative to none declared (the algorithms'"
          " reaction included), and in brackets the phases' own time per tick, ms\n")
    print("| scenario | " + " | ".join(DISTURBED) + " |")
    print("|---|" + "---|" * len(DISTURBED))
    for name in SCENARIOS:
        base = report["none"][name]["step_ms_after"]
        ratios = {d: statistics.median(r[f"{name}+{d}"]["step_ms"] for r in disturbed) / base for d in DISTURBED}
        own = {d: statistics.median(r[f"{name}+{d}"]["phases_ms"] for r in disturbed) for d in DISTURBED}
        report["disturbed"][name] = {"ratio": ratios, "phases_ms": own}
        print(f"| {name} | " + " | ".join(f"{ratios[d]:.2f} ({own[d]:.3f})" for d in DISTURBED) + " |")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
