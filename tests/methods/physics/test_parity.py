"""Each physics model against an independent transcription of its published formula (issue #37).

The transcriptions are written from the sources, scalar by scalar with ``math`` (no numpy, no code
shared with methods/physics), and compared in float64 within 1e-12 (relative).
"""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from swarmscene.methods.physics import battery, crazyflie, downwash, drag, ground_effect, radio

C1, C2, C3 = 2267.18, 0.16, -0.11  # gym-pybullet-drones cf2x.urdf dw_coeff_1..3
R_P = 2.31348e-2  # cf2x.urdf prop_radius


def gym_downwash(positions):
    """gym-pybullet-drones BaseAviary._downwash, per drone: the z forces of every drone above it."""
    forces = []
    for me in positions:
        total = 0.0
        for other in positions:
            delta_z = other[2] - me[2]
            delta_xy = math.hypot(other[0] - me[0], other[1] - me[1])
            if delta_z > 0 and delta_xy < 10:
                alpha = C1 * (R_P / (4 * delta_z)) ** 2
                beta = C2 * delta_z + C3
                total += -alpha * math.exp(-0.5 * (delta_xy / beta) ** 2)
        forces.append(total)
    return forces


def _stack(seed, n=14):
    """Vehicles stacked 0.3 m apart in height (+-2 cm), scattered within 1 m aside: no two are
    near the fit's singular height difference 0.6875 m (differences are 0.3 k +- 4 cm)."""
    rng = random.Random(seed)
    heights = [0.3 * k + rng.uniform(-0.02, 0.02) for k in range(n)]
    rng.shuffle(heights)
    return [(rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), z) for z in heights]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_downwash_kernel_is_the_published_fit_without_regularisation(seed):
    pts = _stack(seed)
    expected = gym_downwash(pts)
    force, strongest, _, _ = downwash.downwash_field(np.array(pts), C1, C2, C3, R_P, 0.0, 0.0, 10.0, 1e3,
                                          np.array(crazyflie.KEEP_OUT_RADII))
    assert strongest == force.max()
    for got, want in zip(-force, expected, strict=True):
        assert got == pytest.approx(want, rel=1e-12, abs=1e-300)
    assert any(f < -1e-3 for f in expected)  # the stacks are close enough to feel it


def test_downwash_vector_form_matches_the_fit_and_regularises_its_singularities():
    dz, r = np.array([0.2, 0.5, 1.0, 2.5]), np.array([0.0, 0.05, 0.1, 0.3])
    want = [C1 * (R_P / (4 * z)) ** 2 * math.exp(-0.5 * (x / (C2 * z + C3)) ** 2) for z, x in zip(dz, r, strict=True)]
    np.testing.assert_allclose(downwash.downwash_force(dz, r, C1, C2, C3, R_P), want, rtol=1e-12)
    # the published width is zero at dz = -C3 / C2: 0/0 straight below; regularised, finite and alpha
    z0 = -C3 / C2
    with np.errstate(invalid="ignore", divide="ignore"):
        assert np.isnan(downwash.downwash_force(z0, 0.0, C1, C2, C3, R_P))
    alpha = C1 * (R_P / (4 * z0)) ** 2
    assert downwash.downwash_force(z0, 0.0, C1, C2, C3, R_P, min_width=0.046) == pytest.approx(alpha, rel=1e-12)
    # and continuous in r there (a millimetre aside it no longer drops to zero)
    aside = downwash.downwash_force(z0, 0.001, C1, C2, C3, R_P, min_width=0.046)
    assert aside == pytest.approx(alpha * math.exp(-0.5 * 0.001**2 / 0.046**2), rel=1e-12)
    # 1 / dz^2 capped at min_height
    assert downwash.downwash_force(1e-6, 0.0, C1, C2, C3, R_P, 0.0, 0.1) == pytest.approx(
        C1 * (R_P / 0.4) ** 2 * math.exp(0.0), rel=1e-12)


def test_keep_out_norm_and_conflicts_match_every_pair():
    pts = np.array([[0, 0, 1.0], [0.05, 0.0, 1.2], [1.0, 0, 1.0], [1.0, 0.1, 1.0], [3, 3, 1]])
    radii = (0.12, 0.12, 0.3)
    norms = {(i, j): math.sqrt(sum(((pts[j][k] - pts[i][k]) / radii[k]) ** 2 for k in range(3)))
             for i in range(5) for j in range(i + 1, 5)}
    _, _, best, conflicts = downwash.downwash_field(pts, C1, C2, C3, R_P, 0.0, 0.1, 1.0, 3.0, np.array(radii))
    near = {k: v for k, v in norms.items() if math.hypot(*(pts[k[1]] - pts[k[0]])[:2]) <= 1.0}
    assert best == pytest.approx(min(near.values()), rel=1e-12)
    assert sorted(map(tuple, conflicts.tolist())) == sorted(k for k, v in norms.items() if v < 1)
    assert downwash.keep_out_norm(pts[1] - pts[0], radii) == pytest.approx(norms[(0, 1)], rel=1e-12)


