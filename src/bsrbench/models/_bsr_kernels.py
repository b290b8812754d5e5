"""Numba kernels of the Bayesian sparse-representation (BSR) Gibbs sampler.

Model and conditionals: Babagholami-Mohamadabadi, Jourabloo, Zarghami & Kasaei, "A Bayesian Framework for
Sparse Representation-Based 3D Human Pose Estimation" (IEEE SPL 2014), Section II and Appendix A, with the
corrections of docs/model.md (section "Sources, and where the paper is wrong"): the (b, s) block update with s
integrated out for b, the atom precision ``g + g_xy sum_i alpha_ki^2`` (the paper prints the square of the sum),
and the Metropolis-Hastings acceptance ratio of the bound-based proposal ``w' ~ N(Sigma Lambda(w), Sigma)`` that
depends on the current state (the paper treats it as an independence chain, which is wrong). Elliptical slice
sampling is from Murray, Adams & MacKay, "Elliptical slice sampling" (AISTATS 2010).

Layout (all C-contiguous float64 unless noted):

- ``V`` (N, M): the data, one training pair ``[x_i; y_i]`` per row; the first ``Mx`` columns are features.
- ``D`` (K, M): the dictionaries, one atom ``d_k = [d^x_k; d^y_k]`` per row (contiguous atoms).
- ``norms`` (K,): ``||d_k||^2``.
- ``B`` (N, K) int8 and ``S`` (N, K): codes ``alpha_ki = B[i, k] * S[i, k]``.
- ``R`` (N, M): the residual ``V - A^T D``, updated in place by the code update.
- ``W`` (N, K): the logits ``w_ik``; atom k's logit vector is the column ``W[:, k]``.
- ``prec`` (6,): ``[g_s, g_xy, g_x, g_y, g_nx, g_ny]``: the noise precisions of the feature rows (g_nx) and of
  the output rows (g_ny). With one shared noise precision (the paper) g_nx = g_ny = g_xy; with separate noise
  precisions (a model extension) g_xy holds the pooled precision ``M / (Mx / g_nx + My / g_ny)`` (the inverse
  of the mean noise variance over all M rows), a summary comparable with the shared g_xy.
- ``Sigma`` (N, N) and its lower Cholesky factor ``Lw``.

Every random draw comes from the ``numpy.random.Generator`` passed in (numba shares its bit generator with
the Python object), in a fixed, documented order, so the plain NumPy reference ``tests/naive.py`` fed the
same Generator reproduces the kernels draw for draw. Uniforms and normals are taken straight from the bit
generator (``_rand``, ``_randn``), bit for bit what ``Generator.random()`` and ``.standard_normal()`` return.
Prediction uses a counter-based stream per test point (splitmix64 seeded by a hash of the point and a fitted
seed; ziggurat normals), so a prediction does not depend on which other points are in the batch (up to the
rounding of the batch's matrix products, about 1e-15 relative).

Speed (benchmarks/bench_bsr.py): the code update and prediction process all points together in blocks of
atoms, with the projections and residual updates as matrix products (BLAS-3); each point still sees its atoms
in order with its own random numbers, so the chain is that of a point-by-point sweep. Loops over elementwise
formulas are written to vectorize (``_VEC`` flags, a libm-free exp, atom-major copies made by tiled transposes).
"""

import ctypes
import ctypes.util
import math
from typing import NamedTuple

import llvmlite.binding as _llvm
import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import get_cython_function_address, intrinsic
from numba.np.random import _constants as _zig
from numba.np.random.generator_core import next_uint64 as _next_uint64

from ..errors import InputError, SamplerError

# Vectorizable reductions: reassociation and FMA contraction only (no nnan/ninf: the MH step uses -inf).
_VEC = {"reassoc", "contract"}

W_UPDATES = {"mh": 0, "ess": 1, "paper-printed-ratio": 2, "paper-literal": 3}
# the acceptance ratio of update_w_mh: exact; the paper's printed ratio with the tight bound lambda = sigmoid(-z w);
# the paper's printed ratio with lambda = sigmoid(+z w) as its appendix prints it
MH_EXACT, MH_PRINTED_RATIO, MH_LITERAL = 0, 1, 2
NOISE_MODELS = {"shared": 0, "separate": 1}
ATOM_UPDATES = {"block": 0, "single": 1}

# Above this logit, 1 + exp(-logit) rounds to 1 in float64, so "u < sigmoid(logit)" holds for every u in [0, 1):
# prediction then skips the exp and the uniform (the reference in tests/naive.py does the same).
_LOGIT_SURE = 37.0


# glibc's mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def keep_freed_memory(mmap_threshold=1 << 26, trim_threshold=1 << 27):
    """Let glibc keep freed memory in the process (for a process that runs sampler sweeps).

    A sweep allocates a few MB of temporaries (atom-major copies, products, random numbers) and frees them. By
    default glibc serves blocks above 128 kB by mmap and trims the heap top when it frees them, so every sweep
    touches fresh pages again: about 570 page faults, 2-3 ms, in the code update alone at N = 200, K = 256.
    This sets glibc's mmap threshold to ``mmap_threshold`` bytes and its trim threshold to ``trim_threshold``
    (``mallopt``; fixed values also stop glibc's dynamic adjustment), for the whole process: freed memory up to
    that size stays mapped. Returns whether both settings took (False without glibc, e.g. on macOS or musl;
    nothing else changes). Called by :meth:`BayesianSR.fit` and by benchmarks/bench_bsr.py.
    """
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    return bool(mallopt(_M_MMAP_THRESHOLD, int(mmap_threshold))) and bool(
        mallopt(_M_TRIM_THRESHOLD, int(trim_threshold))
    )


# ----------------------------------------------------------------------------------------------------------
# small helpers
# ----------------------------------------------------------------------------------------------------------
@njit(cache=True, fastmath=_VEC)
def _dot(a, b):
    """Dot product of two contiguous 1-D arrays of equal length."""
    acc = 0.0
    for m in range(a.shape[0]):
        acc += a[m] * b[m]
    return acc


@njit(cache=True, fastmath=_VEC)
def _axpy(alpha, x, y):
    """y += alpha * x (in place)."""
    for m in range(x.shape[0]):
        y[m] += alpha * x[m]


@njit(cache=True, fastmath=_VEC)
def _dot_rows(A, i, B, k, n):
    """A[i, :n] . B[k, :n] without creating row views (views cost reference-count updates in hot loops)."""
    acc = 0.0
    for m in range(n):
        acc += A[i, m] * B[k, m]
    return acc


@njit(cache=True, fastmath=_VEC)
def _axpy_rows(alpha, B, k, A, i, n):
    """A[i, :n] += alpha * B[k, :n] in place, without row views."""
    for m in range(n):
        A[i, m] += alpha * B[k, m]


@njit(cache=True)
def _sigmoid(x):
    if x >= 0.0:
        return 1.0 / (1.0 + np.exp(-x))
    e = np.exp(x)
    return e / (1.0 + e)


@njit(cache=True)
def _log_sigmoid(x):
    if x >= 0.0:
        return -np.log1p(np.exp(-x))
    return x - np.log1p(np.exp(x))


@njit(cache=True)
def _codes_from(B, S):
    """Dense codes A (N, K) with A[i, k] = B[i, k] * S[i, k]."""
    N, K = S.shape
    A = np.zeros((N, K))
    for i in range(N):
        for k in range(K):
            if B[i, k]:
                A[i, k] = S[i, k]
    return A


@njit(cache=True, fastmath=_VEC)
def _row_norms(D, norms):
    for k in range(D.shape[0]):
        norms[k] = _dot(D[k], D[k])


# ----------------------------------------------------------------------------------------------------------
# BLAS-3 and LAPACK routines numba does not wrap (syrk, trsm, trmm, potrf), from SciPy's Cython BLAS/LAPACK: the
# routines' addresses are registered as named symbols, so cached kernels link to them by name in every process.
# Fortran routines see a C-contiguous (m, n) array as its (n, m) transpose; the wrappers below take row-major
# arrays and do the transposition in the arguments. Scalars go by pointer, in small arrays.
# ----------------------------------------------------------------------------------------------------------
for _lib, _names in (
    ("scipy.linalg.cython_blas", ("dsyrk", "dtrsm", "dtrmm")),
    ("scipy.linalg.cython_lapack", ("dpotrf",)),
):
    for _name in _names:
        _llvm.add_symbol("bsrbench_" + _name, get_cython_function_address(_lib, _name))
_VP = types.voidptr
_dsyrk = types.ExternalFunction("bsrbench_dsyrk", types.void(*(_VP,) * 10))
_dtrsm = types.ExternalFunction("bsrbench_dtrsm", types.void(*(_VP,) * 11))
_dtrmm = types.ExternalFunction("bsrbench_dtrmm", types.void(*(_VP,) * 11))
_dpotrf = types.ExternalFunction("bsrbench_dpotrf", types.void(*(_VP,) * 5))


