"""Virtual Rigid Body (VRB) trajectory from keyframes (Zhou and Schwager, section II-III).

A VRB trajectory delta_v(t) in C^4: R -> R^3 x SO(3) is the position p_v(t) of the origin of the
body frame F_v and its orientation R_v(t), both in the world frame F_w (z up, like the engine, so no
frame conversion is needed). The paper builds it "from the keyframes {K_1, K_2, ...} on which
velocity, acceleration, Euler angles, Euler angle rates and so on are assigned" with the minimum-snap
method of its ref. [8] (Mellinger and Kumar 2011); this module does exactly that.

Choice of interpolant (why minimum snap rather than a scipy spline):
    ``scipy.interpolate.make_interp_spline(k=5)`` is C^4 too, but it only accepts derivative
    conditions at the two ends; a keyframe in the middle of the show that fixes a velocity ("pass
    through the third keyframe with a certain upward speed", Fig. 4) or an Euler-angle rate (the
    constant roll rate of section IV) cannot be expressed. ``BPoly.from_derivatives`` needs every
    derivative at every knot. Minimum snap handles any subset: each of the six channels
    (x, y, z, roll, pitch, yaw) is a piecewise polynomial of degree 7 (the Euler-Lagrange degree of
    the snap functional) whose integral of squared snap is minimised subject to the keyframe values,
    the fixed derivatives and continuity of derivatives 1..4 at every keyframe. The optimum of this
    equality-constrained quadratic programme is one linear KKT solve per channel. Degree 7 with C^4
    constraints is C^4 everywhere (and C^6 at keyframes that fix no derivative, by optimality).

Orientation: Euler angles (roll phi, pitch theta, yaw psi) in the Z-Y-X convention,
R_v = R_z(psi) R_y(theta) R_x(phi). Angles are interpolated as unwrapped reals, so a constant-rate
roll through several turns is represented without jumps. Derivatives of R_v up to order 4 are exact:
the derivatives of cos/sin of each angle follow from complete Bell polynomials of the angle's
derivatives (d^n e^{i a} = B_n(i a', ..., i a^(n)) e^{i a}) and the product rule over the three
elementary rotations.

Unspecified derivatives at the first and last keyframes default to zero up to jerk (the VRB takes
off from rest and lands at rest), which also makes the programme well posed.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import factorial

import numpy as np
import scipy  # its submodules load on first use: registering the VRB plugin must not import them

DEGREE = 7
"""Polynomial degree of each minimum-snap piece (8 coefficients)."""
ORDER = 4
"""Highest derivative used (snap); the VRB trajectory is C^4 (paper, section II)."""
N_CHANNELS = 6
"""x, y, z (m) and roll, pitch, yaw (rad)."""


@dataclass(frozen=True)
class Keyframes:
    """Keyframes K_1..K_K of a VRB trajectory (paper Fig. 3-4).

    Attributes:
        t: (K,) s, strictly increasing keyframe times.
        pos: (K, 3) m, position of the origin of F_v in F_w.
        euler: (K, 3) rad, (roll, pitch, yaw), Z-Y-X convention, unwrapped.
        derivs: optional (K, ORDER, 6) fixed derivatives: ``derivs[k, n-1, c]`` is the n-th time
            derivative (n = 1..4) of channel c (x, y, z, roll, pitch, yaw) at keyframe k; NaN means
            free. ``None``: every interior derivative free, ends at rest.
    """

    t: np.ndarray
    pos: np.ndarray
    euler: np.ndarray
    derivs: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.t, float)
        if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0):
            raise ValueError("Keyframes.t must be a strictly increasing 1-D array of >= 2 times")
        for name in ("pos", "euler"):
            if np.shape(getattr(self, name)) != (t.size, 3):
                raise ValueError(f"Keyframes.{name} must have shape ({t.size}, 3)")
        if self.derivs is not None and np.shape(self.derivs) != (t.size, ORDER, N_CHANNELS):
            raise ValueError(f"Keyframes.derivs must have shape ({t.size}, {ORDER}, {N_CHANNELS})")

    def constraints(self) -> np.ndarray:
        """(K, ORDER, 6) fixed derivatives with the rest defaults at the two ends (NaN = free)."""
        k = len(self.t)
        d = np.full((k, ORDER, N_CHANNELS), np.nan)
        if self.derivs is not None:
            d[:] = self.derivs
        for end in (0, k - 1):  # rest up to jerk unless the caller fixed something else
            free = np.isnan(d[end, :3])
            d[end, :3][free] = 0.0
        return d


@lru_cache(maxsize=8)
def _snap_hessian() -> np.ndarray:
    """H[k, l] = int_0^1 (d^4 s^k / ds^4)(d^4 s^l / ds^4) ds, for the normalised piece s in [0, 1]."""
    ks = np.arange(DEGREE + 1)
    fall = np.array([np.prod(np.arange(k - 3, k + 1)) if k >= 4 else 0 for k in ks], float)
    pw = ks[:, None] + ks[None, :] - 2 * ORDER + 1
    with np.errstate(divide="ignore"):
        h = np.where(pw > 0, fall[:, None] * fall[None, :] / np.maximum(pw, 1), 0.0)
    return h


@lru_cache(maxsize=8)
def _deriv_rows() -> np.ndarray:
    """D[n, e, k]: n-th s-derivative of s^k at s = e (e = 0 start, 1 end) of a normalised piece."""
    d = np.zeros((ORDER + 1, 2, DEGREE + 1))
    for n in range(ORDER + 1):
        for k in range(n, DEGREE + 1):
            coef = factorial(k) / factorial(k - n)
            d[n, 1, k] = coef
            d[n, 0, k] = coef if k == n else 0.0
    return d


def minimum_snap(t: np.ndarray, values: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Minimum-snap piecewise polynomial through ``values`` (ref. [8] of the paper), one channel.

    Args:
        t: (K,) keyframe times, s.
        values: (K,) channel values at the keyframes.
        fixed: (K, ORDER) fixed derivatives 1..4 at each keyframe (NaN = free).

    Returns:
        (K-1, DEGREE+1) coefficients c_k of s^k, s = (t - t_j) / T_j on piece j.
    """
    seg = np.diff(t)
    m = seg.size
    nc = DEGREE + 1
    D = _deriv_rows()
    rows: list[np.ndarray] = []
    rhs: list[float] = []

    def row(j: int, n: int, e: int) -> np.ndarray:
        r = np.zeros(m * nc)
        r[j * nc:(j + 1) * nc] = D[n, e] / seg[j] ** n  # d^n/dt^n = T^-n d^n/ds^n
        return r

    for j in range(m):  # keyframe values at both ends of each piece
        rows += [row(j, 0, 0), row(j, 0, 1)]
        rhs += [values[j], values[j + 1]]
    for k in range(m + 1):
        for n in range(1, ORDER + 1):
            v = fixed[k, n - 1]
            left = row(k - 1, n, 1) if k > 0 else None
            right = row(k, n, 0) if k < m else None
            if not np.isnan(v):  # fixed: each adjacent piece takes the value (implies continuity)
                for r in (left, right):
                    if r is not None:
                        rows.append(r)
                        rhs.append(v)
            elif left is not None and right is not None:  # free interior: continuity (C^4)
                rows.append(left - right)
                rhs.append(0.0)
    A = np.array(rows)
    b = np.array(rhs)
    # Cost: sum_j T_j^-7 c_j^T H c_j (int (d^4/dt^4)^2 dt in normalised time); scaled per piece.
    w = seg ** (1 - 2 * ORDER)
    Q = scipy.sparse.kron(scipy.sparse.diags(w / w.max()), scipy.sparse.csr_matrix(_snap_hessian()))
    As = scipy.sparse.csr_matrix(A)
    nv = m * nc
    # The KKT matrix is banded (pieces couple only at shared keyframes): a sparse LU is fast and
    # avoids dense BLAS, which is slow to share on a loaded machine.
    kkt = scipy.sparse.bmat([[Q, As.T], [As, None]], format="csc")
    sol = scipy.sparse.linalg.spsolve(kkt, np.concatenate([np.zeros(nv), b]))
    return sol[:nv].reshape(m, nc)


