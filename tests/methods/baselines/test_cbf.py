"""Barrier certificates against the same QPs solved by scipy, and against the Robotarium's
single-integrator barrier certificate (``rps``, robotarium_python_simulator, solved with cvxopt)."""

from __future__ import annotations

import numpy as np
import pytest
from cvxopt import solvers
from rps.utilities.barrier_certificates import create_single_integrator_barrier_certificate
from scipy.optimize import minimize
from scipy.spatial import cKDTree

from swarmscene.methods.baselines.cbf import class_k, influence_range, safe_velocities
from swarmscene.methods.baselines.neighbours import neighbour_table


def swarm(rng, n, extent, d_s):
    """n positions in a square, at least d_s apart (h >= 0 for every pair)."""
    pos = []
    while len(pos) < n:
        p = rng.uniform(-extent, extent, 2)
        if all(np.linalg.norm(p - q) > d_s for q in pos):
            pos.append(p)
    return np.array(pos)


def filter_all(pos, u_nom, d_s, gamma, power, v_max, static=None):
    """Every pair as a neighbour (no range cut), the plain certificate (no detour)."""
    n = len(pos)
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)])
    index, valid = neighbour_table(pairs, pos, None)
    static = np.zeros(n, dtype=bool) if static is None else static
    return safe_velocities(pos, u_nom, index, valid, static, d_s, gamma, power, v_max)


def agent_qp_slsqp(i, pos, u_nom, d_s, gamma, power, v_max, static):
    """Agent i's decentralised QP: min |u - u_nom_i|^2 s.t. -2 e_ij^T u <= s_ij gamma kappa(h_ij)
    (s = 1/2, or 1 against a static j) and |u| <= v_max, by SLSQP."""
    others = [j for j in range(len(pos)) if j != i]
    e = pos[i] - pos[others]
    h = np.einsum("ij,ij->i", e, e) - d_s**2
    share = np.where(static[others], 1.0, 0.5)
    b = share * gamma * class_k(h, power)
    cons = [{"type": "ineq", "fun": lambda u: b + 2 * e @ u, "jac": lambda u: 2 * e},
            {"type": "ineq", "fun": lambda u: v_max**2 - u @ u, "jac": lambda u: -2 * u[None]}]
    res = minimize(lambda u: np.sum((u - u_nom[i]) ** 2), np.zeros(2), jac=lambda u: 2 * (u - u_nom[i]),
                   constraints=cons, method="SLSQP", options={"ftol": 1e-14, "maxiter": 1000})
    return res, e, b


@pytest.mark.parametrize("power", [1, 3])
def test_each_agent_gets_the_optimum_of_its_qp(power):
    rng = np.random.default_rng(power)
    d_s, gamma, v_max = 0.6, 1.0, 1.0
    compared = 0
    for _trial in range(12):
        pos = swarm(rng, 10, 2.5, d_s)
        u_nom = rng.uniform(-1.2, 1.2, (10, 2))
        static = rng.uniform(size=10) < 0.2
        u, feasible = filter_all(pos, u_nom, d_s, gamma, power, v_max, static)
        assert feasible.all()  # h >= 0 everywhere: u = 0 is allowed
        for i in np.flatnonzero(~static):
            res, e, b = agent_qp_slsqp(i, pos, u_nom, d_s, gamma, power, v_max, static)
            assert np.all(-2 * e @ u[i] <= b + 1e-9)
            assert np.linalg.norm(u[i]) <= v_max + 1e-9
            if res.success:
                np.testing.assert_allclose(u[i], res.x, atol=1e-6)
                compared += 1
    assert compared > 80


def test_split_halves_imply_the_joint_certificate_and_discrete_time_invariance():
    """Both halves together give -2 e^T (u_i - u_j) <= gamma h; holding the inputs for T with
    gamma T <= 1 then keeps every h >= (1 - gamma T) h >= 0 (single integrator, exact)."""
    rng = np.random.default_rng(9)
    d_s, gamma, v_max, period = 0.6, 10.0, 1.0, 0.1
    for _ in range(20):
        pos = swarm(rng, 12, 2.0, d_s)
        u, _ = filter_all(pos, rng.uniform(-1, 1, (12, 2)), d_s, gamma, 1, v_max)
        i, j = np.triu_indices(12, 1)
        e = pos[i] - pos[j]
        h = np.einsum("ij,ij->i", e, e) - d_s**2
        assert np.all(-2 * np.einsum("ij,ij->i", e, u[i] - u[j]) <= gamma * h + 1e-9)
        moved = pos + period * u
        e1 = moved[i] - moved[j]
        assert np.all(np.einsum("ij,ij->i", e1, e1) - d_s**2 >= (1 - gamma * period) * h - 1e-9)