def test_ground_effect_is_cheeseman_bennett():
    z = [0.02, 0.05, 0.1, 0.5, 2.0]
    want = [1.0 / (1.0 - (R_P / (4.0 * h)) ** 2) for h in z]
    np.testing.assert_allclose(ground_effect.thrust_ratio(z, R_P), want, rtol=1e-12)
    # clipped below min_height (default R / 2: 4 / 3 at most)
    assert ground_effect.thrust_ratio(0.0, R_P, R_P / 2) == pytest.approx(4.0 / 3.0, rel=1e-12)


def _quat_to_r(q):
    w, x, y, z = q
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def test_rotor_drag_is_foerster_and_body_drag_quadratic():
    rng = random.Random(3)
    k = crazyflie.K_AERO
    m = crazyflie.MASS
    quats, vels, sums = [], [], []
    for _ in range(8):
        q = [rng.gauss(0, 1) for _ in range(4)]
        n = math.sqrt(sum(c * c for c in q))
        quats.append([c / n for c in q])
        vels.append([rng.uniform(-3, 3) for _ in range(3)])
        sums.append(rng.uniform(4000, 8000))
    got = drag.rotor_drag(np.array(vels), np.array(quats), np.array(sums), k, m)
    for i in range(8):
        R = _quat_to_r(quats[i])
        v_body = [sum(R[r][c] * vels[i][r] for r in range(3)) for c in range(3)]  # R^T v
        f_body = [-k[c] * sums[i] * v_body[c] for c in range(3)]  # Foerster: F_a = -K_aero theta_sum v_b
        a = [sum(R[r][c] * f_body[c] for c in range(3)) / m for r in range(3)]
        np.testing.assert_allclose(got[i], a, rtol=1e-12, atol=1e-15)
    body = drag.body_drag(np.array(vels), 1.08e-3, m)
    for i in range(8):
        speed = math.sqrt(sum(c * c for c in vels[i]))
        np.testing.assert_allclose(body[i], [-1.08e-3 / m * speed * c for c in vels[i]], rtol=1e-12)
    # at hover rotor speeds the sideways coefficient is the airframe's 0.206 1/s
    hover = 4 * crazyflie.HOVER_ROTOR_SPEED * k[0] / m
    assert hover == pytest.approx(0.206, abs=5e-4)


def battery_step(s, thrust, dt, q=0.25, vf=4.2, ve=3.0, ri=0.2, ph=5.88, w=crazyflie.MASS * 9.81, tw=2.25):
    """One step of the cell, transcribed: P, V_oc, I (smaller root), V, s, T_max."""
    p = ph * (thrust / w) ** 1.5
    v_oc = ve + (vf - ve) * s
    i = (v_oc - math.sqrt(v_oc**2 - 4 * ri * p)) / (2 * ri)
    v = v_oc - i * ri
    s = max(s - i * dt / (3600 * q), 0.0)
    return s, v, tw * w * (v / vf) ** 2


def test_battery_cell_matches_its_transcription():
    w = crazyflie.MASS * 9.81
    s = 0.8
    for thrust in (0.5 * w, w, 1.7 * w):
        s_want, v_want, t_want = battery_step(s, thrust, 0.01)
        p = battery.power(thrust, 5.88, w)
        v_oc = battery.open_circuit_voltage(s, 4.2, 3.0)
        amps = battery.current(v_oc, p, 0.2)
        v = v_oc - amps * 0.2
        assert v == pytest.approx(v_want, rel=1e-12)
        assert s - amps * 0.01 / (3600 * 0.25) == pytest.approx(s_want, rel=1e-12)
        assert battery.max_thrust(v, 2.25, w, 4.2) == pytest.approx(t_want, rel=1e-12)
    # the current delivers P through R_i: P = (V_oc - I R) I
    amps = battery.current(np.array([4.0]), np.array([7.7]), 0.2)
    assert (4.0 - amps[0] * 0.2) * amps[0] == pytest.approx(7.7, rel=1e-12)
    # hover on a full cell lasts the datasheet's 7 minutes, to the cut-off
    s, t, v = 1.0, 0.0, 4.2
    while s > 0 and v >= battery.CUTOFF and t < 1000:
        s, v, _ = battery_step(s, w, 0.5)
        t += 0.5
    assert t == pytest.approx(420.0, abs=1.0)


def test_radio_reception_rate_is_the_fsk_link_model():
    d = [1.0, 10.0, 50.0, 100.0, 130.0, 160.0, 300.0]
    pt, pl0, n_exp, pn, frame = 0.0, 40.05, 2.0, -93.0, 32
    want = []
    for x in d:
        pr = pt - pl0 - 10 * n_exp * math.log10(x / 1.0)
        snr = 10 ** ((pr - pn) / 10)
        want.append((1 - 0.5 * math.exp(-snr / 2)) ** (8 * frame))
    np.testing.assert_allclose(radio.reception_rate(d, pt, pl0, n_exp, pn, frame), want, rtol=1e-12, atol=1e-300)
    assert want[3] > 0.99 and want[-1] < 1e-6  # whole to ~100 m, lost beyond ~160 m
    assert radio.FRIIS_1M_2G4 == pytest.approx(20 * math.log10(4 * math.pi / (299_792_458 / 2.4e9)), rel=1e-12)