@intrinsic
def _ptr(typingctx, arr):
    """The data pointer of an array (of the view's first element), as void*."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        return builder.bitcast(ary.data, ir.IntType(8).as_pointer())

    return types.voidptr(arr), codegen


@njit(cache=True)
def _need_c(a):
    """The BLAS wrappers read arrays by their data pointer: they must be C-contiguous."""
    if not a.flags.c_contiguous:
        raise ValueError("BLAS wrapper: the array must be C-contiguous")


@njit(cache=True)
def _chars(a, b, c, d):
    """Four BLAS option characters, one byte each."""
    out = np.empty(4, dtype=np.uint8)
    out[0], out[1], out[2], out[3] = ord(a), ord(b), ord(c), ord(d)
    return out


@njit(cache=True)
def _syrk_gram(A, G, transpose):
    """G = A^T A (``transpose``; A (n, k) -> G (k, k)) or G = A A^T (A (n, k) -> G (n, n)) for C-contiguous A,
    by dsyrk (half the flops of the product); both triangles of G are filled."""
    _need_c(A)
    _need_c(G)
    n, k = A.shape
    m = k if transpose else n
    ch = _chars("L", "N" if transpose else "T", "N", "N")
    ints = np.array([m, n if transpose else k, k, m], dtype=np.int32)  # n, k, lda, ldc
    sc = np.array([1.0, 0.0])
    _dsyrk(
        _ptr(ch[0:1]), _ptr(ch[1:2]), _ptr(ints[0:1]), _ptr(ints[1:2]), _ptr(sc[0:1]), _ptr(A),
        _ptr(ints[2:3]), _ptr(sc[1:2]), _ptr(G), _ptr(ints[3:4]),
    )  # fmt: skip
    # Fortran's lower triangle is the row-major upper one: mirror it
    for i in range(m):
        for j in range(i):
            G[i, j] = G[j, i]


@njit(cache=True)
def _cholesky_lower(P):
    """In place: P (C-contiguous, symmetric positive definite) becomes its lower Cholesky factor L, P = L L^T
    (dpotrf on the transposed view; the strict upper triangle is zeroed). Raises if P is not positive definite."""
    _need_c(P)
    n = P.shape[0]
    ch = _chars("U", "N", "N", "N")
    ints = np.array([n, n, 0], dtype=np.int32)
    _dpotrf(_ptr(ch[0:1]), _ptr(ints[0:1]), _ptr(P), _ptr(ints[1:2]), _ptr(ints[2:3]))
    if ints[2] != 0:
        raise np.linalg.LinAlgError("Matrix is not positive definite.")
    for i in range(n):
        for j in range(i + 1, n):
            P[i, j] = 0.0


@njit(cache=True)
def _tri_solve(L, Z, transpose):
    """In place: Z (K, m) becomes L^-1 Z, or L^-T Z with ``transpose`` (L (K, K) lower, both C-contiguous),
    by dtrsm on the transposed views (Z^T L^-T, Z^T L^-1 from the right)."""
    _need_c(L)
    _need_c(Z)
    K, m = Z.shape
    if K == 0 or m == 0:
        return
    ch = _chars("R", "U", "T" if transpose else "N", "N")
    ints = np.array([m, K, K, m], dtype=np.int32)
    sc = np.array([1.0])
    _dtrsm(
        _ptr(ch[0:1]), _ptr(ch[1:2]), _ptr(ch[2:3]), _ptr(ch[3:4]), _ptr(ints[0:1]), _ptr(ints[1:2]),
        _ptr(sc), _ptr(L), _ptr(ints[2:3]), _ptr(Z), _ptr(ints[3:4]),
    )  # fmt: skip


@njit(cache=True)
def _times_lower_t(Z, L):
    """In place: Z (m, n) becomes Z L^T for a lower-triangular L (n, n), both C-contiguous (dtrmm: half the flops
    of the product)."""
    _need_c(Z)
    _need_c(L)
    m, n = Z.shape
    if m == 0 or n == 0:
        return
    _trmm_lower(Z, L, True)


@njit(cache=True)
def _times_lower(Z, L):
    """In place: Z (m, n) becomes Z L for a lower-triangular L (n, n), both C-contiguous (dtrmm)."""
    _need_c(Z)
    _need_c(L)
    m, n = Z.shape
    if m == 0 or n == 0:
        return
    _trmm_lower(Z, L, False)


@njit(cache=True)
def _trmm_lower(Z, L, transpose):
    """Z L^T (``transpose``) or Z L in place, by dtrmm on the transposed views (L Z^T or L^T Z^T from the
    left: Fortran sees the row-major lower L as an upper-triangular matrix)."""
    m, n = Z.shape
    ch = _chars("L", "U", "T" if transpose else "N", "N")
    ints = np.array([n, m, n, n], dtype=np.int32)
    sc = np.array([1.0])
    _dtrmm(
        _ptr(ch[0:1]), _ptr(ch[1:2]), _ptr(ch[2:3]), _ptr(ch[3:4]), _ptr(ints[0:1]), _ptr(ints[1:2]),
        _ptr(sc), _ptr(L), _ptr(ints[2:3]), _ptr(Z), _ptr(ints[3:4]),
    )  # fmt: skip


# ----------------------------------------------------------------------------------------------------------
# draws from the Generator's bit generator, bit for bit those of Generator.random() / .standard_normal()
# ----------------------------------------------------------------------------------------------------------
# NumPy's 256-layer ziggurat tables for standard normals (numpy/random/src/distributions; numba copies them):
# the same tables and the same arithmetic give the same doubles from the same 64-bit outputs.
_ZW = np.ascontiguousarray(_zig.wi_double, dtype=np.float64)
_ZK = np.ascontiguousarray(_zig.ki_double).astype(np.int64)  # < 2^52: exact as int64
_ZF = np.ascontiguousarray(_zig.fi_double, dtype=np.float64)
_ZR = float(_zig.ziggurat_nor_r)
_ZINV_R = float(_zig.ziggurat_nor_inv_r)


@njit(cache=True, inline="always")
def _rand(bg):
    """A uniform on [0, 1): ``(next_uint64 >> 11) 2^-53``, which is ``Generator.random()`` for the PCG64 family,
    SFC64 and Philox (numpy's ``next_double``), from one direct call of the bit generator (``rng.random()``
    inside numba goes through a slower wrapper). ``bg`` is ``rng.bit_generator`` inside a jitted function."""
    return np.float64(np.int64(_next_uint64(bg) >> np.uint64(11))) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _randn_slow(bg, r):
    """The ziggurat's rare branches for the 64-bit output ``r`` whose fast test failed (about 1.2% of draws:
    the wedge of its layer, or the tail beyond r for layer 0), then new outputs until one is accepted."""
    while True:
        idx = np.int64(r & np.uint64(0xFF))
        r = r >> np.uint64(8)
        sgn = 1.0 - 2.0 * np.float64(np.int64(r & np.uint64(1)))
        rabs = np.int64((r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF))
        x = sgn * (rabs * _ZW[idx])
        if rabs < _ZK[idx]:
            return x
        if idx == 0:  # the tail beyond r (Marsaglia 1964), as NumPy does it
            while True:
                xx = -_ZINV_R * np.log1p(-_rand(bg))
                yy = -np.log1p(-_rand(bg))
                if yy + yy > xx * xx:
                    return -(_ZR + xx) if (rabs >> 8) & 1 else _ZR + xx
        elif (_ZF[idx - 1] - _ZF[idx]) * _rand(bg) + _ZF[idx] < np.exp(-0.5 * x * x):
            return x
        r = _next_uint64(bg)


@njit(cache=True, inline="always")
def _randn(bg):
    """A standard normal, bit for bit ``Generator.standard_normal()`` (NumPy's ziggurat: layer from bits 0-7,
    sign from bit 8, abscissa from bits 9-60 of one 64-bit output). The accepted-at-once case (98.8%) is inlined
    and branch-free in the sign; the rest is :func:`_randn_slow`."""
    r = _next_uint64(bg)
    idx = np.int64(r & np.uint64(0xFF))
    rs = r >> np.uint64(8)
    rabs = np.int64((rs >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF))
    if rabs < _ZK[idx]:
        return (1.0 - 2.0 * np.float64(np.int64(rs & np.uint64(1)))) * (rabs * _ZW[idx])
    return _randn_slow(bg, r)


@njit(cache=True)
def _randn_fill(bg, out):
    """Fill a C-contiguous array with standard normals in its memory order (= ``rng.standard_normal(shape)``)."""
    flat = out.reshape(out.size)
    for q in range(flat.shape[0]):
        flat[q] = _randn(bg)


@njit(cache=True)
def draw_normals(rng, n):
    """``n`` standard normals from the Generator by the kernels' own ziggurat (for tests)."""
    out = np.empty(n)
    _randn_fill(rng.bit_generator, out)
    return out


@njit(cache=True)
def draw_uniforms(rng, n):
    """``n`` uniforms from the Generator by the kernels' direct draw (for tests)."""
    bg = rng.bit_generator
    out = np.empty(n)
    for q in range(n):
        out[q] = _rand(bg)
    return out


# ----------------------------------------------------------------------------------------------------------
# the updates (each mutates the state in place)
# ----------------------------------------------------------------------------------------------------------
# Square tiles of the cache-friendly transposes between point-major (N, K) and atom-major (K, N) arrays
_TILE = 16


@njit(cache=True)
def _transpose_into(src, dst):
    """dst[k, i] = src[i, k] tile by tile (a plain double loop writes dst with a stride of N doubles)."""
    N, K = src.shape
    for i0 in range(0, N, _TILE):
        i1 = min(i0 + _TILE, N)
        for k0 in range(0, K, _TILE):
            k1 = min(k0 + _TILE, K)
            for k in range(k0, k1):
                for i in range(i0, i1):
                    dst[k, i] = src[i, k]


@njit(cache=True)
def _codes_into_t(B, S, At):
    """At[k, i] = B[i, k] S[i, k] (atom-major codes from the point-major state), tile by tile."""
    N, K = S.shape
    for i0 in range(0, N, _TILE):
        i1 = min(i0 + _TILE, N)
        for k0 in range(0, K, _TILE):
            k1 = min(k0 + _TILE, K)
            for k in range(k0, k1):
                for i in range(i0, i1):
                    At[k, i] = S[i, k] * B[i, k]  # branch-free: b is 0 or 1


