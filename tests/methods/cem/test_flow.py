"""CEM flow math (papers/cem-fluid-flow-navigation.md): eq. 1-8, 16, Algorithms 1-2, section V-A."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene.methods.cem.flow import (
    CEMNavigator,
    NewtonInverter,
    calc_xy,
    complex_potential,
    complex_velocity,
    doublet_strengths,
    jacobian,
    lambda_max,
    planned_exclusion_radius,
    potential_stream,
    theorem1,
    theorem2,
    to_flow_frame,
    to_world_frame,
)

EPS, DELTA = 0.28, 0.40  # section IV
A_F = EPS + DELTA
A_P = planned_exclusion_radius(A_F, DELTA, EPS)  # 1.36 m
D_MIN = 2 * (EPS + DELTA) + A_P  # 2.72 m
PAIR_BOUND = 2 * (EPS + DELTA)  # 1.36 m


def six_vehicle_formation(d: float = D_MIN) -> tuple[np.ndarray, np.ndarray]:
    """Section V-A: a leading triangle (Q1 apex, Q3, Q4) with interior Q2 right behind Q1, and two
    wing agents Q5, Q6 beside Q2; nearest spacing d, flying +x. Returns (failed Q1 (1, 2), healthy
    Q2..Q6 (5, 2))."""
    s3 = np.sqrt(3.0)
    q1 = np.array([[0.0, 0.0]])
    healthy = np.array([[-s3 * d, 0.0], [-s3 / 2 * d, d / 2], [-s3 / 2 * d, -d / 2], [-s3 * d, d], [-s3 * d, -d]])
    return q1, healthy


SIGMA = 1e-3  # m, eq. 6


def run_six(K: int = 2, ticks: int = 1300, seed: int = 1, noise_rule: str = "gated"):
    """Fly Algorithm 1 over the lead's failure; returns (navigator, positions, velocities, dphi, drift)."""
    q1, healthy = six_vehicle_formation()
    nav = CEMNavigator(healthy, q1, a_p=A_P, v_des=1.0, dT=0.01, K=K, n=20, sigma=SIGMA,
                       rng=np.random.default_rng(seed), noise_rule=noise_rule)
    P, V, dphi, drift, margin = [], [], [], 0.0, np.inf
    for _ in range(ticks):
        p, v = nav.step()
        P.append(p.copy())
        V.append(v.copy())
        dphi.append(nav.dphi_used)
        drift = max(drift, float(nav.stream_drift().max()))
        margin = min(margin, float(nav.exclusion_margin().min()))
    return nav, np.array(P), np.array(V), np.array(dphi), drift, margin


@pytest.fixture(scope="module")
def six_k2():
    return run_six(K=2)


@pytest.fixture(scope="module")
def six_printed():
    """Eq. 6 as printed (the default reading), K = 1, 2, 5 on seeds 0-9: {K: [run_six results]}."""
    return {K: [run_six(K=K, ticks=1100, seed=s, noise_rule="printed") for s in range(10)] for K in (1, 2, 5)}


# ---- the field: eq. 1-5 -------------------------------------------------------------------------


def test_planned_exclusion_radius_is_the_papers_1_36_m():
    assert A_P == pytest.approx(1.36)
    assert D_MIN == pytest.approx(2.72)


