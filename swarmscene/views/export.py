"""Exports for other tools and for real vehicles: per-agent CSV, Crazyflie piecewise polynomials.

    python -m swarmscene.views.export RUN_DIR --csv OUT_DIR          # one CSV per agent
    python -m swarmscene.views.export RUN_DIR --crazyflie OUT_DIR    # a planned show for Crazyflies

Per-agent CSV (:func:`trajectory_csv`): ``agent_<i>.csv`` with a header line and the columns
``t, x, y, z, vx, vy, vz, healthy`` (s, m, m/s, 0/1), and with attitude dynamics also
``yaw, qw, qx, qy, qz`` (rad, unwrapped; body-to-world quaternion), one row per recorded frame.

Crazyflie export (:func:`crazyflie_trajectories`): each vehicle's path as piecewise polynomials in
the format the Crazyflie firmware's high-level commander stores (``struct poly4d``: for each
piece, 8 float32 coefficients of x, y, z and yaw in ascending powers of the time since the start
of the piece, and its float32 duration; 132 bytes), written as the CSV that Crazyswarm2's
``uav_trajectory.Trajectory.loadcsv`` reads and ``cf.uploadTrajectory`` sends::

    Duration,x^0,...,x^7,y^0,...,y^7,z^0,...,z^7,yaw^0,...,yaw^7

one file ``cf_<i>.csv`` per vehicle, plus ``crazyflie.json`` with the fit's numbers and the
limits checked, Crazyswarm2's ``crazyflies.yaml`` (:func:`crazyswarm2_config`: each vehicle's
``initial_position``, the start of its trajectory), ``crazyswarm2_show.py``, a script for
Crazyswarm2's ``crazyflie_py`` that uploads the trajectories and flies the show (the module
:mod:`swarmscene.views.crazyswarm2_show`, copied unchanged), and ``crazyswarm2_show.json``, the show it
flies (:func:`crazyswarm2_show_data`: robots, first points, duration, floor). The firmware keeps
uploaded trajectories in ``TRAJECTORY_MEMORY_SIZE`` = 4096 bytes (``crtp_commander_high_level.h``:
"4k allows us to store 31 poly4d pieces"), so a vehicle's path has at most 31 pieces.

Source of the path (``source``): ``plan`` evaluates the formation's open-loop plan (the VRB air
show's flat outputs p_i(t), psi_i(t), Theorems 1-2) at 100 Hz; ``flown`` uses the recorded
trajectory (positions, yaw from the attitude). ``auto`` (default) takes the plan when the run's
formation has one.

Fit: a degree-7 B-spline per vehicle (x, y, z, yaw share its knots, as a poly4d piece shares one
duration) fitted by least squares to the samples, each interior knot of multiplicity 4, so every
join is C^3 (position to jerk continuous: the commander's velocity, acceleration and the body
rates it derives from jerk have no jumps; C^4 needs about 15 % more pieces for the same error).
Knots are added where the error is largest (the worst piece is split in two) until the error is
below ``tolerance`` (5 mm, 0.01 rad yaw by default) or the memory is full. The polynomials are
then evaluated with float32 coefficients, as the vehicle stores them, to report the error.

Limits (:data:`CRAZYFLIE`, Crazyflie 2.x, ``platform_defaults_cf2.h`` of the firmware):
    collective thrust per unit mass |a + g e_3| <= 4 THRUST_MAX / CF_MASS = 15.5 m/s^2
        (THRUST_MAX 0.1125 N per motor, CF_MASS 0.029 kg) and a_z >= -g (rotors only push);
    with the PID controller (``stabilizer.controller: 1``, Crazyswarm2's default) also:
        |v_x|, |v_y|, |v_z| <= 1.0 m/s (PID_POS_VEL_X/Y/Z_MAX, the position loop's velocity cap:
        that controller takes no velocity feed-forward, so a faster plan cannot be tracked) and
        tilt <= 20 degrees (PID_VEL_ROLL_MAX / PID_VEL_PITCH_MAX).
    The Mellinger controller (``controller: 2``) tracks the polynomials' velocity and acceleration
    as feed-forward and has no velocity cap; only the thrust limit applies.
``time_scale`` > 1 slows the show down uniformly (same path; velocity / s, acceleration / s^2);
``time_scale="auto"`` picks the smallest scale >= 1 (in steps of 0.05) within the chosen
controller's limits.

The command line refuses a show that exceeds a limit (one line, exit status 1, nothing written);
``--allow-exceed`` writes it anyway with a warning line.

Safety of the placed show (:func:`safety_checks`, on the fitted polynomials as flown, after any
``--fit-box``, ``--scale`` or ``--time-scale``), refused the same way (one line naming the vehicles,
the time and the scale applied; ``--allow-exceed`` writes it anyway):
    keep-out ellipsoid: two vehicles with ||E^-1 (p_i - p_j)|| < 1, E = diag(0.12, 0.12, 0.3) m
        (``--keep-out``; Preiss et al. 2017, the Crazyswarm planners': the rotors' downwash reaches
        farther below a vehicle than beside it);
    separation limit: two vehicles closer than the run's ``safety.separation_limit`` (the distance
        its safety verdicts were judged at; a show scaled down keeps its shape, not its margins);
    floor clearance: a vehicle in the air lower than ``--floor-clearance`` (0.25 m) above the floor
        (its take-off before it first reaches that height and its landing after it last leaves it
        excepted), or under the floor. The lab's floor is ``--floor``, else the fitted box's (its
        zmin + 2 x tolerance), else the run's ``environment.floor`` for a show not placed (z = 0
        for one placed with ``--scale`` / ``--offset``, or a run without a floor). ``--takeoff`` and
        ``--land`` start and end on it.
``--fit-box`` puts a show that starts in the air (its lowest point more than 5 cm above the run's
ground, ``environment.floor`` or z = 0) with its lowest point at the floor clearance, so its script
takes off to it; a show that starts on the ground starts on the box's floor. The scale applied is
printed.

Placement in a lab (:class:`Placement`, :class:`Box`): ``--scale S`` and ``--offset X Y Z``
(p' = S p + offset) or ``--fit-box`` (the largest uniform S <= 1 and the shift that fit the show into
a box, a margin of twice the tolerance inside each face) act on the samples before the fit, so the
limits are checked on the placed show. ``--geofence`` (or the fitted box) is checked on the fitted
polynomials (:func:`geofence_breach`): a show leaving it is refused in one line naming the vehicle,
the time and the face (exit status 1; ``--allow-exceed`` does not override it).

Take-off and landing (:class:`Segments`): ``--takeoff`` / ``--land`` SECONDS add one degree-7
piece each, from rest on the floor to the show's first state and from its last state to rest,
matched to jerk (:func:`hermite7`); the limits and the geofence are checked on them too.
"""

from __future__ import annotations

import argparse
import io
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.vectors import quat_yaw
from ..runs.outputs import atomic_write_bytes, atomic_write_json
from . import crazyswarm2_show

GRAVITY = 9.81
POLY_DEGREE = 7
"""Degree of each axis's polynomial in a poly4d piece (8 coefficients)."""
AXES = ("x", "y", "z", "yaw")
PIECE_BYTES = (len(AXES) * (POLY_DEGREE + 1) + 1) * 4
"""Bytes of one ``struct poly4d``: float p[4][8] and float duration (132)."""
TRAJECTORY_MEMORY_BYTES = 4096
"""The firmware's TRAJECTORY_MEMORY_SIZE (crtp_commander_high_level.h)."""
MAX_PIECES = TRAJECTORY_MEMORY_BYTES // PIECE_BYTES
"""31 pieces fit in the trajectory memory."""
KNOT_MULTIPLICITY = 4
"""Each interior knot's multiplicity: continuity C^(7-4) = C^3 at every join."""
SAMPLE_RATE = 100.0
"""Hz, samples of the plan fitted and checked."""
MIN_PIECE_SAMPLES = POLY_DEGREE + 1
"""A piece is split only where each half keeps this many samples, as many as its polynomial has
coefficients: shorter pieces leave the least-squares problem undetermined (pieces of 7 ms between
0.1 s samples held inf, or swung 200 m between two samples)."""
CSV_HEADER = "Duration," + ",".join(f"{axis}^{k}" for axis in AXES for k in range(POLY_DEGREE + 1))


