"""Numba kernels of the Bayesian sparse-representation (BSR) Gibbs sampler.

Model and conditionals: Babagholami-Mohamadabadi, Jourabloo, Zarghami & Kasaei, "A Bayesian Framework for
Sparse Representation-Based 3D Human Pose Estimation" (IEEE SPL 2014), Section III and Appendix A, with the
corrections of the project's model reference (docs "MODEL.md"): the (b, s) block update with s integrated out
for b, the atom precision ``g + g_xy sum_i alpha_ki^2`` (the paper prints the square of the sum), and the
Metropolis-Hastings acceptance ratio of the bound-based proposal ``w' ~ N(Sigma Lambda(w), Sigma)`` that
depends on the current state (the paper treats it as an independence chain, which is wrong). Elliptical slice
sampling is from Murray, Adams & MacKay, "Elliptical slice sampling" (AISTATS 2010).

Layout (all C-contiguous float64 unless noted):

- ``V`` (N, M): the data, one training pair ``[x_i; y_i]`` per row; the first ``Mx`` columns are features.
- ``D`` (K, M): the dictionaries, one atom ``d_k = [d^x_k; d^y_k]`` per row (contiguous atoms).
- ``norms`` (K,): ``||d_k||^2``.
- ``B`` (N, K) int8 and ``S`` (N, K): codes ``alpha_ki = B[i, k] * S[i, k]``.
- ``R`` (N, M): the residual ``V - A^T D``, updated in place by the code update.
- ``W`` (N, K): the logits ``w_ik``; atom k's logit vector is the column ``W[:, k]``.
- ``prec`` (4,): ``[g_s, g_xy, g_x, g_y]``.
- ``Sigma`` (N, N) and its lower Cholesky factor ``Lw``.

Every random draw comes from the ``numpy.random.Generator`` passed in (numba shares its bit generator with
the Python object), in a fixed, documented order, so the plain NumPy reference ``tests/naive.py`` fed the
same Generator reproduces the kernels draw for draw. Prediction uses a counter-based stream per test point
(splitmix64 seeded by a hash of the point and a fitted seed; ziggurat normals), so a prediction does not depend
on which other points are in the batch.
"""

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..errors import InputError, SamplerError

# Vectorizable reductions: reassociation and FMA contraction only (no nnan/ninf: the MH step uses -inf).
_VEC = {"reassoc", "contract"}

W_UPDATES = {"mh": 0, "ess": 1, "paper-as-printed": 2}
ATOM_UPDATES = {"block": 0, "single": 1}

# Test points whose code sweeps are interleaved atom by atom in prediction.
_PRED_BLOCK = 8

# Above this logit, 1 + exp(-logit) rounds to 1 in float64, so "u < sigmoid(logit)" holds for every u in [0, 1):
# prediction then skips the exp and the uniform (the reference in tests/naive.py does the same).
_LOGIT_SURE = 37.0


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


@njit(cache=True, fastmath=_VEC)
def _trsv_rows(L, Z, j0, j1, transpose):
    """Unblocked triangular solve on rows j0:j1 of Z (in place) with the diagonal block L[j0:j1, j0:j1]:
    ``L_b X = Z_b`` (forward) or ``L_b^T X = Z_b`` (backward, ``transpose``). Indexed, no row views."""
    ncol = Z.shape[1]
    if not transpose:
        for j in range(j0, j1):
            for i in range(j0, j):
                lji = L[j, i]
                for m in range(ncol):
                    Z[j, m] -= lji * Z[i, m]
            inv = 1.0 / L[j, j]
            for m in range(ncol):
                Z[j, m] *= inv
    else:
        for j in range(j1 - 1, j0 - 1, -1):
            for i in range(j + 1, j1):
                lij = L[i, j]
                for m in range(ncol):
                    Z[j, m] -= lij * Z[i, m]
            inv = 1.0 / L[j, j]
            for m in range(ncol):
                Z[j, m] *= inv


@njit(cache=True)
def _forward_solve(L, Z, nb=48):
    """Solve L X = Z in place (L lower triangular K x K; Z (K, m) row-major); blocked, off-diagonal
    blocks by matrix products (BLAS-3)."""
    K = L.shape[0]
    for j0 in range(0, K, nb):
        j1 = min(j0 + nb, K)
        if j0 > 0:
            Z[j0:j1] -= np.ascontiguousarray(L[j0:j1, :j0]) @ Z[:j0]
        _trsv_rows(L, Z, j0, j1, False)