@njit(cache=True)
def _store_codes_from_t(Bt, St, B, S):
    """S[i, k] = St[k, i] and B[i, k] = (Bt[k, i] != 0) (the atom-major results back into the state), tile by
    tile."""
    N, K = S.shape
    for i0 in range(0, N, _TILE):
        i1 = min(i0 + _TILE, N)
        for k0 in range(0, K, _TILE):
            k1 = min(k0 + _TILE, K)
            for i in range(i0, i1):
                for k in range(k0, k1):
                    S[i, k] = St[k, i]
                    B[i, k] = 1 if Bt[k, i] != 0.0 else 0


@njit(cache=True)
def _code_randoms(rng, N, K, Ut, Zt):
    """The code update's random numbers in their documented order, atom-major: K x N uniforms (atom 1's for
    points 1..N, then atom 2's, ...), then K x N standard normals in the same order, as ``Ut[k, i]``,
    ``Zt[k, i]``."""
    bg = rng.bit_generator
    for k in range(K):
        for i in range(N):
            Ut[k, i] = _rand(bg)
    _randn_fill(bg, Zt)


@njit(cache=True, fastmath=_VEC, error_model="numpy")
def _code_block(
    Ct, Gb, At, Bt, St, Ut, Zt, Wt, Dt, k0, nb, tau, half_log, sd_on, sd_off, g_xy, norms
):
    """The (b, s) block update of atoms k0 .. k0 + nb - 1 for all N points, vectorized over the points.

    ``Ct[j, i]`` holds ``d_{k0+j} . r_i`` for the residual before this block; after atom k's draw the later
    atoms' projections of point i are corrected by ``delta_ik d_k . d_j`` (``Gb`` = the block's Gram matrix), so
    point i sees atom k's conditional given atoms < k exactly as in a point-by-point sweep. Writes the new codes
    (``At`` alpha, ``Bt`` 0/1 as float, ``St`` s) and ``Dt[j, i] = alpha_old - alpha_new``; all arrays are
    atom-major (K or nb rows, N columns). u < sigmoid(logit) is tested as ``u (1 + e) < (1 if logit >= 0 else e)``
    with ``e = exp(-|logit|)`` (branch-free; the polynomial exp of _exp_neg, so the loop vectorizes).
    """
    N = Ct.shape[1]
    for j in range(nb):
        k = k0 + j
        gain = g_xy / tau[k]
        ht = 0.5 * tau[k]
        hl = half_log[k]
        nk = norms[k]
        so = sd_on[k]
        for i in range(N):
            a_old = At[k, i]
            mu = gain * (Ct[j, i] + a_old * nk)
            logit = Wt[k, i] + hl + ht * mu * mu
            e = _exp_neg(abs(logit))
            on = Ut[k, i] * (1.0 + e) < (1.0 if logit >= 0.0 else e)
            z = Zt[k, i]
            s_on = mu + z * so
            a_new = s_on if on else 0.0
            Dt[j, i] = a_old - a_new
            At[k, i] = a_new
            Bt[k, i] = 1.0 if on else 0.0
            St[k, i] = s_on if on else z * sd_off
        for jj in range(j + 1, nb):
            g = Gb[j, jj]
            for i in range(N):
                Ct[jj, i] += g * Dt[j, i]


# atoms per block of the code update: two (N x M) x (M x _CODE_BLOCK) matrix products per block
_CODE_BLOCK = 64
# atoms per block in prediction (more points per product than in a sweep: smaller blocks, fewer corrections)
_PRED_BLOCK = 32


@njit(cache=True)
def update_codes(R, D, norms, B, S, W, g_s, g_xy, rng, keep_residual=True):
    """Joint (b_ki, s_ki) block update for every data point i and atom k, i outer, k inner (docs/model.md,
    section "Codes: the (b, s) block update").

    With ``tau = g_s + g_xy ||d_k||^2`` and ``mu = g_xy d_k^T r_i^(-k) / tau``:
    ``logit P(b=1) = w_ik + 0.5 log(g_s / tau) + 0.5 tau mu^2``; ``s ~ N(mu, 1/tau)`` if b = 1 else
    ``s ~ N(0, 1/g_s)``. Draw order (atom-major): K x N uniforms (for b_ki: k outer, i inner), then K x N
    standard normals (s) in the same order. Codes of different points are independent given D, so which
    point gets which of the i.i.d. draws does not change the conditional.

    Each point's atoms are visited in order k = 1..K, each conditioned on the point's atoms < k, with the
    point's own random numbers: the chain is that of a point-by-point sweep. Codes of different points are
    independent given D, so the points are processed together, in blocks of ``_CODE_BLOCK`` atoms: the
    projections ``d_k . r_i`` of a block come from one matrix product ``D_blk R^T`` (BLAS-3), are corrected
    within the block by the block's Gram matrix (:func:`_code_block`), and the residual is updated once per
    block, ``R += Delta^T D_blk`` (Delta = alpha_old - alpha_new). O(N K M) per sweep, as matrix products.
    Shapes: R (N, M), D (K, M), norms (K,), B (N, K) int8, S, W (N, K); all updated in place but D, W.
    Without ``keep_residual`` R is left stale after the last block (for a caller that recomputes it, as the block
    atom update does): one block's product less.
    """
    N, K = B.shape
    tau = np.empty(K)
    half_log = np.empty(K)
    sd_on = np.empty(K)
    sd_off = 1.0 / np.sqrt(g_s)
    for k in range(K):
        tau[k] = g_s + g_xy * norms[k]
        half_log[k] = 0.5 * np.log(g_s / tau[k])
        sd_on[k] = 1.0 / np.sqrt(tau[k])
    Ut = np.empty((K, N))
    Zt = np.empty((K, N))
    _code_randoms(rng, N, K, Ut, Zt)
    At = np.empty((K, N))
    _codes_into_t(B, S, At)
    Wt = np.empty((K, N))
    _transpose_into(W, Wt)
    Bt = np.empty((K, N))
    St = np.empty((K, N))
    nbmax = min(_CODE_BLOCK, K)
    Dt = np.empty((nbmax, N))
    Rt = R.T
    for k0 in range(0, K, nbmax):
        k1 = min(k0 + nbmax, K)
        nb = k1 - k0
        Db = D[k0:k1]
        Ct = Db @ Rt
        Gb = Db @ Db.T
        _code_block(
            Ct, Gb, At, Bt, St, Ut, Zt, Wt, Dt, k0, nb, tau, half_log, sd_on, sd_off, g_xy, norms
        )
        if keep_residual or k1 < K:
            R += Dt[:nb].T @ Db
    _store_codes_from_t(Bt, St, B, S)


@njit(cache=True)
def update_codes_separate(R, D, B, S, W, g_s, g_nx, g_ny, Mx, rng, keep_residual=True):
    """The (b, s) block update with separate noise precisions g_nx (feature rows) and g_ny (output rows).

    Then ``tau = g_s + g_nx ||d^x_k||^2 + g_ny ||d^y_k||^2`` and
    ``mu = (g_nx d^x_k . r^x_i^(-k) + g_ny d^y_k . r^y_i^(-k)) / tau``; the logit and the draws have the form of
    :func:`update_codes`. Both depend on D and R only through these weighted inner products, so the update is
    :func:`update_codes` with g_xy = 1 on copies of D and R whose feature columns are scaled by sqrt(g_nx) and
    output columns by sqrt(g_ny) (same draws, same order); R is scaled back in place afterwards
    (``keep_residual`` as in :func:`update_codes`: without it R is left stale).
    """
    K, M = D.shape
    N = R.shape[0]
    scale = np.empty(M)
    for m in range(M):
        scale[m] = np.sqrt(g_nx) if m < Mx else np.sqrt(g_ny)
    Ds = np.empty((K, M))
    for k in range(K):
        for m in range(M):
            Ds[k, m] = D[k, m] * scale[m]
    for i in range(N):
        for m in range(M):
            R[i, m] *= scale[m]
    norms_s = np.empty(K)
    _row_norms(Ds, norms_s)
    update_codes(R, Ds, norms_s, B, S, W, g_s, 1.0, rng, keep_residual)
    if not keep_residual:
        return
    for i in range(N):
        for m in range(M):
            R[i, m] /= scale[m]


@njit(cache=True)
def _small_form_cheaper(N, K, M):
    """Whether the N x N form of the block atom draw needs fewer flops than the K x K form (N < K by enough):
    ``N^2 K + 2 N^3 / 3 + 4 N^2 M`` (syrk, two Cholesky, the solves' 2 N^2 M counted twice) against
    ``N K^2 + 2 K^3 / 3 + 2 K^2 M``; the 4 N K M of the other products is common to both. The solves weigh
    double: with their true count (the residual now comes from them) the N x N form would also be chosen at
    N = 30, K = 32 / 60, 64 / 100, 128, where it measured 0.93-1.02x the K x K form (bench_bsr_ab.py), and
    those cells' chains would change."""
    n, k, m = float(N), float(K), float(M)
    return (
        n * n * k + 2.0 * n**3 / 3.0 + 4.0 * n * n * m
        < n * k * k + 2.0 * k**3 / 3.0 + 2.0 * k * k * m
    )