def _to_ppoly(t: np.ndarray, coeffs: np.ndarray) -> scipy.interpolate.PPoly:
    """Pieces (C, K-1, DEGREE+1) in normalised s -> one PPoly over (K-1) intervals with C channels."""
    seg = np.diff(t)
    k = np.arange(DEGREE + 1)
    local = coeffs / seg[None, :, None] ** k  # c_k s^k = (c_k / T^k) tau^k
    c = np.transpose(local[:, :, ::-1], (2, 1, 0))  # PPoly: highest power first, (deg+1, m, C)
    return scipy.interpolate.PPoly(c, t)


@dataclass(frozen=True)
class VRBState:
    """The VRB at sample times: flat-output-ready derivatives of p_v and R_v (paper eq. 2-3).

    Attributes:
        t: (T,) s.
        p: (ORDER+1, T, 3) p_v and its derivatives: m, m/s, m/s^2, m/s^3 (jerk), m/s^4 (snap).
        R: (ORDER+1, T, 3, 3) R_v and its time derivatives (1/s^n).
        euler: (ORDER+1, T, 3) (roll, pitch, yaw) and derivatives; yaw is inherited by every robot.
    """

    t: np.ndarray
    p: np.ndarray
    R: np.ndarray
    euler: np.ndarray

    @property
    def omega_body(self) -> np.ndarray:
        """(T, 3) rad/s, angular velocity of F_v in F_v: (R_v^T dR_v/dt)^vee."""
        return _vee(np.einsum("tji,tjk->tik", self.R[0], self.R[1]))

    @property
    def omega_world(self) -> np.ndarray:
        """(T, 3) rad/s, angular velocity of F_v in F_w: (dR_v/dt R_v^T)^vee."""
        return _vee(np.einsum("tij,tkj->tik", self.R[1], self.R[0]))