@njit(cache=True)
def _backward_solve_t(L, Z, nb=48):
    """Solve L^T X = Z in place (L lower triangular K x K; Z (K, m) row-major); blocked as above."""
    K = L.shape[0]
    nblk = (K + nb - 1) // nb
    for b in range(nblk - 1, -1, -1):
        j0 = b * nb
        j1 = min(j0 + nb, K)
        if j1 < K:
            Z[j0:j1] -= np.ascontiguousarray(L[j1:, j0:j1].T) @ Z[j1:]
        _trsv_rows(L, Z, j0, j1, True)


# ----------------------------------------------------------------------------------------------------------
# the updates (each mutates the state in place)
# ----------------------------------------------------------------------------------------------------------
@njit(cache=True)
def _adjacent_gram(D, lo, hi):
    """g[k] = d_k . d_{k+1} over columns lo:hi (g[K-1] = 0): the look-ahead correction of the code update."""
    K = D.shape[0]
    g = np.zeros(K)
    for k in range(K - 1):
        g[k] = _dot(D[k, lo:hi], D[k + 1, lo:hi])
    return g


@njit(cache=True)
def update_codes(R, D, norms, B, S, W, g_s, g_xy, rng):
    """Joint (b_ki, s_ki) block update for every data point i and atom k (i outer, k inner).

    With ``tau = g_s + g_xy ||d_k||^2`` and ``mu = g_xy d_k^T r_i^(-k) / tau``:
    ``logit P(b=1) = w_ik + 0.5 log(g_s / tau) + 0.5 tau mu^2``; ``s ~ N(mu, 1/tau)`` if b = 1 else
    ``s ~ N(0, 1/g_s)``. Draw order per point i: K uniforms (for b_i1..b_iK), then K standard normals (s).
    The residual row r_i is updated in place by ``d_k (alpha_old - alpha_new)``: O(M) per (i, k).
    Software-pipelined: ``d_{k+1} . r`` is computed before atom k's change ``delta`` is known and corrected
    by ``delta d_k . d_{k+1}``, so the next dot product overlaps the current atom's scalar work.
    """
    N, K = B.shape
    M = R.shape[1]
    tau = np.empty(K)
    half_log = np.empty(K)
    sd_on = np.empty(K)
    sd_off = 1.0 / np.sqrt(g_s)
    for k in range(K):
        tau[k] = g_s + g_xy * norms[k]
        half_log[k] = 0.5 * np.log(g_s / tau[k])
        sd_on[k] = 1.0 / np.sqrt(tau[k])
    gnext = _adjacent_gram(D, 0, M)
    U = np.empty(K)
    Zn = np.empty(K)
    for i in range(N):
        # this point's random numbers up front: no opaque generator calls inside the atom loop
        for k in range(K):
            U[k] = rng.random()
        for k in range(K):
            Zn[k] = rng.standard_normal()
        proj_next = _dot_rows(R, i, D, 0, M)
        for k in range(K):
            proj = proj_next
            if k + 1 < K:
                proj_next = _dot_rows(R, i, D, k + 1, M)  # r without atom k's change (added below)
            a_old = S[i, k] if B[i, k] else 0.0
            mu = g_xy * (proj + a_old * norms[k]) / tau[k]
            logit = W[i, k] + half_log[k] + 0.5 * tau[k] * mu * mu
            # u < sigmoid(logit), branch-free (exp(-logit) = inf gives False, as it should for u > 0)
            on = U[k] * (1.0 + np.exp(-logit)) < 1.0
            z = Zn[k]
            s_on = mu + z * sd_on[k]
            s = s_on if on else z * sd_off
            a_new = s_on if on else 0.0
            delta = a_old - a_new
            if delta != 0.0:
                _axpy_rows(delta, D, k, R, i, M)
                proj_next += delta * gnext[k]
            B[i, k] = 1 if on else 0
            S[i, k] = s


