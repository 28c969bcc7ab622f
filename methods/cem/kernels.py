"""Compiled CEM step (numba): Algorithm 1's K passes of CalcXY (Algorithm 2), eq. 5-6, one call per tick.

Romano, Uppaluru, Rastgoftar, Atkins (papers/cem-fluid-flow-navigation.md). The numerics and the
choices where the paper is ambiguous are those of :mod:`swarmscene.methods.cem.flow` (read its
docstring); this module only computes them without Python and NumPy call overhead. Every function
takes plain arrays and floats; loops run over agents i and doublets f with scalar arithmetic.

Bit for bit with the NumPy implementation it replaced (``tests/oracles/cem.py``), so that seeded
runs keep their metrics:

* Complex products and moduli are computed as NumPy's SIMD loops compute them on x86-64 with FMA:
  ``(a_r b_r - a_i b_i)`` and ``(a_r b_i + a_i b_r)`` each with one fused multiply-add
  (:func:`cmul`; NumPy's in-place product of a single element is not fused, :func:`cmul_plain`,
  which only the one-agent, one-failure case met), ``|z| = L sqrt(1 + (S/L)^2)`` with a fused
  square (:func:`cabs`). Quotients use
  NumPy's Smith division (:func:`cdiv`, :func:`crecip`), sums over doublets NumPy's pairwise order
  (:func:`doublet_sum`). On a CPU without FMA NumPy rounds differently and the two agree to round-off.
* The saddle noise (eq. 6) comes from the run's own ``numpy.random.Generator``: the kernel advances
  its PCG64 state in place (:func:`pcg64_next`, a view of the generator's memory) and draws with
  NumPy's ziggurat (:func:`standard_normal`), in the order NumPy drew them (for each noisy
  iteration, first every ``|N(0, sigma)|`` then every ``N(0, sigma)``), so the generator ends where
  the NumPy code left it and the next draw of any other component is unchanged.

Compiled on first use and cached beside this module (``cache=True``); ``error_model="numpy"`` keeps
IEEE division (a stagnation point gives inf/nan, which the branch guard repairs, as before).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic
from numba.np.random._constants import fi_double, ki_double, wi_double, ziggurat_nor_inv_r, ziggurat_nor_r

JIT = dict(cache=True, error_model="numpy")

NEWTON_TOL = 1e-10  # m, as flow.NEWTON_TOL (not imported: flow imports this module lazily)

# PCG64 (numpy.random.PCG64): 128-bit LCG, state = state * MULT + inc, output XSL-RR.
_MULT_HI = np.uint64(0x2360ED051FC65DA4)
_MULT_LO = np.uint64(0x4385DF649FCCF645)
_M32 = np.uint64(0xFFFFFFFF)
_U32, _U11, _U58, _U63, _U64 = np.uint64(32), np.uint64(11), np.uint64(58), np.uint64(63), np.uint64(64)
_ONE, _ZERO = np.uint64(1), np.uint64(0)

# Work-array rows of the per-agent complex buffer ``zz`` (N agents along the second axis).
Z, Z_PREV, DZ, W, WT, Z_START, POS, VEL = range(8)
# Entries of the float parameter vector ``prm``.
(P_A, P_SIGMA, P_OFF_R, P_OFF_I, P_VDES, P_DT, P_ROT_R, P_ROT_I, P_ROTDT_R, P_ROTDT_I, P_ORIG_R, P_ORIG_I,
 P_DPHI, P_USED, P_ALONG_MIN, N_PRM) = range(16)
# Entries of the integer parameter vector ``iprm`` (agents, doublets, n, K, rule, diagnostics).
I_M, I_F, I_N, I_K, I_PRINTED, I_ITERATIONS, I_ITER_TOTAL, I_TICKS, I_TRACK, N_IPRM = range(10)


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c with one rounding (llvm.fma.f64)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


# ---- complex arithmetic as NumPy does it ------------------------------------------------------


@njit(**JIT)
def cmul(ar, ai, br, bi):
    """(a_r + j a_i)(b_r + j b_i), each part with one fused multiply-add (NumPy's SIMD loop)."""
    return fma(ar, br, -(ai * bi)), fma(ar, bi, ai * br)


@njit(**JIT)
def cmul_plain(ar, ai, br, bi):
    """(a_r + j a_i)(b_r + j b_i) without fusing: NumPy's loop for an in-place product of one element."""
    return ar * br - ai * bi, ar * bi + ai * br


@njit(**JIT)
def cdiv(ar, ai, br, bi):
    """a / b by Smith's method with NumPy's scaling (inf or nan for b = 0)."""
    abr, abi = abs(br), abs(bi)
    if abr >= abi:
        if abr == 0.0 and abi == 0.0:
            return ar / abr, ai / abr
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        return (ar + ai * rat) * scl, (ai - ar * rat) * scl
    rat = br / bi
    scl = 1.0 / (bi + br * rat)
    return (ar * rat + ai) * scl, (ai * rat - ar) * scl


@njit(**JIT)
def crecip(br, bi):
    """1 / b as NumPy's ``reciprocal``."""
    if abs(bi) <= abs(br):
        r = bi / br
        d = br + bi * r
        return 1.0 / d, -r / d
    r = br / bi
    d = br * r + bi
    return r / d, -1.0 / d


@njit(**JIT)
def cabs(re, im):
    """|re + j im| = L sqrt(1 + (S/L)^2), L = max, S = min of the magnitudes (NumPy's SIMD abs)."""
    x, y = abs(re), abs(im)
    if x == np.inf or y == np.inf:
        return np.inf
    if x != x or y != y:
        return np.nan
    big, small = max(x, y), min(x, y)
    if big == 0.0:
        return 0.0
    rat = small / big
    return np.sqrt(fma(rat, rat, 1.0)) * big


@njit(**JIT)
def size_bound(re, im):
    """max(|re|, |im|) (NaN if either is): a lower bound of :func:`cabs`, in floating point too
    (L sqrt(1 + (S/L)^2) >= L), so ``bound >= limit`` proves ``cabs >= limit`` without its
    division and square root."""
    x, y = abs(re), abs(im)
    return x if (x >= y or x != x) else y


@njit(**JIT)
def distance_within(ure, uim, limit):
    """||u|| exactly (:func:`cabs`) where it may be <= limit, else the bound max(|u_r|, |u_i|) > limit:
    every test ``<= limit`` (or ``<`` a smaller threshold) then decides as with the exact value."""
    b = size_bound(ure, uim)
    return b if b > limit else cabs(ure, uim)  # NaN takes the exact path


@njit(**JIT)
def _block_sum(re, im, lo, n):
    """NumPy's pairwise sum of n <= 64 complex values from index lo (8 partial sums of the parts)."""
    if n < 4:
        rr, ri = -0.0, -0.0
        for k in range(lo, lo + n):
            rr += re[k]
            ri += im[k]
        return rr, ri
    r0, r1, r2, r3 = re[lo], re[lo + 1], re[lo + 2], re[lo + 3]
    i0, i1, i2, i3 = im[lo], im[lo + 1], im[lo + 2], im[lo + 3]
    k = 4
    while k < n - n % 4:
        r0 += re[lo + k]
        i0 += im[lo + k]
        r1 += re[lo + k + 1]
        i1 += im[lo + k + 1]
        r2 += re[lo + k + 2]
        i2 += im[lo + k + 2]
        r3 += re[lo + k + 3]
        i3 += im[lo + k + 3]
        k += 4
    rr, ri = (r0 + r1) + (r2 + r3), (i0 + i1) + (i2 + i3)
    while k < n:
        rr += re[lo + k]
        ri += im[lo + k]
        k += 1
    return rr, ri


@njit(**JIT)
def _pairwise(re, im, n):
    """NumPy's pairwise sum of n complex values: blocks of <= 64, halves split at a multiple of 4.

    NumPy recurses; numba cannot cache a recursive function, so the same tree is walked with an
    explicit stack (node = (lo, n); a negative n marks "add the last two results")."""
    if n <= 64:
        return _block_sum(re, im, 0, n)
    todo = np.empty((128, 2), np.int64)
    vals = np.empty((128, 2))
    top, nv = 1, 0
    todo[0, 0], todo[0, 1] = 0, n
    while top:
        top -= 1
        lo, cnt = todo[top, 0], todo[top, 1]
        if cnt < 0:  # both halves done: left + right
            nv -= 1
            vals[nv - 1, 0] += vals[nv, 0]
            vals[nv - 1, 1] += vals[nv, 1]
        elif cnt <= 64:
            vals[nv, 0], vals[nv, 1] = _block_sum(re, im, lo, cnt)
            nv += 1
        else:
            half = 4 * (cnt // 8)
            todo[top, 0], todo[top, 1] = 0, -1
            todo[top + 1, 0], todo[top + 1, 1] = lo + half, cnt - half
            todo[top + 2, 0], todo[top + 2, 1] = lo, half
            top += 3
    return vals[0, 0], vals[0, 1]


@njit(**JIT)
def doublet_sum(re, im):
    """sum over doublets f of one agent's terms, in the order of ``numpy.sum(axis=1)``."""
    rr, ri = _pairwise(re, im, re.size)
    return 0.0 + rr, 0.0 + ri


@njit(**JIT)
def nan_max(x):
    """max(x) with NaN propagation, as ``ndarray.max``."""
    out = x[0]
    for k in range(x.size):
        v = x[k]
        if v != v:
            return v
        if v > out:
            out = v
    return out


@njit(**JIT)
def nan_min(x):
    """min(x) with NaN propagation, as ``ndarray.min`` (any shape, C order)."""
    flat = x.ravel()
    out = flat[0]
    for k in range(flat.size):
        v = flat[k]
        if v != v:
            return v
        if v < out:
            out = v
    return out


# ---- random draws: the run's PCG64 generator, NumPy's ziggurat --------------------------------


@njit(**JIT)
def _mul_hi64(a, b):
    """High 64 bits of the 128-bit product a * b."""
    a_lo, a_hi, b_lo, b_hi = a & _M32, a >> _U32, b & _M32, b >> _U32
    lolo, hilo, lohi = a_lo * b_lo, a_hi * b_lo, a_lo * b_hi
    cross = (lolo >> _U32) + (hilo & _M32) + lohi
    return a_hi * b_hi + (hilo >> _U32) + (cross >> _U32)


@njit(**JIT)
def pcg64_next(state):
    """Next 64 random bits of numpy's PCG64; ``state`` = [state_lo, state_hi, inc_lo, inc_hi] (in place)."""
    lo, hi = state[0], state[1]
    p_lo = lo * _MULT_LO
    p_hi = _mul_hi64(lo, _MULT_LO) + hi * _MULT_LO + lo * _MULT_HI
    s_lo = p_lo + state[2]
    s_hi = p_hi + state[3] + (_ONE if s_lo < p_lo else _ZERO)
    state[0], state[1] = s_lo, s_hi
    x = s_hi ^ s_lo
    rot = s_hi >> _U58
    return (x >> rot) | (x << ((_U64 - rot) & _U63))


@njit(**JIT)
def _next_double(state):
    return np.float64(pcg64_next(state) >> _U11) * (1.0 / 9007199254740992.0)


@njit(**JIT)
def standard_normal(state):
    """One N(0, 1) draw exactly as ``Generator.standard_normal`` (NumPy's ziggurat)."""
    while True:
        r = pcg64_next(state)
        idx = r & 0xFF
        r >>= 8
        sign = r & 0x1
        rabs = (r >> 1) & 0x000FFFFFFFFFFFFF
        x = rabs * wi_double[idx]
        if sign & 0x1:
            x = -x
        if rabs < ki_double[idx]:
            return x
        if idx == 0:
            while True:
                xx = -ziggurat_nor_inv_r * np.log1p(-_next_double(state))
                yy = -np.log1p(-_next_double(state))
                if yy + yy > xx * xx:
                    if (rabs >> 8) & 0x1:
                        return -(ziggurat_nor_r + xx)
                    return ziggurat_nor_r + xx
        elif (fi_double[idx - 1] - fi_double[idx]) * _next_double(state) + fi_double[idx] < np.exp(-0.5 * x * x):
            return x


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
def newton_iterations(z, wt, z_start, c, mu, off_r, off_i, a, sigma, n, printed, U, R, r, d, g, rows, cols, tmp,
                      state):
    """Algorithm 2 lines 3-8 for every agent: n Newton steps dz = (f(z) - w) / f'(z) (eq. 5) plus eq. 6.

    f(z) = (z - zbar_F) + sum_f mu_f / (z - z_f), f'(z) = 1 - sum_f mu_f / (z - z_f)^2 (eq. 1-2);
    ``wt`` holds the targets w = phi + j psi, ``off`` = zbar_F. Stops early once every update is
    below NEWTON_TOL and no noise was drawn in that iteration. Returns the iterations run.
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
        if not noisy and nan_max(r) < NEWTON_TOL:
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
                                           iprm[I_N], iprm[I_PRINTED] != 0, U, R, r, zz[DZ], g, rows, cols, tmp,
                                           state)  # zz[DZ] is free until the navigator's line 19
    if _may_need_guard(z, c, a * (1.0 - 1e-6)):  # skip the call (and its exact distances) when clear
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
        along = min(along, z[i].real)
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
    DENSE_PAIRS_MAX: the caller uses a k-d tree), out[M_SPEED] = max ||v_d|| over all agents under
    CEM, out[M_SPEED_ACT] = max ||v||, out[M_TRACK_ERR] = max ||r - r_d|| (-inf with no live agent).
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
