"""Containment Exclusion Mode (CEM): the ideal-fluid-flow navigation function, vectorised.

Romano, Uppaluru, Rastgoftar, Atkins, "Quadrotor Formation Flying Resilient to Abrupt Vehicle
Failures via a Fluid Flow Navigation Function" (papers/cem-fluid-flow-navigation.md). Healthy
agents slide along streamlines (constant stream function psi) of a uniform flow around one doublet
per failed vehicle; every guidance tick their potential phi advances by the sliding step.

Frames. The paper's plane is the engine's world x-y plane (z up, altitude untouched). The paper
flies along +x only; its future work (rotate the flow to any flight direction) is done here: the
*flow frame* is the world x-y plane translated to ``origin`` and rotated by the flight direction
``theta`` (rad, counter-clockwise from +x), as complex numbers ``zeta = (z - origin) e^{-j theta}``.
Every function below that takes ``zeta`` works in the flow frame; :class:`CEMNavigator` converts.

Speed. The per-tick path (Algorithm 1's K passes of CalcXY, eq. 6, the branch guard) runs as one
compiled call in :mod:`swarmscene.methods.cem.kernels` (numba, imported at the first
:class:`NewtonInverter`, so importing this module stays light); the functions here that run once
per activation or for analysis (eq. 1-5, the theorems, lambda_max) stay NumPy. The kernel draws
eq. 6's noise from the run's own PCG64 generator, so seeded runs are those of the NumPy code it
replaced (kept as the test oracle, tests/oracles/cem.py).

Choices where the paper is ambiguous (each repeated where it is made):

* Eq. 1 sums ``z - z_f`` once per failure, which for N_f > 1 makes the uniform flow N_f times
  stronger and shrinks each doublet's dividing ring to a_p / sqrt(N_f) (commanded points would then
  enter the planned exclusion disks). We keep one uniform term, taken relative to the failures'
  centroid, and one doublet per failure whose strength mu_f keeps its a_p circle a streamline in
  the others' flow (:func:`doublet_strengths`): ``f(z) = (z - zbar_F) + sum_f mu_f / (z - z_f)``.
  For one failure mu = a_p^2 and this is eq. 1 exactly.
* CalcXY (Alg. 2, line 9) differences against its own input, which after the first of the K passes
  would be that pass's result, not the previous tick's command. Every pass starts Newton from the
  previous tick's command ("n iterations from the previous position") and differences against it:
  a warm start from a pass that overshot a saddle point would drag the next pass onto the far side
  of the disk (measured: a 3.4 m/s spike with K = 5).
* Newton iterations, ``newton_stop`` (:data:`NEWTON_STOPS`): ``"fixed_n"`` (the default) runs the
  paper's n iterations every call, as Algorithm 2 prints it. ``"converged"`` (the rule shipped
  before) stops once every update is below 1e-10 m and no noise was drawn in that iteration. That
  is not "the result unchanged": under eq. 6 as printed every remaining iteration whose estimate is
  within a_p draws noise again, so the stop changes the commands near the ring and the seed's
  stream. Measured (section V-A, K = 1, 30 seeds, printed noise): peak commanded speed mean 2.19 m/s
  with the early stop (2 of 30 seeds at or above Fig. 10's 2.4), 2.31 m/s without (8 of 30);
  docs/reproduction.md has the runs.
* Saddle noise (eq. 6), ``noise_rule`` (:data:`NOISE_RULES`). ``"printed"`` (the default) is
  Algorithm 2 line 7 with eq. 6 as printed: in every one of the n iterations, the last included,
  an estimate r with ||r - r_f|| <= a_p (evaluated where the Jacobian is, before the update) gets
  |N(0, sigma)| r_a + N(0, sigma) r_b added to its update. An agent whose streamline touches the
  ring (Q2 on psi = 0 in section V-A) is kicked by up to a few sigma in the last iteration, so its
  command leaves its streamline by |f'| |r_noise| (<= 2 |r_noise| for one failure; measured psi
  drift 3.2e-3 to 7.2e-3 over 30 seeds of sections V-A and V-B with Newton's fixed n; 0.9e-3 to
  5.9e-3 with the early stop), the commanded speed jitters by
  ~|r_noise| / dT, and the run depends on the seed. ``"gated"`` (the reading shipped before) draws the noise only for an
  estimate strictly inside a_p whose Newton update is still at least sigma, and never in the last
  iteration: a converged point (on the ring itself, or on a root a few mm inside a_p that other
  failures' flows create) is not at a saddle, so the command lies on its streamline to machine
  precision (eq. 4 exactly) and the run does not depend on the seed; the noise still fires where
  it is needed (a start on the rear stagnation point, where Newton alone never leaves the axis).
* A final branch guard (``branch_guard``, on by default: a departure, the paper has none) moves a
  point that converged inside a planned disk out through that circle, and restarts a non-finite one
  (kernels.branch_guard): past the front saddle the inside and outside roots are equally close, and
  the paper's claim that commands never enter a_p needs the outside one. Without it (Algorithm 2 as
  printed, Newton for the fixed n), 2 of 200 K = 2 runs of section V-A (seeds 141 and 173) took the
  inner root and flew a vehicle 6 cm from the failed one (a collision; commands 1.30 m inside a_p):
  99.0 % [96.4, 99.7] of runs keep a_f + eps, against 30 of 30 with the guard
  (docs/reproduction.md, cem_clearance_without_branch_guard).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmscene.core.vectors import min_pair_distance

NEWTON_TOL = 1e-10
"""m; a Newton update below this means the estimate has converged (see module docstring)."""

NEWTON_STOPS = ("fixed_n", "converged")
"""When CalcXY's Newton loop stops (see module docstring): ``"fixed_n"``, after the paper's n
iterations (the default); ``"converged"``, once every update is below NEWTON_TOL with no noise drawn."""

NOISE_RULES = ("printed", "gated")
"""When CalcXY draws the saddle noise of eq. 6 (see module docstring): ``"printed"``, every
iteration whose estimate is within a_p (Algorithm 2 line 7 as printed, the default); ``"gated"``,
only while the Newton update is at least sigma, strictly inside a_p, never in the last iteration."""


def planned_exclusion_radius(a_f: float, delta: float, eps: float) -> float:
    """Planned exclusion radius a_p = a_f + delta + eps (eq. 1), m."""
    return a_f + delta + eps


def to_flow_frame(xy: np.ndarray, origin: complex, theta: float) -> np.ndarray:
    """World x-y points (..., 2) m -> flow-frame complex ``zeta`` (...), rotated by -theta."""
    xy = np.asarray(xy, dtype=float)
    return (xy[..., 0] + 1j * xy[..., 1] - origin) * np.exp(-1j * theta)


def to_world_frame(zeta: np.ndarray, origin: complex, theta: float) -> np.ndarray:
    """Flow-frame complex points (...) -> world x-y (..., 2) m."""
    z = np.asarray(zeta) * np.exp(1j * theta) + origin
    return np.stack([z.real, z.imag], axis=-1)


def doublet_strengths(centres: np.ndarray, a_p: float, iterations: int = 100) -> np.ndarray:
    """Doublet strengths mu_f (F,) complex, m^2: a_p^2 for one failure, as in eq. 1.

    With several failures each doublet also sits in the others' flow, which shrinks and tilts its
    dividing ring (eq. 1 as written puts commanded points up to several cm inside a_p for failures
    ~10 m apart). A doublet mu / (z - c) in a local uniform flow U (f ~ U (z - c) + mu / (z - c))
    keeps the circle |z - c| = a_p a streamline when mu = a_p^2 conj(U), so we solve the fixed point
    mu_k = a_p^2 conj(U_k), U_k = 1 - sum_{j != k} mu_j / (z_k - z_j)^2 (still one doublet per
    failed vehicle; exact for one failure, first order in (a_p / distance)^2 for several).
    """
    c = np.atleast_1d(np.asarray(centres, dtype=complex))
    a2 = float(a_p) ** 2
    mu = np.full(c.size, a2, dtype=complex)
    if c.size < 2:
        return mu
    d = c[:, None] - c[None, :] + np.eye(c.size)
    w = 1.0 / d**2
    np.fill_diagonal(w, 0.0)
    for _ in range(iterations):
        nxt = a2 * np.conj(1.0 - w @ mu)
        if np.max(np.abs(nxt - mu)) < 1e-15 * a2:
            return nxt
        mu = nxt
    return mu


def _strengths(centres: np.ndarray, a_p: float, strengths: np.ndarray | None) -> np.ndarray:
    return doublet_strengths(centres, a_p) if strengths is None else np.asarray(strengths, dtype=complex)


def complex_potential(zeta: np.ndarray, centres: np.ndarray, a_p: float,
                      strengths: np.ndarray | None = None) -> np.ndarray:
    """f(z) = phi + j psi = (z - zbar_F) + sum_f mu_f / (z - z_f), eq. 1-2 (see module docstring).

    Args:
        zeta: (N,) complex flow-frame points.
        centres: (F,) complex doublet centres z_f.
        a_p: planned exclusion radius, m.
        strengths: (F,) mu_f (default :func:`doublet_strengths`).
    """
    zeta = np.asarray(zeta, dtype=complex)
    centres = np.atleast_1d(np.asarray(centres, dtype=complex))
    mu = _strengths(centres, a_p, strengths)
    return zeta - centres.mean() + (mu / (zeta[..., None] - centres)).sum(axis=-1)


def potential_stream(x: np.ndarray, y: np.ndarray, centres_xy: np.ndarray, a_p: float):
    """Potential phi (eq. 3a) and stream function psi (eq. 3b) in real arithmetic, as printed.

    Term by term as in the paper with strength a_p^2 per failure (uniform part once, see module
    docstring): an independent check of :func:`complex_potential` with ``strengths = a_p^2``
    (which is the default for one failure). ``centres_xy`` is (F, 2); returns (phi, psi).
    """
    x = np.asarray(x, dtype=float)[..., None]
    y = np.asarray(y, dtype=float)[..., None]
    xf, yf = np.asarray(centres_xy, dtype=float).reshape(-1, 2).T
    dx, dy = x - xf, y - yf
    r2 = dx**2 + dy**2
    extra = len(xf) - 1  # the per-failure sum holds N_f uniform terms; keep one, about the centroid
    phi = (dx * (r2 + a_p**2) / r2).sum(-1) - extra * (x[..., 0] - xf.mean())
    psi = (dy * (r2 - a_p**2) / r2).sum(-1) - extra * (y[..., 0] - yf.mean())
    return phi, psi


def complex_velocity(zeta: np.ndarray, centres: np.ndarray, a_p: float,
                     strengths: np.ndarray | None = None) -> np.ndarray:
    """f'(z) = 1 - sum_f mu_f / (z - z_f)^2 = phi_x - j phi_y (Cauchy-Riemann)."""
    zeta = np.asarray(zeta, dtype=complex)
    centres = np.atleast_1d(np.asarray(centres, dtype=complex))
    mu = _strengths(centres, a_p, strengths)
    return 1.0 - (mu / (zeta[..., None] - centres) ** 2).sum(axis=-1)