def test_radio_budget_keeps_the_nearest_senders():
    dist = np.array([[0, 1, 2, 3], [1, 0, 5, 4], [2, 5, 0, 6], [3, 4, 6, 0]], dtype=float)
    arrived = ~np.eye(4, dtype=bool)
    arrived[0, 1] = False  # the nearest sender of 0 was lost anyway
    kept = radio.within_budget(dist, arrived, 2)
    assert kept.sum(axis=1).tolist() == [2, 2, 2, 2]
    assert kept[0].tolist() == [False, False, True, True]
    assert kept[1].tolist() == [True, False, False, True]


# -- the compiled forms against the NumPy functions above ------------------------------------------
def test_compiled_battery_step_is_the_cell_functions_composed():
    from swarmscene.methods.physics.kernels import battery_step

    rng = np.random.default_rng(4)
    n, w, m = 50, crazyflie.MASS * 9.81, crazyflie.MASS
    charge = rng.uniform(0.0, 1.0, n)
    charge[:3] = [0.0, 1e-6, 1.0]
    tau = rng.normal(0, 4, (n, 3)) + [0, 0, 9.81]
    args = (0.02, m, w, 0.25, 4.2, 3.0, 0.2, 2.8, 5.88, 2.25)
    depleted = np.zeros(n, bool)
    new_charge = charge.copy()
    voltage, cut, out, lowest = battery_step(new_charge, depleted, tau, *args)
    assert lowest == voltage.min()
    thrust = m * np.linalg.norm(tau, axis=1)
    v_oc = battery.open_circuit_voltage(charge, 4.2, 3.0)
    cap = battery.power_cap(v_oc, 2.8, 0.2)
    amps = battery.current(v_oc, np.minimum(battery.power(thrust, 5.88, w), cap), 0.2)
    np.testing.assert_allclose(voltage, v_oc - amps * 0.2, rtol=1e-12)
    want_charge = np.maximum(charge - amps * 0.02 / 900.0, 0.0)
    np.testing.assert_allclose(new_charge, want_charge, rtol=1e-12, atol=1e-300)
    gone = (want_charge <= 0) | (v_oc <= 2.8)
    assert out.tolist() == gone.tolist() == depleted.tolist() and gone[0]
    available = np.minimum(battery.max_thrust(v_oc - amps * 0.2, 2.25, w, 4.2),
                           battery.thrust_at_power(cap, 5.88, w))
    available[gone] = 0.0
    factor = np.where(thrust > available, (thrust - available) / thrust, 0.0)
    np.testing.assert_allclose(cut, -factor[:, None] * tau, rtol=1e-12, atol=1e-300)


def test_compiled_drag_is_rotor_plus_body_drag():
    rng = np.random.default_rng(5)
    q = rng.normal(size=(30, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    vel, sums = rng.normal(0, 3, (30, 3)), rng.uniform(4000, 8000, 30)
    k, m = crazyflie.K_AERO, crazyflie.MASS
    acc, peak = drag.drag_acceleration(vel, q, sums, k, m, 1.08e-3)
    want = drag.rotor_drag(vel, q, sums, k, m) + drag.body_drag(vel, 1.08e-3, m)
    np.testing.assert_allclose(acc, want, rtol=1e-12, atol=1e-14)
    assert peak == pytest.approx(np.linalg.norm(want, axis=1).max(), rel=1e-12)


@pytest.mark.parametrize("seed, spread", [(0, (30, 30, 30)), (1, (100, 0.01, 1)), (2, (1, 1, 50))])
def test_compiled_nearest_distance_is_the_k_d_trees(seed, spread):
    from scipy.spatial import cKDTree

    from swarmscene.methods.physics.cells import nearest_distance

    pos = np.random.default_rng(seed).normal(0, 1, (700, 3)) * spread
    assert np.array_equal(nearest_distance(pos), cKDTree(pos).query(pos, k=2)[0][:, 1])
    assert nearest_distance(pos[:1]).tolist() == [np.inf]


def test_compiled_ground_lift_is_the_ratio_times_the_thrust():
    from swarmscene.methods.physics.kernels import ground_lift

    rng = np.random.default_rng(6)
    z, tau = rng.uniform(0.0, 0.3, 40), rng.normal(0, 3, (40, 3)) + [0, 0, 9.81]
    lift, peak = ground_lift(z, tau, 0.01, R_P, R_P / 2)
    ratio = ground_effect.thrust_ratio(z - 0.01, R_P, R_P / 2)
    np.testing.assert_allclose(lift, (ratio - 1)[:, None] * tau, rtol=1e-12, atol=1e-300)
    assert peak == ratio.max()