@dataclass(frozen=True)
class Limits:
    """What a Crazyflie can fly with a given controller (module docstring for the sources)."""

    controller: str
    max_collective_acc: float  # m/s^2, |a + g e_3|
    max_axis_speed: float | None = None  # m/s, per world axis; None: no cap
    max_tilt_deg: float | None = None  # degrees; None: no cap


_CF_MASS = 0.029  # kg, CF_MASS
_THRUST_MAX = 0.1125  # N per motor, THRUST_MAX
CRAZYFLIE = {
    "mellinger": Limits("mellinger", 4 * _THRUST_MAX / _CF_MASS),
    "pid": Limits("pid", 4 * _THRUST_MAX / _CF_MASS, max_axis_speed=1.0, max_tilt_deg=20.0),
}


KEEP_OUT = (0.12, 0.12, 0.3)
"""m: radii x, y, z of the Crazyflie's keep-out ellipsoid (Preiss, Hönig, Ayanian, Sukhatme,
"Downwash-aware trajectory planning for large quadrotor teams", IROS 2017)."""
FLOOR_CLEARANCE = 0.25
"""m: the least height above the floor of a vehicle in the air (ground effect and the motion
capture's view of the floor make lower flight unreliable; Crazyswarm's examples fly at 0.5-1 m)."""


@dataclass(frozen=True)
class Poly4D:
    """A vehicle's piecewise polynomial trajectory in the high-level commander's poly4d layout.

    Attributes:
        durations: (P,) s, each piece's duration.
        coeffs: (P, 4, 8) coefficients of x, y, z (m) and yaw (rad) in ascending powers of the
            time since the start of the piece.
        t0: s, the simulation time of the start of the first piece.
    """

    durations: np.ndarray
    coeffs: np.ndarray
    t0: float = 0.0

    @property
    def pieces(self) -> int:
        """Number of polynomial pieces."""
        return len(self.durations)

    @property
    def nbytes(self) -> int:
        """Bytes in the vehicle's trajectory memory (PIECE_BYTES per piece)."""
        return self.pieces * PIECE_BYTES

    @property
    def duration(self) -> float:
        """Total duration of the pieces, s."""
        return float(np.sum(self.durations))

    def as_float32(self) -> Poly4D:
        """The polynomials as the vehicle stores them (float32 coefficients and durations)."""
        return Poly4D(self.durations.astype(np.float32).astype(float),
                      self.coeffs.astype(np.float32).astype(float), self.t0)

    def evaluate(self, t: ArrayLike, derivative: int = 0) -> np.ndarray:
        """(T, 4): x, y, z, yaw (or their ``derivative``-th time derivative) at times ``t``
        (simulation time; clipped to the trajectory), vectorised over times."""
        t = np.atleast_1d(np.asarray(t, float)) - self.t0
        starts = np.concatenate([[0.0], np.cumsum(self.durations)[:-1]])
        piece = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, self.pieces - 1)
        tau = np.clip(t - starts[piece], 0.0, self.durations[piece])
        k = np.arange(POLY_DEGREE + 1)
        # d^n/dt^n tau^k = k! / (k-n)! tau^(k-n)
        fall = np.array([np.prod(np.arange(j - derivative + 1, j + 1)) if j >= derivative else 0.0 for j in k])
        powers = np.where(k >= derivative, tau[:, None] ** np.maximum(k - derivative, 0), 0.0) * fall
        return np.einsum("tak,tk->ta", self.coeffs[piece], powers)

    def to_csv(self, path: Path) -> None:
        """Crazyswarm2's trajectory CSV (module docstring), written atomically."""
        rows = np.column_stack([self.durations, self.coeffs.reshape(self.pieces, -1)])
        lines = [CSV_HEADER] + [",".join(f"{v:.9g}" for v in row) for row in rows]
        atomic_write_bytes(Path(path), ("\n".join(lines) + "\n").encode())

    @classmethod
    def from_csv(cls, path: Path, t0: float = 0.0) -> Poly4D:
        """Read a trajectory CSV as Crazyswarm2 does (skip the header, 33 columns)."""
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        return cls(data[:, 0], data[:, 1:].reshape(-1, len(AXES), POLY_DEGREE + 1), t0)


def _lsq_spline(t: np.ndarray, y: np.ndarray, breaks: np.ndarray) -> Any:
    """Least-squares degree-7 B-spline through samples y (T, 4) with interior ``breaks``."""
    from scipy.interpolate import make_lsq_spline

    k = POLY_DEGREE
    interior = np.repeat(breaks[1:-1], KNOT_MULTIPLICITY)
    knots = np.concatenate([np.full(k + 1, breaks[0]), interior, np.full(k + 1, breaks[-1])])
    return make_lsq_spline(t, y, knots, k=k)


def _to_poly4d(spline: Any, breaks: np.ndarray) -> Poly4D:
    """Taylor coefficients of each piece at its start: c_k = f^(k)(t_j+) / k!."""
    from math import factorial

    starts = breaks[:-1]
    # BSpline evaluates at a knot with the piece to its right, so these are the right-hand limits
    coeffs = np.stack([spline(starts, nu=n) / factorial(n) for n in range(POLY_DEGREE + 1)], axis=-1)  # (P, 4, 8)
    return Poly4D(np.diff(breaks), coeffs, float(breaks[0]))


@dataclass(frozen=True)
class Fit:
    """A fitted vehicle path and how well it matches its samples."""

    poly: Poly4D
    max_position_error: float  # m, float32 coefficients, per axis, at the samples and midway between them
    max_yaw_error: float  # rad


def fit_poly4d(t: np.ndarray, samples: np.ndarray, tolerance: float = 0.005, yaw_tolerance: float = 0.01,
               max_pieces: int = MAX_PIECES) -> Fit:
    """Fit piecewise degree-7 polynomials to ``samples`` (T, 4: x, y, z m, yaw rad) at times ``t``.

    Starts from pieces of about 4 s and splits the piece with the largest error (relative to the
    tolerances) until every sample, and every point midway between two samples (against the
    samples' cubic interpolant: a fit may swing between the samples it meets), is within
    ``tolerance`` m and ``yaw_tolerance`` rad, or the vehicle's memory (``max_pieces``) is full,
    or no piece holds enough samples to be split (:data:`MIN_PIECE_SAMPLES` each half); the best
    fit found is returned either way. Coefficients that are not finite are a ValueError.
    """
    from scipy.interpolate import CubicSpline

    t = np.asarray(t, float)
    samples = np.asarray(samples, float)
    scale = np.array([tolerance] * 3 + [yaw_tolerance])
    mid = 0.5 * (t[:-1] + t[1:])
    at = np.concatenate([t, mid])
    want = np.concatenate([samples, CubicSpline(t, samples)(mid)]) if len(t) > 1 else samples
    pieces = int(np.clip(np.ceil((t[-1] - t[0]) / 4.0), 1, max_pieces))
    breaks = np.linspace(t[0], t[-1], pieces + 1)
    while True:
        poly = _to_poly4d(_lsq_spline(t, samples, breaks), breaks).as_float32()
        if not np.isfinite(poly.coeffs).all():
            raise ValueError(f"a fit of {poly.pieces} pieces to {len(t)} samples has coefficients that are not finite")
        err = np.abs(poly.evaluate(at) - want)
        worst = np.max(err / scale, axis=1)  # (T + T - 1,) relative to the tolerances
        splittable = _splittable(t, breaks)
        if worst.max() <= 1.0 or poly.pieces >= max_pieces or not splittable.any():
            return Fit(poly, float(err[:, :3].max()), float(err[:, 3].max()))
        piece = np.clip(np.searchsorted(breaks, at, side="right") - 1, 0, poly.pieces - 1)
        per_piece = np.zeros(poly.pieces)
        np.maximum.at(per_piece, piece, worst)
        j = int(np.argmax(np.where(splittable, per_piece, -np.inf)))
        breaks = np.insert(breaks, j + 1, 0.5 * (breaks[j] + breaks[j + 1]))