@njit(cache=True)
def update_atoms(V, R, D, norms, B, S, g_xy, g_x, g_y, Mx, rng):
    """Draw all atoms given the codes, then recompute the residual.

    Given the codes the rows of D^x are independent with the common K x K precision
    ``P = g_x I + g_xy A A^T`` (A = codes, K x N): ``D^x^T = U^-1 (U^-T g_xy A X^T + E)`` with
    ``P = U^T U``; likewise D^y with g_y. One Cholesky per dictionary and sweep. Draw order: one
    (K, M) array of standard normals E (columns < Mx for D^x, the rest for D^y).
    """
    K, M = D.shape
    A = _codes_from(B, S)
    G = A.T @ A
    AV = A.T @ V
    E = rng.standard_normal((K, M))
    for part in range(2):
        if part == 0:
            lo, hi, g = 0, Mx, g_x
        else:
            lo, hi, g = Mx, M, g_y
        if hi == lo:
            continue
        P = g_xy * G
        for k in range(K):
            P[k, k] += g
        Lc = np.linalg.cholesky(P)
        Z = np.ascontiguousarray(AV[:, lo:hi]) * g_xy
        _forward_solve(Lc, Z)
        Z += E[:, lo:hi]
        _backward_solve_t(Lc, Z)
        D[:, lo:hi] = Z
    _row_norms(D, norms)
    R[:, :] = V - A @ D


@njit(cache=True, fastmath=_VEC, error_model="numpy")
def update_atoms_single(R, D, norms, B, S, g_xy, g_x, g_y, Mx, rng):
    """Draw the atoms one at a time (the paper's Gibbs scheme, with the corrected precision), in place.

    ``d^x_k | rest ~ N(g_xy sum_i alpha_ki x_i^(-k) / p, I / p)`` with ``p = g_x + g_xy sum_i alpha_ki^2``
    (likewise ``d^y_k`` with g_y); then ``r_i -= alpha_ki (d_k' - d_k)`` for the points that use atom k.
    O(nnz_k M) per atom, O(N K M) at most per sweep, against O(K^2 (N + M) + K^3) for the block update; the
    block update mixes better per sweep when atoms are correlated. Draw order: one (K, M) array of standard
    normals E, row k for atom k (as in update_atoms).
    """
    N, K = B.shape
    M = D.shape[1]
    E = rng.standard_normal((K, M))
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
        py = g_y + g_xy * sa2
        cx, sx = g_xy / px, 1.0 / np.sqrt(px)
        cy, sy = g_xy / py, 1.0 / np.sqrt(py)
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


@njit(cache=True)
def update_precisions(R, D, S, prec, Mx, a0, b0, rng):
    """Gamma conditionals of g_s, g_xy, g_x, g_y (shape/rate; drawn in this order).

    g_s ~ Gamma(a + NK/2, b + sum s^2 / 2) over all N K weights (active or not);
    g_xy ~ Gamma(a + NM/2, b + ||R||^2 / 2); g_x ~ Gamma(a + Mx K/2, b + ||D^x||^2 / 2); g_y likewise.
    """
    N, K = S.shape
    M = D.shape[1]
    My = M - Mx
    ss = _sum_sq(S)
    rr = _sum_sq(R)
    dx = 0.0
    dy = 0.0
    for k in range(K):
        for m in range(Mx):
            dx += D[k, m] * D[k, m]
        for m in range(Mx, M):
            dy += D[k, m] * D[k, m]
    prec[0] = rng.gamma(a0 + 0.5 * N * K, 1.0 / (b0 + 0.5 * ss))
    prec[1] = rng.gamma(a0 + 0.5 * N * M, 1.0 / (b0 + 0.5 * rr))
    prec[2] = rng.gamma(a0 + 0.5 * Mx * K, 1.0 / (b0 + 0.5 * dx))
    if My > 0:
        prec[3] = rng.gamma(a0 + 0.5 * My * K, 1.0 / (b0 + 0.5 * dy))


@njit(cache=True)
def _signs_t(B):
    """z = 2 b - 1, transposed to (K, N) so that atom k's vector is a contiguous row."""
    N, K = B.shape
    Zt = np.empty((K, N))
    for i in range(N):
        for k in range(K):
            Zt[k, i] = 1.0 if B[i, k] else -1.0
    return Zt