def jacobian(zeta: np.ndarray, centres: np.ndarray, a_p: float) -> np.ndarray:
    """J = [[phi_x, phi_y], [psi_x, psi_y]] (eq. 5), shape (N, 2, 2).

    From f' = phi_x - j phi_y and Cauchy-Riemann (psi_x = -phi_y, psi_y = phi_x): J is a scaled
    rotation, so J^{-1} e is the complex division e / f' that CalcXY uses.
    """
    fp = complex_velocity(zeta, centres, a_p)
    u, v = fp.real, -fp.imag  # phi_x, phi_y
    return np.stack([np.stack([u, v], -1), np.stack([-v, u], -1)], -2)


def lambda_max(centres: np.ndarray, a_p: float, samples: int = 1440) -> float:
    """lambda_max = max (phi_x^2 + phi_y^2) = max |f'|^2 over the motion space (Theorem 1).

    Over the whole plane it is infinite (f' is singular at each z_f), so the maximum is taken over
    the motion space, outside every planned exclusion disk. f' is analytic there and tends to 1 at
    infinity, so by the maximum modulus principle the maximum lies on the disks' boundary circles
    (or is 1): we sample each circle, keep the samples outside the other disks, and refine the best
    one with a bounded scalar search. One failure gives exactly 4 (|f'| = 2|sin theta| on the ring).
    """
    from scipy.optimize import minimize_scalar

    centres = np.atleast_1d(np.asarray(centres, dtype=complex))

    def ring(k: int, ang: np.ndarray) -> np.ndarray:
        return centres[k] + a_p * np.exp(1j * np.asarray(ang))

    def speed2(k: int, ang: np.ndarray) -> np.ndarray:
        pts = ring(k, ang)
        s = np.abs(complex_velocity(pts, centres, a_p)) ** 2
        others = np.delete(centres, k)
        if others.size:  # points on ring k inside another disk are not motion space
            inside = (np.abs(pts[..., None] - others) < a_p).any(-1)
            s = np.where(inside, 0.0, s)
        return s

    ang = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    best = 1.0
    step = 2 * np.pi / samples
    for k in range(centres.size):  # loop over failures, not agents (cold path, once per activation)
        s = speed2(k, ang)
        i = int(np.argmax(s))
        res = minimize_scalar(lambda t, k=k: -float(speed2(k, t)), bounds=(ang[i] - step, ang[i] + step),
                              method="bounded", options={"xatol": 1e-10})
        best = max(best, float(s[i]), -float(res.fun))
    return best