@njit(cache=True)
def update_atoms(V, R, D, norms, B, S, g_xy, g_x, g_y, Mx, rng, g_ny=-1.0):
    """Draw all atoms given the codes, then recompute the residual.

    Given the codes the rows of D^x are independent with the common K x K precision
    ``P = g_x I + g_xy A A^T`` (A = codes, K x N) and mean ``P^-1 g_xy A X^T``; likewise D^y with g_y. Two
    exact ways to draw them (docs/model.md, section "Atoms"):

    - ``D^x^T = U^-1 (U^-T g_xy A X^T + E)`` with ``P = U^T U`` (one K x K Cholesky per dictionary).
      Draw order: one (K, M) array of standard normals E (columns < Mx for D^x, the rest for D^y).
    - when it needs fewer flops (N well below K, :func:`_small_form_cheaper`): the N x N (Woodbury) form of Bhattacharya, Chakraborty & Mallick (Biometrika 103(4), 2016,
      Algorithm 1) with ``Phi = sqrt(g_xy) A^T``: ``u = E1 / sqrt(g_x)``, ``v = Phi u + E2``,
      ``w = (Phi Phi^T / g_x + I_N)^-1 (sqrt(g_xy) X^T - v)``, ``D^x^T = u + Phi^T w / g_x`` (one N x N
      Cholesky per dictionary). The residual needs no further product: ``X^T - A D^x^T = (E2 + w) / sqrt(g_xy)``
      (code layout). Draw order: a (K, M) array E1, then an (N, M) array E2 of standard normals.

    With separate noise precisions, ``g_xy`` is the feature rows' g_nx and ``g_ny`` (>= 0) the output rows' (it
    replaces g_xy in D^y's precision and mean); the default ``g_ny = -1`` means one shared g_xy.
    """
    if g_ny < 0.0:
        g_ny = g_xy
    N, K = B.shape
    M = D.shape[1]
    A = _codes_from(B, S)
    bg = rng.bit_generator
    if _small_form_cheaper(N, K, M):
        U = np.empty((K, M))  # E1, then u = E1 / sqrt(g) in place, both dictionaries side by side
        _randn_fill(bg, U)
        E2 = np.empty((N, M))
        _randn_fill(bg, E2)
        H = np.empty((N, N))
        _syrk_gram(A, H, False)  # A A^T (code layout: A is N x K)
        sx, sy = 1.0 / np.sqrt(g_x), 1.0 / np.sqrt(g_y)
        for k in range(K):
            for m in range(M):
                U[k, m] *= sx if m < Mx else sy
        Au = A @ U
        Wr = np.empty((N, M))
        for part in range(2):
            if part == 0:
                lo, hi, g, gn = 0, Mx, g_x, g_xy
            else:
                lo, hi, g, gn = Mx, M, g_y, g_ny
            if hi == lo:
                continue
            c = np.sqrt(gn)
            Mm = H * (gn / g)
            for i in range(N):
                Mm[i, i] += 1.0
            _cholesky_lower(Mm)
            Wp = np.empty((N, hi - lo))
            for i in range(N):
                for m in range(hi - lo):
                    Wp[i, m] = c * (V[i, lo + m] - Au[i, m + lo]) - E2[i, lo + m]
            _tri_solve(Mm, Wp, False)
            _tri_solve(Mm, Wp, True)
            # D^T = u + Phi^T w / g = u + (c / g) A^T w. The residual needs no product with H: with
            # rhs = c (X^T - A u) - E2 and Mm w = rhs, H w = (g / gn)(rhs - w), so
            # X^T - A D^T = X^T - A u - (c / g) H w = (E2 + w) / c.
            f = c / g
            for i in range(N):
                for m in range(hi - lo):
                    Wr[i, lo + m] = f * Wp[i, m]
                    R[i, lo + m] = (E2[i, lo + m] + Wp[i, m]) / c
        Dp = A.T @ Wr
        for k in range(K):
            for m in range(M):
                D[k, m] = U[k, m] + Dp[k, m]
        _row_norms(D, norms)
        return
    E = np.empty((K, M))
    _randn_fill(bg, E)
    G = np.empty((K, K))
    _syrk_gram(A, G, True)
    AV = A.T @ V
    for part in range(2):
        if part == 0:
            lo, hi, g, gn = 0, Mx, g_x, g_xy
        else:
            lo, hi, g, gn = Mx, M, g_y, g_ny
        if hi == lo:
            continue
        P = gn * G
        for k in range(K):
            P[k, k] += g
        _cholesky_lower(P)
        Z = np.ascontiguousarray(AV[:, lo:hi]) * gn
        _tri_solve(P, Z, False)
        Z += E[:, lo:hi]
        _tri_solve(P, Z, True)
        D[:, lo:hi] = Z
    _row_norms(D, norms)
    R[:, :] = V - A @ D


@njit(cache=True, fastmath=_VEC, error_model="numpy")
def update_atoms_single(R, D, norms, B, S, g_xy, g_x, g_y, Mx, rng, g_ny=-1.0):
    """Draw the atoms one at a time (the paper's Gibbs scheme, with the corrected precision), in place.

    ``d^x_k | rest ~ N(g_xy sum_i alpha_ki x_i^(-k) / p, I / p)`` with ``p = g_x + g_xy sum_i alpha_ki^2``
    (likewise ``d^y_k`` with g_y); then ``r_i -= alpha_ki (d_k' - d_k)`` for the points that use atom k.
    O(nnz_k M) per atom, O(N K M) at most per sweep, against O(K^2 (N + M) + K^3) for the block update; the
    block update mixes better per sweep when atoms are correlated. Draw order: one (K, M) array of standard
    normals E, row k for atom k (as in update_atoms). ``g_ny`` as in :func:`update_atoms`.
    """
    if g_ny < 0.0:
        g_ny = g_xy
    N, K = B.shape
    M = D.shape[1]
    E = np.empty((K, M))
    _randn_fill(rng.bit_generator, E)
    idx = np.empty(N, dtype=np.int64)
    a = np.empty(N)
    acc = np.empty(M)
    delta = np.empty(M)
    for k in range(K):
        n = 0
        sa2 = 0.0
        for i in range(N):
            if B[i, k]:
                idx[n] = i
                a[n] = S[i, k]
                sa2 += S[i, k] * S[i, k]
                n += 1
        for m in range(M):  # sum_i alpha_ki r_i^(-k) = sum_i alpha_ki r_i + (sum_i alpha_ki^2) d_k
            acc[m] = sa2 * D[k, m]
        for q in range(n):
            i, ai = idx[q], a[q]
            for m in range(M):
                acc[m] += ai * R[i, m]
        px = g_x + g_xy * sa2
        py = g_y + g_ny * sa2
        cx, sx = g_xy / px, 1.0 / np.sqrt(px)
        cy, sy = g_ny / py, 1.0 / np.sqrt(py)
        for m in range(Mx):
            new = cx * acc[m] + sx * E[k, m]
            delta[m] = new - D[k, m]
            D[k, m] = new
        for m in range(Mx, M):
            new = cy * acc[m] + sy * E[k, m]
            delta[m] = new - D[k, m]
            D[k, m] = new
        norms[k] = _dot_rows(D, k, D, k, M)
        for q in range(n):
            i, ai = idx[q], a[q]
            for m in range(M):
                R[i, m] -= ai * delta[m]


@njit(cache=True, fastmath=_VEC)
def _sum_sq(a):
    acc = 0.0
    for v in a.ravel():
        acc += v * v
    return acc


@njit(cache=True, fastmath=_VEC)
def _sum_sq_cols(X, lo, hi):
    """sum of X[:, lo:hi]^2 for a C-contiguous 2-D X (vectorized along the rows' columns)."""
    acc = 0.0
    for r in range(X.shape[0]):
        for m in range(lo, hi):
            acc += X[r, m] * X[r, m]
    return acc


@njit(cache=True)
def update_precisions(R, D, S, prec, Mx, a0, b0, rng, a_xy=-1.0, b_xy=-1.0, separate=False):
    """Gamma conditionals of the precisions (shape/rate), drawn in the order g_s, noise, g_x, g_y.

    g_s ~ Gamma(a + NK/2, b + sum s^2 / 2) over all N K weights (active or not);
    g_xy ~ Gamma(a_xy + NM/2, b_xy + ||R||^2 / 2); g_x ~ Gamma(a + Mx K/2, b + ||D^x||^2 / 2); g_y likewise.
    ``a_xy``, ``b_xy``: the noise precision's own Gamma prior (negative: a0, b0). With ``separate`` noise
    precisions the noise draw is two draws, g_nx ~ Gamma(a_xy + N Mx/2, b_xy + ||R^x||^2 / 2) then
    g_ny ~ Gamma(a_xy + N My/2, b_xy + ||R^y||^2 / 2), and prec[1] becomes the pooled
    ``M / (Mx / g_nx + My / g_ny)``; with a shared one prec[4] = prec[5] = g_xy. ``prec`` has 6 entries
    (module docstring).
    """
    if prec.shape[0] != 6:
        raise ValueError("prec must have 6 entries: g_s, g_xy, g_x, g_y, g_nx, g_ny")
    if a_xy < 0.0:
        a_xy = a0
    if b_xy < 0.0:
        b_xy = b0
    N, K = S.shape
    M = D.shape[1]
    My = M - Mx
    ss = _sum_sq(S)
    dx = _sum_sq_cols(D, 0, Mx)
    dy = _sum_sq_cols(D, Mx, M)
    prec[0] = rng.gamma(a0 + 0.5 * N * K, 1.0 / (b0 + 0.5 * ss))
    if separate:
        rx = _sum_sq_cols(R, 0, Mx)
        ry = _sum_sq_cols(R, Mx, M)
        prec[4] = rng.gamma(a_xy + 0.5 * N * Mx, 1.0 / (b_xy + 0.5 * rx))
        if My > 0:
            prec[5] = rng.gamma(a_xy + 0.5 * N * My, 1.0 / (b_xy + 0.5 * ry))
            prec[1] = M / (Mx / prec[4] + My / prec[5])
        else:
            prec[1] = prec[4]
    else:
        rr = _sum_sq(R)
        prec[1] = rng.gamma(a_xy + 0.5 * N * M, 1.0 / (b_xy + 0.5 * rr))
        prec[4] = prec[1]
        prec[5] = prec[1]
    prec[2] = rng.gamma(a0 + 0.5 * Mx * K, 1.0 / (b0 + 0.5 * dx))
    if My > 0:
        prec[3] = rng.gamma(a0 + 0.5 * My * K, 1.0 / (b0 + 0.5 * dy))


