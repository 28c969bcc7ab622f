"""Wind numerics against independent references: the Dryden spectra (MIL-F-8785C) by Welch's
method, the filters' variances, the exact 1-cosine gust shape, and the scale formulas."""


import numpy as np
import pytest
from scipy.signal import welch

from swarmscene.methods.disturbances.atmosphere import (
    FT,
    DrydenFilters,
    dryden_psd,
    dryden_scales,
    log_profile,
    one_minus_cosine,
)

FS = 20.0          # Hz, sampling of the generated series
AGENTS = 64        # independent realisations averaged
STEPS = 2**15      # samples per realisation (1638 s)
NPERSEG = 2048     # Welch segment (102 s; 31 segments per realisation, 1984 in all)


@pytest.fixture(scope="module")
def series():
    h = 10.0  # m
    L, sigma = dryden_scales(np.full(AGENTS, h), w20=8.0)
    V = np.full(AGENTS, 5.0)
    rng = np.random.default_rng(12)
    filters = DrydenFilters(AGENTS, rng, L, sigma, V)
    out = np.empty((STEPS, AGENTS, 3))
    for k in range(STEPS):
        out[k] = filters.step(1.0 / FS, L, sigma, V)
    return out, L[0], sigma[0], 5.0


def test_scales_are_the_standard_formulas():
    L, sigma = dryden_scales(np.array([100 * FT]), w20=15 * 0.514444)
    base = 0.177 + 0.000823 * 100
    assert L[0, 0] == pytest.approx(100 / base**1.2 * FT, rel=1e-12)
    assert L[0, 2] == pytest.approx(100 * FT, rel=1e-12)
    assert sigma[0, 2] == pytest.approx(0.1 * 15 * 0.514444, rel=1e-12)
    assert sigma[0, 0] == pytest.approx(sigma[0, 2] / base**0.4, rel=1e-12)
    # the mean-wind profile equals W20 at 20 ft
    assert log_profile(np.array([20 * FT]), 7.0)[0] == pytest.approx(7.0, rel=1e-12)


def test_variances_match_the_intensities(series):
    # each sample is exactly N(0, sigma^2) (stationary start, exact discretisation); 2.1e6
    # correlated samples: the relative standard error of the variance is ~ sqrt(2 T fs / n) < 2 %
    out, _, sigma, _ = series
    var = out.reshape(-1, 3).var(axis=0)
    np.testing.assert_allclose(var, sigma**2, rtol=0.05)


@pytest.mark.parametrize("axis, component", [(0, "u"), (1, "v"), (2, "w")])
def test_dryden_spectra_match_the_analytic_ones(series, axis, component):
    """Welch estimate (Hann, 50 % overlap, 1984 segments) against S(f) = 2 pi Phi(2 pi f / V) / V.

    Tolerance: each Welch bin averages ~1984 segments (relative standard deviation ~2.4 %); the
    ratio is pooled over seven log-spaced bands of >= 3 bins (0.05 to 2 Hz), so a band's statistical error is ~1-2 %;
    Welch's leakage on the f^-2 slope and aliasing from above fs/2 stay below ~1 % up to
    fs / 10 = 2 Hz. A band may therefore deviate by 6 % (3-4 standard errors plus bias), and
    the mean over all bands by 3 %.
    """
    out, L, sigma, V = series
    f, pxx = welch(out[:, :, axis], fs=FS, nperseg=NPERSEG, axis=0)
    pxx = pxx.mean(axis=1)
    expected = dryden_psd(f, L[axis], sigma[axis], V, component)
    edges = np.geomspace(0.05, 2.0, 8)
    ratios = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        band = (f >= lo) & (f < hi)
        assert band.sum() >= 3
        ratios.append(pxx[band].sum() / expected[band].sum())
    ratios = np.array(ratios)
    assert np.all(np.abs(ratios - 1.0) < 0.06), ratios
    assert abs(ratios.mean() - 1.0) < 0.03


def test_spectra_integrate_to_the_variance():
    f = np.linspace(0.0, 2000.0, 2_000_001)
    for c in "uvw":
        s = dryden_psd(f, 30.0, 1.2, 4.0, c)
        assert np.trapezoid(s, f) == pytest.approx(1.44, rel=2e-3)