@dataclass(frozen=True)
class Theorem1Check:
    """Theorem 1 precondition (eq. 7-8): p_min0^2 / lambda_max >= 4 (delta + eps)^2."""

    p_min0: float  # eq. 7, minimum phi-psi distance between healthy agents at t0
    lambda_max: float  # max |f'|^2 over the motion space
    lhs: float  # p_min0^2 / lambda_max, m^2
    rhs: float  # 4 (delta + eps)^2, m^2
    holds: bool


@dataclass(frozen=True)
class Theorem2Check:
    """Theorem 2 precondition (eq. 16): d_min0 >= 2 (delta + eps) + a_p, single failure only."""

    d_min0: float  # minimum x-y distance between healthy agents at t0, m
    bound: float  # 2 (delta + eps) + a_p, m
    applicable: bool  # Theorem 2 covers exactly one failed vehicle
    holds: bool  # applicable and d_min0 >= bound


def _min_pairwise(points: np.ndarray) -> float:
    """Minimum distance between distinct complex points (inf for fewer than two)."""
    return min_pair_distance(np.stack([points.real, points.imag], -1))


REL_TOL = 1e-9
"""Relative slack in the theorem inequalities: the paper's own formation sits exactly on eq. 16."""


def theorem1(w0: np.ndarray, centres: np.ndarray, a_p: float, delta: float, eps: float) -> Theorem1Check:
    """Evaluate Theorem 1's precondition from the healthy agents' (phi, psi) at t0, w0 = phi + j psi."""
    p = _min_pairwise(np.asarray(w0, dtype=complex))
    lam = lambda_max(centres, a_p)
    lhs, rhs = p**2 / lam, 4.0 * (delta + eps) ** 2
    return Theorem1Check(p, lam, lhs, rhs, bool(lhs >= rhs * (1 - REL_TOL)))


