"""The NumPy implementation of CEM's per-tick hot path, kept as the oracle of the compiled kernel.

Algorithm 1's K passes and CalcXY (Algorithm 2) with the saddle noise of eq. 6, vectorised over
agents with NumPy, exactly as swarmscene shipped them before issue #20 moved the per-step path to
``swarmscene.methods.cem.kernels``. The kernel must reproduce these to round-off (bit for bit on
an x86-64 CPU with FMA, where NumPy's SIMD loops fuse the complex products); ``tests/methods/cem``
compares them over random geometries and every option.
"""

from __future__ import annotations

import numpy as np

from swarmscene.methods.cem.flow import NEWTON_TOL, NOISE_RULES, CEMNavigator, _strengths


class NumpyNewtonInverter:
    """CalcXY (Algorithm 2): the point z whose (phi, psi) is a target, by Newton's method.

    Each iteration solves ``J dz = [phi_1 - phi, psi_1 - psi]`` (eq. 5), i.e. the complex division
    ``dz = (f(z) - w) / f'(z)``, and adds the saddle noise of eq. 6 when the estimate lies within
    a_p of a failed vehicle. Vectorised over agents (N) and doublets (F); every work array is
    allocated once here, so a guidance tick allocates (almost) nothing.

    Args:
        centres: (F,) complex doublet centres in the flow frame.
        a_p: planned exclusion radius, m.
        n_agents: N. n: Newton iterations per call (paper: 20). sigma: noise deviation, m (1 mm).
        rng: random generator for the noise (the run's generator, so runs are reproducible).
        strengths: (F,) doublet strengths mu_f (default :func:`doublet_strengths`).
        noise_rule: when eq. 6 draws, one of :data:`NOISE_RULES` (module docstring).
    """

    def __init__(self, centres: np.ndarray, a_p: float, n_agents: int, n: int, sigma: float,
                 rng: np.random.Generator, strengths: np.ndarray | None = None,
                 noise_rule: str = "printed", newton_stop: str = "fixed_n", branch_guard: bool = True) -> None:
        if noise_rule not in NOISE_RULES:
            raise ValueError(f"noise_rule: must be one of {', '.join(NOISE_RULES)} (got {noise_rule!r})")
        self.printed = noise_rule == "printed"
        self.converged, self.branch_guard = newton_stop == "converged", branch_guard
        centres = np.atleast_1d(np.asarray(centres, dtype=complex))
        self.c = centres.reshape(1, -1)
        self.mu = _strengths(centres, a_p, strengths).reshape(1, -1)
        self.a, self.a2 = float(a_p), float(a_p) ** 2
        self.offset = complex(self.c.mean())
        self.n, self.sigma, self.rng = int(n), float(sigma), rng
        self.iterations = 0  # Newton iterations run by the last call (diagnostic)
        m, f = n_agents, self.c.shape[1]
        self.z = np.zeros(m, complex)  # the estimate, updated in place
        self._zcol = self.z[:, None]
        self._U, self._V, self._G = (np.empty((m, f), complex) for _ in range(3))
        self._R = np.empty((m, f))
        self._e, self._fp, self._r = np.empty(m, complex), np.empty(m, complex), np.empty(m)
        self._wt, self._z_start = np.empty(m, complex), np.empty(m, complex)
        self._single = f == 1  # one doublet: views instead of sums over the doublet axis
        self._gs = self._G[:, 0] if self._single else np.empty(m, complex)

    def solve(self, w: np.ndarray) -> np.ndarray:
        """Run Algorithm 2 from the current estimate ``self.z`` towards targets w = phi + j psi (N,).

        Returns ``self.z`` (updated in place). Call inside ``np.errstate(all="ignore")``: at a
        stagnation point f' = 0 and the division is guarded afterwards, not before.
        """
        U, V, G, e, fp, r, zc = self._U, self._V, self._G, self._e, self._fp, self._r, self._zcol
        z, c, mu, gs, single = self.z, self.c, self.mu, self._gs, self._single
        np.add(w, self.offset, out=self._wt)
        z_start = self._z_start
        np.copyto(z_start, z)
        it = 0
        for it in range(self.n):
            np.subtract(zc, c, out=U)  # u = z - z_f
            np.reciprocal(U, out=V)
            np.multiply(V, mu, out=G)  # mu_f / u
            if not single:
                np.sum(G, axis=1, out=gs)
            np.add(z, gs, out=e)
            np.subtract(e, self._wt, out=e)  # f(z) - w
            np.multiply(G, V, out=G)  # mu_f / u^2
            if not single:
                np.sum(G, axis=1, out=gs)
            np.subtract(1.0, gs, out=fp)  # f'(z)
            np.divide(e, fp, out=e)  # J^{-1} [phi_1 - phi, psi_1 - psi]
            np.subtract(z, e, out=z)
            np.abs(e, out=r)
            if self.printed:  # eq. 6 as printed: every iteration, the last one too
                noisy = self.sigma > 0 and self._add_noise(U)
            else:
                noisy = it < self.n - 1 and self.sigma > 0 and self._add_noise(U, r)
            if self.converged and not noisy and r.max() < NEWTON_TOL:
                break
        self.iterations = it + 1
        if self.branch_guard:
            self._guard(z_start)
        return z

    def _add_noise(self, U: np.ndarray, step: np.ndarray | None = None, rows: np.ndarray | None = None) -> bool:
        """Eq. 6: |N(0, sigma)| r_a + N(0, sigma) r_b for estimates inside the planned disk.

        r_a = (r - r_f) / ||r - r_f|| points away from the failed vehicle, r_b = [[0, 1], [-1, 0]] r_a,
        which in complex form is -j r_a; r is the estimate the Jacobian was evaluated at (``U`` =
        r - r_f). Printed rule (``step`` None): drawn for every estimate with ||r - r_f|| <= a_p.
        Gated rule: drawn only for an estimate strictly inside a_p whose Newton update ``step`` is
        still at least sigma: an estimate that has converged (onto the ring, where psi = 0 wraps
        the disk, or onto a root that several failures' flows moved a few mm inside a_p) is not at
        a saddle, and kicking it every iteration would keep it from converging; the guard then
        places it. ``rows`` forces noise on those agents (nearest disk). Returns whether any noise
        was drawn.
        """
        R = self._R
        np.abs(U, out=R)
        if rows is None and step is None:
            if not R.min() <= self.a:
                return False
            rows, cols = np.nonzero(R <= self.a)
        elif rows is None:
            if not R.min() < self.a * (1.0 - 1e-9):
                return False
            mask = (R < self.a * (1.0 - 1e-9)) & (step >= self.sigma)[:, None]
            rows, cols = np.nonzero(mask)
            if rows.size == 0:
                return False
        else:
            cols = R[rows].argmin(axis=1)
        ra = U[rows, cols] / R[rows, cols]
        g = self.rng.standard_normal((2, rows.size)) * self.sigma
        np.add.at(self.z, rows, ra * (np.abs(g[0]) - 1j * g[1]))
        return True

    def _guard(self, z_start: np.ndarray) -> None:
        """Keep commands finite and outside every planned disk (see module docstring).

        A non-finite estimate (Newton met f' = 0 exactly, at a stagnation point) restarts from its
        start point plus the eq. 6 noise, which moves it off the saddle for the next call. An estimate
        inside a disk, deeper than rounding, is moved out through that circle by whichever of two
        inversions lands nearer its start point: the mirror u -> mu / (U u) (U the doublet's local
        flow; for one failure u -> a_p^2 / u, which keeps phi and psi exactly, so it turns the inside
        root past the front saddle into the outside one) or the radial u -> a_p^2 / conj(u) (keeps the
        side for a root a few mm inside, where the mirror would jump across the disk).
        """
        U, R, z = self._U, self._R, self.z
        np.subtract(self._zcol, self.c, out=U)
        np.abs(U, out=R)
        inner = self.a * (1.0 - 1e-6)  # a point on the ring itself is outside
        if R.min() >= inner:  # False for NaN too
            return
        bad = np.flatnonzero(~np.isfinite(z))
        if bad.size:
            z[bad] = z_start[bad]
            np.subtract(self._zcol, self.c, out=U)
            self._add_noise(U, rows=bad)
            np.subtract(self._zcol, self.c, out=U)
            np.abs(U, out=R)
        k = R.argmin(axis=1)
        rows = np.flatnonzero(R[np.arange(z.size), k] < inner)
        u, cf, mu = U[rows, k[rows]], self.c[0, k[rows]], self.mu[0, k[rows]]
        mirror = cf + mu * self.a2 / (np.conj(mu) * u)  # local flow U = conj(mu) / a_p^2
        radial = cf + self.a2 / np.conj(u)
        near = np.abs(mirror - z_start[rows]) <= np.abs(radial - z_start[rows])
        z[rows] = np.where(near, mirror, radial)


