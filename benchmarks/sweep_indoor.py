"""Full Fig. 5.13 / Appendix A sweeps of the indoor swarm (thesis ch. 5), one command.

Runs every (shape, width, seed) through the engine (``swarmscene.api.run``), one run at a time in
this process, and prints per width: the success rate (every agent in the exit room, G_n connected
throughout, eq. 5.2 and 5.3 held), the worst minimum inter-agent distance (>= d_c = 0.3 m) and the
worst minimum obstacle distance (>= d_o = 0.1 m) over the seeds, the runs that violated safety,
the mean G_n / G_sigma neighbour counts, the failed seeds, and why they failed (from the
``indoor.disconnect.*`` metrics): ``los`` a wall broke the last link's line of sight (segment
clearance < d_l), ``range`` the last link stretched past d_n, ``stuck`` G_n stayed connected but not
every agent reached the exit room; ``+done`` marks splits after the leader reached its last
way-point.

    python benchmarks/sweep_indoor.py                       # straight + L, w 0.5..0.9, seeds 0..29
    python benchmarks/sweep_indoor.py --shapes l --widths 070 080 --seeds 10
    python benchmarks/sweep_indoor.py --shapes building     # N = 100, seeds 0..9
    python benchmarks/sweep_indoor.py --markdown            # tables for docs/benchmarks.md
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from swarmscene import api

SHAPES = {"straight": "indoor_corridor", "l": "indoor_l_corridor", "building": "indoor_building"}
WIDTHS = ("050", "060", "070", "080", "090")
D_C, D_O, D_L = 0.3, 0.1, 0.05  # Table 5.1


def cause(m: dict) -> str:
    """Why a failed run failed (see the module docstring)."""
    if m.get("indoor.connected", True):
        return "stuck"
    if "indoor.disconnect.link_clearance" not in m:
        return "split"
    why = "los" if m["indoor.disconnect.link_clearance"] < D_L else "range"
    return why + ("+done" if m["indoor.disconnect.leader_done"] else "")


def run_one(scenario: str, environment: str | None, seed: int) -> dict:
    """Metrics of one run (no files written)."""
    overrides = [f"scenario={scenario}", f"seed={seed}", "output.trajectory=false"]
    if environment is not None:
        overrides.append(f"environment={environment}")
    return api.run(overrides).metrics


def summarise(label: str, runs: list[dict], seeds: list[int]) -> dict:
    """One table row from the runs of one (shape, width)."""
    ok = [bool(m["indoor.success"]) for m in runs]
    unsafe = sum(m["collisions"] > 0 or m["clearance_violations"] > 0 for m in runs)
    return {
        "label": label,
        "runs": len(runs),
        "success": 100.0 * sum(ok) / max(len(runs), 1),
        "min_sep": min(m["min_separation"] for m in runs),
        "min_clear": min(m["min_clearance"] for m in runs),
        "unsafe": unsafe,
        "nb_n": float(np.mean([m["indoor.mean_neighbours"] for m in runs])),
        "nb_sigma": float(np.mean([m["indoor.mean_neighbours_sigma"] for m in runs])),
        "failed": [s for s, good in zip(seeds, ok) if not good],
        "causes": [cause(m) for m, good in zip(runs, ok) if not good],
    }


def causes(names: list[str]) -> str:
    """'los 3, range 1' from a list of causes."""
    counts = {name: names.count(name) for name in sorted(set(names))}
    return ", ".join(f"{k} {v}" for k, v in counts.items()) or "-"


def print_table(title: str, rows: list[dict], markdown: bool) -> None:
    head = ("case", "runs", "success %", "worst min sep (m)", "worst min clearance (m)",
            "unsafe runs", "mean nb G_n", "mean nb G_sigma", "failed seeds", "causes")
    cells = [(r["label"], str(r["runs"]), f"{r['success']:.1f}", f"{r['min_sep']:.3f}",
              f"{r['min_clear']:.3f}", str(r["unsafe"]), f"{r['nb_n']:.2f}", f"{r['nb_sigma']:.2f}",
              " ".join(map(str, r["failed"])) or "-", causes(r["causes"])) for r in rows]
    print(f"\n{title}")
    if markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for c in cells:
            print("| " + " | ".join(c) + " |")
    else:
        widths = [max(len(h), *(len(c[k]) for c in cells)) for k, h in enumerate(head)]
        print("  ".join(h.ljust(w) for h, w in zip(head, widths)))
        for c in cells:
            print("  ".join(v.ljust(w) for v, w in zip(c, widths)))
    sys.stdout.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", default=["straight", "l"], choices=list(SHAPES))
    parser.add_argument("--widths", nargs="+", default=list(WIDTHS), help="e.g. 070 080")
    parser.add_argument("--seeds", type=int, default=None, help="seeds 0..n-1 (30; building 10)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--markdown", action="store_true", help="print markdown tables")
    parser.add_argument("--verbose", action="store_true", help="one line per run")
    args = parser.parse_args()
    for shape in args.shapes:
        scenario = SHAPES[shape]
        count = args.seeds if args.seeds is not None else (10 if shape == "building" else 30)
        seeds = list(range(args.first_seed, args.first_seed + count))
        cases = [(None, "N = 100")] if shape == "building" else [
            (f"{scenario}_w{w}", f"w = {int(w) / 100:.1f} m") for w in args.widths]
        rows = []
        t0 = time.perf_counter()
        for environment, label in cases:
            runs = []
            for seed in seeds:
                m = run_one(scenario, environment, seed)
                runs.append(m)
                if args.verbose:
                    print(f"  {scenario} {label} seed {seed}: success={m['indoor.success']} "
                          f"connected={m['indoor.connected']} arrived={m['indoor.arrived']} "
                          f"max_rank={m['indoor.max_rank']} min_sep={m['min_separation']:.3f} "
                          f"min_clear={m['min_clearance']:.3f} cause={'-' if m['indoor.success'] else cause(m)}",
                          flush=True)
            rows.append(summarise(label, runs, seeds))
        print_table(f"{scenario}: {len(seeds)} seeds per case ({time.perf_counter() - t0:.0f} s)",
                    rows, args.markdown)


if __name__ == "__main__":
    main()