def theorem2(zeta0: np.ndarray, n_failures: int, a_p: float, delta: float, eps: float) -> Theorem2Check:
    """Evaluate Theorem 2's precondition (eq. 16) from the healthy agents' positions at t0.

    d_min0 is taken over healthy pairs (the collisions the theorem rules out); the failed vehicle is
    kept off by a_p. With more than one failure the theorem does not apply and ``holds`` is False.
    """
    d = _min_pairwise(np.asarray(zeta0, dtype=complex))
    bound = 2.0 * (delta + eps) + a_p
    applicable = n_failures == 1
    return Theorem2Check(d, bound, applicable, bool(applicable and d >= bound * (1 - REL_TOL)))


def pcg64_state(rng: np.random.Generator) -> np.ndarray:
    """The generator's PCG64 state as a writable (4,) uint64 view [state_lo, state_hi, inc_lo, inc_hi].

    The compiled kernel draws eq. 6's noise by advancing this state in place with NumPy's own
    algorithm, so the run's generator ends where NumPy's draws would have left it. Only PCG64 (the
    engine's ``numpy.random.default_rng``) is supported; the view is checked against ``state``.
    """
    import ctypes

    bg = rng.bit_generator
    if not isinstance(bg, np.random.PCG64):
        raise ValueError(f"rng: CEM draws its saddle noise from a PCG64 generator "
                         f"(numpy.random.default_rng), got {type(bg).__name__}")
    ptr = ctypes.cast(bg.ctypes.state_address, ctypes.POINTER(ctypes.c_void_p))[0]  # pcg64_state.pcg_state
    view = np.ctypeslib.as_array(ctypes.cast(ptr, ctypes.POINTER(ctypes.c_uint64)), shape=(4,))
    s = bg.state["state"]
    words = [s["state"] & (2**64 - 1), s["state"] >> 64, s["inc"] & (2**64 - 1), s["inc"] >> 64]
    if view.tolist() != words:  # another memory layout (a 128-bit emulation build): refuse, never guess
        raise ValueError("rng: this NumPy build's PCG64 state layout is not the one the CEM kernel reads")
    return view


