"""The compiled CEM step (methods/cem/kernels.py, numerics.py) against the NumPy oracle (tests/oracles/cem.py).

The kernel replaced the NumPy hot path of Algorithms 1-2 (papers/cem-fluid-flow-navigation.md);
it must compute the same commands, draw the same eq. 6 noise from the same generator stream and
leave the generator where NumPy left it. Measured on x86-64 with FMA: bit for bit on every case
below; the assertions allow round-off (1e-12 m per tick) for CPUs where NumPy's loops round
differently, and the rng check is exact (a different stream would change every later draw).
"""

from __future__ import annotations

import numpy as np
import pytest
from oracles.cem import NumpyNavigator, NumpyNewtonInverter

from swarmscene.methods.cem import numerics
from swarmscene.methods.cem.flow import CEMNavigator, NewtonInverter, complex_potential, pcg64_state

A_P = 1.36
TOL = 1e-12  # m per tick (measured: 0, bit for bit)
FLOWS = {  # the plugin's multi_failure_flow options as strengths (None: ring_streamlines)
    "ring_streamlines": lambda f: None,
    "unit_doublets": lambda f: np.full(f, A_P**2, dtype=complex),
    "summed": lambda f: np.full(f, A_P**2 / f, dtype=complex),
}


def random_geometry(seed: int, n_agents: int, n_failures: int) -> tuple[np.ndarray, np.ndarray]:
    """Failures >= 3 a_p apart in a 20 m square; agents outside every a_p disk (some on its rim)."""
    rng = np.random.default_rng(seed)
    failed: list[np.ndarray] = []
    while len(failed) < n_failures:
        p = rng.uniform(0, 20, 2)
        if all(np.hypot(*(p - q)) >= 3 * A_P for q in failed):
            failed.append(p)
    agents: list[np.ndarray] = []
    while len(agents) < n_agents:
        if len(agents) % 3 == 0:  # on a ring, where eq. 6 fires and round-off decides ||r - r_f|| <= a_p
            f = failed[rng.integers(n_failures)]
            p = f + A_P * (1 + 1e-12) * np.array([np.cos(a := rng.uniform(0, 2 * np.pi)), np.sin(a)])
        else:
            p = rng.uniform(-10, 10, 2) + np.mean(failed, axis=0)
        if all(np.hypot(*(p - q)) >= A_P for q in failed):
            agents.append(p)
    return np.array(agents), np.array(failed)


def fly_both(agents, failed, ticks: int, seed: int, **kw) -> tuple[float, CEMNavigator, NumpyNavigator]:
    """Step the kernel navigator and the NumPy oracle side by side; returns the worst difference."""
    nav = CEMNavigator(agents, failed, a_p=A_P, rng=np.random.default_rng(seed), **kw)
    ref = NumpyNavigator(nav, np.random.default_rng(seed))
    worst = 0.0
    for _ in range(ticks):
        p, v = nav.step()
        q, u = ref.step()
        worst = max(worst, float(np.abs(p - q).max()), float(np.abs(v - u).max()) * nav.dT)
        assert nav.dphi_used == pytest.approx(ref.dphi_used, rel=1e-12, abs=0)
        assert nav.inverter.iterations == ref.inverter.iterations
    return worst, nav, ref