@njit(cache=True)
def _signs_t(B):
    """z = 2 b - 1, transposed to (K, N) so that atom k's vector is a contiguous row."""
    N, K = B.shape
    Zt = np.empty((K, N))
    for i0 in range(0, N, _TILE):
        i1 = min(i0 + _TILE, N)
        for k0 in range(0, K, _TILE):
            k1 = min(k0 + _TILE, K)
            for k in range(k0, k1):
                for i in range(i0, i1):
                    Zt[k, i] = 2.0 * B[i, k] - 1.0  # branch-free: b is 0 or 1
    return Zt


# Log-ratio sums in the MH step are taken as logs of running products, flushed every _FLUSH factors; factors
# outside [_TINY, 1/_TINY] are added as exact logs, so a product stays within 1e-240..1e240.
_FLUSH = 8
_TINY = 1e-30

# exp(-a) without a libm call, so that loops over it vectorize (with 'reassoc' for the reductions): a is clamped
# to [0, 708] (exp(-708) is still a normal number), a = k ln2 + r with |r| <= ln2 / 2 (ln2 split in two parts,
# as in fdlibm), exp(-r) by its Taylor polynomial of degree 13 (truncation < 4e-18 relative) and 2^-k written
# directly as the bits of a double (0 <= k <= 1022, so 2^-k is a normal number).
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_LOG2E = 1.4426950408889634
_EXP_CLAMP = 708.0
_BITS_2P52 = 0x4330000000000000  # the bits of 2.0**52
# Taylor coefficients 1 / j! of exp, highest degree first (j = 13 .. 0), for Horner's scheme
_EXP_TAYLOR = tuple(1.0 / math.factorial(j) for j in range(13, -1, -1))
# terms per logged product in _sum_log_sigmoid: factors are in [1, 2], so a product stays below 2^512
_LOG_CHUNK = 512


@intrinsic
def _int_bits_as_float(typingctx, bits):
    """The int64 ``bits`` reinterpreted as a float64 (an LLVM bitcast; vectorizes, unlike a table or a view)."""
    if bits != types.int64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


@intrinsic
def _float_bits_as_int(typingctx, x):
    """The float64 ``x`` reinterpreted as an int64 (an LLVM bitcast)."""
    if x != types.float64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@njit(cache=True, inline="always", fastmath=_VEC)
def _exp_neg(a):
    """exp(-a) for a >= 0 (a > _EXP_CLAMP gives exp(-_EXP_CLAMP)); relative error about 1e-16."""
    a = min(a, _EXP_CLAMP)
    kd = np.floor(
        a * _LOG2E + 0.5
    )  # k as a double: no float-int conversion, which AVX2 lacks for vectors
    q = (kd * _LN2_HI - a) + kd * _LN2_LO  # -r
    p = 0.0
    for c in _EXP_TAYLOR:
        p = p * q + c
    kb = _float_bits_as_int(kd + 4503599627370496.0)  # 2^52 + k is exact: its bits are 0x433... + k
    return p * _int_bits_as_float((_BITS_2P52 + 1023 - kb) << 52)  # 2^-k from its exponent bits


@njit(cache=True, inline="always", fastmath=_VEC)
def _sig_pair(x):
    """(sigmoid(x), sigmoid(-x)) from one exp, branch-free (vectorizes)."""
    e = _exp_neg(abs(x))
    inv = 1.0 / (1.0 + e)
    ei = e * inv
    pos = x >= 0.0
    return (inv if pos else ei), (ei if pos else inv)


@njit(cache=True, fastmath=_VEC)
def _sum_log_sigmoid(z, w):
    """sum_i log sigmoid(z_i w_i) for contiguous 1-D z, w, as ``sum_i min(x_i, 0) - log prod_i (1 + exp(-|x_i|))``
    with x_i = z_i w_i: no libm call per term, so the loop vectorizes; one log per _LOG_CHUNK terms."""
    n = w.shape[0]
    lin = 0.0
    logs = 0.0
    for i0 in range(0, n, _LOG_CHUNK):
        prod = 1.0
        for i in range(i0, min(i0 + _LOG_CHUNK, n)):
            x = z[i] * w[i]
            lin += min(x, 0.0)
            prod *= 1.0 + _exp_neg(abs(x))
        logs += np.log(prod)
    return lin - logs


@njit(cache=True, fastmath=_VEC, error_model="numpy")
def _bound_terms(Zt, Wt, Lam, Sig, literal=False):
    """Lam = z sigmoid(-z w) (the gradient of log sigmoid(z w): the tight bound's Lambda) and
    Sig = sigmoid(z w), elementwise over (K, N) arrays. With ``literal``, Lam = z sigmoid(+z w), the lambda
    the paper's appendix prints (not the tight bound). NumPy's error model: numba's default checks every
    float division for zero (1 + e > 0 here), and that branch keeps the loop from vectorizing."""
    K, N = Wt.shape
    if literal:
        for k in range(K):
            for i in range(N):
                sg, sm = _sig_pair(Zt[k, i] * Wt[k, i])
                Sig[k, i] = sg
                Lam[k, i] = Zt[k, i] * sg
    else:
        for k in range(K):
            for i in range(N):
                sg, sm = _sig_pair(Zt[k, i] * Wt[k, i])
                Sig[k, i] = sg
                Lam[k, i] = Zt[k, i] * sm


@njit(cache=True)
def update_w_mh(W, B, Sigma, Lw, rng, ratio=MH_EXACT, w_mean=0.0):
    """Metropolis-Hastings update of every logit vector w_k with the bound-based proposal.

    Prior ``w_k ~ N(m 1, Sigma)`` (m = ``w_mean``, 0 in the paper). Proposal (paper, Appendix A, with the tight
    bound lambda_i = sigmoid(-z_i w_i)): ``w' ~ N(m + mu, Sigma)``, ``mu = Sigma Lambda(w)``, drawn as
    ``m + mu + Lw eps``. The correct log acceptance ratio (the proposal depends on w, so it is not an
    independence chain) is, with u = w - m and u' = w' - m,
    ``sum_i [log sig(z_i w'_i) - log sig(z_i w_i)] + u . Lambda' - u' . Lambda + (Lambda . mu - Lambda' . mu')/2``.
    ``ratio`` selects it (MH_EXACT) or one of two wrong-target ablations: MH_PRINTED_RATIO, the paper's printed
    ratio ``sum_i [...] - Lambda . (w' - w)`` with the tight lambda; MH_LITERAL, the printed ratio and
    lambda_i = sigmoid(+z_i w_i) exactly as the appendix prints it. All K atoms are batched as matrix products
    (Sigma is symmetric, so atom-major (K, N) arrays are multiplied from the right). Draw order: a (K, N) array
    of standard normals (row k for atom k), then K uniforms. Returns the number of accepted atoms. ``Lw`` must be
    the Cholesky factor of ``Sigma`` (the proposal's noise and the ratio's quadratic terms use it).
    """
    N, K = W.shape
    exact = ratio == MH_EXACT
    Zt = _signs_t(B)
    Wt = np.empty((K, N))
    _transpose_into(W, Wt)
    Lam = np.empty((K, N))
    Sig = np.empty((K, N))
    _bound_terms(Zt, Wt, Lam, Sig, ratio == MH_LITERAL)
    Mu = Lam @ Sigma
    Eps = np.empty((K, N))
    _randn_fill(rng.bit_generator, Eps)
    _times_lower_t(Eps, Lw)  # Eps Lw^T
    Wp = Mu + Eps
    if w_mean != 0.0:
        Wp += w_mean
    Lamp = np.empty((K, N))
    Sigp = np.empty((K, N))
    _bound_terms(Zt, Wp, Lamp, Sigp, ratio == MH_LITERAL)
    # Lambda' . mu' = Lambda'^T Sigma Lambda' = ||Lw^T Lambda'||^2: a triangular product (half the flops of
    # Lamp @ Sigma); mu' itself is not needed
    quadp = np.empty(K)
    if exact:
        LamL = Lamp.copy()
        _times_lower(LamL, Lw)  # row k: (Lw^T Lambda'_k)^T
        for k in range(K):
            quadp[k] = _dot_rows(LamL, k, LamL, k, N)
    U = np.empty(K)
    for k in range(K):
        U[k] = _rand(rng.bit_generator)
    accepted = 0
    for k in range(K):
        lr = 0.0
        prod = 1.0
        cnt = 0
        for i in range(N):
            # log-likelihood ratio: log(sig(z w'_i) / sig(z w_i)) as a running product
            a, b = Sigp[k, i], Sig[k, i]
            if a > _TINY and b > _TINY and _TINY < a / b < 1.0 / _TINY:
                prod *= a / b
                cnt += 1
                if cnt == _FLUSH:
                    lr += np.log(prod)
                    prod = 1.0
                    cnt = 0
            else:
                lr += _log_sigmoid(Zt[k, i] * Wp[k, i]) - _log_sigmoid(Zt[k, i] * Wt[k, i])
            if exact:
                lr += (
                    (Wt[k, i] - w_mean) * Lamp[k, i]
                    - (Wp[k, i] - w_mean) * Lam[k, i]
                    + 0.5 * Lam[k, i] * Mu[k, i]
                )
            else:
                lr -= Lam[k, i] * (Wp[k, i] - Wt[k, i])
        lr += np.log(prod)
        if exact:
            lr -= 0.5 * quadp[k]
        if np.log(U[k]) < lr:
            accepted += 1
            for i in range(N):
                Wt[k, i] = Wp[k, i]
    _transpose_into(Wt, W)
    return accepted