def _splittable(t: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    """Per piece: whether both its halves would hold :data:`MIN_PIECE_SAMPLES` samples."""
    halves = np.sort(np.concatenate([breaks, 0.5 * (breaks[:-1] + breaks[1:])]))
    counts = np.diff(np.searchsorted(t, halves, side="left"))
    counts[-1] += int(np.count_nonzero(t == breaks[-1]))  # the last sample closes the last half
    return (counts[0::2] >= MIN_PIECE_SAMPLES) & (counts[1::2] >= MIN_PIECE_SAMPLES)


# -- sources ------------------------------------------------------------------------------------
def planned_flat_outputs(config: dict[str, Any], t: np.ndarray) -> np.ndarray | None:
    """(T, N, 4) planned x, y, z, yaw of every agent at times ``t``, or None when the run's
    formation flies no open-loop plan (only the VRB formation does)."""
    from ..runs.build import build

    formation = build(config).formation  # ConfigError (a ValueError) for a damaged config
    if not (hasattr(formation, "trajectory") and hasattr(formation, "flight")):
        return None
    from ..methods.vrb.transform import robot_flat_outputs

    fo = robot_flat_outputs(formation.trajectory, formation.flight, t)
    return np.concatenate([fo.p[0], fo.yaw[0][..., None]], axis=-1)


def plan_span(config: dict[str, Any], flown_until: float) -> tuple[float, float]:
    """(start, end) s of the show: from t = 0 to where the run ended, ``flown_until`` (its last
    recorded time), or its clock's end if that is earlier. A run that stopped early (a mission
    complete, a stop) flew less than its clock: the show does too (the plan past the stop was
    never flown, and a huge ``clock.duration`` would ask for that many samples)."""
    return 0.0, min(float((config.get("clock") or {}).get("duration", 0.0)), float(flown_until))


def yaw_from_quat(quat: np.ndarray) -> np.ndarray:
    """(T, N) rad, unwrapped over time: the heading of the body x axis, from (w, x, y, z)."""
    return np.unwrap(quat_yaw(quat), axis=0)


def show_samples(run_dir: Path, source: str = "auto") -> tuple[np.ndarray, np.ndarray, str]:
    """(t (T,), samples (T, N, 4), source used) of a run directory's show (module docstring)."""
    from ..core.errors import ConfigError
    from ..runs.rundir import CONFIG, RunFileError
    from .plots import load_run

    run = load_run(run_dir)
    if source in ("auto", "plan"):
        start, end = plan_span(run.config, float(run.t[-1]))
        t = np.linspace(start, end, int(round((end - start) * SAMPLE_RATE)) + 1)
        try:
            planned = planned_flat_outputs(run.config, t)
        except ConfigError as exc:  # the run's config.yaml no longer validates: name the file
            raise RunFileError(Path(run_dir) / CONFIG, f"does not load as a scenario ({exc.lines[0]})") from None
        if planned is not None:
            return t, planned, "plan"
        if source == "plan":
            name = (run.config.get("formation") or {}).get("name")
            raise ValueError(f"formation {name!r} flies no open-loop plan: use source 'flown'")
    _refuse_non_finite(Path(run_dir) / "trajectory.npz", run.t, run.pos)
    yaw = yaw_from_quat(run.quat) if run.quat is not None else np.zeros(run.pos.shape[:2])
    return np.asarray(run.t, float), np.concatenate([run.pos, yaw[..., None]], axis=-1), "flown"


def _refuse_non_finite(where: Any, t: np.ndarray, pos: np.ndarray) -> None:
    """A ValueError naming ``where``, the first vehicle and the time of a non-finite position."""
    bad = ~np.isfinite(np.asarray(pos, float)).all(axis=-1)  # (T, N)
    if bad.any():
        k, i = (int(v[0]) for v in np.nonzero(bad))  # row-major: the earliest time, then the lowest index
        raise ValueError(f"{where}: vehicle {i} has a non-finite position {np.asarray(pos)[k, i].tolist()} at "
                         f"t = {float(np.asarray(t)[k]):g} s ({int(bad.any(axis=0).sum())} vehicles); nothing written")


# -- limits -------------------------------------------------------------------------------------
def limit_checks(poly: Poly4D, limits: Limits, t: np.ndarray) -> list[dict[str, Any]]:
    """Each limit of ``limits`` with the polynomials' extreme value over times ``t``."""
    vel = poly.evaluate(t, 1)[:, :3]
    acc = poly.evaluate(t, 2)[:, :3]
    thrust = acc + np.array([0.0, 0.0, GRAVITY])
    checks: list[dict[str, Any]] = [
        {"name": "collective thrust |a + g e3| (m/s^2)", "value": float(np.linalg.norm(thrust, axis=1).max()),
         "limit": limits.max_collective_acc},
        {"name": "downward acceleration -a_z (m/s^2)", "value": float(-acc[:, 2].min()), "limit": GRAVITY},
    ]
    if limits.max_axis_speed is not None:
        checks.append({"name": "axis speed max(|vx|, |vy|, |vz|) (m/s)", "value": float(np.abs(vel).max()),
                       "limit": limits.max_axis_speed})
    if limits.max_tilt_deg is not None:
        tilt = np.degrees(np.arccos(np.clip(thrust[:, 2] / np.linalg.norm(thrust, axis=1), -1.0, 1.0)))
        checks.append({"name": "tilt (deg)", "value": float(tilt.max()), "limit": limits.max_tilt_deg})
    for check in checks:
        check["holds"] = bool(check["value"] <= check["limit"])
    return checks


AUTO_SCALE_MAX = 5.0
"""The slowest ``--time-scale auto`` plays a show (five times as long)."""
AUTO_SCALE_STEP = 1.1
"""Factor by which ``auto`` raises the scale while the fitted polynomials break a limit."""


def _auto_time_scale(samples: np.ndarray, t: np.ndarray, limits: Limits) -> float:
    """Smallest scale >= 1 (steps of 0.05) at which the sampled plan is within ``limits`` (the
    first guess of ``--time-scale auto``: :func:`crazyflie_trajectories` raises it while the
    fitted polynomials break a limit)."""
    dt = np.gradient(t)
    vel = np.gradient(samples[..., :3], axis=0) / dt[:, None, None]
    acc = np.gradient(vel, axis=0) / dt[:, None, None]
    for scale in np.arange(1.0, AUTO_SCALE_MAX + 1e-4, 0.05):
        a = acc / scale**2 + np.array([0.0, 0.0, GRAVITY])
        ok = (np.linalg.norm(a, axis=-1).max() <= limits.max_collective_acc
              and (acc[..., 2] / scale**2).min() >= -GRAVITY)
        if limits.max_axis_speed is not None:
            ok &= np.abs(vel / scale).max() <= limits.max_axis_speed * 0.98  # margin for the fit
        if limits.max_tilt_deg is not None:
            tilt = np.degrees(np.arccos(np.clip(a[..., 2] / np.linalg.norm(a, axis=-1), -1, 1)))
            ok &= tilt.max() <= limits.max_tilt_deg
        if ok:
            return float(round(scale, 2))
    raise ValueError(f"no time scale up to 5 brings the show within the {limits.controller} limits")


def safety_checks(fits: list[Fit], t: np.ndarray, floor: float, clearance: float,
                  keep_out: tuple[float, float, float], separation_limit: float | None,
                  tolerance: float) -> list[dict[str, Any]]:
    """The placed show's safety over times ``t`` (module docstring): each check with its worst value,
    its limit, whether it holds and, where it does not, the first breach (vehicles, time)."""
    pos = np.stack([fit.poly.evaluate(t)[:, :3] for fit in fits], axis=1)  # (T, N, 3), float32 as flown
    checks = [_floor_check(pos, t, floor, clearance, tolerance),
              _pair_check(pos, t, "keep-out ellipsoid ||E^-1 (p_i - p_j)||", np.asarray(keep_out, float), 1.0)]
    if separation_limit is not None and separation_limit > 0:
        checks.append(_pair_check(pos, t, "separation (m)", np.ones(3), separation_limit))
    return checks


def _floor_check(pos: np.ndarray, t: np.ndarray, floor: float, clearance: float, tolerance: float) -> dict[str, Any]:
    """The least height above the floor of a vehicle in the air: below ``clearance`` only before its
    first reaching it (take-off) and after its last leaving it (landing); never under the floor."""
    height = pos[..., 2] - floor  # (T, N)
    worst, first = np.inf, None
    for i in range(height.shape[1]):
        h = height[:, i]
        up = np.flatnonzero(h >= clearance - 1e-9)
        flying = np.zeros(h.size, bool)
        if up.size:
            flying[up[0]: up[-1] + 1] = True
        low = (flying & (h < clearance - 1e-9)) | (h < -2 * tolerance) | (not up.size)
        value = float(h[flying].min()) if up.size else float(h.max())
        worst = min(worst, value)
        if low.any():
            k = int(np.flatnonzero(low)[0])
            if first is None or t[k] < first["time"]:
                first = {"vehicles": [f"cf_{i}"], "time": float(t[k]), "value": float(h[k])}
    return {"name": "height above the floor in the air (m)", "value": float(worst), "limit": clearance,
            "min": True, "holds": first is None, "first": first}


def _pair_check(pos: np.ndarray, t: np.ndarray, name: str, radii: np.ndarray, limit: float) -> dict[str, Any]:
    """The smallest ||(p_i - p_j) / radii|| over pairs and times against ``limit``, and its first breach."""
    n = pos.shape[1]
    worst, first = np.inf, None
    for i in range(n - 1):  # one vehicle against the later ones: (T, n - i - 1) at a time
        norm = np.sqrt((((pos[:, i + 1:] - pos[:, i: i + 1]) / radii) ** 2).sum(axis=-1))
        worst = min(worst, float(norm.min()))
        low = np.argwhere(norm < limit)
        if low.size:
            k, j = (int(v) for v in low[np.argmin(t[low[:, 0]])])
            if first is None or t[k] < first["time"]:
                first = {"vehicles": [f"cf_{i}", f"cf_{i + 1 + j}"], "time": float(t[k]), "value": float(norm[k, j])}
    return {"name": name, "value": float(worst) if np.isfinite(worst) else None, "limit": limit, "min": True,
            "holds": first is None, "first": first}


@dataclass(frozen=True)
class ShowExport:
    """The fitted trajectories of every vehicle and the checks (what ``crazyflie.json`` holds)."""

    fits: list[Fit]
    source: str
    time_scale: float
    controller: str
    checks: list[list[dict[str, Any]]]
    placement: Placement | None = None
    geofence: Box | None = None
    breach: dict[str, Any] | None = None  # the first exit from the geofence, None: inside
    segments: Segments | None = None
    safety: tuple[dict[str, Any], ...] = ()  # safety_checks of the placed show
    floor: float = 0.0  # m, the lab's floor the show was checked against

    def record(self) -> dict[str, Any]:
        """What the export records of itself: format, source, time scale, placement, memory limits, checks."""
        return {
            "format": "poly4d (Crazyflie high-level commander; Crazyswarm2 trajectory CSV)",
            "source": self.source, "time_scale": self.time_scale, "controller": self.controller,
            "memory_bytes": TRAJECTORY_MEMORY_BYTES, "piece_bytes": PIECE_BYTES, "max_pieces": MAX_PIECES,
            "placement": {"scale": (self.placement or Placement()).scale,
                          "offset": list((self.placement or Placement()).offset)},
            "segments": None if self.segments is None else {"takeoff": self.segments.takeoff,
                                                             "land": self.segments.land, "floor": self.segments.floor},
            "geofence": None if self.geofence is None else {
                "min": list(self.geofence.lo), "max": list(self.geofence.hi), "breach": self.breach},
            "floor": self.floor, "safety": list(self.safety),
            "vehicles": [
                {"file": f"cf_{i}.csv", "pieces": fit.poly.pieces, "bytes": fit.poly.nbytes,
                 "duration": fit.poly.duration, "start_time": fit.poly.t0,
                 "max_position_error": fit.max_position_error, "max_yaw_error": fit.max_yaw_error,
                 "limits": checks}
                for i, (fit, checks) in enumerate(zip(self.fits, self.checks, strict=True))
            ],
        }

    def exceeded(self) -> list[str]:
        """One phrase per vehicle that breaks a limit (``cf_<i>: name value > limit``), empty when
        every limit holds."""
        phrases = []
        for i, checks in enumerate(self.checks):
            bad = [f"{c['name']} {c['value']:.3g} > {c['limit']:.3g}" for c in checks if not c["holds"]]
            if bad:
                phrases.append(f"cf_{i}: " + ", ".join(bad))
        return phrases

    def unsafe(self) -> list[str]:
        """One phrase per safety check that fails, naming its first breach (empty when safe)."""
        phrases = []
        for c in self.safety:
            if c["holds"]:
                continue
            f = c["first"]
            who = " and ".join(f["vehicles"])
            # the first breach, and the worst of the show where it is worse
            worse = c["value"] is not None and round(c["value"], 3) < round(f["value"], 3)
            if c["name"].startswith("height"):
                worst = f" ({c['value']:.3f} m at the lowest)" if worse else ""
                phrases.append(f"{who} flies {f['value']:.3f} m above the floor (z = {self.floor:g} m) at "
                               f"t = {f['time']:.2f} s{worst}, under the floor clearance {c['limit']:g} m")
            elif c["name"].startswith("keep-out"):
                worst = f", {c['value']:.2f} at the worst" if worse else ""
                phrases.append(f"{who} come inside each other's keep-out ellipsoid at t = {f['time']:.2f} s "
                               f"(||E^-1 (p_i - p_j)|| = {f['value']:.2f} < 1{worst})")
            else:
                worst = f" ({c['value']:.3f} m at the closest)" if worse else ""
                phrases.append(f"{who} come {f['value']:.3f} m apart at t = {f['time']:.2f} s{worst}, under the "
                               f"run's separation limit {c['limit']:g} m")
        return phrases

    def write(self, out_dir: Path) -> None:
        """``cf_<i>.csv`` per vehicle, ``crazyflie.json``, ``crazyflies.yaml``, ``crazyswarm2_show.json`` and
        ``crazyswarm2_show.py``, each written atomically."""
        out_dir = Path(out_dir)
        for i, fit in enumerate(self.fits):
            fit.poly.to_csv(out_dir / f"cf_{i}.csv")
        atomic_write_json(out_dir / "crazyflie.json", self.record())
        atomic_write_bytes(out_dir / "crazyflies.yaml", crazyswarm2_config(self).encode())
        atomic_write_json(out_dir / LAUNCH_DATA, crazyswarm2_show_data(self))
        atomic_write_bytes(out_dir / LAUNCH_SCRIPT, crazyswarm2_program())


# -- placement in a lab volume -------------------------------------------------------------------
@dataclass(frozen=True)
class Box:
    """An axis-aligned box of the world frame, m: lo = (xmin, ymin, zmin), hi = (xmax, ymax, zmax)."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    @classmethod
    def parse(cls, option: str, values: list[str]) -> Box:
        """``--fit-box`` / ``--geofence`` XMIN YMIN ZMIN XMAX YMAX ZMAX: finite, each min < max."""
        numbers = _finite_numbers(option, values)
        box = cls(_xyz(numbers[:3]), _xyz(numbers[3:]))
        for axis, lo, hi in zip("xyz", box.lo, box.hi, strict=True):
            if not lo < hi:
                raise ValueError(f"{option}: {axis}min must be below {axis}max (got {lo:g} and {hi:g})")
        return box


@dataclass(frozen=True)
class Placement:
    """The uniform similarity p' = scale p + offset applied to every position sample before the fit
    (yaw unchanged), so the fitted polynomials, the limits and the geofence are those of the placed
    show: velocity and acceleration scale by ``scale`` too."""

    scale: float = 1.0
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def apply(self, samples: np.ndarray) -> np.ndarray:
        """The samples placed: positions scaled about the origin and shifted by ``offset`` (yaw unchanged)."""
        placed = np.array(samples, float)
        placed[..., :3] = self.scale * placed[..., :3] + np.asarray(self.offset)
        return placed

    @classmethod
    def into(cls, samples: np.ndarray, box: Box, margin: float, lift: float = 0.0) -> Placement:
        """The largest uniform scale <= 1 (a show is never enlarged) that fits every position of
        ``samples`` (T, N, >=3) into ``box`` shrunk by ``margin`` on every face, and the shift that
        centres the show in x and y and puts its lowest point ``lift`` m above the shrunk floor
        (0: a show that starts on the ground starts on the lab's floor; a show that starts in the
        air is lifted to the floor clearance)."""
        lo, hi = samples[..., :3].min(axis=(0, 1)), samples[..., :3].max(axis=(0, 1))
        room_lo, room_hi = np.asarray(box.lo) + margin, np.asarray(box.hi) - margin
        room_lo[2] += lift
        room, extent = room_hi - room_lo, hi - lo
        if np.any(room <= 0):
            raise ValueError(f"--fit-box: the box leaves no room inside its {margin * 100:g} cm margin")
        ratios = [r / e for r, e in zip(room, extent, strict=True) if e > 0]
        scale = float(min([1.0, *ratios]))
        offset = 0.5 * (room_lo + room_hi) - scale * 0.5 * (lo + hi)
        offset[2] = room_lo[2] - scale * lo[2]
        return cls(scale, _xyz([float(v) for v in offset]))


FACES = ("min", "max")


def geofence_breach(fits: list[Fit], box: Box, t: np.ndarray) -> dict[str, Any] | None:
    """The earliest time over ``t`` at which a vehicle's polynomials (float32, as flown) leave ``box``:
    vehicle, time, face (``x min`` ... ``z max``) and the position there; None when all stay inside."""
    first = None
    for i, fit in enumerate(fits):
        pos = fit.poly.evaluate(t)[:, :3]
        outside = np.concatenate([pos < np.asarray(box.lo), pos > np.asarray(box.hi)], axis=1)  # (T, 6)
        rows = np.flatnonzero(outside.any(axis=1))
        if rows.size and (first is None or t[rows[0]] < first["time"]):
            k = int(rows[0])
            face = int(np.flatnonzero(outside[k])[0])
            axis, side = face % 3, FACES[face // 3]
            first = {"vehicle": f"cf_{i}", "time": float(t[k]), "face": f"{'xyz'[axis]} {side}",
                     "value": float(pos[k, axis]), "bound": float((box.lo, box.hi)[face // 3][axis])}
    return first


# -- take-off and landing -----------------------------------------------------------------------
def hermite7(start: np.ndarray, end: np.ndarray, duration: float) -> np.ndarray:
    """(4, 8) coefficients, ascending powers of tau in [0, duration], of the degree-7 polynomial per
    axis with the given position, velocity, acceleration and jerk at both ends (``start``, ``end``:
    (4 derivatives, 4 axes)): eight conditions, eight coefficients, so it joins a show C^3 as the
    fit's own joins are."""
    from math import factorial

    rows = []
    for tau in (0.0, duration):
        for n in range(4):  # d^n/dtau^n tau^k = k! / (k-n)! tau^(k-n)
            rows.append([factorial(k) / factorial(k - n) * tau ** (k - n) if k >= n else 0.0
                         for k in range(POLY_DEGREE + 1)])
    return np.linalg.solve(np.array(rows), np.concatenate([start, end])).T


@dataclass(frozen=True)
class Segments:
    """A take-off of ``takeoff`` s from rest on the floor (z = ``floor``) below the show's first point
    to the show's first state, and a landing of ``land`` s from its last state to rest on the floor
    below its last point (yaw held); each is one poly4d piece (:func:`hermite7`), None: none."""

    takeoff: float | None = None
    land: float | None = None
    floor: float | None = None  # m; None: 0, or with a fit box its shrunk floor (crazyflie_trajectories)

    @property
    def pieces(self) -> int:
        """Pieces it adds to a trajectory: one each for the take-off and the landing given."""
        return (self.takeoff is not None) + (self.land is not None)

    def _rest_below(self, state: np.ndarray) -> np.ndarray:
        rest = np.zeros((4, len(AXES)))
        rest[0] = state[0]
        rest[0, 2] = self.floor
        return rest

    def around(self, poly: Poly4D) -> Poly4D:
        """``poly`` with the take-off before it (its t0 moves ``takeoff`` s earlier) and the landing after."""
        end = poly.t0 + poly.duration
        first = np.stack([poly.evaluate([poly.t0], n)[0] for n in range(4)])  # (4 derivatives, 4 axes)
        last = np.stack([poly.evaluate([end], n)[0] for n in range(4)])
        durations: list[ArrayLike] = [poly.durations]
        coeffs, t0 = [poly.coeffs], poly.t0
        if self.takeoff is not None:
            durations.insert(0, [self.takeoff])
            coeffs.insert(0, hermite7(self._rest_below(first), first, self.takeoff)[None])
            t0 -= self.takeoff
        if self.land is not None:
            durations.append([self.land])
            coeffs.append(hermite7(last, self._rest_below(last), self.land)[None])
        return Poly4D(np.concatenate(durations), np.concatenate(coeffs), t0).as_float32()


CONTROLLER_PARAM = {"pid": 1, "mellinger": 2}
"""Firmware parameter ``stabilizer.controller`` of each controller."""


def crazyswarm2_config(show: ShowExport) -> str:
    """Crazyswarm2's ``crazyflies.yaml`` for the show: one robot ``cf_<i>`` per ``cf_<i>.csv`` with
    its ``initial_position`` (the start of its trajectory, float32 as stored, where the vehicle must
    stand), a placeholder radio address 0xE7E7E7E7<i> (Crazyswarm's convention; edit it to the lab's
    vehicles), the high-level commander on and the controller the limits were checked for."""
    import yaml

    robots = {
        f"cf_{i}": {"enabled": True, "uri": f"radio://0/80/2M/E7E7E7E7{i:02X}",
                    "initial_position": [float(v) for v in fit.poly.evaluate([fit.poly.t0])[0, :3]],
                    "type": "cf21"}
        for i, fit in enumerate(show.fits)
    }
    config = {
        "fileversion": 3,
        "robots": robots,
        "robot_types": {"cf21": {"motion_capture": {"enabled": True, "marker": "default_single_marker",
                                                    "dynamics": "default"},
                                 "big_quad": False}},
        "all": {"firmware_params": {"commander": {"enHighLevel": 1},
                                    "stabilizer": {"estimator": 2, "controller": CONTROLLER_PARAM[show.controller]}}},
    }
    header = ("# Crazyswarm2 crazyflies.yaml written by python -m swarmscene.views.export: one robot per cf_<i>.csv,\n"
              "# placed at the start of its trajectory. The radio addresses are placeholders: edit them.\n")
    return header + yaml.safe_dump(config, sort_keys=False)


LAUNCH_SCRIPT = "crazyswarm2_show.py"
"""The bundle's Crazyswarm2 script: :mod:`swarmscene.views.crazyswarm2_show` copied unchanged
(:func:`crazyswarm2_program`)."""
LAUNCH_DATA = crazyswarm2_show.DATA
"""``crazyswarm2_show.json``: the show the script flies (:func:`crazyswarm2_show_data`), beside it."""
ON_FLOOR = 0.05
"""m: a trajectory whose first (last) point is within this height of the floor starts (ends) on the
ground, so the script takes off (lands) with the trajectory itself."""
LANDING_CLEARANCE = 0.06
"""m above the floor where the script's own landing ends (Crazyswarm2's examples land at 0.06 m, so
that the controller does not press into a floor the motion capture sees a little off)."""


def _floor(show: ShowExport) -> float:
    """The floor of the show's lab (m), the one its safety was checked against (ShowExport.floor)."""
    return float(show.floor)


def crazyswarm2_show_data(show: ShowExport) -> dict[str, Any]:
    """``crazyswarm2_show.json``, the data :mod:`swarmscene.views.crazyswarm2_show` flies (its ``Show``).

    Each robot ``cf_<i>`` with its file ``cf_<i>.csv`` and its trajectory's first point (x, y, z m,
    yaw rad; float32, as the vehicle stores it), the trajectories' longest duration (float32), whether
    every trajectory starts (ends) within :data:`ON_FLOOR` of the floor, the floor (the one the show's
    safety was checked against) and :data:`LANDING_CLEARANCE` above it, where a landing from the air
    ends."""
    floor = _floor(show)
    starts = [fit.poly.evaluate([fit.poly.t0])[0] for fit in show.fits]
    ends = [fit.poly.evaluate([fit.poly.t0 + fit.poly.duration])[0] for fit in show.fits]
    duration = max(fit.poly.duration for fit in show.fits)
    return {
        "version": crazyswarm2_show.VERSION,
        "robots": [{"name": f"cf_{i}", "trajectory": f"cf_{i}.csv", "start": [float(np.float32(v)) for v in p]}
                   for i, p in enumerate(starts)],
        "show_seconds": float(np.float32(duration)),
        "starts_on_floor": all(p[2] - floor <= ON_FLOOR for p in starts),
        "ends_on_floor": all(p[2] - floor <= ON_FLOOR for p in ends),
        "floor": floor,
        "landing_height": round(floor + LANDING_CLEARANCE, 6),
    }


def crazyswarm2_program() -> bytes:
    """``crazyswarm2_show.py``: the module :mod:`swarmscene.views.crazyswarm2_show` as shipped, byte for byte
    (the bundle's copy reads its show from ``crazyswarm2_show.json`` beside it)."""
    from importlib import resources

    return resources.files("swarmscene.views").joinpath(LAUNCH_SCRIPT).read_bytes()


def crazyflie_trajectories(source: Path | tuple[np.ndarray, np.ndarray], out_dir: Path | None = None,
                           controller: str = "mellinger", time_scale: float | str = 1.0,
                           tolerance: float = 0.005, kind: str = "auto", placement: Placement | None = None,
                           fit_box: Box | None = None, geofence: Box | None = None,
                           segments: Segments | None = None, floor_clearance: float = FLOOR_CLEARANCE,
                           keep_out: tuple[float, float, float] = KEEP_OUT,
                           separation_limit: float | None = None, source_floor: float | None = None) -> ShowExport:
    """Fit every vehicle's path (a run directory, or (t (T,), samples (T, N, 4))) and write
    ``cf_<i>.csv`` and ``crazyflie.json`` into ``out_dir`` when given (module docstring).

    ``placement`` scales and shifts the show, or ``fit_box`` computes the placement that fits it
    into a box (a margin of twice the tolerance on every face, for the fit's error) and is then the
    geofence unless ``geofence`` is given. The geofence is checked on the fitted polynomials
    (``breach``); nothing here refuses: the command line does. ``segments`` adds a take-off before
    and a landing after each path (:class:`Segments`); the limits and the geofence cover them.
    The placed show's safety (:func:`safety_checks`: keep-out, ``separation_limit``, the floor
    clearance) is checked on the fitted polynomials; ``source_floor`` is the run's ground (z = 0 when
    None): a show whose lowest point is above it starts in the air (``--fit-box`` lifts it)."""
    limits = CRAZYFLIE[controller]
    if isinstance(source, tuple):
        t, samples = (np.asarray(a, float) for a in source)
        used = "samples"
    else:
        t, samples, used = show_samples(Path(source), kind)
    ground = 0.0 if source_floor is None else float(source_floor)
    names = {"samples": "samples", "plan": f"{source}: the formation's plan"}
    _refuse_non_finite(names.get(used, Path(str(source)) / "trajectory.npz"), t, samples[..., :3])
    if len(t) < MIN_PIECE_SAMPLES:  # one piece's coefficients need as many samples
        raise ValueError(f"{names.get(used, source)}: {len(t)} samples, fewer than the {MIN_PIECE_SAMPLES} a "
                         f"degree-{POLY_DEGREE} piece needs (a longer run, or a trajectory recorded more often)")
    if fit_box is not None:
        in_air = bool(samples[..., 2].min() > ground + ON_FLOOR)
        # lifted by the fit's tolerance too, so the fitted polynomials keep the clearance
        lift = floor_clearance + tolerance if in_air else 0.0
        placement = Placement.into(samples, fit_box, margin=2 * tolerance, lift=lift)
        geofence = geofence or fit_box
        if segments is not None and segments.floor is None:  # land where the placed show's lowest point is
            segments = Segments(segments.takeoff, segments.land, fit_box.lo[2] + 2 * tolerance)
    lab_floor = ground if placement is None else 0.0  # unplaced, the run's ground is the lab's floor
    if segments is not None and segments.floor is None:
        segments = Segments(segments.takeoff, segments.land, lab_floor)
    if placement is not None:  # before the time scale and the fit: the limits are the placed show's
        samples = placement.apply(samples)
    scale = _auto_time_scale(samples, t, limits) if time_scale == "auto" else float(time_scale)
    room = MAX_PIECES - (segments.pieces if segments is not None else 0)  # the segments' pieces are memory too
    while True:
        ts = t[0] + (t - t[0]) * scale
        fits = [fit_poly4d(ts, samples[:, i], tolerance=tolerance, max_pieces=room) for i in range(samples.shape[1])]
        if segments is not None:
            fits = [Fit(segments.around(fit.poly), fit.max_position_error, fit.max_yaw_error) for fit in fits]
        start, end = fits[0].poly.t0, fits[0].poly.t0 + fits[0].poly.duration
        dense = np.linspace(start, end, 4 * int(round((end - start) / (ts[-1] - ts[0]) * len(ts))))
        checks = [limit_checks(fit.poly, limits, dense) for fit in fits]
        # auto: the scale the samples suggested, raised while the fitted polynomials (what flies,
        # whose accelerations a fit of sparse flown samples can exceed) break a limit
        if time_scale != "auto" or all(c["holds"] for cs in checks for c in cs) or scale >= AUTO_SCALE_MAX:
            break
        scale = float(round(min(scale * AUTO_SCALE_STEP, AUTO_SCALE_MAX), 2))
    breach = geofence_breach(fits, geofence, dense) if geofence is not None else None
    if segments is not None and segments.floor is not None:
        floor = float(segments.floor)
    elif fit_box is not None:
        floor = fit_box.lo[2] + 2 * tolerance
    else:  # the run's ground (environment.floor, else z = 0); with --scale or --offset, z = 0
        floor = lab_floor
    safety = safety_checks(fits, dense, floor, floor_clearance, keep_out, separation_limit, tolerance)
    result = ShowExport(fits, used, scale, controller, checks, placement, geofence, breach, segments,
                        tuple(safety), floor)
    if out_dir is not None:
        result.write(out_dir)
    return result


def trajectory_csv(source: Any, out_dir: Path) -> list[Path]:
    """One ``agent_<i>.csv`` per agent from a run directory or a run's RunData (module docstring)."""
    from .plots import RunData, load_run

    run = source if isinstance(source, RunData) else load_run(Path(source))
    where = "trajectory" if isinstance(source, RunData) else Path(source) / "trajectory.npz"
    _refuse_non_finite(where, run.t, run.pos)
    columns = ["t", "x", "y", "z", "vx", "vy", "vz", "healthy"]
    t = np.broadcast_to(np.asarray(run.t, float)[:, None], run.pos.shape[:2])
    blocks = [t[..., None], np.asarray(run.pos, float), np.asarray(run.vel, float),
              np.asarray(run.healthy, float)[..., None]]
    if run.quat is not None:
        columns += ["yaw", "qw", "qx", "qy", "qz"]
        blocks += [yaw_from_quat(run.quat)[..., None], np.asarray(run.quat, float)]
    table = np.concatenate(blocks, axis=-1)  # (T, N, C)
    fmt = ["%.9g"] * (len(columns))
    fmt[columns.index("healthy")] = "%d"
    out_dir = Path(out_dir)
    written = []
    for i in range(run.n):  # one file per agent (export, not a per-step path)
        buffer = io.StringIO()
        np.savetxt(buffer, table[:, i], delimiter=",", fmt=fmt, header=",".join(columns), comments="")
        path = out_dir / f"agent_{i}.csv"
        atomic_write_bytes(path, buffer.getvalue().encode())
        written.append(path)
    return written


PROG = "python -m swarmscene.views.export"


def run_problem(run_dir: Path) -> str | None:
    """Why a run directory should not be exported (it failed, collided or did not complete), or
    None for a complete run without collisions. Reads through :mod:`swarmscene.runs.rundir`."""
    from ..runs.rundir import ERROR, MANIFEST, METRICS, RunDir, finite_or_none

    run = RunDir(run_dir)
    if not run.has(MANIFEST):
        return "did not complete (no manifest.json: the run was stopped before its end)"
    manifest = run.manifest()
    if run.has(ERROR) or manifest.get("status") == "failed":
        reason = run.error().get("error") if run.has(ERROR) else manifest.get("error")
        return f"failed ({reason})" if isinstance(reason, str) else "failed"
    if manifest.get("complete") is not True:
        return "did not complete (manifest.json: complete is not true)"
    metrics = run.metrics() if run.has(METRICS) else {}
    collisions = finite_or_none(metrics.get("collisions"))
    if metrics.get("stop_reason") == "collision" or (collisions is not None and collisions > 0):
        return f"collided (collisions = {metrics.get('collisions')}, stop_reason = {metrics.get('stop_reason')})"
    if metrics.get("stop_reason") == "non_finite":
        return "failed (a non-finite state)"
    return None


def _time_scale(text: str) -> float | str:
    """``--time-scale``: a finite number > 0, or ``auto``."""
    if text == "auto":
        return text
    value = _number(text)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"--time-scale: must be a number > 0 or 'auto' (got {text!r})")
    return value


