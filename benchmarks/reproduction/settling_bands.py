"""Settling times of the thesis' step responses (Figs. 3.5, 3.8, 3.11, 3.13) in one band for all.

Karydes (2020), chapter 3 (../shared/papers/quadrotor-swarms-thesis.md). The thesis reads each
settling time off its figure and states no band; the report's claims
(benchmarks/reproduction/claims/thesis_quadrotor.yaml) use one band for all four, 2 % first and 5 % as the second
reading, so no band is picked per figure to match. The responses are fig_thesis.py's simulations.

    python -c "from settling_bands import settling; print(settling(0, '3.11', '0.05'))"
"""

from __future__ import annotations

from fig_thesis import Mode, settling_time, simulate

FIGURES = {
    # figure: (response, final value, scale of the band)
    "3.5": (lambda: simulate(Mode.VELOCITY, 30, 3.4, v_ref=0.5)["v"], 0.5, 0.5),  # velocity PI, 0.5 m/s step
    "3.8": (lambda: simulate(Mode.POSITION, 400, 2.6, r_ref=50.0)["r"], 50.0, 50.0),  # position PID, 50 m step
    "3.11": (lambda: simulate(Mode.TRACK, 100, 1e9, r0=2.5)["r"], 0.0, 2.5),  # tracker, 2.5 m error, no u_sat
    "3.13": (lambda: simulate(Mode.TRACK, 100, 3.4, r0=2.5)["r"], 0.0, 2.5),  # tracker, u_sat 3.4 m/s^2
}


def settling(seed: int, figure: str, band: str) -> float:
    """Settling time, s, of the thesis figure's response into ``band`` (a fraction, e.g. "0.02") of
    its step; deterministic (the seed is unused)."""
    response, final, scale = FIGURES[figure]
    return settling_time(response(), final, band=float(band), scale=scale)