class NewtonInverter:
    """CalcXY (Algorithm 2): the point z whose (phi, psi) is a target, by Newton's method.

    Each iteration solves ``J dz = [phi_1 - phi, psi_1 - psi]`` (eq. 5), i.e. the complex division
    ``dz = (f(z) - w) / f'(z)``, and adds the saddle noise of eq. 6 when the estimate lies within
    a_p of a failed vehicle; a branch guard keeps the result finite and outside every planned disk
    (module docstring). The work runs in one compiled call (:mod:`swarmscene.methods.cem.kernels`)
    on arrays allocated once here; :class:`CEMNavigator` runs Algorithm 1's K passes in the same call.

    Args:
        centres: (F,) complex doublet centres in the flow frame.
        a_p: planned exclusion radius, m.
        n_agents: N. n: Newton iterations per call (paper: 20). sigma: noise deviation, m (1 mm).
        rng: random generator for the noise (the run's PCG64 generator, advanced in place).
        strengths: (F,) doublet strengths mu_f (default :func:`doublet_strengths`).
        noise_rule: when eq. 6 draws, one of :data:`NOISE_RULES` (module docstring).
        newton_stop: one of :data:`NEWTON_STOPS`. branch_guard: run the branch guard (module docstring).
    """

    def __init__(self, centres: np.ndarray, a_p: float, n_agents: int, n: int, sigma: float,
                 rng: np.random.Generator, strengths: np.ndarray | None = None,
                 noise_rule: str = "printed", newton_stop: str = "fixed_n", branch_guard: bool = True) -> None:
        if noise_rule not in NOISE_RULES:
            raise ValueError(f"noise_rule: must be one of {', '.join(NOISE_RULES)} (got {noise_rule!r})")
        if newton_stop not in NEWTON_STOPS:
            raise ValueError(f"newton_stop: must be one of {', '.join(NEWTON_STOPS)} (got {newton_stop!r})")
        # numba loads here, at first use, not when the plugin module is imported (start-up time)
        from swarmscene.methods.cem import kernels

        self._k = kernels
        centres = np.atleast_1d(np.asarray(centres, dtype=complex))
        m, f = int(n_agents), centres.size
        self.rng = rng  # keeps the generator (whose memory the state view reads) alive
        self.state = pcg64_state(rng)
        # three packed work arrays, one per dtype (kernels.unpack); the attributes below are views
        n_c, n_f, n_i = kernels.sizes(m, f)
        self.cw, self.fw, self.iw = np.zeros(n_c, complex), np.zeros(n_f), np.zeros(n_i, np.int64)
        self.iw[[kernels.I_M, kernels.I_F]] = m, f
        views = kernels.unpack.py_func(self.cw, self.fw, self.iw)  # the kernel's own layout, as NumPy views
        self.zz, self.flow, self.U, self.prm, self.R, self.iprm = (views[i] for i in (0, 1, 2, 3, 4, 8))
        self.flow[0], self.flow[1] = centres, _strengths(centres, a_p, strengths)  # z_f, mu_f
        offset = complex(centres.mean())
        self.prm[[kernels.P_A, kernels.P_SIGMA, kernels.P_OFF_R, kernels.P_OFF_I]] = (
            float(a_p), float(sigma), offset.real, offset.imag)
        self.iprm[[kernels.I_N, kernels.I_PRINTED, kernels.I_CONVERGED, kernels.I_GUARD]] = (
            int(n), int(noise_rule == "printed"), int(newton_stop == "converged"), int(bool(branch_guard)))
        self.z = self.zz[kernels.Z]  # the estimate, updated in place (a view)

    @property
    def kernels(self) -> Any:
        """The compiled kernels module this inverter runs (:mod:`swarmscene.methods.cem.kernels`):
        its index constants (``N_MEAS``, ``M_PAIR``, ...) name the slots of the work arrays."""
        return self._k

    @property
    def iterations(self) -> int:
        """Newton iterations run by the last CalcXY call (diagnostic)."""
        return int(self.iprm[self._k.I_ITERATIONS])

    def solve(self, w: np.ndarray) -> np.ndarray:
        """Run Algorithm 2 from the current estimate ``self.z`` towards targets w = phi + j psi (N,).

        Returns ``self.z`` (updated in place).
        """
        k = self._k
        self.zz[k.WT] = w
        k.calc_xy(self.cw, self.fw, self.iw, self.state)
        return self.z


