"""CEM paper Fig. 10: how the number of replanning passes K orders the peak speed, seed by seed.

Romano et al. (papers/cem-fluid-flow-navigation.md), section V-A: the six-vehicle flight repeated
with K in {1, 2, 5}; "K=1 reached a 2D speed of 2.4 m/s ... Speed error with K=2 was significant
lower, while K=5 performed a bit better". Each K is one flight in the paper, so the ordering is a
statement about one draw of each. Here every seed is flown with both K of a comparison (the same
seed: the same failure and the same saddle noise stream), and the claim's rate is the share of
seeds in which the first K's peak 2-D commanded speed (``cem.max_speed``) is below the second's.

Run: python benchmarks/reproduction/fig_10_cem.py [seeds]   (prints the shares; ~2 s a flight)
Claims: ``peak_speed_below(seed, k_low, k_high)`` (a bool: the report counts it as a rate).
"""

from __future__ import annotations

import argparse
from functools import lru_cache

QUIET = ["output.trajectory=false", "output.summary=false", "output.progress=off"]


@lru_cache(maxsize=256)
def peak_speed(seed: int, k: int) -> float:
    """Peak 2-D commanded speed of any agent, m/s, in cem_six_vehicle with ``avoidance.K = k``."""
    from swarmscene import api

    result = api.run(["scenario=cem_six_vehicle", f"avoidance.K={k}", f"seed={seed}", *QUIET])
    return float(result.metrics["cem.max_speed"])


def peak_speed_below(seed: int, k_low: str, k_high: str) -> bool:
    """Whether the peak speed with K = ``k_low`` is below the one with K = ``k_high`` for ``seed``."""
    return peak_speed(seed, int(k_low)) < peak_speed(seed, int(k_high))


def main() -> None:
    """Count the seeds in which each of Fig. 10's orderings holds."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("seeds", type=int, nargs="?", default=10)
    n = parser.parse_args().seeds
    for low, high in (("2", "1"), ("5", "2")):
        below = sum(peak_speed_below(seed, low, high) for seed in range(n))
        print(f"K = {low} below K = {high} in {below} of {n} seeds")
    for k in (1, 2, 5):
        print(f"K = {k}: mean peak {sum(peak_speed(s, k) for s in range(n)) / n:.3f} m/s")


if __name__ == "__main__":
    main()