def test_one_minus_cosine_gust_is_exact():
    t = np.linspace(0.0, 10.0, 1001)
    start, rise = 2.0, 1.5
    shape = one_minus_cosine(t, start, rise, None)
    tau = t - start
    ref = np.where(tau < 0, 0.0, np.where(tau <= rise, 0.5 * (1 - np.cos(np.pi * tau / rise)), 1.0))
    np.testing.assert_array_equal(shape, ref)
    # hold = 0: the CS-25 pulse U/2 (1 - cos(pi s / H)) over 0 <= s <= 2H, zero after
    pulse = one_minus_cosine(t, start, rise, 0.0)
    ref = np.where((tau >= 0) & (tau <= 2 * rise), 0.5 * (1 - np.cos(np.pi * tau / rise)), 0.0)
    np.testing.assert_allclose(pulse, ref, atol=1e-15)
    assert one_minus_cosine(start + rise, start, rise, 0.0) == 1.0
    held = one_minus_cosine(np.array([start + rise + 3.0, start + 2 * rise + 3.0]), start, rise, 3.0)
    np.testing.assert_allclose(held, [1.0, 0.0], atol=1e-15)


def _stepped_as_written(filters, rng, dt, L, sigma, V):
    """One filter step as the docstrings write it: the exact transition of each filter and its
    noise factor, with u's draw, then z1's and z2's (three calls), and the output's formula."""
    T = L / V[:, None]
    Tvw = T[:, 1:]
    a = np.exp(-dt / T[:, 0])
    r = dt / Tvw
    e = np.exp(-r)
    p11, p12, p21, p22 = e * (1.0 + r), e * dt, -e * r / Tvw, e * (1.0 - r)
    P1, P2 = Tvw**3 / 4.0, Tvw / 4.0
    q11 = P1 - (p11 * p11 * P1 + p12 * p12 * P2)
    q12 = -(p11 * p21 * P1 + p12 * p22 * P2)
    q22 = P2 - (p21 * p21 * P1 + p22 * p22 * P2)
    c11 = np.sqrt(np.maximum(q11, 0.0))
    c21 = np.where(c11 > 0.0, q12 / np.where(c11 > 0.0, c11, 1.0), 0.0)
    c22 = np.sqrt(np.maximum(q22 - c21 * c21, 0.0))
    u, x, xd = filters
    u = a * u + np.sqrt(1.0 - a * a) * rng.standard_normal(u.shape)
    z1, z2 = rng.standard_normal(x.shape), rng.standard_normal(x.shape)
    x, xd = p11 * x + p12 * xd + c11 * z1, p21 * x + p22 * xd + c21 * z1 + c22 * z2
    vw = sigma[:, 1:] * Tvw**-1.5 * (x + np.sqrt(3.0) * Tvw * xd)
    return (u, x, xd), np.column_stack([sigma[:, 0] * u, vw])


@pytest.mark.parametrize("m", [1, 5])
def test_the_filters_step_is_the_written_one_draw_for_draw(m):
    """200 steps of m realisations whose scales, intensities and airspeed change every 5 steps
    (as the wind model holds them over a guidance tick): every gust equals the written step's to
    the bit, so the kept factors and the draws taken in one call change no number of a run."""
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    h, V = np.linspace(3.0, 40.0, m), np.linspace(2.0, 9.0, m)
    L, sigma = dryden_scales(h, w20=9.0)
    filters = DrydenFilters(m, rng_a, L, sigma, V)
    DrydenFilters(m, rng_b, L, sigma, V)  # the same draws for the written one's start
    state = (filters.u.copy(), filters.x.copy(), filters.xd.copy())
    for k in range(200):
        if k % 5 == 0:
            h, V = h + 0.3, V * 1.01
            L, sigma = dryden_scales(h, w20=9.0)
        gust = filters.step(0.01, L, sigma, V)
        state, written = _stepped_as_written(state, rng_b, 0.01, L, sigma, V)
        assert np.array_equal(gust, written), k
