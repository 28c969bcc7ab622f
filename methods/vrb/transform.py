"""Formations Pi_m and collision-free transformations Phi between them (Zhou and Schwager, III-B/C).

A flight task (Remark 2) is the sequence {Pi_1, Phi^1_2, Pi_2, ..., Phi^{M-1}_M, Pi_M} with durations
{T_1, T^1_2, T_2, ...}. In a formation the local positions r_i in the body frame F_v are constant;
in a transformation they move from ^m r_i to ^{m+1} r_i. Global flat outputs follow from
Theorems 1-2 (eq. 1-3): p_i = p_v + R_v r_i and the Leibniz rule, yaw inherited from the body.

Transformation law (the paper leaves it open; this is our design)
------------------------------------------------------------------
Target assignment: the slots of Pi_{m+1} are assigned to robots by the Hungarian algorithm
(``scipy.optimize.linear_sum_assignment``) on squared distances from ^m r_i (the CAPT cost of the
paper's ref. [16]: among assignments it minimises the sum of squared path lengths).

Local position during Phi^m_{m+1}, tau = t - t^m_{m+1}, T = T^m_{m+1}, s = tau / T in [0, 1]:

    r_i(t) = ^m r_i + phi(s) Delta_i + E_i(s),   Delta_i = ^{m+1} r_i - ^m r_i,

E_i the smoothed deviation e_i that the repelling field builds up (below).

* Transformation field, eq. 7. Taken literally, v_T = A sin(a r + c) is a field of position that
  vanishes at ^m r_i, so its flow never leaves the formation (and reaches ^{m+1} r_i only
  asymptotically). We therefore take the sine of the transformation's phase instead and raise it to
  the fourth power: v_Ti = A_i sin^4(a tau + c) Delta_i/|Delta_i| with a = pi/T, c = 0,
  A_i = 8 |Delta_i| / (3 T) (so the path length is covered exactly). Integrating,
  phi(s) = s - 2/(3 pi) sin(2 pi s) + 1/(12 pi) sin(4 pi s); phi(0) = 0, phi(1) = 1 and
  phi^(n)(0) = phi^(n)(1) = 0 for n = 1..4, so the nominal path alone meets eq. 4-6.
* Repelling field, eq. 8-9. The deviation e_i from the nominal point is integrated from e_i = 0 as
      de_i/dt = sum_{j in N_i} v_Ri^j(r) - k_r e_i,
  i.e. the robot follows eq. 9 with the transformation field read as a tracking field
  v_Ti(r, t) = dphi/dt Delta_i + k_r (rbar_i(t) - r_i) (it also pulls a pushed robot back to its
  straight line once the neighbour is passed). v_Ri^j is exactly eq. 8: magnitude
  B_j ((D - d_ij)/(D - s_i - s_j))^2 along (r_i - r_j)/d_ij for d_ij <= D, zero beyond D.
  Integration: exponential Euler on a uniform grid (step <= ``max_step``), vectorised over robots
  and over the pairs that come within reach of D (``integrate_deviation``).
* Smoothness and exact arrival. Eq. 8 is only C^1 in d_ij (kink at D), so the raw integral is only
  C^2 in time, and it does not end exactly at zero (the pull k_r leaves a residual of a few mm).
  The sampled e_i is therefore represented by a clamped quintic B-spline E_i(s) on uniform knots
  about ``knot_spacing`` apart, fitted by least squares to the samples with its first five and last
  five coefficients held at zero. For a clamped spline of degree 5, E^(n)(0) depends only on the
  first n + 1 coefficients (and E^(n)(1) on the last n + 1), so E_i and its derivatives 1..4 vanish
  at s = 0 and s = 1 by construction, whatever the samples are. Hence r_i(t^m_{m+1}) = ^m r_i,
  r_i(t_{m+1}) = ^{m+1} r_i (eq. 4) and dr_i..d^4 r_i = 0 at both switches (eq. 6), which with
  eq. 3 gives eq. 5: p_i and its velocity, acceleration, jerk and snap are continuous at the
  switches. A quintic spline is C^4, so r_i is C^4 inside Phi too and delta_i is C^4 for the whole
  task (Problems 2-3). The knot spacing also smooths the kink of eq. 8 over a few tenths of a
  second, which bounds the jerk and snap that the kink would otherwise put into the feed-forward.
* Safety (Problem 4) is what eq. 8 is for: inside D the pair is pushed apart at up to 2B when
  d_ij = s_ij, so choose B above half the nominal closing speed. It is verified, not guaranteed:
  the pull k_r and the spline fit can give back a little of the clearance, so the planned r_i(t)
  (the spline, not the raw integral) is what ``Transformation.min_distance`` measures, and the
  tests check min_{i != j} d_ij >= s_i + s_j for every transformation of the air show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from math import comb

import numpy as np
import scipy  # its submodules load on first use: registering the VRB plugin must not import them

from .trajectory import ORDER, VRBState, VRBTrajectory

SPLINE_DEGREE = 5
"""Quintic B-spline for the deviation E_i(s): the lowest degree that is C^4."""


def assign_targets(r_from: np.ndarray, slots: np.ndarray) -> np.ndarray:
    """Hungarian target assignment: robot i (at ``r_from[i]``) goes to ``slots[perm[i]]``.

    Args:
        r_from: (N, 3) m, local positions ^m r_i of the robots in Pi_m.
        slots: (N, 3) m, the local positions of Pi_{m+1}, in any order.

    Returns:
        (N,) int, ``perm``; cost is the sum of squared distances (CAPT, ref. [16]).
    """
    cost = np.sum((r_from[:, None, :] - slots[None, :, :]) ** 2, axis=-1)
    rows, cols = scipy.optimize.linear_sum_assignment(cost)
    perm = np.empty(len(rows), dtype=int)
    perm[rows] = cols
    return perm


def sine_profile(s: np.ndarray, order: int = ORDER) -> np.ndarray:
    """(order+1, S): phi(s) and s-derivatives; phi' = (8/3) sin^4(pi s) (eq. 7, see module doc)."""
    s = np.asarray(s, float)
    out = np.empty((order + 1,) + s.shape)
    out[0] = s - 2.0 / (3.0 * np.pi) * np.sin(2 * np.pi * s) + np.sin(4 * np.pi * s) / (12.0 * np.pi)
    for n in range(1, order + 1):  # d^m cos(ws) = w^m cos(ws + m pi/2)
        m = n - 1
        out[n] = (
            (1.0 if n == 1 else 0.0)
            - 4.0 / 3.0 * (2 * np.pi) ** m * np.cos(2 * np.pi * s + m * np.pi / 2)
            + 1.0 / 3.0 * (4 * np.pi) ** m * np.cos(4 * np.pi * s + m * np.pi / 2)
        )
    return out


