"""NumPy's floating-point results in scalar numba code: complex arithmetic, sums, normal draws.

The CEM kernel (:mod:`swarmscene.methods.cem.kernels`) must reproduce, bit for bit, the NumPy code
it replaced (``tests/oracles/cem.py``), so that seeded runs keep their metrics. These helpers
compute what NumPy's loops compute on x86-64 with FMA (measured against NumPy 2.x, AVX-512 host):

* complex products ``(a_r b_r - a_i b_i)``, ``(a_r b_i + a_i b_r)`` each with one fused multiply-add
  (:func:`cmul`; NumPy's in-place product of a single element is not fused: :func:`cmul_plain`);
* ``|z| = L sqrt(1 + (S/L)^2)`` with a fused square (:func:`cabs`), NumPy's SIMD modulus;
* quotients by Smith's method with NumPy's scaling (:func:`cdiv`, :func:`crecip`);
* sums over the last axis in NumPy's pairwise order (:func:`doublet_sum`);
* N(0, 1) draws from the run's PCG64 generator with NumPy's ziggurat (:func:`standard_normal`),
  advancing the generator's own state in place (:func:`pcg64_next`).

On a CPU without FMA NumPy rounds differently and the kernel agrees with it to round-off only.
Compiled on first use, cached beside this module.
"""

from __future__ import annotations

from typing import Literal, TypedDict

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic
from numba.np.random._constants import fi_double, ki_double, wi_double, ziggurat_nor_inv_r, ziggurat_nor_r


class JitOptions(TypedDict):
    """The options every kernel here is compiled with (``njit(**JIT)``), typed so that mypy
    matches them against njit's keywords."""

    cache: bool
    error_model: Literal["python", "numpy"]


JIT: JitOptions = {"cache": True, "error_model": "numpy"}  # IEEE division: inf and nan, never an exception

# PCG64 (numpy.random.PCG64): 128-bit LCG, state = state * MULT + inc, output XSL-RR.
_MULT_HI = np.uint64(0x2360ED051FC65DA4)
_MULT_LO = np.uint64(0x4385DF649FCCF645)
_M32 = np.uint64(0xFFFFFFFF)
_U32, _U11, _U58, _U63, _U64 = np.uint64(32), np.uint64(11), np.uint64(58), np.uint64(63), np.uint64(64)
_ONE, _ZERO = np.uint64(1), np.uint64(0)


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