# Log-ratio sums in the MH step are taken as logs of running products, flushed every _FLUSH factors; factors
# outside [_TINY, 1/_TINY] are added as exact logs, so a product stays within 1e-240..1e240.
_FLUSH = 8
_TINY = 1e-30

# exp(-a) without a libm call, so that loops over it vectorize (with 'reassoc' for the reductions): a is clamped
# to [0, 708] (exp(-708) is still a normal number), a = k ln2 + r with |r| <= ln2 / 2 (ln2 split in two parts,
# as in fdlibm), exp(-r) by its Taylor polynomial of degree 13 (truncation < 4e-18 relative) and 2^-k from the
# ten bits of k (no table gather).
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_LOG2E = 1.4426950408889634
_EXP_CLAMP = 708.0
# Taylor coefficients 1 / j! of exp, highest degree first (j = 13 .. 0), for Horner's scheme
_EXP_TAYLOR = tuple(1.0 / math.factorial(j) for j in range(13, -1, -1))
# 2^-(2^j) for j = 0 .. 9: 2^-k is the product of those whose bit j is set in k (0 <= k <= 1021)
_POW2_NEG = tuple(2.0 ** -(2**j) for j in range(10))
# terms per logged product in _sum_log_sigmoid: factors are in [1, 2], so a product stays below 2^512
_LOG_CHUNK = 512


@njit(cache=True, inline="always", fastmath=_VEC)
def _exp_neg(a):
    """exp(-a) for a >= 0 (a > _EXP_CLAMP gives exp(-_EXP_CLAMP)); relative error about 1e-16."""
    a = min(a, _EXP_CLAMP)
    k = np.int64(a * _LOG2E + 0.5)
    q = (k * _LN2_HI - a) + k * _LN2_LO  # -r
    p = 0.0
    for c in _EXP_TAYLOR:
        p = p * q + c
    scale = 1.0
    for j in range(10):
        if (k >> j) & 1:
            scale *= _POW2_NEG[j]
    return p * scale


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
def _bound_terms(Zt, Wt, Lam, Sig):
    """Lam = z sigmoid(-z w) (the gradient of log sigmoid(z w): the tight bound's Lambda) and
    Sig = sigmoid(z w), elementwise over (K, N) arrays. NumPy's error model: numba's default checks every
    float division for zero (1 + e > 0 here), and that branch keeps the loop from vectorizing."""
    K, N = Wt.shape
    for k in range(K):
        for i in range(N):
            sg, sm = _sig_pair(Zt[k, i] * Wt[k, i])
            Sig[k, i] = sg
            Lam[k, i] = Zt[k, i] * sm


@njit(cache=True)
def update_w_mh(W, B, Sigma, Lw, rng, paper_as_printed=False):
    """Metropolis-Hastings update of every logit vector w_k with the bound-based proposal.

    Proposal (paper, Appendix A, with the tight bound lambda_i = sigmoid(-z_i w_i)):
    ``w' ~ N(mu, Sigma)``, ``mu = Sigma Lambda(w)``, drawn as ``mu + Lw eps``. The correct log acceptance
    ratio (the proposal depends on w, so it is not an independence chain) is
    ``sum_i [log sig(z_i w'_i) - log sig(z_i w_i)] + w . Lambda' - w' . Lambda + (Lambda . mu - Lambda' . mu')/2``.
    With ``paper_as_printed`` the paper's printed ratio ``sum_i [...] - Lambda . (w' - w)`` is used instead
    (wrong target; an ablation only). All K atoms are batched as matrix products (Sigma is symmetric, so
    atom-major (K, N) arrays are multiplied from the right). Draw order: a (K, N) array of standard normals
    (row k for atom k), then K uniforms. Returns the number of accepted atoms.
    """
    N, K = W.shape
    Zt = _signs_t(B)
    Wt = np.ascontiguousarray(W.T)
    Lam = np.empty((K, N))
    Sig = np.empty((K, N))
    _bound_terms(Zt, Wt, Lam, Sig)
    Mu = Lam @ Sigma
    Wp = Mu + rng.standard_normal((K, N)) @ Lw.T
    Lamp = np.empty((K, N))
    Sigp = np.empty((K, N))
    _bound_terms(Zt, Wp, Lamp, Sigp)
    Mup = Mu if paper_as_printed else Lamp @ Sigma
    U = rng.random(K)
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
            if paper_as_printed:
                lr -= Lam[k, i] * (Wp[k, i] - Wt[k, i])
            else:
                lr += (Wt[k, i] * Lamp[k, i] - Wp[k, i] * Lam[k, i]
                       + 0.5 * (Lam[k, i] * Mu[k, i] - Lamp[k, i] * Mup[k, i]))
        lr += np.log(prod)
        if np.log(U[k]) < lr:
            accepted += 1
            for i in range(N):
                W[i, k] = Wp[k, i]
    return accepted