@njit(cache=True)
def update_w_ess(W, B, Lw, rng, w_mean=0.0):
    """Elliptical slice sampling (Murray, Adams & MacKay 2010) of every w_k, prior N(m 1, Sigma = Lw Lw^T).

    With a prior mean m (``w_mean``) the ellipse is drawn for u = w - m, whose prior is N(0, Sigma) (Murray
    et al., Sec. 2): ``u' = u cos(theta) + nu sin(theta)``, ``w' = u' + m``. Draw order: one (K, N) array of
    standard normals (row k gives atom k's ellipse ``nu = Lw eps_k``); then per atom k: one uniform for the
    slice height, one for the initial angle, one per shrinkage step. Returns the number of logit vectors that
    moved (K unless the shrinkage guard was hit or the new point equals the old one).
    """
    N, K = W.shape
    Zt = _signs_t(B)
    Wt = np.empty((K, N))
    _transpose_into(W, Wt)
    bg = rng.bit_generator
    Nu = np.empty((K, N))
    _randn_fill(bg, Nu)
    _times_lower_t(Nu, Lw)  # the ellipses Lw eps_k, one per row
    wp = np.empty(N)
    two_pi = 2.0 * np.pi
    moved = 0
    for k in range(K):
        wk = Wt[k]
        zk = Zt[k]
        nk = Nu[k]
        log_y = _sum_log_sigmoid(zk, wk) + np.log(_rand(bg))
        theta = _rand(bg) * two_pi
        lo = theta - two_pi
        hi = theta
        while True:
            c = np.cos(theta)
            sn = np.sin(theta)
            for i in range(N):
                wp[i] = ((wk[i] - w_mean) * c + nk[i] * sn) + w_mean
            if _sum_log_sigmoid(zk, wp) > log_y:
                break
            if theta < 0.0:
                lo = theta
            else:
                hi = theta
            if hi - lo < 1e-300:  # cannot happen for a finite log-likelihood; guard against a hang
                wp[:] = wk
                break
            theta = lo + _rand(bg) * (hi - lo)
        changed = False
        for i in range(N):
            if wk[i] != wp[i]:
                changed = True
            wk[i] = wp[i]  # wk is row k of Wt
        if changed:
            moved += 1
    _transpose_into(Wt, W)
    return moved


@njit(cache=True)
def log_likelihood(R, g_xy):
    """log p(V | D, A, g_xy) = N M / 2 log(g_xy / 2 pi) - g_xy ||R||^2 / 2."""
    n = R.size
    return 0.5 * n * (np.log(g_xy) - np.log(2.0 * np.pi)) - 0.5 * g_xy * _sum_sq(R)


@njit(cache=True)
def log_likelihood_separate(R, Mx, g_nx, g_ny):
    """log p(V | D, A, g_nx, g_ny) with precision g_nx on the feature columns and g_ny on the output columns."""
    N, M = R.shape
    rx = 0.0
    ry = 0.0
    for i in range(N):
        for m in range(Mx):
            rx += R[i, m] * R[i, m]
        for m in range(Mx, M):
            ry += R[i, m] * R[i, m]
    ll = 0.5 * N * Mx * (np.log(g_nx) - np.log(2.0 * np.pi)) - 0.5 * g_nx * rx
    if M > Mx:
        ll += 0.5 * N * (M - Mx) * (np.log(g_ny) - np.log(2.0 * np.pi)) - 0.5 * g_ny * ry
    return ll


@njit(cache=True)
def _sweep(
    V,
    R,
    D,
    norms,
    B,
    S,
    W,
    prec,
    Sigma,
    Lw,
    Mx,
    a0,
    b0,
    a_xy,
    b_xy,
    w_mean,
    separate,
    w_code,
    atom_code,
    rng,
    stats,
):
    """One full Gibbs sweep: codes, atoms (+ residual), precisions, logits. Writes
    ``stats = [log-likelihood, number of active atoms, fraction of moved logit vectors]`` (MH: accepted)."""
    keep = (
        atom_code == 1
    )  # the block atom update recomputes the residual; the single-site one reads it
    if separate:
        update_codes_separate(R, D, B, S, W, prec[0], prec[4], prec[5], Mx, rng, keep)
        g_nx, g_ny = prec[4], prec[5]
    else:
        update_codes(R, D, norms, B, S, W, prec[0], prec[1], rng, keep)
        g_nx, g_ny = prec[1], prec[1]
    if atom_code == 1:
        update_atoms_single(R, D, norms, B, S, g_nx, prec[2], prec[3], Mx, rng, g_ny)
    else:
        update_atoms(V, R, D, norms, B, S, g_nx, prec[2], prec[3], Mx, rng, g_ny)
    update_precisions(R, D, S, prec, Mx, a0, b0, rng, a_xy, b_xy, separate)
    K = W.shape[1]
    if w_code == 1:
        acc = update_w_ess(W, B, Lw, rng, w_mean)
    elif w_code == 0:
        acc = update_w_mh(W, B, Sigma, Lw, rng, MH_EXACT, w_mean)
    elif w_code == 2:
        acc = update_w_mh(W, B, Sigma, Lw, rng, MH_PRINTED_RATIO, w_mean)
    else:
        acc = update_w_mh(W, B, Sigma, Lw, rng, MH_LITERAL, w_mean)
    if separate:
        stats[0] = log_likelihood_separate(R, Mx, prec[4], prec[5])
    else:
        stats[0] = log_likelihood(R, prec[1])
    active = 0
    for k in range(K):
        for i in range(B.shape[0]):
            if B[i, k]:
                active += 1
                break
    stats[1] = active
    stats[2] = acc / K


@njit(cache=True)
def redraw_data(V, R, D, B, S, g_xy, rng, g_ny=-1.0, Mx=0):
    """Replace V by a draw from the likelihood ``V = A D + E`` and set R = V - A D.

    E has precision g_xy on every column, or with ``g_ny >= 0`` g_xy (= g_nx) on the first ``Mx`` columns and
    g_ny on the others. Draw order: one (N, M) array of standard normals. Used by the Geweke test and for
    simulation.
    """
    E = rng.standard_normal(V.shape)
    if g_ny < 0.0:
        E /= np.sqrt(g_xy)
    else:
        E[:, :Mx] /= np.sqrt(g_xy)
        E[:, Mx:] /= np.sqrt(g_ny)
    V[:, :] = _codes_from(B, S) @ D + E
    R[:, :] = E


# ----------------------------------------------------------------------------------------------------------
# state containers and the sweep-level API
# ----------------------------------------------------------------------------------------------------------
class BSRState(NamedTuple):
    """Sampler state; arrays are mutated in place by the updates (layout in the module docstring)."""

    D: np.ndarray
    norms: np.ndarray
    B: np.ndarray
    S: np.ndarray
    W: np.ndarray
    R: np.ndarray
    prec: np.ndarray  # [g_s, g_xy, g_x, g_y, g_nx, g_ny]


class BSRData(NamedTuple):
    """Observed data and the fixed logit prior: ``V = [X | Y]`` (N, M), ``Mx``, ``Sigma`` and its factor."""

    V: np.ndarray
    Mx: int
    Sigma: np.ndarray
    Lw: np.ndarray


class BSRHyper(NamedTuple):
    """The prior: Gamma(a0, b0) (shape, rate) on g_s, g_x, g_y; Gamma(a_xy, b_xy) on the noise precision(s)
    (None: a0, b0); the prior mean ``w_mean`` of the logits; ``noise`` "shared" (one g_xy, the paper) or
    "separate" (g_nx for the feature rows, g_ny for the output rows)."""

    a0: float = 1e-6
    b0: float = 1e-6
    a_xy: float | None = None
    b_xy: float | None = None
    w_mean: float = 0.0
    noise: str = "shared"

    @property
    def noise_ab(self):
        """(shape, rate) of the noise precisions' Gamma prior."""
        return (self.a0 if self.a_xy is None else self.a_xy), (
            self.b0 if self.b_xy is None else self.b_xy
        )


def gibbs_sweep(state, data, hyper, rng, w_update="mh", atom_update="block"):
    """Run one full Gibbs sweep (a single jitted call); returns ``(state, stats)``.

    ``state`` is updated in place and returned; ``stats`` is ``[log-likelihood, active atoms, acceptance]``.
    ``w_update`` is ``"mh"`` (corrected MH), ``"ess"`` (elliptical slice), ``"paper-printed-ratio"`` or
    ``"paper-literal"`` (wrong-target ablations, see update_w_mh); ``atom_update`` is ``"block"`` (all atoms
    jointly, update_atoms) or ``"single"`` (one at a time). ``hyper`` (BSRHyper) gives the priors and the noise
    model.
    """
    if w_update not in W_UPDATES:
        raise InputError(f"w_update must be one of {sorted(W_UPDATES)}; got {w_update!r}")
    if atom_update not in ATOM_UPDATES:
        raise InputError(f"atom_update must be one of {sorted(ATOM_UPDATES)}; got {atom_update!r}")
    if hyper.noise not in NOISE_MODELS:
        raise InputError(f"noise must be one of {sorted(NOISE_MODELS)}; got {hyper.noise!r}")
    a_xy, b_xy = hyper.noise_ab
    stats = np.zeros(3)
    _sweep(
        data.V,
        state.R,
        state.D,
        state.norms,
        state.B,
        state.S,
        state.W,
        state.prec,
        data.Sigma,
        data.Lw,
        data.Mx,
        float(hyper.a0),
        float(hyper.b0),
        float(a_xy),
        float(b_xy),
        float(hyper.w_mean),
        hyper.noise == "separate",
        W_UPDATES[w_update],
        ATOM_UPDATES[atom_update],
        rng,
        stats,
    )
    return state, stats