def _vee(m: np.ndarray) -> np.ndarray:
    """(T, 3, 3) -> (T, 3), the vector of the skew-symmetric part."""
    return 0.5 * np.stack(
        [m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], axis=-1
    )


def _cos_sin_derivs(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives 0..4 of cos(a(t)), sin(a(t)) from a's derivatives a: (5, ...).

    d^n e^{ia}/dt^n = B_n(x_1..x_n) e^{ia}, x_k = i a^(k), B_n the complete Bell polynomials.
    """
    x1, x2, x3, x4 = (1j * a[k] for k in range(1, 5))
    bell = [
        np.ones_like(x1),
        x1,
        x2 + x1**2,
        x3 + 3 * x1 * x2 + x1**3,
        x4 + 4 * x1 * x3 + 3 * x2**2 + 6 * x1**2 * x2 + x1**4,
    ]
    u = np.exp(1j * a[0])
    d = np.stack([b * u for b in bell])
    return d.real, d.imag


# Elementary rotations about x, y, z (the axes of roll, pitch, yaw) as R = E0 + cos(a) Ec + sin(a) Es
# (constant part only at order 0), stacked along a leading axis so all three are built at once.
_E0 = np.stack([np.diag([1.0, 0, 0]), np.diag([0, 1.0, 0]), np.diag([0, 0, 1.0])])
_EC = np.stack([np.diag([0, 1.0, 1.0]), np.diag([1.0, 0, 1.0]), np.diag([1.0, 1.0, 0])])
_ES = np.array([
    [[0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]],
    [[0, 0, 1.0], [0, 0, 0], [-1.0, 0, 0]],
    [[0, -1.0, 0], [1.0, 0, 0], [0, 0, 0]],
])


def _elementary_derivs(euler: np.ndarray) -> np.ndarray:
    """(5, T, 3, 3, 3): R_x(roll), R_y(pitch), R_z(yaw) (third axis) and derivatives 1..4."""
    c, s = _cos_sin_derivs(euler)  # (5, T, 3) each
    out = c[..., None, None] * _EC + s[..., None, None] * _ES
    out[0] += _E0
    return out


@lru_cache(maxsize=1)
def _leibniz3() -> np.ndarray:
    """W (5, 5, 5, 5): W[n, a, b, c] = n!/(a! b! c!) if a + b + c = n, else 0 (product rule)."""
    w = np.zeros((ORDER + 1,) * 4)
    for a in range(ORDER + 1):
        for b in range(ORDER + 1 - a):
            for c in range(ORDER + 1 - a - b):
                w[a + b + c, a, b, c] = factorial(a + b + c) / (factorial(a) * factorial(b) * factorial(c))
    return w


def rotation_derivatives(euler: np.ndarray) -> np.ndarray:
    """R_v = R_z(yaw) R_y(pitch) R_x(roll) and its time derivatives.

    Args:
        euler: (5, T, 3) (roll, pitch, yaw) and their derivatives 1..4.

    Returns:
        (5, T, 3, 3).
    """
    elem = _elementary_derivs(euler)
    rx, ry, rz = elem[:, :, 0], elem[:, :, 1], elem[:, :, 2]
    # every product R_z^(a) R_y^(b) R_x^(c) at once, then the Leibniz sum over a + b + c = n
    prod = (rz[:, None] @ ry[None, :])[:, :, None] @ rx[None, None, :]  # (5, 5, 5, T, 3, 3)
    return np.tensordot(_leibniz3(), prod, axes=3)


class VRBTrajectory:
    """delta_v(t) in C^4: minimum-snap position and Euler-angle trajectory through keyframes.

    Before the first and after the last keyframe the body holds the end pose (derivatives zero).
    """

    def __init__(self, keyframes: Keyframes) -> None:
        self.keyframes = keyframes
        t = np.asarray(keyframes.t, float)
        vals = np.concatenate([keyframes.pos, keyframes.euler], axis=1)  # (K, 6)
        fixed = keyframes.constraints()
        coeffs = np.stack([minimum_snap(t, vals[:, c], fixed[:, :, c]) for c in range(N_CHANNELS)])
        self.ppoly = _to_ppoly(t, coeffs)
        # ascending coefficients of tau^k of every derivative n of every piece: (5, 8, m, 6)
        asc = self.ppoly.c[::-1]
        k = np.arange(DEGREE + 1)
        self._dcoef = np.zeros((ORDER + 1,) + asc.shape)
        for n in range(ORDER + 1):
            fall = np.array([np.prod(np.arange(j + 1, j + n + 1)) for j in k[: DEGREE + 1 - n]], float)
            self._dcoef[n, : DEGREE + 1 - n] = asc[n:] * fall[:, None, None]

    @property
    def t_start(self) -> float:
        """Time of the first key frame, s."""
        return float(self.keyframes.t[0])

    @property
    def t_end(self) -> float:
        """Time of the last key frame, s (the trajectory holds its end after it)."""
        return float(self.keyframes.t[-1])

    def channels(self, t: np.ndarray | float) -> np.ndarray:
        """(5, T, 6): x, y, z, roll, pitch, yaw and derivatives 1..4 at times ``t``."""
        t = np.atleast_1d(np.asarray(t, float))
        x = self.ppoly.x
        tc = np.clip(t, x[0], x[-1])
        piece = np.clip(np.searchsorted(x, tc, side="right") - 1, 0, x.size - 2)
        powers = (tc - x[piece])[:, None] ** np.arange(DEGREE + 1.0)  # (T, 8)
        out = np.einsum("nktc,tk->ntc", self._dcoef[:, :, piece], powers)
        outside = (t < x[0]) | (t > x[-1])
        out[1:, outside] = 0.0  # holding the end pose
        return out

    def evaluate(self, t: np.ndarray | float) -> VRBState:
        """p_v, R_v and their derivatives up to snap at times ``t`` (vectorised)."""
        t = np.atleast_1d(np.asarray(t, float))
        ch = self.channels(t)
        return VRBState(t=t, p=ch[:, :, :3], R=rotation_derivatives(ch[:, :, 3:]), euler=ch[:, :, 3:])

    def knot_jumps(self) -> np.ndarray:
        """(ORDER+1, K-2, 6): jump of each derivative 0..4 at each interior keyframe (C^4 check)."""
        c = self.ppoly.c  # (deg+1, m, 6), local tau powers, highest first
        h = np.diff(self.ppoly.x)
        jumps = []
        for n in range(ORDER + 1):
            dc = c
            for _ in range(n):  # differentiate the local polynomials n times
                p = dc.shape[0] - 1
                dc = dc[:-1] * np.arange(p, 0, -1)[:, None, None]
            powers = h[None, :, None] ** np.arange(dc.shape[0] - 1, -1, -1)[:, None, None]
            left_end = np.sum(dc * powers, axis=0)  # each piece at its right end
            right_start = dc[-1]  # each piece at its left end
            jumps.append(right_start[1:] - left_end[:-1])
        return np.stack(jumps)