def _number(text: Any) -> float:
    """An option's text as a float; NaN when it is not a number (each caller words its own line)."""
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _xyz(numbers: list[float]) -> tuple[float, float, float]:
    """Three numbers as a point (x, y, z); argparse gave exactly three per point (nargs)."""
    x, y, z = numbers
    return x, y, z


def _finite_numbers(option: str, values: list[str]) -> list[float]:
    numbers = []
    for text in values:
        value = _number(text)
        if not math.isfinite(value):
            raise ValueError(f"{option}: must be finite numbers of metres (got {text!r})")
        numbers.append(value)
    return numbers


def _placement(args: argparse.Namespace) -> tuple[Placement | None, Box | None, Box | None]:
    """``--scale`` / ``--offset`` or ``--fit-box``, and ``--geofence``, checked (one line each)."""
    given = [name for name, value in (("--scale", args.scale), ("--offset", args.offset), ("--fit-box", args.fit_box),
                                      ("--geofence", args.geofence), ("--takeoff", args.takeoff),
                                      ("--land", args.land), ("--floor", args.floor)) if value is not None]
    if given and args.crazyflie is None:
        raise ValueError(f"{given[0]}: places the Crazyflie show: give --crazyflie DIR")
    if args.fit_box is not None and (args.scale is not None or args.offset is not None):
        raise ValueError("--fit-box: computes the scale and offset itself: give it without --scale and --offset")
    placement = None
    if args.scale is not None or args.offset is not None:
        scale = _number(args.scale or "1")
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"--scale: must be a finite number > 0 (got {args.scale!r})")
        offset = _finite_numbers("--offset", args.offset or ["0", "0", "0"])
        placement = Placement(scale, _xyz(offset))
    fit_box = Box.parse("--fit-box", args.fit_box) if args.fit_box is not None else None
    geofence = Box.parse("--geofence", args.geofence) if args.geofence is not None else None
    return placement, fit_box, geofence