def draw_from_prior(N, K, Mx, My, Sigma, Lw, a0, b0, rng, hyper=None):
    """Draw (state, V) from the joint prior (precisions, atoms, logits, codes, data). Needs proper priors.

    ``hyper`` (BSRHyper, optional) overrides a0, b0 and adds the noise prior, the noise model and the logit
    prior mean. Draw order: g_s, g_xy (g_nx when separate), g_x, g_y, [g_ny when separate], then as before.
    """
    hyper = BSRHyper(a0, b0) if hyper is None else hyper
    a0, b0 = hyper.a0, hyper.b0
    a_xy, b_xy = hyper.noise_ab
    M = Mx + My
    prec = np.empty(6)
    prec[0] = rng.gamma(a0, 1.0 / b0)
    prec[1] = rng.gamma(a_xy, 1.0 / b_xy)
    prec[2] = rng.gamma(a0, 1.0 / b0)
    prec[3] = rng.gamma(a0, 1.0 / b0)
    prec[4] = prec[5] = prec[1]
    if hyper.noise == "separate":
        prec[5] = rng.gamma(a_xy, 1.0 / b_xy)
        prec[1] = M / (Mx / prec[4] + My / prec[5]) if My > 0 else prec[4]
    D = np.empty((K, M))
    D[:, :Mx] = rng.standard_normal((K, Mx)) / np.sqrt(prec[2])
    D[:, Mx:] = rng.standard_normal((K, My)) / np.sqrt(prec[3])
    W = Lw @ rng.standard_normal((N, K)) + hyper.w_mean
    B = (rng.random((N, K)) < 1.0 / (1.0 + np.exp(-W))).astype(np.int8)
    S = rng.standard_normal((N, K)) / np.sqrt(prec[0])
    E = rng.standard_normal((N, M))
    E[:, :Mx] /= np.sqrt(prec[4])
    E[:, Mx:] /= np.sqrt(prec[5])
    V = (B * S) @ D + E
    R = V - (B * S) @ D
    state = BSRState(D=D, norms=np.einsum("km,km->k", D, D), B=B, S=S, W=W, R=R, prec=prec)
    return state, V


# ----------------------------------------------------------------------------------------------------------
# logit prior
# ----------------------------------------------------------------------------------------------------------
def logit_prior_cov(Y, eta_scale=1.0):
    """Sigma_w(i, j) = exp(-||y_i - y_j|| / eta), eta = eta_scale * 2 sum_{i<j} ||y_i - y_j||^2 / (N (N - 1)).

    The paper's kernel (Sec. III) has eta_scale = 1; returns ``(Sigma, eta)``.
    """
    Y = np.asarray(Y, dtype=float)
    N = Y.shape[0]
    sq = np.einsum("ij,ij->i", Y, Y)
    d2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * Y @ Y.T, 0.0)
    np.fill_diagonal(d2, 0.0)
    eta = d2[np.triu_indices(N, 1)].sum() * 2.0 / (N * (N - 1)) if N > 1 else 1.0
    if not eta > 0.0:
        eta = 1.0  # all points identical: the kernel is constant; any eta gives the same matrix
    eta *= float(eta_scale)
    return np.exp(-np.sqrt(d2) / eta), eta


#: Logit prior covariances: the paper's kernel on the poses, the same kernel on the inputs, independent logits.
LOGIT_KERNELS = ("pose", "input", "identity")


def logit_prior(kernel, X, Y, eta_scale=1.0):
    """Sigma_w of the logits for a kernel choice, and its bandwidth eta (None for the identity).

    "pose": :func:`logit_prior_cov` of the (standardized) training poses Y, the paper's prior: points with
    similar poses use similar atoms. "input": the same kernel on the (standardized) training inputs X: codes
    tied by appearance instead. "identity": Sigma_w = I, independent logits (no pose information).
    """
    if kernel == "pose":
        return logit_prior_cov(Y, eta_scale)
    if kernel == "input":
        return logit_prior_cov(X, eta_scale)
    if kernel == "identity":
        return np.eye(np.asarray(Y).shape[0]), None
    raise ValueError(f"logit_kernel must be one of {list(LOGIT_KERNELS)}; got {kernel!r}")


def cholesky_with_jitter(Sigma, eta=None, max_tries=8):
    """Lower Cholesky factor of Sigma, adding jitter 1e-6 * mean(diag) and growing it x10 on failure.

    Returns ``(L, jitter)``; raises :class:`SamplerError` naming eta and N after ``max_tries`` failures.
    """
    N = Sigma.shape[0]
    scale = float(np.mean(np.diag(Sigma))) if N else 1.0
    try:
        return np.linalg.cholesky(Sigma), 0.0
    except np.linalg.LinAlgError:
        pass
    jitter = 1e-6 * scale
    for _ in range(max_tries):
        try:
            return np.linalg.cholesky(Sigma + jitter * np.eye(N)), jitter
        except np.linalg.LinAlgError:
            jitter *= 10.0
    raise SamplerError(
        f"Sigma_w (N={N}, eta={eta!r}) is not positive definite even with jitter {jitter / 10:.3g} "
        f"(= {jitter / 10 / scale:.3g} x mean diagonal); check for non-finite or degenerate training poses"
    )


# ----------------------------------------------------------------------------------------------------------
# prediction
# ----------------------------------------------------------------------------------------------------------
@njit(cache=True)
def _splitmix(state):
    """One step of splitmix64 (Steele, Lea & Flood 2014): returns (new state, 64-bit output)."""
    state = state + np.uint64(0x9E3779B97F4A7C15)
    z = state
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return state, z ^ (z >> np.uint64(31))