def numpy_calc_xy(w, zeta, centres, a_p, n=20, sigma=1e-3, rng=None, noise_rule="printed"):
    """Algorithm 2 as a function (flow frame), the NumPy way."""
    zeta = np.asarray(zeta, dtype=complex)
    inv = NumpyNewtonInverter(centres, a_p, zeta.size, n, sigma, rng or np.random.default_rng(0),
                              noise_rule=noise_rule)
    inv.z[:] = zeta
    with np.errstate(all="ignore"):
        return inv.solve(np.asarray(w, dtype=complex)).copy()


class NumpyNavigator:
    """Algorithm 1 for one activation, stepped with :class:`NumpyNewtonInverter`.

    Built from a :class:`~swarmscene.methods.cem.flow.CEMNavigator` (``nav``) before its first
    step: the same flow frame, targets, sliding step and options; ``rng`` is a generator in the
    state the navigator's was in at construction (pass a copy made with the same seed).
    """

    def __init__(self, nav: CEMNavigator, rng: np.random.Generator) -> None:
        self.origin, self.theta, self.dT, self.K, self.v_des = nav.origin, nav.theta, nav.dT, nav.K, nav.v_des
        self.rot = nav.rot
        self.w = nav.w.copy()
        self.dphi = nav.dphi
        self.dphi_used = 0.0
        self.inverter = NumpyNewtonInverter(nav.centres, nav.a_p, nav.n_agents, nav.n, nav.sigma, rng,
                                            nav.strengths, nav.noise_rule, nav.newton_stop, nav.branch_guard)
        self.inverter.z[:] = nav.zeta
        m = nav.n_agents
        self._z_prev, self._dz, self._speed = np.empty(m, complex), np.empty(m, complex), np.empty(m)
        self._wt = np.empty(m, complex)
        self._pos_c, self._vel_c = np.empty(m, complex), np.empty(m, complex)
        self.positions = self._pos_c.view(float).reshape(m, 2)
        self.velocities = self._vel_c.view(float).reshape(m, 2)

    @property
    def zeta(self) -> np.ndarray:
        return self.inverter.z

    def step(self) -> tuple[np.ndarray, np.ndarray]:
        """One guidance tick (Algorithm 1 lines 13-22); returns world (N, 2) positions, velocities."""
        z, dz, speed = self.inverter.z, self._dz, self._speed
        np.copyto(self._z_prev, z)  # r_{-1}: the previous tick's command
        with np.errstate(all="ignore"):
            for _ in range(self.K):
                used = self.dphi
                np.add(self.w, used, out=self._wt)  # line 16: phi_last + dphi (psi unchanged)
                np.copyto(z, self._z_prev)  # every pass starts from the previous tick's command
                self.inverter.solve(self._wt)  # line 17
                np.subtract(z, self._z_prev, out=dz)
                np.abs(dz, out=speed)
                v_max = speed.max() / self.dT  # line 19
                if v_max > 0.0:
                    self.dphi = used * self.v_des / v_max  # line 20
        self.dphi_used = used
        np.add(self.w, used, out=self.w)
        np.multiply(z, self.rot, out=self._pos_c)
        np.add(self._pos_c, self.origin, out=self._pos_c)
        np.multiply(dz, self.rot / self.dT, out=self._vel_c)
        return self.positions, self.velocities