def _segments(args: argparse.Namespace) -> Segments | None:
    """``--takeoff`` / ``--land`` SECONDS (finite, > 0) and ``--floor`` Z (finite, with one of them)."""
    seconds = {}
    for option, text in (("--takeoff", args.takeoff), ("--land", args.land)):
        if text is None:
            continue
        value = _number(text)
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{option}: must be a finite number of seconds > 0 (got {text!r})")
        seconds[option] = value
    if args.floor is not None and not seconds:
        raise ValueError("--floor: is where --takeoff starts and --land ends: give one of them")
    if not seconds:
        return None
    floor = _finite_numbers("--floor", [args.floor])[0] if args.floor is not None else None
    return Segments(seconds.get("--takeoff"), seconds.get("--land"), floor)


def _safety_options(args: argparse.Namespace) -> tuple[float, tuple[float, float, float]]:
    """``--floor-clearance`` (finite, >= 0) and ``--keep-out`` (three finite radii > 0)."""
    clearance = _number(args.floor_clearance)
    if not (math.isfinite(clearance) and clearance >= 0):
        raise ValueError(f"--floor-clearance: must be a finite number of metres >= 0 (got {args.floor_clearance!r})")
    if args.keep_out is None:
        return clearance, KEEP_OUT
    radii = _finite_numbers("--keep-out", args.keep_out)
    if min(radii) <= 0:
        raise ValueError(f"--keep-out: each radius must be > 0 m (got {' '.join(args.keep_out)})")
    return clearance, _xyz(radii)