@njit(cache=True)
def _uniform(state):
    """A uniform on [0, 1) with 53 random bits."""
    state, z = _splitmix(state)
    return state, np.float64(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


# Ziggurat tables for standard normals (Marsaglia & Tsang, "The Ziggurat Method for Generating Random
# Variables", J. Stat. Softw. 5(8), 2000): 256 layers of equal area ZIG_V under f(x) = exp(-x^2 / 2); layer 0
# is the rectangle [0, ZIG_R] x [0, f(ZIG_R)] plus the tail beyond ZIG_R, with pseudo-width V / f(R).
ZIG_R = 3.6541528853610088
ZIG_V = 4.92867323399e-3


def ziggurat_tables(n=256, r=ZIG_R, v=ZIG_V):
    """Layer edges x[0..n] (x[0] = v / f(r), x[1] = r, decreasing to x[n] = 0) and f(x) at them."""
    x = np.empty(n + 1)
    x[0] = v / np.exp(-0.5 * r * r)
    x[1] = r
    for i in range(1, n - 1):
        x[i + 1] = np.sqrt(-2.0 * np.log(v / x[i] + np.exp(-0.5 * x[i] * x[i])))
    x[n] = 0.0
    return x, np.exp(-0.5 * x * x)


_ZIG_X, _ZIG_F = ziggurat_tables()


@njit(cache=True)
def _normal(state):
    """A standard normal by the ziggurat: one 64-bit output gives the layer (bits 0-7), the sign (bit 8) and
    the abscissa (bits 11-63); about 99% of draws are accepted at once, without a transcendental function."""
    while True:
        state, z = _splitmix(state)
        i = np.int64(z & np.uint64(255))
        neg = (z >> np.uint64(8)) & np.uint64(1)
        x = np.float64(z >> np.uint64(11)) * (1.0 / 9007199254740992.0) * _ZIG_X[i]
        if x < _ZIG_X[i + 1]:
            return state, -x if neg else x
        if (
            i == 0
        ):  # the tail beyond r (Marsaglia 1964): x = r + e1 / r, accepted if 2 e2 > (e1 / r)^2
            while True:
                state, u1 = _uniform(state)
                state, u2 = _uniform(state)
                xt = -np.log1p(-u1) / ZIG_R
                if -2.0 * np.log1p(-u2) > xt * xt:
                    break
            x = ZIG_R + xt
            return state, -x if neg else x
        state, u = _uniform(
            state
        )  # the wedge of layer i: accept if y ~ U[f(x_i), f(x_i+1)] is under f(x)
        if _ZIG_F[i] + u * (_ZIG_F[i + 1] - _ZIG_F[i]) < np.exp(-0.5 * x * x):
            return state, -x if neg else x


@njit(cache=True)
def stream_normals(seed, n):
    """``n`` consecutive normals of the prediction stream seeded by ``seed`` (for tests)."""
    out = np.empty(n)
    state = np.uint64(seed)
    for q in range(n):
        state, out[q] = _normal(state)
    return out


@njit(cache=True)
def point_seeds(Xbits, seed):
    """A 64-bit stream seed per row of ``Xbits`` (the rows' float64 bits as uint64), mixed with ``seed``."""
    T = Xbits.shape[0]
    out = np.empty(T, dtype=np.uint64)
    for t in range(T):
        h = np.uint64(seed)
        for m in range(Xbits.shape[1]):
            h, z = _splitmix(h ^ Xbits[t, m])
            h = z
        out[t] = h
    return out


@njit(cache=True, fastmath=_VEC, error_model="numpy")
def _predict_block(Ct, Gb, At, Dt, Wt, streams, k0, nb, nx, gain, half_tau, half_log, sd_on):
    """One sweep of the (b, s) block update of atoms k0 .. k0 + nb - 1 for every test point (prediction).

    As :func:`_code_block`: ``Ct[j, t] = d^x_{k0+j} . r_t`` for the residual before the block, corrected within
    the block by the block's Gram matrix ``Gb``; ``At`` (K, T) the codes, ``Dt[j, t] = alpha_old - alpha_new``.
    Random numbers from each point's own splitmix64 stream (``streams[t]``), in the point's atom order: one
    uniform unless the logit exceeds ``_LOGIT_SURE``, then one ziggurat normal if the atom is on.
    """
    T = Ct.shape[1]
    for j in range(nb):
        k = k0 + j
        for t in range(T):
            a_old = At[k, t]
            mu = gain[k] * (Ct[j, t] + a_old * nx[k])
            logit = Wt[k, t] + half_log[k] + half_tau[k] * mu * mu
            st = streams[t]
            on = logit > _LOGIT_SURE  # then P(on) rounds to 1: no uniform is drawn
            if not on:
                st, u = _uniform(st)
                on = u * (1.0 + np.exp(-logit)) < 1.0  # u < sigmoid(logit)
            if on:
                st, z = _normal(st)
                a_new = mu + z * sd_on[k]
            else:
                a_new = 0.0  # s of an inactive atom does not enter the prediction
            streams[t] = st
            At[k, t] = a_new
            Dt[j, t] = a_old - a_new
        for jj in range(j + 1, nb):
            g = Gb[j, jj]
            for t in range(T):
                Ct[jj, t] += g * Dt[j, t]


@njit(cache=True)
def predict_kernel(Xt, nbr, Dx, Dy, Ws, gs, gxy, n_sweeps, seeds, out_y, out_ll):
    """Posterior predictive draws of y for every test point and retained sample.

    For test point t and sample l: ``w_t = mean_{i in J_t} W^l[i, :]`` (J_t = its neighbours, ``nbr[t]``);
    ``n_sweeps`` sweeps of the (b, s) block update restricted to the feature rows, from zero codes;
    ``out_y[t, l] = D^y alpha_t``; ``out_ll[t, l] = log N(x_t; D^x alpha_t, 1/g_xy I)`` (for the paper's
    likelihood weights). Random numbers: a splitmix64 stream per test point seeded by ``seeds[t]`` (per atom
    one uniform unless the logit exceeds ``_LOGIT_SURE``, where P(on) is 1 in float64; then one ziggurat
    normal if the atom is on), so a point's prediction does not depend on the batch (up to rounding). Each
    point's atoms are visited in order within a sweep, as in a point-by-point loop; the points are processed
    together, in blocks of ``_PRED_BLOCK`` atoms as in :func:`update_codes` (projections ``D^x_blk R^T`` and the
    residual update ``R += Delta^T D^x_blk`` as matrix products, within-block corrections by the block's Gram
    matrix).
    Shapes: Xt (T, Mx); nbr (T, j); Dx (L, K, Mx); Dy (L, K, My); Ws (L, N, K); gs, gxy (L,);
    out_y (T, L, My) and out_ll (T, L) are written.
    """
    T, Mx = Xt.shape
    L, K, _ = Dx.shape
    My = out_y.shape[2]
    nj = nbr.shape[1]
    nbmax = min(_PRED_BLOCK, K)
    R = np.empty((T, Mx))
    At = np.empty((K, T))
    Wp = np.empty((T, K))
    Wt = np.empty((K, T))
    Dt = np.empty((nbmax, T))
    Gbs = np.empty(((K + nbmax - 1) // nbmax, nbmax, nbmax))
    nx = np.empty(K)
    gain = np.empty(K)  # g_xy / tau_k
    half_tau = np.empty(K)
    half_log = np.empty(K)
    sd_on = np.empty(K)
    streams = seeds.copy()  # one stream per test point, advanced sample after sample
    for l in range(L):
        g_s = gs[l]
        g_xy = gxy[l]
        Dxl = np.ascontiguousarray(Dx[l])
        for k in range(K):
            nx[k] = _dot_rows(Dxl, k, Dxl, k, Mx)
            tau = g_s + g_xy * nx[k]
            gain[k] = g_xy / tau
            half_tau[k] = 0.5 * tau
            half_log[k] = 0.5 * np.log(g_s / tau)
            sd_on[k] = 1.0 / np.sqrt(tau)
        for t in range(T):
            for k in range(K):
                Wp[t, k] = 0.0
            for q in range(nj):
                for k in range(K):
                    Wp[t, k] += Ws[l, nbr[t, q], k]
            for k in range(K):
                Wp[t, k] /= nj
            for m in range(Mx):
                R[t, m] = Xt[t, m]
        _transpose_into(Wp, Wt)
        for k0 in range(0, K, nbmax):  # the Gram matrices of the atom blocks, once per sample
            k1 = min(k0 + nbmax, K)
            Gbs[k0 // nbmax, : k1 - k0, : k1 - k0] = Dxl[k0:k1] @ Dxl[k0:k1].T
        At[:, :] = 0.0
        Rt = R.T
        for _ in range(n_sweeps):
            for k0 in range(0, K, nbmax):
                k1 = min(k0 + nbmax, K)
                nb = k1 - k0
                Db = Dxl[k0:k1]
                Ct = Db @ Rt
                _predict_block(
                    Ct,
                    Gbs[k0 // nbmax],
                    At,
                    Dt,
                    Wt,
                    streams,
                    k0,
                    nb,
                    nx,
                    gain,
                    half_tau,
                    half_log,
                    sd_on,
                )
                R += Dt[:nb].T @ Db
        Yl = At.T @ np.ascontiguousarray(Dy[l])
        for t in range(T):
            for m in range(My):
                out_y[t, l, m] = Yl[t, m]
            rr = _dot_rows(R, t, R, t, Mx)
            out_ll[t, l] = 0.5 * Mx * (np.log(g_xy) - np.log(2.0 * np.pi)) - 0.5 * g_xy * rr


@njit(cache=True)
def predict_kernel_prior_codes(Xt, nbr, Dx, Dy, Ws, gs, gxy, seeds, out_y, out_ll):
    """Posterior predictive draws with the codes' on/off pattern drawn from the logits alone (the paper's text).

    The paper's Section "Pose Prediction" draws ``z_t ~ P(z_t | w_t)`` with ``w_t`` from the neighbours' logits
    and weights samples by ``N(x_t; D^x alpha_t, 1/g_xy I)``. Here, for test point t and sample l:
    ``w_t = mean_{i in J_t} W^l[i, :]``; ``z_tk ~ Bernoulli(sigmoid(w_tk))`` independently, NOT conditioned on
    x_t; then the active weights s_A exactly from their Gaussian given x_t and z_t:
    precision ``P = g_s I + g_xy D^x_A D^x_A^T`` (rows of D^x_A are the active atoms' feature parts), mean
    ``g_xy P^-1 D^x_A x_t``, drawn as ``L^-T (L^-1 g_xy D^x_A x_t + eps)`` with ``P = L L^T``.
    ``out_y[t, l] = D^y alpha_t`` and ``out_ll[t, l] = log N(x_t; D^x alpha_t, 1/g_xy I)`` (the paper's weights
    beta). Random numbers per test point on its splitmix64 stream (as predict_kernel): per sample K uniforms
    (atom order), then one ziggurat normal per active atom (atom order). Shapes as in predict_kernel.
    """
    T, Mx = Xt.shape
    L, K, _ = Dx.shape
    My = out_y.shape[2]
    nj = nbr.shape[1]
    streams = seeds.copy()
    wt = np.empty(K)
    act = np.empty(K, dtype=np.int64)
    for l in range(L):
        g_s = gs[l]
        g_xy = gxy[l]
        Dxl = np.ascontiguousarray(Dx[l])
        G = Dxl @ Dxl.T
        for t in range(T):
            for k in range(K):
                wt[k] = 0.0
            for q in range(nj):
                for k in range(K):
                    wt[k] += Ws[l, nbr[t, q], k]
            st = streams[t]
            na = 0
            for k in range(K):
                w = wt[k] / nj
                st, u = _uniform(st)
                if u * (1.0 + np.exp(-w)) < 1.0:  # u < sigmoid(w)
                    act[na] = k
                    na += 1
            c = np.empty(na)
            for a in range(na):
                c[a] = g_xy * _dot_rows(Dxl, act[a], Xt, t, Mx)
            s = np.empty(na)
            if na > 0:
                P = np.empty((na, na))
                for a in range(na):
                    for b in range(na):
                        P[a, b] = g_xy * G[act[a], act[b]]
                    P[a, a] += g_s
                Lc = np.linalg.cholesky(P)
                for a in range(na):  # forward: L c' = c
                    acc = c[a]
                    for b in range(a):
                        acc -= Lc[a, b] * c[b]
                    c[a] = acc / Lc[a, a]
                for a in range(na):
                    st, z = _normal(st)
                    c[a] += z
                for a in range(na - 1, -1, -1):  # backward: L^T s = c' + eps
                    acc = c[a]
                    for b in range(a + 1, na):
                        acc -= Lc[b, a] * s[b]
                    s[a] = acc / Lc[a, a]
            streams[t] = st
            for m in range(My):
                out_y[t, l, m] = 0.0
            rr = 0.0
            for m in range(Mx):
                v = Xt[t, m]
                for a in range(na):
                    v -= s[a] * Dxl[act[a], m]
                rr += v * v
            for a in range(na):
                for m in range(My):
                    out_y[t, l, m] += s[a] * Dy[l, act[a], m]
            out_ll[t, l] = 0.5 * Mx * (np.log(g_xy) - np.log(2.0 * np.pi)) - 0.5 * g_xy * rr


@njit(cache=True)
def nearest_neighbours(Xt, Xtr, j):
    """Indices (T, j) of the j nearest rows of Xtr for each row of Xt (Euclidean; ties by lower index).

    Computed row by row, so a test point's neighbours do not depend on the other points in the batch.
    """
    T = Xt.shape[0]
    N, Mx = Xtr.shape
    out = np.empty((T, j), dtype=np.int64)
    dist = np.empty(N)
    for t in range(T):
        for i in range(N):
            acc = 0.0
            for m in range(Mx):
                diff = Xt[t, m] - Xtr[i, m]
                acc += diff * diff
            dist[i] = acc
        order = np.argsort(dist, kind="mergesort")
        out[t, :] = order[:j]
    return out
