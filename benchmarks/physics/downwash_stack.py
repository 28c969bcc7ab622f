"""Where downwash decides the outcome: two Crazyflies stacked, the lower one's track (issue #37).

The lower vehicle holds (0, 0, 1) m, the upper one (0, 0, 1 + Δz) straight above, for ``--duration``
s (``quadrotor`` dynamics, the Crazyflie airframe, SE(3) control; floor at z = 0; no avoidance).
For each vertical separation Δz, without downwash, with the ``downwash`` model (the
gym-pybullet-drones fit) and with it at ``scale`` 0.3 (about Neural-Swarm's measured force),
the lower vehicle's largest position error after the first second, and whether it crashed on the
floor. It loses its track where the error passes ``--track`` (0.1 m).

    python benchmarks/physics/downwash_stack.py [--png docs/physics_downwash.png] [--csv out.csv]

Prints a table (Markdown) and the separation below which the track is lost, per model.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

MODELS = {"no downwash": None, "downwash (fit)": 1.0, "downwash x 0.3": 0.3}


def lower_error(gap: float, scale: float | None, duration: float) -> tuple[float, bool]:
    """(largest position error of the lower vehicle after 1 s, m; whether a vehicle crashed)."""
    from swarmscene import api
    from swarmscene.core.setpoint import Setpoints

    overrides = ["scenario=default", "environment=open", "swarm.n=2", "swarm.leader=null",
                 "swarm.start.layout=explicit", f"swarm.start.positions=[[0,0,1],[0,0,{1 + gap}]]",
                 "avoidance=none", "dynamics=quadrotor", "events=none", "environment.floor=0",
                 "clock.guidance_period=0.1", "clock.physics_step=0.02", f"clock.duration={duration}",
                 "termination.on_complete=false", "safety.start_overlap=warn", "output.summary=false"]
    if scale is not None:
        overrides += ["disturbances=[downwash]", f"disturbances.downwash.scale={scale}"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # stacked closer than the separation limit on purpose
        sim = api.build(overrides)
    target = sim.world.pos.copy()
    sim.formation.setpoints = lambda world, sensing: Setpoints.hold(target)
    worst = 0.0
    while sim.step_count < sim.total_steps:
        sim.step()
        if sim.world.t > 1.0 - 1e-9:
            worst = max(worst, float(np.linalg.norm(sim.world.pos[0] - target[0])))
    crashed = bool(sim.floor is not None and sim.floor.crashed)
    return worst, crashed


def main() -> None:
    """Fly the stacked pair at each vertical gap, with and without downwash, and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gaps", nargs=3, type=float, default=[0.2, 1.5, 0.05], metavar=("FROM", "TO", "STEP"))
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--track", type=float, default=0.1)
    parser.add_argument("--png", type=Path)
    parser.add_argument("--csv", type=Path)
    args = parser.parse_args()
    gaps = np.round(np.arange(args.gaps[0], args.gaps[1] + 1e-9, args.gaps[2]), 6)
    table = {label: [lower_error(g, scale, args.duration) for g in gaps] for label, scale in MODELS.items()}
    print("| Δz (m) | " + " | ".join(f"{label}: error (m)" for label in MODELS) + " |")
    print("|---|" + "---|" * len(MODELS))
    for k, g in enumerate(gaps):
        cells = [f"{e:.3f}{' crash' if c else ''}" for e, c in (table[label][k] for label in MODELS)]
        print(f"| {g:.2f} | " + " | ".join(cells) + " |")
    for label in MODELS:
        lost = [g for g, (e, c) in zip(gaps, table[label], strict=True) if e > args.track or c]
        edge = f"below {max(lost) + args.gaps[2]:.2f} m" if lost else "never (in the range swept)"
        print(f"{label}: the lower vehicle loses its track (error > {args.track} m) {edge}")
    if args.csv:
        rows = ["gap," + ",".join(f"{label} error,{label} crash" for label in MODELS)]
        rows += [f"{g}," + ",".join(f"{table[label][k][0]},{int(table[label][k][1])}" for label in MODELS)
                 for k, g in enumerate(gaps)]
        args.csv.write_text("\n".join(rows) + "\n")
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4))
        for label, style in zip(MODELS, ("k:", "C0-o", "C1-s"), strict=True):
            err = np.array([e for e, _ in table[label]])
            shown = label if err.max() >= 1e-4 else f"{label} (< 1e-4 m, drawn at 1e-4)"
            ax.semilogy(gaps, np.maximum(err, 1e-4), style, label=shown, markersize=4)
            crash = [g for g, (_, c) in zip(gaps, table[label], strict=True) if c]
            if crash:
                ax.semilogy(crash, np.maximum(err[np.isin(gaps, crash)], 1e-4), "rx", markersize=8)
        ax.axhline(args.track, color="0.5", lw=0.8)
        ax.text(gaps[-1], args.track * 1.15, f"track lost ({args.track} m)", ha="right", color="0.4", fontsize=8)
        ax.set_xlabel("vertical separation Δz of the stacked pair (m)")
        ax.set_ylabel("lower vehicle's largest position error (m)")
        ax.set_title("Two Crazyflies stacked: the lower one under the upper one's downwash\n"
                     "(red x: crashed on the floor)",
                     fontsize=10)
        ax.legend(fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        fig.savefig(args.png, dpi=110)
        print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