def repelling_velocity(
    r: np.ndarray, clearance: np.ndarray, threshold: float, gain: np.ndarray
) -> np.ndarray:
    """sum_{j in N_i} v_Ri^j, eq. 8-9, for all robots at once.

    Args:
        r: (N, 3) m, local positions.
        clearance: (N,) m, s_i (the safety distance of a pair is s_i + s_j).
        threshold: D, m; j in N_i iff ||r_i - r_j|| <= D.
        gain: (N,) m/s, B_j of the repelling robot j.

    Returns:
        (N, 3) m/s.
    """
    pairs = _PairField(clearance, threshold, gain)
    return pairs.velocity(pairs.incidence_t @ r)


_ONES3 = np.ones(3)


class _PairField:
    """Eq. 8 over a set of unordered pairs (i_p, j_p), constants precomputed.

    With the signed incidence matrix A (N, P) (+1 at i_p, -1 at j_p), the pair differences are
    A^T r and the summed field is ``push @ (per-pair vectors)``, where ``push`` is A weighted by the
    gain of the other robot of each pair and 1 / (D - s_ij)^2.
    """

    DENSE_PAIRS = 256
    """Up to this many pairs the (N, P) matrices are dense (fastest for small teams), else CSR."""

    def __init__(
        self,
        clearance: np.ndarray,
        threshold: float,
        gain: np.ndarray,
        pairs: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        n = len(clearance)
        i, j = np.triu_indices(n, 1) if pairs is None else pairs
        self.i, self.j, self.threshold = i, j, threshold
        p = np.arange(i.size)
        gap2 = (threshold - clearance[i] - clearance[j]) ** 2
        # robot i is pushed with B_j, robot j with B_i (B belongs to the repelling robot, eq. 8)
        wi, wj = gain[j] / gap2, -gain[i] / gap2
        # d/dd of the pair's closing speed (B_i + B_j)((D - d)/(D - s_ij))^2, per metre of depth
        self.stiffness = float(np.max(2.0 * (gain[i] + gain[j]) / gap2, initial=0.0))
        self.depth = 0.0
        if i.size <= self.DENSE_PAIRS:
            self.push = np.zeros((n, i.size))
            self.push[i, p], self.push[j, p] = wi, wj
            self.incidence_t = np.zeros((i.size, n))
            self.incidence_t[p, i], self.incidence_t[p, j] = 1.0, -1.0
        else:
            rows, cols = np.r_[i, j], np.r_[p, p]
            self.push = scipy.sparse.csr_matrix((np.r_[wi, wj], (rows, cols)), (n, i.size))
            ones = np.r_[np.ones(i.size), -np.ones(i.size)]
            self.incidence_t = scipy.sparse.csr_matrix((ones, (cols, rows)), (i.size, n))

    def velocity(self, diff: np.ndarray, push: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) summed eq. 8 from the (P, 3) pair differences r_i - r_j (``push`` may be scaled)."""
        d = np.sqrt((diff * diff) @ _ONES3)
        np.maximum(d, 1e-12, out=d)  # coincident robots: no defined direction, no push
        x = self.threshold - d
        np.maximum(x, 0.0, out=x)
        self.depth = float(x.max())  # deepest pair inside D: sets the local stiffness
        x *= x
        x /= d  # (D - d)^2 / d; times diff gives the unit direction of eq. 8
        return (self.push if push is None else push) @ (x[:, None] * diff)


@dataclass(frozen=True)
class TransformationLaw:
    """Parameters of the transformation law (module docstring).

    Attributes:
        clearance: s_i, m, scalar or (N,); paper: s_i + s_j = 0.6 m, so s_i = 0.3 m.
        threshold: D, m (paper 0.7 m); must exceed s_i + s_j.
        gain: B_j, m/s, scalar or (N,); 0 switches the repelling field off.
        k_return: k_r, 1/s, pull of the tracking field back onto the straight path.
        max_step: s, largest integration step (eq. 8 is stiff near s_ij: 4B/(D - s_ij) 1/s).
        min_steps: fewest integration intervals (the spline is fitted to steps + 1 samples).
        knot_spacing: s, knot spacing of the deviation spline (smooths the kink of eq. 8).
    """

    clearance: float | np.ndarray = 0.3
    threshold: float = 0.7
    gain: float | np.ndarray = 0.8
    k_return: float = 1.5
    max_step: float = 0.06
    min_steps: int = 16
    knot_spacing: float = 0.3

    def intervals(self, duration: float) -> int:
        """Knot intervals of the deviation spline (at least 6, so one coefficient is free)."""
        return max(ORDER + 2, int(np.ceil(duration / self.knot_spacing)))

    def steps(self, duration: float) -> int:
        """Integration intervals for a transformation of ``duration`` s (step <= max_step)."""
        return max(self.min_steps, int(np.ceil(duration / self.max_step)))

    def per_robot(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(clearance (N,), gain (N,)) broadcast to N robots."""
        s = np.broadcast_to(np.asarray(self.clearance, float), (n,))
        b = np.broadcast_to(np.asarray(self.gain, float), (n,))
        if np.any(self.threshold <= s[:, None] + s[None, :]):
            raise ValueError("threshold D must exceed every s_i + s_j (eq. 8 divides by D - s_ij)")
        return s, b


@lru_cache(maxsize=32)
def _deviation_operator(n_samples: int, intervals: int) -> tuple[np.ndarray, np.ndarray]:
    """(knots, M): the end-flat least-squares quintic spline of samples y on the uniform s-grid
    has B-spline coefficients M @ y (module docstring); cached per grid and knot count."""
    k = SPLINE_DEGREE
    knots = np.concatenate([np.zeros(k), np.linspace(0.0, 1.0, intervals + 1), np.ones(k)])
    n_coef = intervals + k
    s = np.linspace(0.0, 1.0, n_samples)
    basis = scipy.interpolate.BSpline.design_matrix(s, knots, k).toarray()  # (S, n_coef)
    free = slice(ORDER + 1, n_coef - ORDER - 1)  # first/last five coefficients held at zero
    op = np.zeros((n_coef, n_samples))
    op[free] = np.linalg.pinv(basis[:, free])
    return knots, op


@lru_cache(maxsize=32)
def _grid_phi(steps: int) -> np.ndarray:
    """phi on the uniform s-grid of ``steps`` intervals (shared by every plan)."""
    phi = sine_profile(np.linspace(0.0, 1.0, steps + 1), order=0)[0]
    phi.flags.writeable = False
    return phi


def integrate_deviation(
    r_from: np.ndarray, r_to: np.ndarray, duration: float, law: TransformationLaw
) -> np.ndarray:
    """e_i on the uniform grid of ``law.steps(duration)`` intervals, shape (S, N, 3).

    de/dt = v_R(rbar + e) - k_r e, exponential Euler (the linear pull is integrated exactly).
    Only pairs whose nominal distance comes within D + margin are integrated (for large teams most
    pairs never meet); the result is exact as long as 2 max|e_i| <= margin, which is checked
    afterwards, and the margin is widened and the integration redone if it was not.
    """
    n = r_from.shape[0]
    clearance, gain = law.per_robot(n)
    steps = law.steps(duration)
    if n < 2 or not np.any(gain > 0.0):
        return np.zeros((steps + 1, n, 3))
    phi = _grid_phi(steps)
    i, j = np.triu_indices(n, 1)
    delta = r_to - r_from
    # pair differences of the nominal sine-profile motion, (S, P, 3)
    dbar = (r_from[i] - r_from[j]) + phi[:, None, None] * (delta[i] - delta[j])
    gap = np.sqrt(np.einsum("spk,spk->sp", dbar, dbar))
    margin = 0.5 * law.threshold
    while True:
        near = np.flatnonzero(gap.min(axis=0) <= law.threshold + margin)
        if near.size == 0:
            return np.zeros((steps + 1, n, 3))
        pairs = _PairField(clearance, law.threshold, gain, (i[near], j[near]))
        e, reach = _integrate_pairs(pairs, dbar[:, near], gap[:, near].min(axis=1), duration, law)
        if 2.0 * reach <= margin:
            return e
        margin = 4.0 * reach


def _integrate_pairs(
    pairs: _PairField, dbar: np.ndarray, nominal_gap: np.ndarray, duration: float,
    law: TransformationLaw,
) -> tuple[np.ndarray, float]:
    """Exponential Euler of de/dt = v_R(rbar + e) - k_r e over the given pairs; (e, max |e_i|).

    Steps where every pair is farther than D + 2 max|e_i| feel no repulsion, so they reduce to the
    exact decay e <- e exp(-k_r h) with no field evaluation. Where a pair is deep inside D the field
    is stiff (rate 2 (B_i + B_j)(D - d)/(D - s_ij)^2 1/s), and the step is split so that its product
    with the step stays below ``STIFF_STEP`` (explicit Euler is stable below 2).
    """
    steps = dbar.shape[0] - 1
    n = pairs.push.shape[0]
    e = np.zeros((steps + 1, n, 3))
    h = duration / steps
    decay = float(np.exp(-law.k_return * h))
    drive = h if law.k_return == 0.0 else (1.0 - decay) / law.k_return
    push = drive * pairs.push  # exponential-Euler drive folded into the pair weights
    inc_t = pairs.incidence_t
    D = law.threshold
    gaps = nominal_gap.tolist()
    # depth inside D beyond which (stiffness x step) exceeds STIFF_STEP
    stiff_depth = STIFF_STEP / (h * pairs.stiffness) if pairs.stiffness > 0 else math.inf
    ek = e[0]
    reach = 0.0  # upper bound of max_i |e_i|, keeps the skip test conservative
    reach_max = 0.0
    for k in range(steps):  # sequential in time, vectorised over robots and pairs
        if gaps[k] > D + 2.0 * reach:
            ek = ek * decay
            reach *= decay
        else:
            v = pairs.velocity(dbar[k] + inc_t @ ek, push)
            if pairs.depth <= stiff_depth:
                ek = decay * ek + v
            else:  # rare: a pair nearly on top of each other; nominal motion interpolated
                split = math.ceil(pairs.depth / stiff_depth)
                ek = _substeps(pairs, dbar[k], dbar[k + 1], ek, h, split, law.k_return)
            reach = 1.7320508075688772 * float(np.abs(ek).max())  # |e_i| <= sqrt(3) max component
            reach_max = max(reach_max, reach)
        e[k + 1] = ek
    return e, reach_max


STIFF_STEP = 1.0
"""Largest (field stiffness x step) of the explicit integration before a step is split."""


def _substeps(
    pairs: _PairField, d0: np.ndarray, d1: np.ndarray, e: np.ndarray, h: float, split: int,
    k_return: float,
) -> np.ndarray:
    """One step of ``_integrate_pairs`` split into ``split`` equal exponential-Euler sub-steps."""
    hs = h / split
    decay = float(np.exp(-k_return * hs))
    push = (hs if k_return == 0.0 else (1.0 - decay) / k_return) * pairs.push
    for q in range(split):
        dq = d0 + (q / split) * (d1 - d0)
        e = decay * e + pairs.velocity(dq + pairs.incidence_t @ e, push)
    return e


@dataclass(frozen=True)
class Transformation:
    """Phi^m_{m+1}: time-varying local positions from ^m r_i to ^{m+1} r_i (Definition 3).

    Attributes:
        t_start: t^m_{m+1}, s. t_end: t_{m+1}, s.
        r_from: (N, 3) ^m r_i, robot order. r_to: (N, 3) ^{m+1} r_i, robot order.
        deviation: end-flat quintic B-spline E(s) with values (N*3,), or ``None`` (field off).
    """

    t_start: float
    t_end: float
    r_from: np.ndarray
    r_to: np.ndarray
    deviation: scipy.interpolate.BSpline | None = None

    @property
    def duration(self) -> float:
        """t_end - t_start: the transformation's length, s."""
        return self.t_end - self.t_start

    def local(self, t: np.ndarray) -> np.ndarray:
        """(5, T, N, 3): r_i(t) and its time derivatives 1..4 (times clipped to the segment)."""
        t = np.atleast_1d(np.asarray(t, float))
        T = self.duration
        s = np.clip((t - self.t_start) / T, 0.0, 1.0)
        scale = T ** -np.arange(ORDER + 1.0)  # d^n/dt^n = T^-n d^n/ds^n
        phi = sine_profile(s) * scale[:, None]
        out = phi[:, :, None, None] * (self.r_to - self.r_from)
        out[0] += self.r_from
        if self.deviation is not None:
            dev = np.stack([self.deviation(s, nu) for nu in range(ORDER + 1)])
            out += (dev * scale[:, None, None]).reshape(out.shape)
        return out

    def min_distance(self, samples: int = 401) -> float:
        """min over t in [t_start, t_end] and i != j of ||r_i(t) - r_j(t)|| (Problem 4), m."""
        r = self.local(np.linspace(self.t_start, self.t_end, samples))[0]
        return min_pair_distance(r)


def min_pair_distance(r: np.ndarray) -> float:
    """Closest pair over samples: r (T, N, 3) -> m (pdist per sample: no (T, N, N) array)."""
    if r.shape[1] < 2:
        return float("inf")
    return float(min(scipy.spatial.distance.pdist(sample).min() for sample in r))


def plan_transformation(
    r_from: np.ndarray, r_to: np.ndarray, t_start: float, t_end: float, law: TransformationLaw
) -> Transformation:
    """Plan Phi^m_{m+1} between two robot-ordered formations (module docstring)."""
    r_from = np.asarray(r_from, float)
    r_to = np.asarray(r_to, float)
    if t_end <= t_start:
        raise ValueError("a transformation needs t_end > t_start")
    e = integrate_deviation(r_from, r_to, t_end - t_start, law)
    if not np.any(e):  # field off, or no pair ever within D: the straight sine-profile paths
        return Transformation(t_start, t_end, r_from, r_to)
    knots, fit = _deviation_operator(e.shape[0], law.intervals(t_end - t_start))
    coef = fit @ e.reshape(e.shape[0], -1)
    spline = scipy.interpolate.BSpline.construct_fast(knots, coef, SPLINE_DEGREE, extrapolate=False)
    return Transformation(t_start, t_end, r_from, r_to, spline)


@dataclass(frozen=True)
class FormationSequence:
    """A flight task of Remark 2: M formations and the M-1 transformations between them.

    Attributes:
        slots: (M, N, 3) m, local positions of each formation Pi_m in F_v. Robot i occupies
            ``slots[0, i]`` in Pi_1; later slots are assigned by the Hungarian algorithm.
        durations: (M,) s, T_m of each formation.
        transitions: (M-1,) s, T^m_{m+1} of each transformation.
        t1: s, start of Pi_1.
    """

    slots: np.ndarray
    durations: np.ndarray
    transitions: np.ndarray
    t1: float = 0.0

    def __post_init__(self) -> None:
        m = np.shape(self.slots)[0]
        if np.shape(self.durations) != (m,) or np.shape(self.transitions) != (m - 1,):
            raise ValueError("need M formation durations and M-1 transformation durations")
        if np.any(np.asarray(self.durations) <= 0) or np.any(np.asarray(self.transitions) <= 0):
            raise ValueError("durations T_m and T^m_{m+1} must be > 0 (Definitions 2-3)")

    def phase_bounds(self) -> np.ndarray:
        """(2M,) s: t_1, t^1_2, t_2, t^2_3, ..., t_M, t^M_{M+1} (the 2(M-1) switches are inside)."""
        d = np.empty(2 * len(self.durations) - 1)
        d[0::2] = self.durations
        d[1::2] = self.transitions
        return self.t1 + np.concatenate([[0.0], np.cumsum(d)])


@dataclass(frozen=True)
class FormationFlight:
    """The planned task: robot-ordered formations and the transformations between them.

    Attributes:
        sequence: the task (slots and durations).
        formations: (M, N, 3) m, ^m r_i in robot order.
        assignment: (M, N) int, slot of robot i in Pi_m.
        transformations: the M-1 planned Phi^m_{m+1}.
    """

    sequence: FormationSequence
    formations: np.ndarray
    assignment: np.ndarray
    transformations: tuple[Transformation, ...] = field(default_factory=tuple)

    @property
    def bounds(self) -> np.ndarray:
        """(2M,) s: the phases' bounds, formations and transformations alternating (Definition 4)."""
        return self.sequence.phase_bounds()

    @property
    def switch_times(self) -> np.ndarray:
        """(2(M-1),) s, the switches of Definition 4."""
        return self.bounds[1:-1]

    def phase_local(self, phase: int, t: np.ndarray) -> np.ndarray:
        """(5, T, N, 3): the law of phase ``phase`` (even: Pi_{phase/2+1}, odd: a Phi) at ``t``."""
        t = np.atleast_1d(np.asarray(t, float))
        if phase % 2:
            return self.transformations[phase // 2].local(t)
        out = np.zeros((ORDER + 1, t.size) + self.formations.shape[1:])
        out[0] = self.formations[phase // 2]
        return out

    def local(self, t: np.ndarray | float) -> np.ndarray:
        """(5, T, N, 3): r_i(t) and derivatives 1..4; Pi_1 before t_1, Pi_M after the end."""
        t = np.atleast_1d(np.asarray(t, float))
        phase = np.clip(np.searchsorted(self.bounds, t, side="right") - 1, 0, len(self.bounds) - 2)
        out = np.empty((ORDER + 1, t.size) + self.formations.shape[1:])
        for ph in np.unique(phase):
            sel = phase == ph
            out[:, sel] = self.phase_local(int(ph), t[sel])
        return out

    def min_transformation_distance(self, samples: int = 401) -> float:
        """min over every transformation of the closest pair distance, m (Problem 4)."""
        return min(tf.min_distance(samples) for tf in self.transformations)


def plan_flight(sequence: FormationSequence, law: TransformationLaw) -> FormationFlight:
    """Assign targets formation by formation and plan every transformation (section III-C)."""
    slots = np.asarray(sequence.slots, float)
    m, n, _ = slots.shape
    assignment = np.empty((m, n), dtype=int)
    assignment[0] = np.arange(n)
    formations = np.empty_like(slots)
    formations[0] = slots[0]
    for k in range(1, m):
        assignment[k] = assign_targets(formations[k - 1], slots[k])
        formations[k] = slots[k][assignment[k]]
    b = sequence.phase_bounds()
    transformations = tuple(
        plan_transformation(formations[k], formations[k + 1], b[2 * k + 1], b[2 * k + 2], law)
        for k in range(m - 1)
    )
    return FormationFlight(sequence, formations, assignment, transformations)


@lru_cache(maxsize=1)
def _binomial_weights() -> np.ndarray:
    """W (5, 5, 5): W[n, k, j] = C(n, k) if k + j = n (Leibniz rule of eq. 3)."""
    w = np.zeros((ORDER + 1,) * 3)
    for n in range(ORDER + 1):
        for k in range(n + 1):
            w[n, k, n - k] = comb(n, k)
    return w


@dataclass(frozen=True)
class FlatOutputs:
    """Flat outputs sigma_i = [p_i, psi_i] of every robot and their derivatives up to snap.

    Attributes:
        p: (5, T, N, 3): position (m), velocity, acceleration, jerk, snap of robot i in F_w.
        yaw: (5, T, N): psi_i (rad) and derivatives, inherited from the VRB (Theorems 1-2).
    """

    p: np.ndarray
    yaw: np.ndarray


def flat_outputs(body: VRBState, local: np.ndarray) -> FlatOutputs:
    """Theorems 1-2: p_i^(n) = p_v^(n) + sum_k C(n, k) R_v^(k) r_i^(n-k) (eq. 1-3).

    Eq. 2 (formation) is the special case r_i^(k) = 0 for k >= 1.

    Args:
        body: the VRB at T times (p_v, R_v and derivatives).
        local: (5, T, N, 3), r_i and derivatives at the same times.
    """
    # R_v^(k) r_i^(j) for every k, j at once: (5, 5, T, N, 3), then the binomial sum over k + j = n
    rr = local[None, :] @ np.swapaxes(body.R, -1, -2)[:, None]
    p = body.p[:, :, None, :] + np.tensordot(_binomial_weights(), rr, axes=2)
    yaw = np.repeat(body.euler[:, :, 2][:, :, None], local.shape[2], axis=2)
    return FlatOutputs(p=p, yaw=yaw)


def robot_flat_outputs(
    trajectory: VRBTrajectory, flight: FormationFlight, t: np.ndarray | float
) -> FlatOutputs:
    """Every robot's flat outputs at times ``t`` (vectorised over times and robots)."""
    t = np.atleast_1d(np.asarray(t, float))
    return flat_outputs(trajectory.evaluate(t), flight.local(t))


def switch_jumps(trajectory: VRBTrajectory, flight: FormationFlight) -> np.ndarray:
    """(2(M-1), 5): max over robots of |jump| of p_i^(n), n = 0..4, at each switch (eq. 5).

    Each side is evaluated with its own phase's law at the switch time, so this measures the
    design, not a finite difference.
    """
    ts = flight.switch_times
    body = trajectory.evaluate(ts)
    out = np.empty((ts.size, ORDER + 1))
    for k, t in enumerate(ts):  # 2(M-1) switches, not a per-step path
        b = VRBState(body.t[k:k + 1], body.p[:, k:k + 1], body.R[:, k:k + 1], body.euler[:, k:k + 1])
        left = flat_outputs(b, flight.phase_local(k, t)).p
        right = flat_outputs(b, flight.phase_local(k + 1, t)).p
        out[k] = np.max(np.linalg.norm(left - right, axis=-1), axis=(1, 2))
    return out
