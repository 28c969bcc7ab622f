"""How far the quadrotor's float32 physics step (``dynamics.dtype=float32``) flies from float64's.

Each case is one composition run twice in lockstep, tick by tick, in float64 and in float32; printed:
the largest position difference between the two over the run, and the median over the agents of
each agent's difference at the end. The flock is also run in float64 a second time with its start
moved by 1e-5 m, to tell float32's error from the flock's own sensitivity to a small change::

    python benchmarks/reproduction/float32_error.py
"""

from __future__ import annotations

import numpy as np

from swarmscene import api

CASES = {
    "the default scenario with dynamics=quadrotor, 10 s": ["dynamics=quadrotor", "clock.duration=10"],
    "swap with dynamics=quadrotor, 4 agents": ["scenario=swap", "dynamics=quadrotor", "swarm.n=4"],
    "vrb_airshow": ["scenario=vrb_airshow"],
    "flocking with dynamics=quadrotor, 100 agents, 10 s": ["scenario=flocking", "dynamics=quadrotor",
                                                           "swarm.n=100", "clock.duration=10"],
}
NUDGE = 1e-5
"""m: the flock's start moved by this much (normal per coordinate) in the control run."""


def apart(overrides: list[str], second: list[str], nudge: float = 0.0) -> tuple[float, float, int]:
    """The largest |p_a - p_b| over the run, the median over agents of each one's at the end, and the
    ticks, of ``overrides`` run as is and with ``second`` added (its start moved by ``nudge``)."""
    sims = [api.build(api.compose([*overrides, "output.summary=false", *extra])) for extra in ([], second)]
    if nudge:
        sims[1].world.pos[:] += nudge * np.random.default_rng(0).normal(size=sims[1].world.pos.shape)
    worst = 0.0
    while sims[0].going() and sims[1].going():
        for sim in sims:
            sim.step()
        worst = max(worst, float(np.abs(sims[0].world.pos - sims[1].world.pos).max()))
    final = np.abs(sims[0].world.pos - sims[1].world.pos).max(axis=1)
    return worst, float(np.median(final)), sims[0].step_count


def main() -> None:
    """Every case's float32 error, and the flock's float64 control, printed as a table."""
    print(f"{'case':<56}{'max over the run':>18}{'median at the end':>19}{'ticks':>7}")
    for name, overrides in CASES.items():
        worst, median, ticks = apart(overrides, ["dynamics.dtype=float32"])
        print(f"{name:<56}{worst:>16.3g} m{median:>17.3g} m{ticks:>7}")
    flock = CASES["flocking with dynamics=quadrotor, 100 agents, 10 s"]
    worst, median, ticks = apart(flock, [], nudge=NUDGE)
    print(f"{'  control: the flock in float64, its start moved 1e-5 m':<56}{worst:>16.3g} m{median:>17.3g} m{ticks:>7}")


if __name__ == "__main__":
    main()