@pytest.mark.parametrize("stop", ["fixed_n", "converged"])
@pytest.mark.parametrize("rule", ["printed", "gated"])
@pytest.mark.parametrize("flow", list(FLOWS))
def test_kernel_matches_numpy_oracle_over_random_geometries(rule, flow, stop):
    """Random swarms around 1-4 failures (some agents starting on a ring), K = 1, 2, 3, theta random;
    Newton for the paper's fixed n (the default) and with the early stop."""
    for seed, (n_agents, n_failures, K) in enumerate([(1, 1, 2), (5, 1, 2), (7, 2, 1), (9, 3, 3), (4, 4, 2)]):
        agents, failed = random_geometry(seed, n_agents, n_failures)
        theta = np.random.default_rng(100 + seed).uniform(-np.pi, np.pi)
        worst, nav, ref = fly_both(agents, failed, 150, seed, theta=theta, K=K, n=20, sigma=1e-3,
                                   noise_rule=rule, strengths=FLOWS[flow](n_failures), newton_stop=stop)
        assert worst <= TOL, (seed, worst)
        np.testing.assert_allclose(nav.w, ref.w, rtol=0, atol=TOL)  # phi_last advanced alike
        # the same draws: the generators end in the same state
        assert nav.inverter.rng.bit_generator.state == ref.inverter.rng.bit_generator.state


@pytest.mark.parametrize("rule", ["printed", "gated"])
def test_six_vehicle_manoeuvre_matches_the_oracle_and_draws_noise(rule):
    """Section V-A through both saddle points: same commands, same stream, and the noise did fire."""
    s3, d = np.sqrt(3.0), 2.72
    healthy = np.array([[-s3 * d, 0], [-s3 / 2 * d, d / 2], [-s3 / 2 * d, -d / 2], [-s3 * d, d], [-s3 * d, -d]])
    untouched = np.random.default_rng(4).bit_generator.state
    worst, nav, ref = fly_both(healthy, np.zeros((1, 2)), 1300, 4, K=2, n=20, sigma=1e-3, noise_rule=rule)
    assert worst <= TOL
    assert nav.inverter.rng.bit_generator.state == ref.inverter.rng.bit_generator.state
    assert nav.inverter.rng.bit_generator.state != untouched  # eq. 6 drew on this run


def test_calc_xy_kernel_matches_oracle_on_stagnation_and_inside_starts():
    """The branch guard's paths: a start on the stagnation point (f' = 0, restart plus noise, drawn
    even with sigma = 0) and starts inside the disk (mirror or radial inversion)."""
    c = np.array([0j, 5.0 + 1j])
    starts = np.array([-A_P + 0j, 0.3 + 0.2j, 5.0 + 1j + 0.5 * np.exp(2j), A_P * np.exp(0.02j), -4 + 3j])
    w = complex_potential(starts + 0.05, c, A_P) + 0.01
    for sigma in (1e-3, 0.0):
        for rule in ("printed", "gated"):
            a = NewtonInverter(c, A_P, starts.size, 20, sigma, np.random.default_rng(8), noise_rule=rule)
            b = NumpyNewtonInverter(c, A_P, starts.size, 20, sigma, np.random.default_rng(8), noise_rule=rule)
            a.z[:] = starts
            b.z[:] = starts
            with np.errstate(all="ignore"):
                za, zb = a.solve(w).copy(), b.solve(w).copy()
            np.testing.assert_allclose(za, zb, rtol=0, atol=TOL)
            assert np.isfinite(za).all() and (np.abs(za[:, None] - c).min(1) >= A_P * (1 - 1e-6)).all()
            assert a.rng.bit_generator.state == b.rng.bit_generator.state
            assert a.iterations == b.iterations


def test_standard_normal_is_numpys_stream_and_advances_the_generator_in_place():
    rng, ref = np.random.default_rng(2024), np.random.default_rng(2024)
    state = pcg64_state(rng)
    draws = np.array([numerics.standard_normal(state) for _ in range(20000)])  # tails and wedges included
    np.testing.assert_array_equal(draws, ref.standard_normal(20000))
    assert rng.standard_normal() == ref.standard_normal()  # the Generator itself moved on


def test_only_a_pcg64_generator_is_accepted():
    with pytest.raises(ValueError, match="rng: CEM draws its saddle noise from a PCG64 generator "
                                         r"\(numpy.random.default_rng\), got MT19937"):
        pcg64_state(np.random.Generator(np.random.MT19937(0)))