@njit(cache=True)
def update_w_ess(W, B, Lw, rng):
    """Elliptical slice sampling (Murray, Adams & MacKay 2010) of every w_k, prior N(0, Sigma = Lw Lw^T).

    Draw order: one (K, N) array of standard normals (row k gives atom k's ellipse ``nu = Lw eps_k``); then
    per atom k: one uniform for the slice height, one for the initial angle, one per shrinkage step.
    Returns K (every update moves).
    """
    N, K = W.shape
    Zt = _signs_t(B)
    Wt = np.ascontiguousarray(W.T)
    Nu = rng.standard_normal((K, N)) @ Lw.T
    wp = np.empty(N)
    two_pi = 2.0 * np.pi
    for k in range(K):
        wk = Wt[k]
        zk = Zt[k]
        nk = Nu[k]
        log_y = _sum_log_sigmoid(zk, wk) + np.log(rng.random())
        theta = rng.random() * two_pi
        lo = theta - two_pi
        hi = theta
        while True:
            c = np.cos(theta)
            sn = np.sin(theta)
            for i in range(N):
                wp[i] = wk[i] * c + nk[i] * sn
            if _sum_log_sigmoid(zk, wp) > log_y:
                break
            if theta < 0.0:
                lo = theta
            else:
                hi = theta
            if hi - lo < 1e-300:  # cannot happen for a finite log-likelihood; guard against a hang
                wp[:] = wk
                break
            theta = lo + rng.random() * (hi - lo)
        for i in range(N):
            W[i, k] = wp[i]
    return K


@njit(cache=True)
def log_likelihood(R, g_xy):
    """log p(V | D, A, g_xy) = N M / 2 log(g_xy / 2 pi) - g_xy ||R||^2 / 2."""
    n = R.size
    return 0.5 * n * (np.log(g_xy) - np.log(2.0 * np.pi)) - 0.5 * g_xy * _sum_sq(R)


@njit(cache=True)
def _sweep(V, R, D, norms, B, S, W, prec, Sigma, Lw, Mx, a0, b0, w_code, atom_code, rng, stats):
    """One full Gibbs sweep: codes, atoms (+ residual), precisions, logits. Writes
    ``stats = [log-likelihood, number of active atoms, fraction of accepted logit moves]``."""
    update_codes(R, D, norms, B, S, W, prec[0], prec[1], rng)
    if atom_code == 1:
        update_atoms_single(R, D, norms, B, S, prec[1], prec[2], prec[3], Mx, rng)
    else:
        update_atoms(V, R, D, norms, B, S, prec[1], prec[2], prec[3], Mx, rng)
    update_precisions(R, D, S, prec, Mx, a0, b0, rng)
    K = W.shape[1]
    if w_code == 1:
        acc = update_w_ess(W, B, Lw, rng)
    else:
        acc = update_w_mh(W, B, Sigma, Lw, rng, w_code == 2)
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
def redraw_data(V, R, D, B, S, g_xy, rng):
    """Replace V by a draw from the likelihood ``V = A D + E / sqrt(g_xy)`` and set R = V - A D.

    Draw order: one (N, M) array of standard normals. Used by the Geweke test and for simulation.
    """
    E = rng.standard_normal(V.shape) / np.sqrt(g_xy)
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
    prec: np.ndarray  # [g_s, g_xy, g_x, g_y]


class BSRData(NamedTuple):
    """Observed data and the fixed logit prior: ``V = [X | Y]`` (N, M), ``Mx``, ``Sigma`` and its factor."""

    V: np.ndarray
    Mx: int
    Sigma: np.ndarray
    Lw: np.ndarray