def numpy_measure(nav: CEMNavigator, idx: np.ndarray, healthy: np.ndarray, pos: np.ndarray, vel: np.ndarray,
                  failed_xy: np.ndarray) -> dict:
    """The ``cem`` plugin's per-tick safety quantities the NumPy way (its step-end hook before the
    compiled ``kernels.measure_tick``): per-agent |psi - psi_0|, exclusion margin of the commands,
    and over the agents still healthy the distance to the failures' centres, the min pair
    distances of actual and commanded x-y (k-d tree), the peak commanded and actual speeds and the
    tracking error (None where no agent is live)."""
    from scipy.spatial import cKDTree

    def min_pair(xy):
        return np.inf if xy.shape[0] < 2 else float(cKDTree(xy).query(xy, k=2)[0][:, 1].min())

    live = healthy[idx]
    actual = pos[idx[live], :2]
    return {
        "drift": nav.stream_drift(),
        "margin": float(nav.exclusion_margin().min()),
        "clear": float(np.linalg.norm(actual[:, None, :] - failed_xy[None], axis=2).min()) if actual.size else np.inf,
        "pair": min_pair(actual),
        "pair_cmd": min_pair(nav.positions[live]),
        "speed": float(np.linalg.norm(nav.velocities, axis=1).max()),
        "speed_act": float(np.linalg.norm(vel[idx[live], :2], axis=1).max()) if actual.size else None,
        "track_err": float(np.linalg.norm(actual - nav.positions[live], axis=1).max()) if actual.size else None,
    }