def test_influence_range_bounds_the_active_constraints():
    d_s, gamma, v_max = 0.6, 1.0, 1.0
    r = influence_range(d_s, gamma, 1, v_max)
    # at r the worst-case |u| = v_max straight at the neighbour meets the half-constraint exactly
    assert 2 * r * v_max == pytest.approx(gamma * (r * r - d_s * d_s) / 2, rel=1e-12)
    rng = np.random.default_rng(4)
    pos = swarm(rng, 30, 6.0, d_s)
    u_nom = rng.uniform(-1, 1, (30, 2))
    full, _ = filter_all(pos, u_nom, d_s, gamma, 1, v_max)
    index, valid = neighbour_table(cKDTree(pos).query_pairs(r, output_type="ndarray"), pos, None)
    cut, _ = safe_velocities(pos, u_nom, index, valid, np.zeros(30, bool), d_s, gamma, 1, v_max)
    np.testing.assert_allclose(cut, full, atol=1e-12)


@pytest.fixture
def tight_cvxopt():
    """The Robotarium loosens cvxopt globally (reltol = feastol = 1e-2); solve its QP tightly."""
    saved = dict(solvers.options)
    solvers.options.update({"reltol": 1e-10, "abstol": 1e-10, "feastol": 1e-10, "maxiters": 200})
    yield
    solvers.options.clear()
    solvers.options.update(saved)


def test_two_agents_match_the_robotarium(tight_cvxopt):
    """The Robotarium solves the joint QP; for two agents whose nominal inputs sum to a vector
    perpendicular to p_1 - p_2 the decentralised halves give the same inputs (equal multipliers),
    so the outputs must agree. Robotarium units and defaults: gamma = 100, kappa = h^3,
    D_s = 0.17 m, |u_nom| <= 0.2 m/s."""
    certificate = create_single_integrator_barrier_certificate()
    rng = np.random.default_rng(12)
    engaged = 0
    for _ in range(50):
        x = rng.uniform(-0.6, 0.6, (2, 2))
        while np.linalg.norm(x[0] - x[1]) <= 0.2:
            x = rng.uniform(-0.6, 0.6, (2, 2))
        e = x[0] - x[1]
        perp = np.array([-e[1], e[0]]) / np.linalg.norm(e)
        u1 = rng.uniform(-0.14, 0.14, 2)
        u2 = -u1 + rng.uniform(-0.05, 0.05) * perp
        u_nom = np.array([u1, u2])
        theirs = np.asarray(certificate(u_nom.T.copy(), x.T.copy())).T
        mine, _ = filter_all(x, u_nom, 0.17, 100.0, 3, 10.0)
        np.testing.assert_allclose(mine, theirs, atol=1e-6)
        engaged += not np.allclose(theirs, u_nom, atol=1e-6)
    assert engaged > 5


def test_many_agents_keep_the_robotarium_constraints_at_no_lower_cost(tight_cvxopt):
    """For N agents the decentralised inputs satisfy every constraint of the Robotarium's joint QP
    (they satisfy both halves), so they cost at least its optimum."""
    certificate = create_single_integrator_barrier_certificate()
    rng = np.random.default_rng(13)
    for _ in range(10):
        x = swarm(rng, 8, 0.8, 0.2)
        u_nom = rng.uniform(-0.14, 0.14, (8, 2))
        theirs = np.asarray(certificate(u_nom.T.copy(), x.T.copy())).T
        mine, _ = filter_all(x, u_nom, 0.17, 100.0, 3, 10.0)
        i, j = np.triu_indices(8, 1)
        e = x[i] - x[j]
        h = np.einsum("ij,ij->i", e, e) - 0.17**2
        assert np.all(-2 * np.einsum("ij,ij->i", e, mine[i] - mine[j]) <= 100 * h**3 + 1e-9)
        assert np.sum((mine - u_nom) ** 2) >= np.sum((theirs - u_nom) ** 2) - 1e-9