class BSRHyper(NamedTuple):
    """Gamma(a0, b0) (shape, rate) hyper-prior of all four precisions."""

    a0: float = 1e-6
    b0: float = 1e-6


def gibbs_sweep(state, data, hyper, rng, w_update="mh", atom_update="block"):
    """Run one full Gibbs sweep (a single jitted call); returns ``(state, stats)``.

    ``state`` is updated in place and returned; ``stats`` is ``[log-likelihood, active atoms, acceptance]``.
    ``w_update`` is ``"mh"`` (corrected MH), ``"ess"`` (elliptical slice) or ``"paper-as-printed"``;
    ``atom_update`` is ``"block"`` (all atoms jointly, update_atoms) or ``"single"`` (one at a time).
    """
    if w_update not in W_UPDATES:
        raise InputError(f"w_update must be one of {sorted(W_UPDATES)}; got {w_update!r}")
    if atom_update not in ATOM_UPDATES:
        raise InputError(f"atom_update must be one of {sorted(ATOM_UPDATES)}; got {atom_update!r}")
    stats = np.zeros(3)
    _sweep(data.V, state.R, state.D, state.norms, state.B, state.S, state.W, state.prec, data.Sigma, data.Lw,
           data.Mx, float(hyper.a0), float(hyper.b0), W_UPDATES[w_update], ATOM_UPDATES[atom_update], rng,
           stats)
    return state, stats


def draw_from_prior(N, K, Mx, My, Sigma, Lw, a0, b0, rng):
    """Draw (state, V) from the joint prior (precisions, atoms, logits, codes, data). Needs proper a0, b0."""
    M = Mx + My
    prec = np.array([rng.gamma(a0, 1.0 / b0) for _ in range(4)])
    D = np.empty((K, M))
    D[:, :Mx] = rng.standard_normal((K, Mx)) / np.sqrt(prec[2])
    D[:, Mx:] = rng.standard_normal((K, My)) / np.sqrt(prec[3])
    W = Lw @ rng.standard_normal((N, K))
    B = (rng.random((N, K)) < 1.0 / (1.0 + np.exp(-W))).astype(np.int8)
    S = rng.standard_normal((N, K)) / np.sqrt(prec[0])
    V = (B * S) @ D + rng.standard_normal((N, M)) / np.sqrt(prec[1])
    R = V - (B * S) @ D
    state = BSRState(D=D, norms=np.einsum("km,km->k", D, D), B=B, S=S, W=W, R=R, prec=prec)
    return state, V


# ----------------------------------------------------------------------------------------------------------
# logit prior
# ----------------------------------------------------------------------------------------------------------
def logit_prior_cov(Y):
    """Sigma_w(i, j) = exp(-||y_i - y_j|| / eta), eta = 2 sum_{i<j} ||y_i - y_j||^2 / (N (N - 1)) (paper, Sec. IV)."""
    Y = np.asarray(Y, dtype=float)
    N = Y.shape[0]
    sq = np.einsum("ij,ij->i", Y, Y)
    d2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * Y @ Y.T, 0.0)
    np.fill_diagonal(d2, 0.0)
    eta = d2[np.triu_indices(N, 1)].sum() * 2.0 / (N * (N - 1)) if N > 1 else 1.0
    if not eta > 0.0:
        eta = 1.0  # all poses identical: the kernel is constant; any eta gives the same matrix
    return np.exp(-np.sqrt(d2) / eta), eta


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
        if i == 0:  # the tail beyond r (Marsaglia 1964): x = r + e1 / r, accepted if 2 e2 > (e1 / r)^2
            while True:
                state, u1 = _uniform(state)
                state, u2 = _uniform(state)
                xt = -np.log1p(-u1) / ZIG_R
                if -2.0 * np.log1p(-u2) > xt * xt:
                    break
            x = ZIG_R + xt
            return state, -x if neg else x
        state, u = _uniform(state)  # the wedge of layer i: accept if y ~ U[f(x_i), f(x_i+1)] is under f(x)
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


