r"""Fig. 5.13 / Appendix A sweeps of the indoor swarm (thesis ch. 5), per reading, one command.

Runs every (shape, width, reading, seed) through the engine (``swarmscene.api.run``) and prints
per case: the success rate (every agent in the exit room, G_n connected throughout, eq. 5.2 and
5.3 held) with its 95 % Wilson interval, the worst minimum inter-agent distance (>= d_c = 0.3 m)
and the worst minimum obstacle distance (>= d_o = 0.1 m) over the seeds, the runs that violated
safety, the mean G_n / G_sigma neighbour counts, the failed seeds, and why they failed (from the
``indoor.disconnect.*`` metrics): ``los`` a wall broke the last link's line of sight (segment
clearance < d_l), ``range`` the last link stretched past d_n, ``stuck`` G_n stayed connected but not
every agent reached the exit room; ``+done`` marks splits after the leader reached its last
way-point.

A reading is a named set of overrides of the paper's ambiguous points (issue 17):
``--candidates`` the edge deactivation candidates of eq. 5.15-5.16 (``formation.
deactivation_candidates``: neighbours = literal, the default; common; directed) and ``--doors``
the building's room doors (closed = the default reading, beside Appendix A; open =
``environment=indoor_building_open_doors``). ``--override`` adds any other override to every run.
``--json`` writes every run's metrics and every case's summary (the input of the reproduction
report); ``--n-jobs`` runs seeds in parallel (joblib; 1 = in this process).

    python benchmarks/reproduction/sweep_indoor.py                       # straight + L, w 0.5..0.9, seeds 0..29
    python benchmarks/reproduction/sweep_indoor.py --shapes l --widths 070 080 --seeds 10
    python benchmarks/reproduction/sweep_indoor.py --shapes straight l --seeds 100 \
        --candidates neighbours common directed --json out/indoor_corridors.json --n-jobs 2
    python benchmarks/reproduction/sweep_indoor.py --shapes building --seeds 30 --doors closed open
    python benchmarks/reproduction/sweep_indoor.py --markdown            # tables for docs/benchmarks.md
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from swarmscene import api
from swarmscene.sweeps.stats import wilson  # the sweeps' 95 % Wilson interval

SHAPES = {"straight": "indoor_corridor", "l": "indoor_l_corridor", "building": "indoor_building"}
WIDTHS = ("050", "060", "070", "080", "090")
CANDIDATES = ("neighbours", "common", "directed")  # eq. 5.15-5.16; the first is the literal one
DOORS = {"closed": "indoor_building", "open": "indoor_building_open_doors"}
D_C, D_O, D_L = 0.3, 0.1, 0.05  # Table 5.1


def cause(m: dict) -> str:
    """Why a failed run failed (see the module docstring)."""
    if m.get("indoor.connected", True):
        return "stuck"
    if "indoor.disconnect.link_clearance" not in m:
        return "split"
    why = "los" if m["indoor.disconnect.link_clearance"] < D_L else "range"
    return why + ("+done" if m["indoor.disconnect.leader_done"] else "")


def run_one(overrides: list[str], seed: int) -> dict:
    """Metrics of one run (no files written), plain JSON types."""
    quiet = ["output.trajectory=false", "output.summary=false", "output.progress=off"]
    metrics = api.run([*overrides, f"seed={seed}", *quiet]).metrics
    return json.loads(json.dumps(metrics, default=float))


def summarise(label: str, runs: list[dict], seeds: list[int]) -> dict:
    """One table row from the runs of one case."""
    ok = [bool(m["indoor.success"]) for m in runs]
    unsafe = sum(m["collisions"] > 0 or m["clearance_violations"] > 0 for m in runs)
    low, high = wilson(sum(ok), len(runs))
    return {
        "label": label,
        "runs": len(runs),
        "success": 100.0 * sum(ok) / max(len(runs), 1),
        "success_ci95": [100.0 * low, 100.0 * high],
        "min_sep": min(m["min_separation"] for m in runs),
        "min_clear": min(m["min_clearance"] for m in runs),
        "unsafe": unsafe,
        "unsafe_seeds": [s for s, m in zip(seeds, runs, strict=True)
                         if m["collisions"] > 0 or m["clearance_violations"] > 0],
        "nb_n": float(np.mean([m["indoor.mean_neighbours"] for m in runs])),
        "nb_sigma": float(np.mean([m["indoor.mean_neighbours_sigma"] for m in runs])),
        "failed": [s for s, good in zip(seeds, ok, strict=True) if not good],
        "causes": [cause(m) for m, good in zip(runs, ok, strict=True) if not good],
    }


def causes(names: list[str]) -> str:
    """'los 3, range 1' from a list of causes."""
    counts = {name: names.count(name) for name in sorted(set(names))}
    return ", ".join(f"{k} {v}" for k, v in counts.items()) or "-"


def print_table(title: str, rows: list[dict], markdown: bool) -> None:
    """Print one shape's case summaries as a plain text table, or a markdown one with ``markdown``."""
    head = ("case", "runs", "success % (95 % CI)", "worst min sep (m)", "worst min clearance (m)",
            "unsafe runs", "mean nb G_n", "mean nb G_sigma", "failed seeds", "causes")
    cells = [(r["label"], str(r["runs"]),
              f"{r['success']:.1f} ({r['success_ci95'][0]:.0f}-{r['success_ci95'][1]:.0f})",
              f"{r['min_sep']:.3f}", f"{r['min_clear']:.3f}", str(r["unsafe"]), f"{r['nb_n']:.2f}",
              f"{r['nb_sigma']:.2f}", " ".join(map(str, r["failed"])) or "-", causes(r["causes"]))
             for r in rows]
    print(f"\n{title}")
    if markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for c in cells:
            print("| " + " | ".join(c) + " |")
    else:
        widths = [max(len(h), *(len(c[k]) for c in cells)) for k, h in enumerate(head)]
        print("  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True)))
        for c in cells:
            print("  ".join(v.ljust(w) for v, w in zip(c, widths, strict=True)))
    sys.stdout.flush()


def cases(args: argparse.Namespace) -> list[dict]:
    """Every (shape, width, reading) case: its label, overrides and reading."""
    out = []
    for shape in args.shapes:
        scenario = SHAPES[shape]
        if shape == "building":
            geometry = [(f"doors {d}", {"doors": d}, [f"environment={DOORS[d]}"]) for d in args.doors]
        else:
            geometry = [(f"w = {int(w) / 100:.1f} m", {"width": int(w) / 100},
                         [f"environment={scenario}_w{w}"]) for w in args.widths]
        for label, where, env in geometry:
            for reading in args.candidates:
                out.append({
                    "shape": shape, "scenario": scenario, **where,
                    "reading": {"deactivation_candidates": reading,
                                **({"doors": where["doors"]} if "doors" in where else {})},
                    "label": f"{label}, {reading}",
                    "overrides": [f"scenario={scenario}", *env,
                                  f"formation.deactivation_candidates={reading}",
                                  f"avoidance.deactivation_candidates={reading}", *args.override],
                })
    return out


def run_case(case: dict, seeds: list[int], n_jobs: int, verbose: bool) -> list[dict]:
    """The metrics of every seed of one case, in seed order."""
    if n_jobs == 1:
        runs = []
        for seed in seeds:
            runs.append(run_one(case["overrides"], seed))
            if verbose:
                m = runs[-1]
                print(f"  {case['label']} seed {seed}: success={m['indoor.success']} "
                      f"min_sep={m['min_separation']:.3f} min_clear={m['min_clearance']:.3f} "
                      f"cause={'-' if m['indoor.success'] else cause(m)}", flush=True)
        return runs
    from joblib import Parallel, delayed

    return Parallel(n_jobs=n_jobs)(delayed(run_one)(case["overrides"], s) for s in seeds)


def main(argv: list[str] | None = None) -> None:
    """Run every case of each chosen shape over its seeds, print a table per shape, write ``--json`` as it goes."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", default=["straight", "l"], choices=list(SHAPES))
    parser.add_argument("--widths", nargs="+", default=list(WIDTHS), help="e.g. 070 080")
    parser.add_argument("--candidates", nargs="+", default=[CANDIDATES[0]], choices=CANDIDATES,
                        help="readings of eq. 5.15-5.16 (formation.deactivation_candidates)")
    parser.add_argument("--doors", nargs="+", default=["closed"], choices=list(DOORS),
                        help="the building's room doors (shape building only)")
    parser.add_argument("--override", nargs="*", default=[], help="more overrides for every run")
    parser.add_argument("--seeds", type=int, default=None, help="seeds 0..n-1 (30; building 10)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--n-jobs", type=int, default=1, help="parallel runs (joblib)")
    parser.add_argument("--json", type=Path, default=None, help="write every run's metrics here")
    parser.add_argument("--markdown", action="store_true", help="print markdown tables")
    parser.add_argument("--verbose", action="store_true", help="one line per run (n-jobs 1)")
    args = parser.parse_args(argv)
    record = {"command": " ".join(["python", "benchmarks/reproduction/sweep_indoor.py", *(argv or sys.argv[1:])]),
              "cases": []}
    for shape in args.shapes:
        count = args.seeds if args.seeds is not None else (10 if shape == "building" else 30)
        seeds = list(range(args.first_seed, args.first_seed + count))
        rows, t0 = [], time.perf_counter()
        for case in (c for c in cases(args) if c["shape"] == shape):
            runs = run_case(case, seeds, args.n_jobs, args.verbose)
            row = summarise(case["label"], runs, seeds)
            rows.append(row)
            record["cases"].append({**case, "seeds": seeds, "summary": row, "runs": runs})
            if args.json is not None:  # after every case, so a long sweep leaves partial results
                args.json.parent.mkdir(parents=True, exist_ok=True)
                args.json.write_text(json.dumps(record, indent=1))
        print_table(f"{SHAPES[shape]}: {len(seeds)} seeds per case "
                    f"({time.perf_counter() - t0:.0f} s)", rows, args.markdown)


if __name__ == "__main__":
    main()
