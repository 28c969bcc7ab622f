"""Thesis numbers reproduced by the shipped controllers and formation code (claim functions).

Karydes (2020), papers/quadrotor-swarms-thesis.md. Chapter 3: the synthesised gains (eq. 3.28,
3.36-3.40, section 3.2.5) and the step responses of Fig. 3.5, 3.8, 3.11, 3.13 and 3.14, flown on the
thesis' discrete double integrator (eq. 3.21-3.22, T_s = 0.1 s) with
:mod:`swarmscene.methods.quadrotor.thesis_controllers`, exactly as tests/methods/quadrotor/ do.
Chapter 4: Fig. 4.8's formation graph for N = 40 (M_max = 60 cells, M = 42 kept).

Every function takes the seed first (ignored: all of this is deterministic) and returns a float;
benchmarks/reproduction/claims/thesis_quadrotor.yaml and thesis_outdoor.yaml call them.

Run: python benchmarks/reproduction/fig_thesis.py   (prints every value)
"""

from __future__ import annotations

import numpy as np

from swarmscene.core.setpoint import Mode
from swarmscene.methods.outdoor.hex_pattern import hex_pattern
from swarmscene.methods.quadrotor.thesis_controllers import (
    ThesisController,
    position_gains,
    tracker_gains,
    velocity_gains,
)

T_S = 0.1
VG = velocity_gains(0.30, 0.80, T_S)  # section 3.2.3
PG = position_gains(0.23, 0.71, T_S)  # section 3.2.4
TG = tracker_gains(1.5, 0.71, T_S)  # section 3.2.5
GAINS = {"K_Pv": VG.K_Pv, "K_Iv": VG.K_Iv, "K_Fv": VG.K_Fv, "K_Pr": PG.K_Pr, "K_Ir": PG.K_Ir,
         "K_Dr": PG.K_Dr, "K_Fr": PG.K_Fr, "K_Pt": TG.K_Pt, "K_It": TG.K_It, "K_Dt": TG.K_Dt}
ZERO = np.zeros((1, 3))


def gain(seed: int, name: str) -> float:
    """A synthesised gain by its thesis name (K_Pv ... K_Dt)."""
    return float(GAINS[name])


def simulate(mode: Mode, steps: int, u_sat: float, r0: float = 0.0, r_ref: float = 0.0,
             v_ref: float = 0.0) -> dict[str, np.ndarray]:
    """One agent on the x axis of the discrete double integrator, one law (r, v, u per tick)."""
    ctrl = ThesisController(1, VG, PG, TG, u_sat)
    r, v = ZERO.copy(), ZERO.copy()
    r[0, 0] = r0
    rr, vr = ZERO.copy(), ZERO.copy()
    rr[0, 0], vr[0, 0] = r_ref, v_ref
    out: dict[str, list[float]] = {"r": [], "v": [], "u": []}
    for _ in range(steps):
        u = ctrl.step(np.array([mode], dtype=np.int8), r, v, rr, vr, ZERO)
        out["r"].append(r[0, 0])
        out["v"].append(v[0, 0])
        out["u"].append(u[0, 0])
        r, v = r + T_S * v + 0.5 * T_S**2 * u, v + T_S * u
    return {k: np.array(a) for k, a in out.items()}


def settling_time(y: np.ndarray, final: float, band: float = 0.05, scale: float | None = None) -> float:
    """First time after which |y - final| stays within band * scale, s."""
    scale = abs(final) if scale is None else scale
    outside = np.flatnonzero(np.abs(y - final) > band * scale)
    return 0.0 if outside.size == 0 else float((outside[-1] + 1) * T_S)


def fig_3_5_settling(seed: int) -> float:
    """Velocity PI, 0.5 m/s step, u_sat = 3.4 m/s^2: 5 % settling time, s (thesis: 0.3 s)."""
    return settling_time(simulate(Mode.VELOCITY, 30, 3.4, v_ref=0.5)["v"], 0.5)