def calc_xy(w: np.ndarray, zeta: np.ndarray, centres: np.ndarray, a_p: float, n: int = 20,
            sigma: float = 1e-3, rng: np.random.Generator | None = None, dT: float | None = None,
            noise_rule: str = "printed", newton_stop: str = "fixed_n", branch_guard: bool = True):
    """Algorithm 2 as a function: positions for targets w from start points zeta (flow frame).

    Returns the (N,) complex positions, and with ``dT`` also the first-difference velocity
    (r - r_{-1}) / dT (line 9). Prefer :class:`NewtonInverter` in a loop (it reuses its buffers).
    """
    zeta = np.asarray(zeta, dtype=complex)
    inv = NewtonInverter(centres, a_p, zeta.size, n, sigma, rng or np.random.default_rng(0),
                         noise_rule=noise_rule, newton_stop=newton_stop, branch_guard=branch_guard)
    inv.z[:] = zeta
    z = inv.solve(np.asarray(w, dtype=complex)).copy()
    return z if dT is None else (z, (z - zeta) / dT)


class CEMNavigator:
    """Algorithm 1 (CEM navigation) for one activation: N healthy agents around F failed ones.

    On construction (lines 5-10) each agent's (phi_i0, psi_i0) is fixed from its position and the
    sliding step is set for the undistorted flow, dphi = v_des dT (line 6). Each :meth:`step` is one
    pass of the t loop (lines 13-22): K times, phi = phi_last + dphi, CalcXY, and
    dphi <- dphi v_des / v_max (line 20), so the fastest agent flies at about v_des.

    Args:
        positions: (N, 2) world x-y of the healthy agents at activation, m (r in Alg. 1).
        failures: (F, 2) world x-y of the failed vehicles' centres z_f, m.
        a_p: planned exclusion radius, m. theta: flight direction, rad from world +x (the flow
            runs along it). origin: flow-frame origin (default: the failures' centroid).
        v_des: desired speed of the fastest agent, m/s. dT: guidance period, s.
        K: sliding-step passes per tick. n: Newton iterations. sigma: saddle noise, m.
        rng: random generator for the saddle noise (PCG64, :func:`pcg64_state`). noise_rule: when eq. 6 draws
            (:data:`NOISE_RULES`). strengths: doublet strengths (default :func:`doublet_strengths`).
        newton_stop: :data:`NEWTON_STOPS`. branch_guard: run the branch guard (module docstring).
    """

    def __init__(self, positions: np.ndarray, failures: np.ndarray, *, a_p: float, theta: float = 0.0,
                 v_des: float = 1.0, dT: float = 0.01, K: int = 2, n: int = 20, sigma: float = 1e-3,
                 rng: np.random.Generator | None = None, origin: complex | None = None,
                 noise_rule: str = "printed", strengths: np.ndarray | None = None, newton_stop: str = "fixed_n",
                 branch_guard: bool = True) -> None:
        failures = np.asarray(failures, dtype=float).reshape(-1, 2)
        self.origin = complex(*failures.mean(0)) if origin is None else complex(origin)
        self.theta, self.a_p = float(theta), float(a_p)
        self.v_des, self.dT, self.K = float(v_des), float(dT), int(K)
        self.rot = complex(np.exp(1j * self.theta))
        self.centres = to_flow_frame(failures, self.origin, self.theta)
        zeta0 = to_flow_frame(np.asarray(positions, dtype=float).reshape(-1, 2), self.origin, self.theta)
        self.zeta0 = zeta0
        self.strengths = _strengths(self.centres, a_p, strengths)
        self.w0 = complex_potential(zeta0, self.centres, a_p, self.strengths)  # lines 7-10: phi_i0 + j psi_i0
        self.n, self.sigma, self.noise_rule = int(n), float(sigma), noise_rule
        self.newton_stop, self.branch_guard = newton_stop, bool(branch_guard)
        self.inverter = NewtonInverter(self.centres, a_p, zeta0.size, n, sigma, rng or np.random.default_rng(),
                                       self.strengths, noise_rule, newton_stop, branch_guard)
        inv, k = self.inverter, self.inverter.kernels
        inv.z[:] = zeta0  # r_d <- r, line 5
        inv.zz[k.W] = self.w0  # phi_last + j psi_i0
        rot_dt = self.rot / self.dT
        inv.prm[[k.P_VDES, k.P_DT, k.P_ROT_R, k.P_ROT_I, k.P_ROTDT_R, k.P_ROTDT_I, k.P_ORIG_R, k.P_ORIG_I]] = (
            self.v_des, self.dT, self.rot.real, self.rot.imag, rot_dt.real, rot_dt.imag,
            self.origin.real, self.origin.imag)
        inv.prm[k.P_DPHI] = self.v_des * self.dT  # line 6
        inv.iprm[k.I_K] = self.K
        inv.prm[k.P_ALONG_MIN] = zeta0.real.min() if zeta0.size else np.inf
        m = zeta0.size
        self.w = inv.zz[k.W]  # phi_last + j psi_i0 (a view)
        self.positions = inv.zz[k.POS].view(float).reshape(m, 2)  # world x-y, m (a view, no copy)
        self.velocities = inv.zz[k.VEL].view(float).reshape(m, 2)  # world x-y, m/s
        self._step_args = (inv.cw, inv.fw, inv.iw, inv.state)
        self._step = k.navigator_step
        # step_into(mode, pos, vel, acc): :meth:`step` and write the commands into setpoint arrays in
        # the same compiled call: rows set by :meth:`track_rows` get its mode, x-y of ``pos``/``vel``
        # (M, 3) the commands, x-y of ``acc`` zero (first differences only); the rest is untouched.
        # A partial of the kernel, not a method: no Python frame on the plugin's per-tick path.
        self.step_into = functools.partial(k.navigator_step_into, *self._step_args)
        mean = complex(self.centres.mean())  # zbar_F as complex_potential subtracts it
        self._w0_imag, self._consts = self.w0.imag.copy(), np.array([mean.real, mean.imag, self.a_p])

    @property
    def kernels(self) -> Any:
        """The compiled kernels module of this navigator's inverter (:attr:`NewtonInverter.kernels`),
        for a caller that reads the measurement slots of :meth:`measure_tick`."""
        return self.inverter.kernels

    @property
    def dphi(self) -> float:
        """The sliding step for the next tick (line 20), phi units."""
        return float(self.inverter.prm[self.inverter.kernels.P_DPHI])

    @property
    def dphi_used(self) -> float:
        """The step phi actually advanced by at the last tick (Fig. 8); 0 before the first."""
        return float(self.inverter.prm[self.inverter.kernels.P_USED])

    @property
    def n_agents(self) -> int:
        """N, the agents this navigator steers."""
        return self.w0.size

    @property
    def zeta(self) -> np.ndarray:
        """(N,) complex commanded positions in the flow frame (along-track = real part)."""
        return self.inverter.z

    @property
    def phi(self) -> np.ndarray:
        """(N,) velocity potential phi of each agent's streamline point (eq. 1, the along-flow coordinate)."""
        return self.w.real

    @property
    def iterations_total(self) -> tuple[int, int]:
        """(sum over ticks of the last pass's Newton iterations, ticks stepped), for their mean."""
        k = self.inverter.kernels
        return int(self.inverter.iprm[k.I_ITER_TOTAL]), int(self.inverter.iprm[k.I_TICKS])

    @property
    def along_track_min(self) -> float:
        """min over agents of the commands' along-track coordinate (flow frame, m): Re(zeta).min()."""
        return float(self.inverter.prm[self.inverter.kernels.P_ALONG_MIN])

    def step(self) -> tuple[np.ndarray, np.ndarray]:
        """One guidance tick (Algorithm 1 lines 13-22, one compiled call): returns world (N, 2)
        commanded positions and velocities (views owned by the navigator, overwritten next call)."""
        self._step(*self._step_args)
        return self.positions, self.velocities

    def track_rows(self, idx: np.ndarray, track: int) -> None:
        """Set where ``step_into`` writes: agent j's commands go to setpoint row idx[j] (N,),
        whose mode becomes ``track``."""
        k, iw = self.inverter.kernels, self.inverter.iw
        iw[iw.size - self.n_agents:] = idx
        iw[k.I_TRACK] = track

    def measure_tick(self, healthy: np.ndarray, pos: np.ndarray, vel: np.ndarray, failed: np.ndarray,
                     drift: np.ndarray, out: np.ndarray) -> int:
        """This tick's safety quantities in one compiled call (:func:`kernels.measure_tick`): raises
        ``drift`` (world-indexed, (M,)) to each agent's |psi - psi_0| and fills ``out`` (kernels.N_MEAS,)
        from the world's ``healthy`` (M,), ``pos``/``vel`` (M, 3) and the failures' x-y ``failed``
        (F, 2). Returns how many agents under CEM are still healthy."""
        inv = self.inverter
        return inv.kernels.measure_tick(inv.cw, inv.iw, self._w0_imag, self._consts, healthy, pos, vel, failed,
                                        drift, out)

    def stream_drift(self) -> np.ndarray:
        """|psi_i(t) - psi_i0| of the commanded positions, (N,) (eq. 4 says it stays zero)."""
        return np.abs(complex_potential(self.zeta, self.centres, self.a_p, self.strengths).imag - self.w0.imag)

    def exclusion_margin(self) -> np.ndarray:
        """(N,) min over failures of ||r_d,i - z_f|| - a_p for the commands (>= 0 means outside)."""
        return np.abs(self.zeta[:, None] - self.centres).min(axis=1) - self.a_p

    def theorem1(self, delta: float, eps: float) -> Theorem1Check:
        """Theorem 1's precondition (eq. 7-8) for this activation."""
        return theorem1(self.w0, self.centres, self.a_p, delta, eps)

    def theorem2(self, delta: float, eps: float) -> Theorem2Check:
        """Theorem 2's precondition (eq. 16) for this activation."""
        return theorem2(self.zeta0, self.centres.size, self.a_p, delta, eps)


def segment_clearance(start: np.ndarray, end: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(N,) min over failures of the x-y distance from z_f to the segment start_i -> end_i, m.

    ``start``/``end`` (N, 2) and ``centres`` (F, 2) are world x-y (any one frame will do: distances
    do not depend on it). The hand-back test (plugins/avoidance/cem.py) asks whether the straight
    path from each healthy agent to its formation setpoint stays at least a_p from every failed
    vehicle; inf for no failure.
    """
    start = np.asarray(start, dtype=float).reshape(-1, 2)
    end = np.asarray(end, dtype=float).reshape(-1, 2)
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    if centres.shape[0] == 0 or start.shape[0] == 0:
        return np.full(start.shape[0], np.inf)
    seg = (end - start)[:, None, :]  # (N, 1, 2)
    rel = centres[None, :, :] - start[:, None, :]  # (N, F, 2)
    length2 = (seg**2).sum(-1)
    # the closest point's parameter along the segment, clipped to [0, 1] (0 for a zero-length path)
    s = np.clip(np.divide((rel * seg).sum(-1), length2, out=np.zeros(rel.shape[:2]), where=length2 > 0), 0.0, 1.0)
    return np.linalg.norm(rel - s[..., None] * seg, axis=-1).min(axis=1)