def test_complex_potential_matches_eq_3a_3b_term_by_term():
    rng = np.random.default_rng(0)
    xy = rng.uniform(-6, 6, (200, 2))
    for centres_xy in (np.array([[0.3, -0.2]]), np.array([[0.0, 0.0], [4.0, 3.0], [-3.0, 5.0]])):
        phi, psi = potential_stream(xy[:, 0], xy[:, 1], centres_xy, A_P)
        c = centres_xy[:, 0] + 1j * centres_xy[:, 1]
        w = complex_potential(xy[:, 0] + 1j * xy[:, 1], c, A_P, strengths=np.full(len(c), A_P**2))
        np.testing.assert_allclose(w.real, phi, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(w.imag, psi, rtol=1e-12, atol=1e-12)


def test_single_failure_uses_eq_1_exactly_and_psi_zero_wraps_the_disk():
    assert doublet_strengths(np.array([2.0 + 1j]), A_P) == pytest.approx(A_P**2)
    ring = 2.0 + 1j + A_P * np.exp(1j * np.linspace(0, 2 * np.pi, 50))
    w = complex_potential(ring, np.array([2.0 + 1j]), A_P)
    np.testing.assert_allclose(w.imag, 0.0, atol=1e-12)  # Fig. 2: psi = 0 circumvents the zone
    np.testing.assert_allclose(w.real, 2 * A_P * np.cos(np.linspace(0, 2 * np.pi, 50)), atol=1e-12)


def test_several_failures_keep_each_planned_circle_nearly_a_streamline():
    c = np.array([0 - 9j, 0 + 9j, -9 - 9j])
    th = np.linspace(0, 2 * np.pi, 721)
    spread = {}
    for name, mu in (("eq1", np.full(3, A_P**2)), ("corrected", doublet_strengths(c, A_P))):
        spread[name] = max(np.ptp(complex_potential(ck + A_P * np.exp(1j * th), c, A_P, mu).imag) for ck in c)
    # the local-flow correction removes most of the interaction that eq. 1 leaves on the rings
    assert spread["corrected"] < spread["eq1"] / 4


def test_jacobian_eq_5_matches_finite_differences_and_cauchy_riemann():
    rng = np.random.default_rng(1)
    c = np.array([0.0 + 0j, 5.0 + 2j])
    z = rng.uniform(-8, 8, 30) + 1j * rng.uniform(-8, 8, 30)
    z = z[np.abs(z[:, None] - c).min(1) > A_P]
    J = jacobian(z, c, A_P)
    h = 1e-6
    f = lambda q: complex_potential(q, c, A_P)  # noqa: E731
    dx, dy = (f(z + h) - f(z - h)) / (2 * h), (f(z + 1j * h) - f(z - 1j * h)) / (2 * h)
    np.testing.assert_allclose(J[:, 0, 0], dx.real, atol=1e-6)
    np.testing.assert_allclose(J[:, 0, 1], dy.real, atol=1e-6)
    np.testing.assert_allclose(J[:, 1, 0], dx.imag, atol=1e-6)
    np.testing.assert_allclose(J[:, 1, 1], dy.imag, atol=1e-6)
    JtJ = np.einsum("nki,nkj->nij", J, J)  # proof of Theorem 1: J^T J = (phi_x^2 + phi_y^2) I
    lam = np.abs(complex_velocity(z, c, A_P)) ** 2
    np.testing.assert_allclose(JtJ, lam[:, None, None] * np.eye(2), atol=1e-9)


def test_flow_frame_round_trip_and_direction():
    xy = np.array([[1.0, 2.0], [-3.0, 0.5]])
    z = to_flow_frame(xy, 1 + 1j, np.pi / 2)
    assert z[0] == pytest.approx(1.0 - 0.0j)  # world +y is flow +x for theta = 90 deg
    np.testing.assert_allclose(to_world_frame(z, 1 + 1j, np.pi / 2), xy, atol=1e-12)


# ---- Algorithm 2: CalcXY ------------------------------------------------------------------------


def test_calc_xy_inverts_the_conformal_map_from_a_nearby_start():
    rng = np.random.default_rng(2)
    c = np.array([0.0 + 0j, 6.0 - 1j])
    z_true = rng.uniform(-10, 10, 100) + 1j * rng.uniform(-10, 10, 100)
    z_true = z_true[np.abs(z_true[:, None] - c).min(1) > A_P + 0.3]
    w = complex_potential(z_true, c, A_P)
    start = z_true + 0.02 * (rng.standard_normal(z_true.size) + 1j * rng.standard_normal(z_true.size))
    z, v = calc_xy(w, start, c, A_P, n=20, sigma=1e-3, rng=rng, dT=0.01)
    np.testing.assert_allclose(z, z_true, atol=1e-10)
    np.testing.assert_allclose(v, (z - start) / 0.01)


@pytest.mark.parametrize("rule", ["printed", "gated"])
def test_saddle_noise_eq_6_lets_an_agent_on_the_axis_leave_the_rear_stagnation_point(rule):
    # Q2 sits exactly on psi = 0 behind the failure; phi past -2 a_p has no root on the axis.
    c = np.array([0j])
    start = np.array([-A_P - 1e-3 + 0j])
    w = np.array([-2 * A_P + 0.01 + 0j])
    stuck = calc_xy(w, start, c, A_P, n=20, sigma=0.0)
    assert abs(stuck.imag[0]) == 0.0  # without noise Newton never leaves the real axis
    assert abs(complex_potential(stuck, c, A_P) - w)[0] > 1e-3
    inv = NewtonInverter(c, A_P, 1, 20, 1e-3, np.random.default_rng(0), noise_rule=rule)
    z = start.copy()
    with np.errstate(all="ignore"):
        for _ in range(3):  # a few ticks at the same target: the noise kicks it onto the ring
            inv.z[:] = z
            z = inv.solve(w).copy()
    # on the ring psi = 0 at the target phi: exactly when gated; as printed the last iteration's
    # kick |r_noise| (a few sigma) stays in the command, which moves (phi, psi) by <= 2 |r_noise|
    tol = 1e-9 if rule == "gated" else 10 * SIGMA
    assert abs(z[0]) == pytest.approx(A_P, abs=tol)
    assert abs(complex_potential(z, c, A_P) - w)[0] < tol
    assert abs(z[0]) >= A_P * (1 - 1e-6)  # outside a_p either way (the guard's tolerance)


def test_printed_noise_is_drawn_in_the_last_iteration_gated_noise_is_not():
    """A converged point on the ring (||r - r_f|| <= a_p to rounding): eq. 6 as printed kicks it in
    every iteration, the last one included, so the command leaves the target by ~sigma; the gated
    rule draws nothing (the update is below sigma) and returns the point unchanged."""
    c = np.array([0j])
    ring = A_P * np.exp(1j * np.linspace(0.3, 2.8, 8)) * (1 - 1e-15)  # on the ring, just inside
    w = complex_potential(ring, c, A_P)
    moved = {}
    for rule in ("printed", "gated"):
        z = calc_xy(w, ring, c, A_P, n=20, sigma=SIGMA, rng=np.random.default_rng(7), noise_rule=rule)
        moved[rule] = np.abs(complex_potential(z, c, A_P) - w)
    assert moved["gated"].max() < 1e-12
    # printed: a kick stays in every command whose last estimate was <= a_p, which on the ring is
    # rounding's coin toss (an estimate a hair outside converges undisturbed): here 4 of 8 points
    assert (moved["printed"] > 1e-4).sum() >= 3 and moved["printed"].max() < 10 * SIGMA
    with pytest.raises(ValueError, match="noise_rule: must be one of printed, gated"):
        NewtonInverter(c, A_P, 1, 20, SIGMA, np.random.default_rng(0), noise_rule="always")


def test_exact_stagnation_point_start_stays_finite_and_outside():
    c = np.array([0j])
    z = calc_xy(np.array([-2 * A_P + 1e-3 + 0j]), np.array([-A_P + 0j]), c, A_P, n=20, sigma=1e-3,
                rng=np.random.default_rng(3))
    assert np.isfinite(z).all()
    assert abs(z[0]) >= A_P * (1 - 1e-9)


def test_front_saddle_takes_the_outside_root():
    # Past phi = 2 a_p the axis has two roots, a_p +- s; Newton from the ring may find the inside one.
    c = np.array([0j])
    start = np.array([A_P * np.exp(0.02j)])
    w = np.array([2 * A_P + 0.004 + 0j])
    z = calc_xy(w, start, c, A_P, n=20, sigma=1e-3, rng=np.random.default_rng(4))
    assert abs(z[0]) > A_P
    assert abs(complex_potential(z, c, A_P) - w)[0] < 1e-9


# ---- Theorems 1 and 2 ---------------------------------------------------------------------------


def test_lambda_max_is_4_for_one_failure_and_bounds_a_grid_for_several():
    assert lambda_max(np.array([1.0 + 2j]), A_P) == pytest.approx(4.0, rel=1e-9)
    c = np.array([0j, 3.5 + 1j, -1 + 4j])
    lam = lambda_max(c, A_P)
    xs = np.linspace(-6, 8, 500)
    g = (xs[:, None] + 1j * xs[None, :]).ravel()
    g = g[np.abs(g[:, None] - c).min(1) >= A_P]
    grid = (np.abs(complex_velocity(g, c, A_P)) ** 2).max()
    assert grid <= lam * (1 + 1e-9)
    assert grid > 0.97 * lam


def test_theorems_on_the_six_vehicle_formation():
    q1, healthy = six_vehicle_formation()
    c = to_flow_frame(q1, 0j, 0.0)
    z0 = to_flow_frame(healthy, 0j, 0.0)
    t2 = theorem2(z0, 1, A_P, DELTA, EPS)
    assert t2.d_min0 == pytest.approx(2.72) and t2.bound == pytest.approx(2.72)
    assert t2.applicable and t2.holds  # the paper's formation sits exactly on eq. 16
    t1 = theorem1(complex_potential(z0, c, A_P), c, A_P, DELTA, EPS)
    # Q3 and Q4 (2.72 m from Q1) are only 2.04 apart in psi: Theorem 1 is conservative here.
    assert t1.p_min0 == pytest.approx(2.04, abs=1e-9)
    assert t1.lambda_max == pytest.approx(4.0)
    assert t1.rhs == pytest.approx(4 * 0.68**2)
    assert not t1.holds


def test_theorem2_fails_for_a_tighter_formation_and_does_not_apply_to_two_failures():
    q1, healthy = six_vehicle_formation(d=2.6)
    z0 = to_flow_frame(healthy, 0j, 0.0)
    assert not theorem2(z0, 1, A_P, DELTA, EPS).holds
    t = theorem2(to_flow_frame(six_vehicle_formation()[1], 0j, 0.0), 2, A_P, DELTA, EPS)
    assert not t.applicable and not t.holds


def test_theorem1_holds_for_a_spread_formation():
    c = np.array([0j])
    z0 = np.array([-6 - 6j, -6 + 6j, -12 + 0j, -12 - 6j, -12 + 6j, 6 + 6j])
    t1 = theorem1(complex_potential(z0, c, A_P), c, A_P, DELTA, EPS)
    assert t1.holds and t1.lhs >= t1.rhs


# ---- Algorithm 1 and section V-A -----------------------------------------------------------------


def min_pair(P: np.ndarray) -> float:
    d = np.linalg.norm(P[:, :, None] - P[:, None, :], axis=3)
    d[:, np.arange(P.shape[1]), np.arange(P.shape[1])] = np.inf
    return float(d.min())


def test_six_vehicles_keep_the_papers_invariants(six_k2):
    """Gated noise: eq. 4 and the section III-B claim hold to rounding, and the seed only picks the
    side on which Q2 leaves the rear stagnation point (where the noise is drawn): the run is the
    same or its mirror image."""
    nav, P, V, dphi, drift, margin = six_k2
    assert drift < 1e-9  # eq. 4: psi constant along every path
    assert margin >= -1e-12  # commands never inside a_p
    assert min_pair(P) >= PAIR_BOUND  # Fig. 9: every pair keeps 2 (delta + eps)
    assert (P[-1, :, 0] > A_P).all()  # everyone has passed the failed lead
    _, P2, V2, *_ = run_six(K=2, seed=12345)
    np.testing.assert_allclose(np.linalg.norm(V2, axis=2).max(1), np.linalg.norm(V, axis=2).max(1), atol=1e-6)
    np.testing.assert_allclose(P2[:, 0, 0], P[:, 0, 0], atol=1e-6)  # Q2 along track, ...
    np.testing.assert_allclose(np.abs(P2[:, 0, 1]), np.abs(P[:, 0, 1]), atol=1e-6)  # ... either side


def test_printed_noise_keeps_theorem_2_and_bounds_its_departures(six_printed):
    """Eq. 6 as printed, K = 1, 2, 5 x 10 seeds: what it guarantees, and the measured bounds.

    * Theorem 2's conclusion (every pair >= 2 (delta + eps), Fig. 9) holds on every run: the
      formation's margin (1.42 m vs 1.36 m) dwarfs the noise.
    * Eq. 4 holds only up to the last iteration's kick: |psi - psi_0| <= |f'| |r_noise| <=
      sqrt(lambda_max) |r_noise| = 2 |r_noise|, |r_noise| = sigma sqrt(g_a^2 + g_b^2) with g
      standard normal. Measured over 30 seeds x K = 1, 2, 5 (full scenario): 2.3e-3 ... 5.8e-3, i.e.
      |r_noise| up to ~2.9 sigma; we assert 2 x 5 sigma = 0.01 (5 sigma: ~4e-6 per draw).
    * Commands stay outside a_p only to the branch guard's tolerance 1e-6 a_p (1.36 um): the Newton
      update after an outward kick can end a hair inside the ring, and the guard moves only deeper
      points. Measured: -1.36e-6 m (without the guard: -6.8e-5 m on 10 seeds, the issue's ~0.2 mm).
    * The seed matters.
    """
    for _K, runs in six_printed.items():
        for _nav, P, _V, _dphi, drift, margin in runs:
            assert min_pair(P) >= PAIR_BOUND
            assert 1e-4 < drift <= 2 * 5 * SIGMA
            assert margin >= -1e-6 * A_P
            assert (P[-1, :, 0] > A_P).all()
        peaks = [np.linalg.norm(r[2], axis=2).max() for r in runs]
        assert len(set(np.round(peaks, 9))) > 5  # different seeds, different runs


def test_fastest_agent_flies_at_v_des_away_from_the_saddles(six_k2):
    nav, P, V, dphi, drift, margin = six_k2
    vmax = np.linalg.norm(V, axis=2).max(axis=1)
    assert np.median(vmax) == pytest.approx(1.0, abs=0.01)  # line 20 tracks v_des


def test_sliding_step_collapses_at_both_saddle_points(six_k2):
    """Fig. 8: dphi gets very small twice, as Q2 traverses the saddle points at each end."""
    nav, P, V, dphi, drift, margin = six_k2
    base = 1.0 * 0.01
    small = dphi < 0.1 * base
    runs = np.flatnonzero(np.diff(small.astype(int)) == 1) + 1
    assert len(runs) == 2
    for start in runs:
        end = start + np.argmax(~small[start:])
        k = start + np.argmin(dphi[start:end])
        q2 = P[k, 0]
        assert min(np.hypot(q2[0] + A_P, q2[1]), np.hypot(q2[0] - A_P, q2[1])) < 0.05
        assert np.argmax(np.linalg.norm(V[k], axis=1)) == 0  # Q2 moves, the others nearly stop
        assert dphi[k] < 0.05 * base
    assert P[runs[0], 0, 0] < 0 < P[runs[1], 0, 0]  # rear saddle first, then the front one


def test_k_sweep_reproduces_fig_10_gated():
    """Gated noise: one run for every seed, 2.162 / 1.293 / 1.077 m/s; K = 1 misses Fig. 10's 2.4."""
    peaks = {K: np.linalg.norm(run_six(K=K, ticks=1100)[2], axis=2).max() for K in (1, 2, 5)}
    assert peaks[1] == pytest.approx(2.162, abs=0.002)  # the paper: 2.4 m/s at v_des = 1.0
    assert peaks[2] == pytest.approx(1.293, abs=0.002)  # much lower
    assert peaks[5] == pytest.approx(1.077, abs=0.002)  # a bit better again


def test_k_sweep_reproduces_fig_10_printed(six_printed):
    """Eq. 6 as printed, Newton for the paper's fixed n: the K = 1 peak varies with the seed (these
    10 seeds: 2.12-2.93 m/s, so a single run, as Fig. 10 is, lands on 2.4 m/s for some seeds; the
    30-seed share is in docs/reproduction.md); K = 2 is much lower on every seed (1.20-1.454 m/s;
    1.26-1.43 with the early stop of newton_stop=converged), K = 5 lower again on average (1.18-1.382; the
    noise's speed jitter ~|r_noise| / dT blurs the gap, which three seeds can hide)."""
    peaks = {K: np.array([np.linalg.norm(r[2], axis=2).max() for r in runs]) for K, runs in six_printed.items()}
    assert (peaks[1] > 2.0).all() and peaks[1].max() > 2.3
    assert (peaks[2] < peaks[1]).all() and (peaks[2] < 1.5).all()
    assert peaks[5].mean() < peaks[2].mean() and (peaks[5] < 1.4).all()  # fixed n: 1.18-1.382 m/s


def test_rotating_the_flow_rotates_the_paths():
    q1, healthy = six_vehicle_formation()
    th = np.deg2rad(37.0)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    # gated: the printed rule's draws hinge on ||r - r_f|| <= a_p to rounding, which a rotation changes
    kw = dict(a_p=A_P, K=2, n=20, sigma=1e-3, noise_rule="gated")
    ref = CEMNavigator(healthy, q1, rng=np.random.default_rng(5), **kw)
    rot = CEMNavigator(healthy @ R.T + [3.0, -2.0], q1 @ R.T + [3.0, -2.0], theta=th,
                       rng=np.random.default_rng(5), **kw)
    for _ in range(400):
        p, _ = ref.step()
        q, _ = rot.step()
    np.testing.assert_allclose(q, p @ R.T + [3.0, -2.0], atol=1e-6)


def test_the_navigator_names_its_kernels_module_publicly():
    """The plugin reads the measurement slots through ``CEMNavigator.kernels`` (issue 27: no reach
    into the inverter's private attribute); it is the compiled module the inverter runs."""
    from swarmscene.methods.cem import kernels
    from swarmscene.methods.cem.flow import CEMNavigator

    nav = CEMNavigator(np.array([[-5.0, 0.3], [-5.0, -0.4]]), np.array([[0.0, 0.0]]), a_p=1.0, theta=0.0,
                       v_des=1.0, dT=0.1, K=1, n=20, sigma=0.001, rng=np.random.default_rng(0))
    assert nav.kernels is kernels and nav.inverter.kernels is kernels