@njit(cache=True, fastmath=_VEC)
def predict_kernel(Xt, nbr, Dx, Dy, Ws, gs, gxy, n_sweeps, seeds, out_y, out_ll):
    """Posterior predictive draws of y for every test point and retained sample.

    For test point t and sample l: ``w_t = mean_{i in J_t} W^l[i, :]`` (J_t = its neighbours, ``nbr[t]``);
    ``n_sweeps`` sweeps of the (b, s) block update restricted to the feature rows, from zero codes;
    ``out_y[t, l] = D^y alpha_t``; ``out_ll[t, l] = log N(x_t; D^x alpha_t, 1/g_xy I)`` (for the paper's
    likelihood weights). Random numbers: a splitmix64 stream per test point seeded by ``seeds[t]`` (per atom
    one uniform unless the logit exceeds ``_LOGIT_SURE``, where P(on) is 1 in float64; then one ziggurat
    normal if the atom is on), so a point's prediction does not depend on the
    batch. Samples are the outer loop (one sample's dictionaries stay in cache for all test points); blocks
    of ``_PRED_BLOCK`` test points are interleaved atom by atom, and the residual update of atom k is fused
    with the projection on atom k + 1 (one pass over the residual per atom).
    Shapes: Xt (T, Mx); nbr (T, j); Dx (L, K, Mx); Dy (L, K, My); Ws (L, N, K); gs, gxy (L,).
    """
    T, Mx = Xt.shape
    L, K, _ = Dx.shape
    My = out_y.shape[2]
    nj = nbr.shape[1]
    P = _PRED_BLOCK
    r = np.empty((P, Mx))  # residuals of a block of test points
    alpha = np.empty((P, K))
    wt = np.empty((P, K))
    pn = np.empty(P)
    nx = np.empty(K)
    gain = np.empty(K)  # g_xy / tau_k
    half_tau = np.empty(K)
    half_log = np.empty(K)
    sd_on = np.empty(K)
    streams = seeds.copy()  # one stream per test point, advanced sample after sample
    for l in range(L):
        g_s = gs[l]
        g_xy = gxy[l]
        Dxl = Dx[l]
        for k in range(K):
            nx[k] = _dot_rows(Dxl, k, Dxl, k, Mx)
            tau = g_s + g_xy * nx[k]
            gain[k] = g_xy / tau
            half_tau[k] = 0.5 * tau
            half_log[k] = 0.5 * np.log(g_s / tau)
            sd_on[k] = 1.0 / np.sqrt(tau)
        for t0 in range(0, T, P):
            nb = min(P, T - t0)
            for p in range(nb):
                t = t0 + p
                for k in range(K):
                    wt[p, k] = 0.0
                for q in range(nj):
                    for k in range(K):
                        wt[p, k] += Ws[l, nbr[t, q], k]
                for k in range(K):
                    wt[p, k] /= nj
                    alpha[p, k] = 0.0
                for m in range(Mx):
                    r[p, m] = Xt[t, m]
            for _ in range(n_sweeps):
                for p in range(nb):
                    pn[p] = _dot_rows(Dxl, 0, r, p, Mx)
                for k in range(K):
                    for p in range(nb):
                        t = t0 + p
                        a_old = alpha[p, k]
                        mu = gain[k] * (pn[p] + a_old * nx[k])
                        logit = wt[p, k] + half_log[k] + half_tau[k] * mu * mu
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
                        alpha[p, k] = a_new
                        delta = a_old - a_new
                        if k + 1 < K:
                            if delta != 0.0:  # r += delta d_k and the projection on d_{k+1}, in one pass
                                acc = 0.0
                                for m in range(Mx):
                                    v = r[p, m] + delta * Dxl[k, m]
                                    r[p, m] = v
                                    acc += Dxl[k + 1, m] * v
                                pn[p] = acc
                            else:
                                pn[p] = _dot_rows(Dxl, k + 1, r, p, Mx)
                        elif delta != 0.0:
                            _axpy_rows(delta, Dxl, k, r, p, Mx)
            for p in range(nb):
                t = t0 + p
                for m in range(My):
                    out_y[t, l, m] = 0.0
                for k in range(K):
                    a = alpha[p, k]
                    if a != 0.0:
                        for m in range(My):
                            out_y[t, l, m] += a * Dy[l, k, m]
                rr = _dot_rows(r, p, r, p, Mx)
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