def fig_3_8_settling(seed: int) -> float:
    """Position PID, 50 m step, u_sat = 2.6 m/s^2: 5 % settling time, s (thesis: 13 s)."""
    return settling_time(simulate(Mode.POSITION, 400, 2.6, r_ref=50.0)["r"], 50.0)


def fig_3_8_overshoot(seed: int) -> float:
    """Position PID, 50 m step: overshoot as a fraction (thesis: below 5 %)."""
    return float(simulate(Mode.POSITION, 400, 2.6, r_ref=50.0)["r"].max() / 50.0 - 1.0)


def fig_3_11_undershoot(seed: int) -> float:
    """Tracker, 2.5 m initial error, no saturation: undershoot as a fraction (thesis: 30 %)."""
    return float(-simulate(Mode.TRACK, 100, 1e9, r0=2.5)["r"].min() / 2.5)


def fig_3_11_settling(seed: int) -> float:
    """Tracker, 2.5 m initial error, no saturation: 2 % settling time, s (thesis: 5 s)."""
    return settling_time(simulate(Mode.TRACK, 100, 1e9, r0=2.5)["r"], 0.0, band=0.02, scale=2.5)


def fig_3_13_settling(seed: int) -> float:
    """Tracker, 2.5 m initial error, u_sat = 3.4 m/s^2: 5 % settling time, s (thesis: 3 s)."""
    return settling_time(simulate(Mode.TRACK, 100, 3.4, r0=2.5)["r"], 0.0, scale=2.5)


def fig_3_14_error(seed: int, delay: str = "0.3") -> float:
    """Max distance, m, between the tracker and its target (position PID on a 50 m step, u_sat
    2.6 m/s^2), the tracker (u_sat 3.4 m/s^2) receiving r̄, v̄, ū ``delay`` s late (thesis: < 1.6 m
    at 0.3 s). Same setting as tests/methods/quadrotor/test_fig_3_14.py."""
    lag = int(round(float(delay) / T_S))
    target, tracker = ThesisController(1, VG, PG, TG, 2.6), ThesisController(1, VG, PG, TG, 3.4)
    r_t, v_t, r, v = ZERO.copy(), ZERO.copy(), ZERO.copy(), ZERO.copy()
    ref = ZERO.copy()
    ref[0, 0] = 50.0
    sent, worst = [], 0.0
    for k in range(600):
        u_t = target.step(np.array([Mode.POSITION]), r_t, v_t, ref, ZERO, ZERO)
        sent.append((r_t.copy(), v_t.copy(), u_t.copy()))
        u = tracker.step(np.array([Mode.TRACK]), r, v, *sent[max(0, k - lag)])
        worst = max(worst, float(np.linalg.norm(r - r_t)))
        r_t, v_t = r_t + T_S * v_t + 0.5 * T_S**2 * u_t, v_t + T_S * u_t
        r, v = r + T_S * v + 0.5 * T_S**2 * u, v + T_S * u
    return worst


def fig_4_8_cells(seed: int, which: str = "m", n: str = "40") -> float:
    """Fig. 4.8, N = 40: ``m_max`` hexagon cells of rings 1..rho_max (60) or ``m`` kept (42)."""
    p = hex_pattern(int(n), 5.0)
    return float(p.m_max if which == "m_max" else len(p.axial))


def main() -> int:
    """Print the gains and every thesis figure's reading for seed 0, one ``name = value`` line each."""
    for name in GAINS:
        print(f"{name} = {gain(0, name):.5g}")
    for f in (fig_3_5_settling, fig_3_8_settling, fig_3_8_overshoot, fig_3_11_undershoot, fig_3_11_settling,
              fig_3_13_settling, fig_3_14_error):
        print(f"{f.__name__} = {f(0):.4g}")
    print(f"fig_4_8 M_max = {fig_4_8_cells(0, 'm_max'):.0f}, M = {fig_4_8_cells(0, 'm'):.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