def _run_limits(run_dir: Path) -> tuple[float | None, float | None]:
    """The run's ``safety.separation_limit`` and ``environment.floor`` (None where its config has none),
    read through :mod:`swarmscene.runs.rundir`."""
    from ..runs.rundir import RunDir, finite_or_none

    config = RunDir(run_dir).config()
    safety, environment = config.get("safety"), config.get("environment")
    limit = safety.get("separation_limit") if isinstance(safety, dict) else None
    floor = environment.get("floor") if isinstance(environment, dict) else None
    return finite_or_none(limit), finite_or_none(floor)


def _tolerance(value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"--tolerance: must be a finite number of metres > 0 (got {value!r})")
    return value


class Unflyable(Exception):
    """The show cannot be flown as exported (a limit exceeded): exit status 1, nothing written."""


def _refuse_or_warn(show: ShowExport, allow_exceed: bool) -> None:
    """Refuse a show that leaves its geofence (always) or breaks its controller's limits (one line),
    or warn of the limits under ``--allow-exceed``."""
    b = show.breach
    if b is not None:
        sign = "<" if b["face"].endswith("min") else ">"
        raise Unflyable(f"{b['vehicle']} leaves the geofence at t = {b['time']:.2f} s through the {b['face']} face "
                        f"({b['face'][0]} = {b['value']:.3f} m {sign} {b['bound']:g} m); refused, nothing written "
                        "(--fit-box scales the show into a box)")
    unsafe = show.unsafe()
    if unsafe:
        what = f"{'; '.join(unsafe)} ({_placed(show)})"
        if not allow_exceed:
            raise Unflyable(f"{what}; refused, nothing written (--allow-exceed writes it anyway)")
        print(f"{PROG}: warning: {what}; written because of --allow-exceed", file=sys.stderr)
    exceeded = show.exceeded()
    if not exceeded:
        return
    what = f"the show exceeds the {show.controller} controller's limits ({'; '.join(exceeded)})"
    if not allow_exceed:
        slower = "--time-scale auto or a longer --takeoff/--land" if show.segments else "--time-scale auto"
        raise Unflyable(f"{what}; refused, nothing written ({slower} slows it down; "
                        "--allow-exceed writes it anyway)")
    print(f"{PROG}: warning: {what}; written because of --allow-exceed", file=sys.stderr)


