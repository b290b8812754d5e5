"""Numba kernel of DDL's Lasso coding: FISTA over all rows at once (Beck & Teboulle, SIAM J. Imaging Sci. 2009).

The iteration is that of the plain NumPy loop it replaces, step for step (``W = V - (V G - Z D^T) / L``, soft
threshold, momentum, stop when the largest change of a code is below ``tol``); only the order of the sums in
``V G`` differs, so the codes agree to rounding. One pass per iteration does the elementwise steps (NumPy makes
about ten temporaries), and ``V G`` is taken over the non-zero entries of each row of V when V is sparse (Lasso
codes mostly are), else as one matrix product.
"""

import numpy as np
from numba import njit

# below this fraction of non-zero entries in V, V G is summed over the non-zero entries of each row
_SPARSE_FRACTION = 0.25


@njit(cache=True)
def _times_gram(V, G, out, idx):
    """out = V G, as one matrix product or, for a sparse V, row by row over the non-zero entries of V."""
    n, K = V.shape
    nnz = 0
    for i in range(n):
        for k in range(K):
            if V[i, k] != 0.0:
                nnz += 1
    if nnz > _SPARSE_FRACTION * n * K:
        np.dot(V, G, out)
        return
    for i in range(n):
        m = 0
        for k in range(K):
            if V[i, k] != 0.0:
                idx[m] = k
                m += 1
        for c in range(K):
            out[i, c] = 0.0
        for q in range(m):
            k = idx[q]
            v = V[i, k]
            for c in range(K):
                out[i, c] += v * G[k, c]


@njit(cache=True, error_model="numpy")
def _step(V, VG, ZD, C, L, thr, beta, tol):
    """One FISTA step after ``VG = V G``, in place: ``C <- soft(V - (VG - ZD) / L, thr)``, ``V <- C + beta
    (C - C_old)``; returns how many codes changed by ``tol`` or more. Branch-free, so the loop vectorizes
    (NumPy's error model: no zero-division branch)."""
    n, K = C.shape
    big = 0
    for i in range(n):
        for k in range(K):
            w = V[i, k] - (VG[i, k] - ZD[i, k]) / L
            a = abs(w) - thr
            c_new = np.copysign(a if a > 0.0 else 0.0, w)  # sign(w) max(|w| - thr, 0)
            diff = c_new - C[i, k]
            V[i, k] = c_new + beta * diff
            C[i, k] = c_new
            big += abs(diff) >= tol
    return big


@njit(cache=True)
def fista_codes(ZD, G, L, alpha, C, n_iter, tol):
    """FISTA for ``argmin_C 0.5 ||Z - C D||^2 + alpha ||C||_1`` given ``ZD = Z D^T`` (n, K), ``G = D D^T``
    (K, K) and the step's Lipschitz constant ``L`` (the largest eigenvalue of G). ``C`` (n, K) holds the start
    and is overwritten with the result; stops after ``n_iter`` iterations or when no code changed by ``tol``
    or more; returns the number of iterations run."""
    n, K = C.shape
    V = C.copy()
    VG = np.empty((n, K))
    idx = np.empty(K, dtype=np.int64)
    t = 1.0
    thr = alpha / L
    it = 0
    while it < n_iter:
        it += 1
        _times_gram(V, G, VG, idx)
        t_new = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * t * t))
        big = _step(V, VG, ZD, C, L, thr, (t - 1.0) / t_new, tol)
        t = t_new
        if big == 0:
            break
    return it


@njit(cache=True)
def update_atoms(D, A, B, k0):
    """Block-coordinate atom update (Mairal, Bach, Ponce & Sapiro, JMLR 2010, Algorithm 2) of atoms k0, k0 + 1,
    ... in place: ``d_k <- d_k + (B[:, k] - D^T A[:, k]) / A[k, k]``, then ``d_k / max(||d_k||, 1)``, each with
    the atoms before it already updated. ``A = C^T C`` (K, K), ``B = Z^T C`` (p, K). Stops at the first unused
    atom (``A[k, k] < 1e-12``, which the caller re-draws from the data) and returns its index, or K."""
    K, p = D.shape
    d = np.empty(p)
    for k in range(k0, K):
        akk = A[k, k]
        if akk < 1e-12:
            return k
        for m in range(p):
            acc = 0.0
            for j in range(K):
                acc += D[j, m] * A[j, k]
            d[m] = D[k, m] + (B[m, k] - acc) / akk
        nrm = np.sqrt(np.dot(d, d))
        scale = max(nrm, 1.0)
        for m in range(p):
            D[k, m] = d[m] / scale
    return K
