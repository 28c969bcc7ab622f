"""The lock-step closest-velocity solver against scipy's general-purpose solvers on the same problems."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize, nnls

from swarmscene.methods.baselines.halfplanes import (
    closest_velocity,
    halfplane_from_normal,
    linear_program3,
    violation,
)


def random_halfplanes(rng, m, lines, radius, feasible=True):
    """(point, direction, valid) of ``lines`` half-planes per row; with ``feasible`` each row's
    half-planes all contain a random point of the disc; some rows padded."""
    angle = rng.uniform(0, 2 * np.pi, (m, lines))
    normal = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    if feasible:
        inside = rng.uniform(-0.7, 0.7, (m, 2)) * radius
        offset = np.einsum("mkj,mj->mk", normal, inside) - rng.uniform(0, 0.5, (m, lines))
    else:
        offset = rng.uniform(0.2, 0.9, (m, lines)) * radius  # every plane pushes outwards
    point, direction = halfplane_from_normal(normal, offset)
    valid = rng.uniform(size=(m, lines)) < 0.85
    return point, direction, valid


def scipy_closest(point, direction, valid, v_pref, radius):
    """argmin |v - v_pref|^2 s.t. the valid half-planes and |v| <= radius, by SLSQP."""
    q, d = point[valid], direction[valid]
    cons = [{"type": "ineq", "fun": lambda v: -(d[:, 0] * (q[:, 1] - v[1]) - d[:, 1] * (q[:, 0] - v[0]))},
            {"type": "ineq", "fun": lambda v: radius**2 - v @ v}]
    res = minimize(lambda v: np.sum((v - v_pref) ** 2), np.zeros(2), jac=lambda v: 2 * (v - v_pref),
                   constraints=cons, method="SLSQP", options={"ftol": 1e-12, "maxiter": 500})
    return res.x if res.success else None


def kkt_residual(point, direction, valid, v, v_pref, radius, tol=1e-9):
    """|v_pref - v - sum_k lambda_k a_k| with lambda >= 0 over the active constraints (outward
    normals a_k of the half-planes met with equality, and v itself for the disc): zero at the optimum
    of the convex problem (Karush-Kuhn-Tucker), found by non-negative least squares."""
    normal = np.stack([-direction[:, 1], direction[:, 0]], axis=-1)  # inward normals
    active = valid & (np.abs(violation(point[None], direction[None], v[None])[0]) <= tol)
    columns = [-normal[active]]
    if abs(np.linalg.norm(v) - radius) <= tol:
        columns.append(v[None] / radius)
    a = np.concatenate(columns, axis=0).T if sum(len(c) for c in columns) else np.zeros((2, 0))
    if a.shape[1] == 0:
        return float(np.linalg.norm(v_pref - v))
    _, residual = nnls(a, v_pref - v)
    return residual


def test_closest_velocity_is_the_qp_optimum_and_meets_every_halfplane():
    rng = np.random.default_rng(7)
    m, radius = 300, 1.5
    point, direction, valid = random_halfplanes(rng, m, 8, radius)
    v_pref = rng.uniform(-2.5, 2.5, (m, 2))
    v, feasible = closest_velocity(point, direction, valid, v_pref, radius)
    assert feasible.all()
    assert np.all(np.where(valid, violation(point, direction, v), -np.inf) <= 1e-9)
    assert np.all(np.linalg.norm(v, axis=1) <= radius + 1e-9)
    for i in range(m):
        assert kkt_residual(point[i], direction[i], valid[i], v[i], v_pref[i], radius) <= 1e-9
        reference = scipy_closest(point[i], direction[i], valid[i], v_pref[i], radius)
        if reference is not None:  # SLSQP converged
            np.testing.assert_allclose(v[i], reference, atol=1e-6)
    # rows whose preferred velocity is allowed keep it exactly
    free = np.all(np.where(valid, violation(point, direction, v_pref), -1) <= 0, axis=1) & (
        np.linalg.norm(v_pref, axis=1) <= radius)
    assert free.any()
    np.testing.assert_array_equal(v[free], v_pref[free])


def test_infeasible_rows_get_the_least_largest_penetration():
    """linearProgram3 = min over the disc of max_k penetration_k (hard lines: none here)."""
    rng = np.random.default_rng(3)
    m, radius = 30, 1.0
    point, direction, valid = random_halfplanes(rng, m, 6, radius, feasible=False)
    valid[:] = True
    v, feasible = closest_velocity(point, direction, valid, np.zeros((m, 2)), radius)
    assert (~feasible).sum() >= 25  # planes pushing outwards from every side leave nothing
    ours = violation(point, direction, v).max(axis=1)
    for i in np.flatnonzero(~feasible):
        q, d = point[i], direction[i]
        pen = lambda x: d[:, 0] * (q[:, 1] - x[1]) - d[:, 1] * (q[:, 0] - x[0])  # noqa: E731, B023 (used in this iteration)
        best = min(
            (minimize(lambda x: x[2], np.r_[start, 5.0], method="SLSQP",
                      constraints=[{"type": "ineq", "fun": lambda x: x[2] - pen(x)},  # noqa: B023 (this iteration)
                                   {"type": "ineq", "fun": lambda x: radius**2 - x[:2] @ x[:2]}],
                      options={"ftol": 1e-13, "maxiter": 500}).fun
             for start in ([0.0, 0.0], [0.5, -0.5])),
        )
        assert ours[i] == pytest.approx(best, abs=1e-6)


def test_hard_lines_stay_met_in_the_fallback():
    rng = np.random.default_rng(11)
    m, radius = 40, 1.0
    point, direction, valid = random_halfplanes(rng, m, 6, radius, feasible=False)
    valid[:] = True
    # line 0 hard: the half-plane v_x >= 0.2, compatible with the disc
    point[:, 0], direction[:, 0] = halfplane_from_normal(np.array([1.0, 0.0]), np.array(0.2))
    v = linear_program3(point, direction, valid, 1, np.zeros(m, dtype=int), radius, np.zeros((m, 2)))
    assert np.all(v[:, 0] >= 0.2 - 1e-9)
