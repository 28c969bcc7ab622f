"""Wind numerics: the 1-cosine discrete gust, the mean-wind log profile and Dryden turbulence.

Sources: MIL-F-8785C (1980), section 3.7 (atmospheric disturbances), and MIL-HDBK-1797 (1997),
appendix A, section 4.9.2; the forms below are MIL-F-8785C's.

Dryden turbulence, low altitude (h < 1000 ft; lengths in ft inside the standard, m here):

    L_w = h,   L_u = L_v = h / (0.177 + 0.000823 h)^1.2                      (scale lengths)
    sigma_w = 0.1 W_20,   sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4   (intensities)

with W_20 the wind speed at 20 ft. The spatial spectra (one-sided in Omega, rad/m) are

    Phi_u(Omega) = sigma_u^2 (2 L_u / pi) / (1 + (L_u Omega)^2)
    Phi_v(Omega) = sigma_v^2 (L_v / pi) (1 + 3 (L_v Omega)^2) / (1 + (L_v Omega)^2)^2   (w alike)

and a vehicle moving through the frozen field at airspeed V sees the temporal spectrum
Phi(omega / V) / V. MIL-HDBK-1797 writes the v and w spectra with 2 L_v and 2 L_w and halves the
low-altitude lengths (2 L_v = L_u, 2 L_w = h): the same spectra, so one implementation serves both.

The shaping filters, driven by unit-intensity white noise n (E[n(t) n(s)] = delta(t - s)):

    H_u(s) = sigma_u sqrt(2 T_u) / (1 + T_u s)
    H_v(s) = sigma_v sqrt(T_v) (1 + sqrt(3) T_v s) / (1 + T_v s)^2,      T = L / V  (w alike)

are discretised exactly (matrix exponential; noise covariance Q = P - Phi P Phi^T from the
stationary covariance P), so a series sampled at any step has exactly the filter's variance and
autocorrelation; only the spectrum's aliasing above the Nyquist frequency differs from the
continuous one. Everything is vectorised over agents: each agent (or the whole swarm, see the
``dryden`` disturbance model, ``plugins/disturbance/dryden.py``) carries its own filter state.

Choices where the standards leave room, for a hovering multirotor:
* V is the vehicle's speed through the air mass (|v - w_mean|), at least ``MIN_AIRSPEED``: a
  hovering vehicle sees the field advected past it by the mean wind (Taylor's frozen turbulence).
* h is clamped to [10 ft, 1000 ft] (``ALTITUDE_RANGE``): L_w = h vanishes at the ground, and the
  low-altitude formulas stop at 1000 ft.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

FT = 0.3048
"""m per ft."""
ALTITUDE_RANGE = (10.0 * FT, 1000.0 * FT)
"""Altitudes (m) at which the low-altitude model is evaluated; outside, the nearest bound."""
MIN_AIRSPEED = 0.5
"""m/s: the least airspeed V of the frozen-field mapping (T = L / V must stay finite)."""
Z0_FT = 0.15
"""Surface roughness z_0 of the MIL-F-8785C wind-shear profile, ft (0.15 ft: flight phase C,
terminal flight near the ground; the standard gives 2.0 ft for other phases)."""
H20 = 20.0 * FT
"""The reference height of W_20, m."""


# ----------------------------------------------------------------------------- 1-cosine gust


def one_minus_cosine(t: np.ndarray | float, start: float, rise: float, hold: float | None) -> np.ndarray:
    """Shape of the discrete gust, 0..1, at times ``t`` s (MIL-F-8785C 3.7.5).

    v/V_m = 0 before ``start``; (1 - cos(pi tau / rise)) / 2 for 0 <= tau = t - start <= rise;
    1 after, for ``hold`` s (``None``: for ever, the standard's form); then the mirror image back to
    0 over ``rise`` s. ``hold = 0`` is the full 1-cosine pulse U/2 (1 - cos(pi s / H)),
    0 <= s <= 2 H, of the airworthiness codes (CS-25.341), with H = rise.
    """
    tau = np.asarray(t, dtype=float) - start
    up = 0.5 * (1.0 - np.cos(np.pi * np.clip(tau, 0.0, rise) / rise))
    if hold is None:
        return up
    down = 0.5 * (1.0 + np.cos(np.pi * np.clip(tau - rise - hold, 0.0, rise) / rise))
    return np.where(tau <= rise + hold, up, down)


# ----------------------------------------------------------------------------- mean wind


def log_profile(h: np.ndarray, w20: float) -> np.ndarray:
    """Mean wind speed at altitude ``h`` (m) for W_20 = ``w20`` m/s (MIL-F-8785C 3.7.2.1):
    u = W_20 ln(h / z_0) / ln(20 ft / z_0), h clamped to ``ALTITUDE_RANGE``."""
    h_ft = np.clip(h, *ALTITUDE_RANGE) / FT
    return w20 * np.log(h_ft / Z0_FT) / math.log(20.0 / Z0_FT)


# ----------------------------------------------------------------------------- Dryden


def dryden_scales(h: np.ndarray, w20: float) -> tuple[np.ndarray, np.ndarray]:
    """Scale lengths (L_u, L_v, L_w) and intensities (sigma_u, sigma_v, sigma_w) at altitude ``h``.

    Args:
        h: altitudes, m, any shape (clamped to ``ALTITUDE_RANGE``).
        w20: W_20, the wind speed at 20 ft, m/s (MIL-F-8785C: 15 kt light, 30 kt moderate, 45 kt
            severe).

    Returns:
        L (..., 3) m and sigma (..., 3) m/s, components (u, v, w).
    """
    h_ft = np.clip(np.asarray(h, dtype=float), *ALTITUDE_RANGE) / FT
    base = 0.177 + 0.000823 * h_ft
    L_uv = h_ft / base**1.2 * FT
    L = np.stack([L_uv, L_uv, h_ft * FT], axis=-1)
    sigma_w = 0.1 * w20 * np.ones_like(h_ft)
    sigma_uv = sigma_w / base**0.4
    return L, np.stack([sigma_uv, sigma_uv, sigma_w], axis=-1)


def dryden_psd(f: np.ndarray, L: float, sigma: float, V: float, component: str) -> np.ndarray:
    """One-sided temporal power spectral density of one Dryden component, (m/s)^2 / Hz, at
    frequencies ``f`` Hz, for scale ``L`` m, intensity ``sigma`` m/s and airspeed ``V`` m/s:
    S(f) = 2 pi Phi(2 pi f / V) / V (so its integral over f >= 0 is sigma^2)."""
    omega = 2.0 * np.pi * np.asarray(f, dtype=float) / V
    x = (L * omega) ** 2
    if component == "u":
        phi = sigma**2 * 2.0 * L / np.pi / (1.0 + x)
    else:
        phi = sigma**2 * L / np.pi * (1.0 + 3.0 * x) / (1.0 + x) ** 2
    return 2.0 * np.pi * phi / V


class DrydenFilters:
    """The three Dryden shaping filters of many independent realisations, stepped exactly.

    State: ``u`` (M,) the first-order filter's output; ``x``, ``xd`` (M, 2) the v and w filters'
    states (x and its derivative, of s^2 x + 2 s x / T + x / T^2 = n). Each :meth:`step` takes the
    realisations' scales, intensities and airspeeds (they may change with altitude and speed) and
    returns the gust velocities (M, 3) (u, v, w).

    Args:
        m: number of realisations (agents, or 1 for a field shared by the swarm).
        rng: the generator of the disturbance stream (never the run's).
        L, sigma, V: (M, 3), (M, 3), (M,) at t = 0: the state starts stationary.
    """

    def __init__(self, m: int, rng: np.random.Generator, L: np.ndarray, sigma: np.ndarray,
                 V: np.ndarray) -> None:
        self.rng = rng
        T = L / V[:, None]
        self.u = rng.standard_normal(m)  # normalised: sigma_u applied at the output
        # stationary covariance of (x, xd): diag(T^3 / 4, T / 4)
        Tvw = T[:, 1:]
        self.x = rng.standard_normal((m, 2)) * np.sqrt(Tvw**3 / 4.0)
        self.xd = rng.standard_normal((m, 2)) * np.sqrt(Tvw / 4.0)
        self.output = self._output(T, sigma)
        self._key: tuple | None = None
        self._together: tuple | None = None  # step_together's stacked factors, kept on a batch's first

    def step(self, dt: float, L: np.ndarray, sigma: np.ndarray, V: np.ndarray) -> np.ndarray:
        """Advance every filter by ``dt`` s; return the gust velocities (M, 3), m/s.

        The transition and noise factors depend only on (dt, L, V), the output's on (L, V, sigma):
        they are kept while the same arrays are passed again (the wind model holds its conditions
        over a guidance tick). The step's 5 M normal draws are taken in one call, in the order of
        three (u, then z1 and z2 of the v and w filters): the generator fills them one after
        another either way, so the draws are the same."""
        key = (dt, id(L), id(V), id(sigma))
        if self._key != key:
            self._key, self._held = key, (L, V, sigma)  # held: the ids stay valid while cached
            T = L / V[:, None]
            self._coef, self._factors = _transition(dt, T), _output_factors(T, sigma)
        m = self.u.size
        noise = self.rng.standard_normal(5 * m)
        self.u, self.x, self.xd = _advanced(self._coef, self.u, self.x, self.xd, noise[:m],
                                            noise[m:3 * m].reshape(m, 2), noise[3 * m:].reshape(m, 2))
        self.output = _scaled(self._factors, self.u, self.x, self.xd)
        return self.output

    @staticmethod
    def step_together(filters: Sequence[DrydenFilters], dt: float,
                      conditions: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> list[np.ndarray]:
        """:meth:`step` of B sets of filters of M realisations each (B worlds' winds), given each
        set's (L, sigma, V), in one pass: each set draws from its own generator and keeps its own
        state, and every set's gusts are the bits of its own :meth:`step`. The stacked factors are
        kept on the first set while the same conditions are passed again."""
        first, m = filters[0], filters[0].u.size
        key = (dt, tuple(id(a) for condition in conditions for a in condition))
        if first._together is None or first._together[0] != key:
            T = [L / V[:, None] for L, _, V in conditions]
            factors = [_output_factors(t, sigma) for t, (_, sigma, _) in zip(T, conditions, strict=True)]
            first._together = (key, conditions, _transition(dt, np.concatenate(T)),
                               tuple(np.concatenate(part) for part in zip(*factors, strict=True)))
        _, _, coef, stacked_factors = first._together  # conditions held: the ids stay valid
        noise = np.stack([f.rng.standard_normal(5 * m) for f in filters])
        b = len(filters)
        u, x, xd = _advanced(coef, np.concatenate([f.u for f in filters]), np.concatenate([f.x for f in filters]),
                             np.concatenate([f.xd for f in filters]), noise[:, :m].reshape(b * m),
                             noise[:, m:3 * m].reshape(b * m, 2), noise[:, 3 * m:].reshape(b * m, 2))
        out = _scaled(stacked_factors, u, x, xd)
        for i, f in enumerate(filters):
            rows = slice(i * m, (i + 1) * m)
            f.u, f.x, f.xd, f.output = u[rows], x[rows], xd[rows], out[rows]
        return [f.output for f in filters]

    def _output(self, T: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """y_u = sigma_u u (u of unit variance); y = sigma T^-3/2 (x + sqrt(3) T xd) for v, w."""
        return _scaled(_output_factors(T, sigma), self.u, self.x, self.xd)


def _transition(dt: float, T: np.ndarray) -> tuple:
    """The filters' step factors for time constants T (M, 3) = L / V: u: a = exp(-dt / T_u),
    b = sqrt(1 - a^2). v, w: the exact step of the critically damped pair, e^{A dt} = e^{-dt/T}
    [[1 + dt/T, dt], [-dt/T^2, 1 - dt/T]], and the Cholesky factor of Q = P - Phi P Phi^T with
    P = diag(T^3/4, T/4)."""
    a = np.exp(-dt / T[:, 0])
    Tvw = T[:, 1:]
    r = dt / Tvw
    e = np.exp(-r)
    p11, p12, p21, p22 = e * (1.0 + r), e * dt, -e * r / Tvw, e * (1.0 - r)
    P1, P2 = Tvw**3 / 4.0, Tvw / 4.0
    q11 = P1 - (p11 * p11 * P1 + p12 * p12 * P2)
    q12 = -(p11 * p21 * P1 + p12 * p22 * P2)
    q22 = P2 - (p21 * p21 * P1 + p22 * p22 * P2)
    # 2x2 Cholesky factor of Q, element-wise (q11 > 0 for dt > 0)
    c11 = np.sqrt(np.maximum(q11, 0.0))
    c21 = np.where(c11 > 0.0, q12 / np.where(c11 > 0.0, c11, 1.0), 0.0)
    c22 = np.sqrt(np.maximum(q22 - c21 * c21, 0.0))
    return a, np.sqrt(1.0 - a * a), (p11, p12, p21, p22), (c11, c21, c22)


def _advanced(coef: tuple, u: np.ndarray, x: np.ndarray, xd: np.ndarray, n: np.ndarray, z1: np.ndarray,
              z2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The filters' state one step on (:func:`_transition`'s factors), driven by unit normals n
    (u's) and z1, z2 (the v and w filters')."""
    a, b, (p11, p12, p21, p22), (c11, c21, c22) = coef
    return a * u + b * n, p11 * x + p12 * xd + c11 * z1, p21 * x + p22 * xd + c21 * z1 + c22 * z2


def _output_factors(T: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The output's factors, which change only with the conditions: sigma_u, sigma T^-3/2 and
    sqrt(3) T of the v and w filters (computed per set of filters: numpy's ``power`` may give an
    element other bits in a longer array)."""
    Tvw = T[:, 1:]
    return sigma[:, 0], sigma[:, 1:] * Tvw**-1.5, math.sqrt(3.0) * Tvw


def _scaled(factors: tuple, u: np.ndarray, x: np.ndarray, xd: np.ndarray) -> np.ndarray:
    """The gust velocities (M, 3): y_u = sigma_u u; y = sigma T^-3/2 (x + sqrt(3) T xd) for v, w."""
    sigma_u, scale_vw, sqrt3_T = factors
    out = np.empty((u.size, 3))
    np.multiply(sigma_u, u, out=out[:, 0])
    np.multiply(scale_vw, x + sqrt3_T * xd, out=out[:, 1:])
    return out


def wind_axes(heading: float) -> np.ndarray:
    """Rows: the world directions of the Dryden components u (along the mean wind, horizontal),
    v (horizontal, to its left) and w (up), for a mean wind blowing toward ``heading`` rad
    (counter-clockwise from +x, east)."""
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