def test_complex_helpers_follow_numpy_rounding():
    """Products, quotients, moduli and doublet sums as NumPy computes them (exact on x86-64 + FMA,
    else within an ulp or two)."""
    rng = np.random.default_rng(5)
    a = rng.standard_normal(400) * 10 ** rng.uniform(-3, 3, 400) + 1j * rng.standard_normal(400)
    b = rng.standard_normal(400) + 1j * rng.standard_normal(400) * 10 ** rng.uniform(-3, 3, 400)
    pairs = [(np.multiply(a, b), numerics.cmul), (np.divide(a, b), numerics.cdiv)]
    for ref, fn in pairs:
        got = np.array([complex(*fn(x.real, x.imag, y.real, y.imag)) for x, y in zip(a, b, strict=True)])
        np.testing.assert_allclose(got, ref, rtol=4e-16, atol=0)
    recip = np.array([complex(*numerics.crecip(y.real, y.imag)) for y in b])
    np.testing.assert_allclose(recip, np.reciprocal(b), rtol=4e-16, atol=0)
    mod = np.array([numerics.cabs(y.real, y.imag) for y in b])
    np.testing.assert_allclose(mod, np.abs(b), rtol=4e-16, atol=0)
    assert numerics.cabs(np.inf, np.nan) == np.inf and np.isnan(numerics.cabs(1.0, np.nan))
    for f in (1, 2, 3, 4, 5, 9, 64, 65, 200):
        terms = a[:f]
        got = complex(*numerics.doublet_sum(terms.real.copy(), terms.imag.copy()))
        assert got == pytest.approx(complex(np.sum(terms[None, :], axis=1)[0]), rel=1e-15, abs=0)


def test_distance_bounds_decide_every_test_as_the_exact_distance():
    """max(|u_r|, |u_i|) <= ||u|| as computed (so a bound above a limit proves the distance is too),
    and distance_within is exact wherever the distance may be <= the limit (eq. 6's and the guard's
    tests then decide as before); NaN takes the exact path."""
    rng = np.random.default_rng(9)
    u = (rng.standard_normal(5000) + 1j * rng.standard_normal(5000)) * A_P * rng.uniform(0.5, 1.5, 5000)
    u = np.concatenate([u, A_P * np.exp(1j * rng.uniform(0, 2 * np.pi, 500)), [0j, A_P + 0j, 1j * A_P]])
    for x in u:
        exact = numerics.cabs(x.real, x.imag)
        assert numerics.size_bound(x.real, x.imag) <= exact
        d = numerics.distance_within(x.real, x.imag, A_P)
        assert (d <= A_P) == (exact <= A_P) and (d < A_P * (1 - 1e-9)) == (exact < A_P * (1 - 1e-9))
        if exact <= A_P:
            assert d == exact
    assert np.isnan(numerics.size_bound(np.nan, 1.0)) and np.isnan(numerics.size_bound(1.0, np.nan))
    assert np.isnan(numerics.distance_within(5.0, np.nan, A_P))  # a NaN still disables eq. 6 that iteration


def test_fixed_n_runs_every_iteration_and_converged_stops_early():
    """Algorithm 2 as printed runs its n iterations on every call; the early stop does fewer away
    from the ring, and without the guard a command may stay where Newton left it."""
    agents, failed = random_geometry(3, 6, 1)
    fixed = CEMNavigator(agents, failed, a_p=A_P, n=20, rng=np.random.default_rng(0))
    early = CEMNavigator(agents, failed, a_p=A_P, n=20, rng=np.random.default_rng(0), newton_stop="converged")
    fixed.step(), early.step()
    assert fixed.inverter.iterations == 20 and early.inverter.iterations < 20
    with pytest.raises(ValueError, match="newton_stop: must be one of fixed_n, converged"):
        NewtonInverter(failed[:, 0] + 1j * failed[:, 1], A_P, 3, 20, 1e-3, np.random.default_rng(0), newton_stop="x")