def _placed(show: ShowExport) -> str:
    """The placement and time scale the show was checked at, as a phrase."""
    placement = show.placement or Placement()
    offset = ", ".join(f"{v:g}" for v in placement.offset)
    return f"scale {placement.scale:.3g}, offset ({offset}) m, time scale {show.time_scale:g}"


def main(argv: list[str] | None = None) -> None:
    """``python -m swarmscene.views.export RUN_DIR [--csv DIR] [--crazyflie DIR] ...``.

    Every problem is one line on stderr and exit status 2: a bad option (named), a run directory
    whose files are missing or damaged (the file named), a run that failed, collided or did not
    complete (unless ``--force``: then a warning, and the export goes on). A show that exceeds its
    controller's limits is one line and exit status 1, nothing written (unless ``--allow-exceed``:
    then a warning, the files written and exit status 0).
    """
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--csv", type=Path, metavar="DIR", help="write agent_<i>.csv (the recorded trajectory)")
    parser.add_argument("--crazyflie", type=Path, metavar="DIR",
                        help="write cf_<i>.csv, crazyflie.json, crazyflies.yaml, crazyswarm2_show.py and "
                             "crazyswarm2_show.json")
    parser.add_argument("--source", choices=("auto", "plan", "flown"), default="auto")
    parser.add_argument("--controller", choices=sorted(CRAZYFLIE), default="mellinger")
    parser.add_argument("--time-scale", default="1.0", help="slow the show down by this factor (> 0), or 'auto'")
    parser.add_argument("--tolerance", type=float, default=0.005, help="position fit tolerance, m (> 0)")
    parser.add_argument("--scale", metavar="S", help="scale the show's positions by S (> 0) about the world origin, "
                        "before the fit and the limits")
    parser.add_argument("--offset", nargs=3, metavar=("X", "Y", "Z"), help="then shift them by (X, Y, Z) m")
    parser.add_argument("--fit-box", nargs=6, metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
                        help="scale (never up) and shift the show into this box, m (also the geofence "
                             "unless --geofence is given)")
    parser.add_argument("--geofence", nargs=6, metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
                        help="refuse (exit status 1) a show whose polynomials leave this box, m")
    parser.add_argument("--takeoff", metavar="SECONDS", help="add a take-off: from rest on the floor below each "
                        "vehicle's first point to its first state, in SECONDS before the show")
    parser.add_argument("--land", metavar="SECONDS", help="add a landing: from each vehicle's last state to rest on "
                        "the floor below its last point, in SECONDS")
    parser.add_argument("--floor", metavar="Z", help="the floor's height, m (default: the run's environment.floor, "
                        "else 0; with --fit-box its zmin + 2 x --tolerance; with --scale/--offset 0)")
    parser.add_argument("--floor-clearance", metavar="M", default=str(FLOOR_CLEARANCE),
                        help=f"least height above the floor of a vehicle in the air, m (default {FLOOR_CLEARANCE}; "
                             "take-off and landing excepted)")
    parser.add_argument("--keep-out", nargs=3, metavar=("RX", "RY", "RZ"),
                        help="radii of the keep-out ellipsoid no two vehicles may enter, m (default "
                             f"{' '.join(map(str, KEEP_OUT))}, Crazyswarm's)")
    parser.add_argument("--allow-exceed", action="store_true",
                        help="write a show that exceeds the controller's limits or breaks the keep-out, "
                             "separation or floor clearance (a warning, exit 0), instead of refusing it "
                             "with exit status 1")
    parser.add_argument("--force", action="store_true",
                        help="export a run that failed, collided or did not complete (a warning, not a refusal)")
    parser.add_argument("--mcap", type=Path, metavar="OUT", help="write the run as a ROS 2 bag folder (docs/ros.md)")
    args = parser.parse_args(argv)
    if args.mcap is not None:  # the bag is a view of any run, failed or not: swarmscene/views/mcap_bag.py
        from .mcap_bag import export_main

        export_main(parser, args.run_dir, args.mcap)
        if args.csv is None and args.crazyflie is None:
            return
    if args.csv is None and args.crazyflie is None:
        parser.error("nothing to do: give --csv DIR and/or --crazyflie DIR")
    from ..runs.rundir import RunFileError

    try:
        scale = _time_scale(args.time_scale)
        tolerance = _tolerance(args.tolerance)
        placement, fit_box, geofence = _placement(args)
        segments = _segments(args)
        problem = run_problem(args.run_dir)
        if problem is not None:
            if not args.force:
                raise ValueError(f"{args.run_dir}: the run {problem}; refused (--force exports it anyway)")
            print(f"{PROG}: warning: {args.run_dir}: the run {problem}; exported because of --force",
                  file=sys.stderr)
        if args.crazyflie is not None:  # the show first: a refused one leaves nothing written, CSVs included
            clearance, keep_out = _safety_options(args)
            separation, ground = _run_limits(args.run_dir)
            show = crazyflie_trajectories(args.run_dir, None, args.controller, scale, tolerance, args.source,
                                          placement, fit_box, geofence, segments, clearance, keep_out,
                                          separation, ground)
            _refuse_or_warn(show, args.allow_exceed)  # before anything is written
        if args.csv is not None:
            print(f"{len(trajectory_csv(args.run_dir, args.csv))} agent CSV files in {args.csv}")
        if args.crazyflie is not None:
            show.write(args.crazyflie)
            for i, fit in enumerate(show.fits):  # the best fit is written; one that misses is said
                if fit.max_position_error > tolerance:
                    print(f"{PROG}: warning: cf_{i}'s fit misses the tolerance: {fit.max_position_error * 1000:.1f} mm "
                          f"> {tolerance * 1000:g} mm (the memory is full, or its samples too sparse to split "
                          "further)", file=sys.stderr)
    except Unflyable as exc:  # the show itself: a limit exceeded (status 1, not a bad input's 2)
        parser.exit(1, f"{PROG}: {exc}\n")
    except (RunFileError, ValueError) as exc:  # a damaged file, a bad option, a show no scale rescues
        parser.exit(2, f"{PROG}: {' '.join(str(exc).split())}\n")
    except OSError as exc:  # the output directory cannot be written (read-only, full disk)
        where = exc.filename or args.crazyflie or args.csv
        parser.exit(2, f"{PROG}: {where}: cannot be written ({exc.strerror or exc})\n")
    if args.crazyflie is not None:
        origin = {"plan": "plan", "flown": "flown trajectory"}.get(show.source, show.source)
        print(f"crazyflie: {len(show.fits)} vehicles from the {origin}, time scale {show.time_scale:g}, "
              f"controller {show.controller}")
        for i, (fit, checks) in enumerate(zip(show.fits, show.checks, strict=True)):
            bad = [c["name"] for c in checks if not c["holds"]]
            print(f"  cf_{i}.csv: {fit.poly.pieces} pieces ({fit.poly.nbytes} of {TRAJECTORY_MEMORY_BYTES} bytes), "
                  f"max error {fit.max_position_error * 1000:.1f} mm, {fit.max_yaw_error:.4f} rad; "
                  + ("limits hold" if not bad else "EXCEEDS " + "; ".join(bad)))
        print(f"  placed: {_placed(show)}; floor z = {show.floor:g} m, "
              + "; ".join(f"{c['name']} {c['value']:.3g} (limit {c['limit']:g})" for c in show.safety
                          if c["value"] is not None))
        print(f"  crazyflies.yaml, {LAUNCH_SCRIPT} and {LAUNCH_DATA} (Crazyswarm2: the show lasts "
              f"{show.fits[0].poly.duration:.2f} s)")


if __name__ == "__main__":
    main()
