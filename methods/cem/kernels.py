"""Compiled CEM tick (numba): Algorithm 1's K passes of CalcXY (Algorithm 2), eq. 5-6, in one call.

Romano, Uppaluru, Rastgoftar, Atkins (papers/cem-fluid-flow-navigation.md). The numerics and the
choices where the paper is ambiguous are those of :mod:`swarmscene.methods.cem.flow` (read its
docstring); this module only computes them without Python and NumPy call overhead. Every function
takes plain arrays and floats; loops run over agents i and doublets f with scalar arithmetic.

Bit for bit with the NumPy implementation it replaced (``tests/oracles/cem.py``), so that seeded
runs keep their metrics: the arithmetic is NumPy's (:mod:`swarmscene.methods.cem.numerics`), and
the saddle noise (eq. 6) comes from the run's own ``numpy.random.Generator`` (its PCG64 state
advanced in place, NumPy's ziggurat), drawn in the order NumPy drew it (for each noisy iteration,
first every ``|N(0, sigma)|`` then every ``N(0, sigma)``), so the generator ends where the NumPy
code left it and the next draw of any other component is unchanged. Work the NumPy code did for
every agent is skipped where it cannot change a result: eq. 6's routine runs only when some
estimate may be within a_p and the branch guard only when some command may be inside a disk,
both decided by max(|u_r|, |u_i|) <= ||u||.

The plugin's per-tick safety measurements (:func:`measure_tick`) are here too.

Compiled on first use and cached beside this module (``cache=True``); ``error_model="numpy"`` keeps
IEEE division (a stagnation point gives inf/nan, which the branch guard repairs, as before).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from swarmscene.methods.cem.numerics import (
    JIT,
    cabs,
    cdiv,
    cmul,
    cmul_plain,
    crecip,
    distance_within,
    doublet_sum,
    nan_max,
    nan_min,
    size_bound,
    standard_normal,
)

NEWTON_TOL = 1e-10  # m, as flow.NEWTON_TOL (not imported: flow imports this module lazily)

# Work-array rows of the per-agent complex buffer ``zz`` (N agents along the second axis).
Z, Z_PREV, DZ, W, WT, Z_START, POS, VEL = range(8)
# Entries of the float parameter vector ``prm``.
(P_A, P_SIGMA, P_OFF_R, P_OFF_I, P_VDES, P_DT, P_ROT_R, P_ROT_I, P_ROTDT_R, P_ROTDT_I, P_ORIG_R, P_ORIG_I,
 P_DPHI, P_USED, P_ALONG_MIN, N_PRM) = range(16)
# Entries of the integer parameter vector ``iprm`` (agents, doublets, n, K, rule, diagnostics).
I_M, I_F, I_N, I_K, I_PRINTED, I_ITERATIONS, I_ITER_TOTAL, I_TICKS, I_TRACK, I_CONVERGED, I_GUARD, N_IPRM = range(12)
# I_CONVERGED: 1 stops Newton once it has converged (newton_stop="converged"), 0 runs the paper's n;
# I_GUARD: 1 runs the branch guard (a departure, flow module docstring), 0 leaves CalcXY's result as is.


# ---- eq. 6: saddle noise ----------------------------------------------------------------------


@njit(**JIT)
def _kick(z, U, R, rows, cols, count, sigma, g, state):
    """Add eq. 6's |N(0, sigma)| r_a + N(0, sigma) r_b to z[rows[k]] for k < count (r_b = -j r_a).

    r_a = U / |U| points from doublet cols[k] to the estimate. The 2 * count normals are drawn first
    (all |N| terms, then all N terms: NumPy's ``standard_normal((2, count))``), then added in order.
    """
    for k in range(2 * count):
        g[k] = standard_normal(state) * sigma
    for k in range(count):
        i, f = rows[k], cols[k]
        u = U[i, f]
        ra_r, ra_i = cdiv(u.real, u.imag, R[i, f], 0.0)
        dr, di = cmul(ra_r, ra_i, abs(g[k]), -g[count + k])
        z[i] = complex(z[i].real + dr, z[i].imag + di)


@njit(**JIT)
def saddle_noise(z, U, R, step, a, sigma, printed, rows, cols, g, state):
    """Eq. 6 for every estimate within a_p of a doublet; returns whether any noise was drawn.

    ``U`` (N, F) = r - r_f at the estimate the Jacobian was evaluated at and ``R`` = ||U|| (both
    filled by the caller). Printed rule: drawn for ||r - r_f|| <= a_p. Gated rule: only strictly
    inside (a_p (1 - 1e-9)) and while the Newton update ``step`` is at least sigma (the caller skips
    the last iteration). A NaN anywhere disables the draw for the whole iteration, as NumPy's
    ``R.min()`` did.
    """
    m, nf = U.shape
    rmin = nan_min(R)
    thr = a if printed else a * (1.0 - 1e-9)
    if printed:
        if not rmin <= thr:
            return False
    elif not rmin < thr:
        return False
    count = 0
    for i in range(m):
        for f in range(nf):
            if (R[i, f] <= thr) if printed else (R[i, f] < thr and step[i] >= sigma):
                rows[count], cols[count] = i, f
                count += 1
    if count == 0:
        return False
    _kick(z, U, R, rows, cols, count, sigma, g, state)
    return True


# ---- Algorithm 2: CalcXY ----------------------------------------------------------------------


@njit(**JIT)
def _differences(z, c, U):
    for i in range(z.size):
        for f in range(c.size):
            U[i, f] = z[i] - c[f]


@njit(**JIT)
def _argmin_row(R, i):
    """numpy.argmin of row i (the first NaN, else the first minimum)."""
    best = 0
    for f in range(R.shape[1]):
        v = R[i, f]
        if v != v:
            return f
        if v < R[i, best]:
            best = f
    return best


@njit(**JIT)
def branch_guard(z, z_start, c, mu, a, sigma, U, R, rows, cols, g, state):
    """Keep commands finite and outside every planned disk (flow.NewtonInverter's guard).

    A non-finite estimate restarts from its start point plus eq. 6's noise towards its nearest
    doublet; an estimate deeper than 1e-6 a_p inside a disk goes out through that circle by the
    mirror u -> mu a_p^2 / (conj(mu) u) or the radial inversion u -> a_p^2 / conj(u), whichever
    lands nearer its start point.
    """
    m, nf = U.shape
    a2 = a * a
    inner = a * (1.0 - 1e-6)
    _differences(z, c, U)
    for i in range(m):
        for f in range(nf):
            R[i, f] = cabs(U[i, f].real, U[i, f].imag)
    if nan_min(R) >= inner:
        return
    nbad = 0
    for i in range(m):
        if not (np.isfinite(z[i].real) and np.isfinite(z[i].imag)):
            z[i] = z_start[i]
            rows[nbad] = i
            nbad += 1
    if nbad:
        _differences(z, c, U)
        for i in range(m):
            for f in range(nf):
                R[i, f] = cabs(U[i, f].real, U[i, f].imag)
        for k in range(nbad):
            cols[k] = _argmin_row(R, rows[k])
        _kick(z, U, R, rows, cols, nbad, sigma, g, state)  # drawn even for sigma = 0, as before
        _differences(z, c, U)
        for i in range(m):
            for f in range(nf):
                R[i, f] = cabs(U[i, f].real, U[i, f].imag)
    for i in range(m):
        k = _argmin_row(R, i)
        if not R[i, k] < inner:
            continue
        u, cf, mf = U[i, k], c[k], mu[k]
        num_r, num_i = cmul(mf.real, mf.imag, a2, 0.0)
        den_r, den_i = cmul(mf.real, -mf.imag, u.real, u.imag)
        q_r, q_i = cdiv(num_r, num_i, den_r, den_i)
        mir_r, mir_i = cf.real + q_r, cf.imag + q_i
        q_r, q_i = cdiv(a2, 0.0, u.real, -u.imag)
        rad_r, rad_i = cf.real + q_r, cf.imag + q_i
        s = z_start[i]
        if cabs(mir_r - s.real, mir_i - s.imag) <= cabs(rad_r - s.real, rad_i - s.imag):
            z[i] = complex(mir_r, mir_i)
        else:
            z[i] = complex(rad_r, rad_i)


@njit(**JIT)
def newton_iterations(z, wt, z_start, c, mu, off_r, off_i, a, sigma, n, printed, converged, U, R, r, d, g, rows,
                      cols, tmp, state):
    """Algorithm 2 lines 3-8 for every agent: n Newton steps dz = (f(z) - w) / f'(z) (eq. 5) plus eq. 6.

    f(z) = (z - zbar_F) + sum_f mu_f / (z - z_f), f'(z) = 1 - sum_f mu_f / (z - z_f)^2 (eq. 1-2);
    ``wt`` holds the targets w = phi + j psi, ``off`` = zbar_F. Runs all n iterations (Algorithm 2 as
    printed), or with ``converged`` stops early once every update is below NEWTON_TOL and no noise was
    drawn in that iteration. Returns the iterations run.
    ``R`` gets ||r - r_f|| exactly where it may be <= a_p (elsewhere a bound above a_p, which eq. 6's
    tests decide alike); with the printed rule ``r`` first gets the bound of each update's size
    (``d`` keeps the updates) and the exact sizes only when every bound is below NEWTON_TOL.
    """
    m, nf = U.shape
    single = nf == 1
    for i in range(m):
        z_start[i] = z[i]
    it = 0
    for it in range(n):
        near = False  # some ||r - r_f|| <= a_p, or NaN: only then can eq. 6 draw
        for i in range(m):
            zr, zi = z[i].real, z[i].imag
            if single:  # one doublet: no sums (the NumPy code used views)
                ur, ui = zr - c[0].real, zi - c[0].imag
                U[i, 0] = complex(ur, ui)
                R[i, 0] = distance_within(ur, ui, a)  # for eq. 6
                near |= not R[i, 0] > a
                vr, vi = crecip(ur, ui)  # 1 / u
                gr, gi = cmul(vr, vi, mu[0].real, mu[0].imag)  # mu / u
                if m == 1:  # NumPy's in-place G *= V of a single element did not fuse (bit for bit)
                    hr, hi = cmul_plain(gr, gi, vr, vi)  # mu / u^2
                else:
                    hr, hi = cmul(gr, gi, vr, vi)
            else:
                for f in range(nf):
                    ur, ui = zr - c[f].real, zi - c[f].imag
                    U[i, f] = complex(ur, ui)
                    R[i, f] = distance_within(ur, ui, a)
                    near |= not R[i, f] > a
                    vr, vi = crecip(ur, ui)
                    tmp[0, f], tmp[1, f] = cmul(vr, vi, mu[f].real, mu[f].imag)
                    tmp[2, f], tmp[3, f] = cmul(tmp[0, f], tmp[1, f], vr, vi)
                gr, gi = doublet_sum(tmp[0], tmp[1])
                hr, hi = doublet_sum(tmp[2], tmp[3])
            er = (zr + gr) - (wt[i].real + off_r)  # f(z) - w (phi_1 - phi, psi_1 - psi)
            ei = (zi + gi) - (wt[i].imag + off_i)
            dr, di = cdiv(er, ei, 1.0 - hr, 0.0 - hi)  # J^{-1} e = e / f'
            z[i] = complex(zr - dr, zi - di)
            d[i] = complex(dr, di)
            r[i] = size_bound(dr, di) if printed else cabs(dr, di)  # gated compares r with sigma
        noisy = False
        if near and sigma > 0.0 and (printed or it < n - 1):  # gated: never in the last iteration
            noisy = saddle_noise(z, U, R, r, a, sigma, printed, rows, cols, g, state)
        if converged and not noisy and nan_max(r) < NEWTON_TOL:
            if not printed:
                break
            for i in range(m):  # every bound is below: the exact sizes decide
                r[i] = cabs(d[i].real, d[i].imag)
            if nan_max(r) < NEWTON_TOL:
                break
    return it + 1


@njit(**JIT)
def unpack(cw, fw, iw):
    """Views of the three packed work arrays (one array per dtype keeps the call cheap).

    cw (complex): zz (8, N) rows Z..VEL, flow (2, F) = [z_f; mu_f], U (N, F) = r - r_f.
    fw (float): prm (N_PRM,), R (N, F) = ||r - r_f||, r (N,) update sizes, g (2 N F,) normals,
    tmp (4, F) one agent's doublet terms. iw (int): iprm (N_IPRM,), rows, cols (N F,) noisy pairs,
    then (read by :func:`write_track` only) the N setpoint rows the commands go to.
    """
    m, nf = iw[I_M], iw[I_F]
    mf = m * nf
    zz = cw[:8 * m].reshape((8, m))
    flow = cw[8 * m:8 * m + 2 * nf].reshape((2, nf))
    U = cw[8 * m + 2 * nf:8 * m + 2 * nf + mf].reshape((m, nf))
    prm = fw[:N_PRM]
    R = fw[N_PRM:N_PRM + mf].reshape((m, nf))
    r = fw[N_PRM + mf:N_PRM + mf + m]
    g = fw[N_PRM + mf + m:N_PRM + 3 * mf + m]
    tmp = fw[N_PRM + 3 * mf + m:N_PRM + 3 * mf + m + 4 * nf].reshape((4, nf))
    return zz, flow, U, prm, R, r, g, tmp, iw[:N_IPRM], iw[N_IPRM:N_IPRM + mf], iw[N_IPRM + mf:N_IPRM + 2 * mf]


def sizes(m: int, nf: int) -> tuple[int, int, int]:
    """Lengths of (cw, fw, iw) for N = m agents and F = nf doublets (see :func:`unpack`)."""
    mf = m * nf
    return 8 * m + 2 * nf + mf, N_PRM + 3 * mf + m + 4 * nf, N_IPRM + 2 * mf + m


@njit(**JIT)
def _may_need_guard(z, c, inner):
    """False when every ||r - r_f|| >= inner for sure (then the guard would return at once)."""
    for i in range(z.size):
        for f in range(c.size):
            if not size_bound(z[i].real - c[f].real, z[i].imag - c[f].imag) >= inner:  # NaN too
                return True
    return False


@njit(**JIT)
def _calc_xy(zz, flow, U, prm, R, r, g, tmp, iprm, rows, cols, state):
    z, z_start, c, mu = zz[Z], zz[Z_START], flow[0], flow[1]
    a, sigma = prm[P_A], prm[P_SIGMA]
    iprm[I_ITERATIONS] = newton_iterations(z, zz[WT], z_start, c, mu, prm[P_OFF_R], prm[P_OFF_I], a, sigma,
                                           iprm[I_N], iprm[I_PRINTED] != 0, iprm[I_CONVERGED] != 0, U, R, r,
                                           zz[DZ], g, rows, cols, tmp, state)  # zz[DZ] is free until line 19
    # skip the call (and its exact distances) when clear
    if iprm[I_GUARD] != 0 and _may_need_guard(z, c, a * (1.0 - 1e-6)):
        branch_guard(z, z_start, c, mu, a, sigma, U, R, rows, cols, g, state)


@njit(**JIT)
def calc_xy(cw, fw, iw, state):
    """Algorithm 2 (CalcXY) from zz[Z] towards the targets zz[WT]; zz[Z] is updated in place."""
    _calc_xy(*unpack(cw, fw, iw), state)


@njit(**JIT)
def navigator_step(cw, fw, iw, state):
    """One guidance tick of Algorithm 1 (lines 13-22): K passes of phi = phi_last + dphi, CalcXY,
    dphi <- dphi v_des / v_max; then r_d and (r_d - r_{-1}) / dT in the world frame.

    Every pass starts Newton from the previous tick's command r_{-1} (flow module docstring).
    Reads and writes prm[P_DPHI]; writes prm[P_USED] (the step phi advanced by), prm[P_ALONG_MIN]
    (min along-track coordinate of the commands), zz[W] (phi_last), zz[Z] (the command, flow
    frame), zz[DZ], zz[POS], zz[VEL] (world x-y as complex), the last pass's iterations and their
    running total over ticks (iprm[I_ITER_TOTAL], iprm[I_TICKS]).
    """
    zz, flow, U, prm, R, r, g, tmp, iprm, rows, cols = unpack(cw, fw, iw)
    z, z_prev, dz, w, wt = zz[Z], zz[Z_PREV], zz[DZ], zz[W], zz[WT]
    m = z.size
    for i in range(m):
        z_prev[i] = z[i]
    dphi = prm[P_DPHI]
    used = dphi
    for _ in range(iprm[I_K]):
        used = dphi
        for i in range(m):
            wt[i] = complex(w[i].real + used, w[i].imag + 0.0)  # line 16 (psi unchanged)
            z[i] = z_prev[i]
        _calc_xy(zz, flow, U, prm, R, r, g, tmp, iprm, rows, cols, state)  # line 17
        speed = r  # free between CalcXY calls
        for i in range(m):
            dz[i] = z[i] - z_prev[i]
            speed[i] = cabs(dz[i].real, dz[i].imag)
        v_max = nan_max(speed) / prm[P_DT]  # line 19
        if v_max > 0.0:
            dphi = used * prm[P_VDES] / v_max  # line 20
    prm[P_DPHI], prm[P_USED] = dphi, used
    rot_r, rot_i, rotdt_r, rotdt_i = prm[P_ROT_R], prm[P_ROT_I], prm[P_ROTDT_R], prm[P_ROTDT_I]
    along = np.inf
    for i in range(m):
        along = z[i].real if (z[i].real < along or z[i].real != z[i].real) else along  # NaN sticks, as .min()
        w[i] = complex(w[i].real + used, w[i].imag + 0.0)
        pr, pi = cmul(z[i].real, z[i].imag, rot_r, rot_i)
        zz[POS, i] = complex(pr + prm[P_ORIG_R], pi + prm[P_ORIG_I])
        vr, vi = cmul(dz[i].real, dz[i].imag, rotdt_r, rotdt_i)
        zz[VEL, i] = complex(vr, vi)
    prm[P_ALONG_MIN] = along  # the hand-back test reads it without another pass
    iprm[I_ITER_TOTAL] += iprm[I_ITERATIONS]
    iprm[I_TICKS] += 1


@njit(**JIT)
def write_track(cw, iw, mode, pos, vel, acc):
    """Write the tick's commands into setpoint arrays: row idx[j] (iw's last N entries) gets mode
    iprm[I_TRACK], x-y position zz[POS, j], x-y velocity zz[VEL, j] and zero x-y acceleration
    (first differences only); z and yaw stay as they are (the formation's altitude, Assumption 2)."""
    m, nf = iw[I_M], iw[I_F]
    zz = cw[:8 * m].reshape((8, m))
    idx = iw[N_IPRM + 2 * m * nf:N_IPRM + 2 * m * nf + m]
    track = iw[I_TRACK]
    for j in range(m):
        i = idx[j]
        mode[i] = track
        pos[i, 0], pos[i, 1] = zz[POS, j].real, zz[POS, j].imag
        vel[i, 0], vel[i, 1] = zz[VEL, j].real, zz[VEL, j].imag
        acc[i, 0], acc[i, 1] = 0.0, 0.0


@njit(**JIT)
def navigator_step_into(cw, fw, iw, state, mode, pos, vel, acc):
    """:func:`navigator_step` then :func:`write_track`: the plugin's tick in one call."""
    navigator_step(cw, fw, iw, state)
    write_track(cw, iw, mode, pos, vel, acc)


# ---- the plugin's safety measurements of one tick ---------------------------------------------

DENSE_PAIRS_MAX = 256  # healthy agents up to which the min pair distance is an O(N^2) loop here
(M_MARGIN, M_CLEAR, M_PAIR, M_PAIR_CMD, M_SPEED, M_SPEED_ACT, M_TRACK_ERR, N_MEAS) = range(8)


@njit(**JIT)
def _nan_better(best, v, lower):
    """NumPy's min (lower) or max reduction step: a NaN wins and stays."""
    if best != best or v != v:
        return np.nan
    return min(best, v) if lower else max(best, v)


@njit(**JIT)
def _min_pair_2d(x, y, n):
    """min over i < j < n of sqrt(dx^2 + dy^2) (inf below two points), as cKDTree's k = 2 query."""
    best = np.inf
    for i in range(n):
        for j in range(i + 1, n):
            dx, dy = x[i] - x[j], y[i] - y[j]
            d2 = dx * dx + dy * dy
            if d2 < best:
                best = d2
    return np.sqrt(best)  # sqrt is monotone: the min of the roots is the root of the min


@njit(**JIT)
def measure_tick(cw, iw, w0_imag, consts, healthy, pos, vel, failed, drift, out):
    """The ``cem`` plugin's per-tick safety quantities from the world and this tick's commands.

    drift[idx[j]] = max(drift, |psi(r_d,j) - psi_j0|) (eq. 4, psi from eq. 1-3 as
    flow.complex_potential computes it); out[M_MARGIN] = min_j (min_f ||r_d,j - z_f|| - a_p);
    over live agents (healthy now): out[M_CLEAR] = min ||r - z_f|| (world x-y, ``failed`` (F, 2)),
    out[M_PAIR] / out[M_PAIR_CMD] = min pair distance of actual / commanded x-y (NaN above
    DENSE_PAIRS_MAX: the caller uses core.vectors.min_pair_distance, a compiled cell list),
    out[M_SPEED] = max ||v_d|| over all agents under CEM, out[M_SPEED_ACT] = max ||v||,
    out[M_TRACK_ERR] = max ||r - r_d|| (-inf with no live agent).
    Reductions propagate NaN as NumPy's do. consts = [Re zbar_F, Im zbar_F, a_p].
    """
    m, nf = iw[I_M], iw[I_F]
    zz = cw[:8 * m].reshape((8, m))
    flow = cw[8 * m:8 * m + 2 * nf].reshape((2, nf))
    idx = iw[N_IPRM + 2 * m * nf:N_IPRM + 2 * m * nf + m]
    z, c, mu = zz[Z], flow[0], flow[1]
    terms_r, terms_i = np.empty(nf), np.empty(nf)
    margin, speed = np.inf, -np.inf
    for j in range(m):
        for f in range(nf):
            ur, ui = z[j].real - c[f].real, z[j].imag - c[f].imag
            terms_r[f], terms_i[f] = cdiv(mu[f].real, mu[f].imag, ur, ui)  # mu_f / (z - z_f)
        near = cabs(z[j].real - c[0].real, z[j].imag - c[0].imag)
        for f in range(1, nf):
            near = _nan_better(near, cabs(z[j].real - c[f].real, z[j].imag - c[f].imag), True)
        margin = _nan_better(margin, near - consts[2], True)
        psi = (z[j].imag - consts[1]) + doublet_sum(terms_r, terms_i)[1]
        i = idx[j]
        drift[i] = _nan_better(drift[i], abs(psi - w0_imag[j]), False)
        vr, vi = zz[VEL, j].real, zz[VEL, j].imag
        speed = _nan_better(speed, np.sqrt(vr * vr + vi * vi), False)
    out[M_MARGIN], out[M_SPEED] = margin, speed
    ax, ay, cx, cy = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    n = 0
    clear, speed_act, err = np.inf, -np.inf, -np.inf
    for j in range(m):
        i = idx[j]
        if not healthy[i]:  # failed during this tick's events
            continue
        ax[n], ay[n] = pos[i, 0], pos[i, 1]
        cx[n], cy[n] = zz[POS, j].real, zz[POS, j].imag
        for f in range(failed.shape[0]):
            dx, dy = ax[n] - failed[f, 0], ay[n] - failed[f, 1]
            clear = _nan_better(clear, np.sqrt(dx * dx + dy * dy), True)
        speed_act = _nan_better(speed_act, np.sqrt(vel[i, 0] * vel[i, 0] + vel[i, 1] * vel[i, 1]), False)
        dx, dy = ax[n] - cx[n], ay[n] - cy[n]
        err = _nan_better(err, np.sqrt(dx * dx + dy * dy), False)
        n += 1
    out[M_CLEAR], out[M_SPEED_ACT], out[M_TRACK_ERR] = clear, speed_act, err
    if n <= DENSE_PAIRS_MAX:
        out[M_PAIR], out[M_PAIR_CMD] = _min_pair_2d(ax, ay, n), _min_pair_2d(cx, cy, n)
    else:
        out[M_PAIR], out[M_PAIR_CMD] = np.nan, np.nan
    return n


# ---- after hand-back: the formation's ticks -----------------------------------------------------
# The plugin's NumPy code for these ran every tick after a hand-back (two thirds of a cem_six_vehicle
# run): ~15 small array operations a tick. The same arithmetic, operation for operation, in one call.
(F_CLEAR, F_PAIR, F_MARGIN, F_PAIR_CMD, N_FORM) = range(5)
FORMATION_POINTS_MAX = 32  # as core.vectors.DENSE_POINTS: above it min_pair_distance is a cell list


@njit(**JIT)
def _min_pair_rows(x, y, n):
    """core.vectors.min_pair_distance of n <= 32 points: sqrt of NumPy's min over i < j of
    (x_j - x_i)^2 + (y_j - y_i)^2 (a NaN wins); inf below two points."""
    if n < 2:
        return np.inf
    best = np.inf
    for i in range(n):
        for j in range(i + 1, n):
            dx, dy = x[j] - x[i], y[j] - y[i]
            best = _nan_better(best, dx * dx + dy * dy, True)
    return np.sqrt(best)


@njit(**JIT)
def _min_to_failed(x, y, n, failed):
    """core.vectors.min_distance_between(rows, failed): sqrt of NumPy's min of dx^2 + dy^2; inf if
    either is empty."""
    if n == 0 or failed.shape[0] == 0:
        return np.inf
    best = np.inf
    for i in range(n):
        for f in range(failed.shape[0]):
            dx, dy = x[i] - failed[f, 0], y[i] - failed[f, 1]
            best = _nan_better(best, dx * dx + dy * dy, True)
    return np.sqrt(best)


@njit(**JIT)
def measure_formation(healthy, pos, mode, sp_pos, failed, track, position, out):
    """The ``cem`` plugin's per-tick safety quantities after a hand-back (``handback.SafetyRecord.measure_formation``):
    over healthy agents' actual x-y, out[F_CLEAR] = min distance to a failed vehicle and out[F_PAIR]
    = min pair distance; over the setpoints of TRACK and POSITION rows, out[F_MARGIN] and
    out[F_PAIR_CMD] the same. Returns (healthy agents, placed setpoints); the caller uses
    core.vectors above FORMATION_POINTS_MAX healthy agents."""
    m = healthy.shape[0]
    ax, ay, cx, cy = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    n, p = 0, 0
    for i in range(m):
        if not healthy[i]:
            continue
        ax[n], ay[n] = pos[i, 0], pos[i, 1]
        n += 1
        if mode[i] == track or mode[i] == position:
            cx[p], cy[p] = sp_pos[i, 0], sp_pos[i, 1]
            p += 1
    if n == 0 or n > FORMATION_POINTS_MAX:
        return n, p
    out[F_CLEAR], out[F_PAIR] = _min_to_failed(ax, ay, n, failed), _min_pair_rows(ax, ay, n)
    out[F_MARGIN], out[F_PAIR_CMD] = _min_to_failed(cx, cy, p, failed), _min_pair_rows(cx, cy, p)
    return n, p


@njit(**JIT)
def path_clear(healthy, pos, mode, sp_pos, sp_vel, failed, hold, velocity, lookahead, a_p):
    """The ``clear_path`` hand-back test (flow.segment_clearance of the plugin's setpoint targets):
    True when, for every healthy agent and failed vehicle, the distance from z_f to the segment from
    the agent to its target is >= a_p (False for a NaN, as NumPy's min and >= give). The target:
    the agent's own x-y (HOLD), x-y + lookahead * v (VELOCITY), else the setpoint's x-y."""
    for i in range(healthy.shape[0]):
        if not healthy[i]:
            continue
        sx, sy = pos[i, 0], pos[i, 1]
        if mode[i] == hold:
            ex, ey = sx, sy
        elif mode[i] == velocity:
            ex, ey = sx + lookahead * sp_vel[i, 0], sy + lookahead * sp_vel[i, 1]
        else:
            ex, ey = sp_pos[i, 0], sp_pos[i, 1]
        gx, gy = ex - sx, ey - sy
        length2 = gx * gx + gy * gy
        for f in range(failed.shape[0]):
            rx, ry = failed[f, 0] - sx, failed[f, 1] - sy
            s = (rx * gx + ry * gy) / length2 if length2 > 0 else 0.0
            if s != s:
                pass  # NaN stays NaN through the clip, as np.clip keeps it
            elif s < 0.0:
                s = 0.0
            elif s > 1.0:
                s = 1.0
            dx, dy = rx - s * gx, ry - s * gy
            if not np.sqrt(dx * dx + dy * dy) >= a_p:
                return False
    return True
