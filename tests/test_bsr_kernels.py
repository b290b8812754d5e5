"""BSR kernels: equal to the NumPy reference draw for draw, and each conditional equal to a brute-force one."""

import math
import sys

import naive
import numpy as np
import pytest
from numba import njit
from scipy import stats
from scipy.special import expit

from bsrbench.models import _bsr_kernels as kern


def _problem(seed, N=7, K=5, Mx=4, My=3, a=3.0, b=3.0, **model):
    """A state and data drawn from the prior; ``model``: a_xy, b_xy, w_mean, noise (BSRHyper fields)."""
    rng = np.random.default_rng(seed)
    Yk = rng.standard_normal((N, 2))
    Sigma, eta = kern.logit_prior_cov(Yk)
    Lw, _ = kern.cholesky_with_jitter(Sigma, eta)
    hyper = kern.BSRHyper(a, b, **model)
    state, V = kern.draw_from_prior(N, K, Mx, My, Sigma, Lw, a, b, rng, hyper)
    data = kern.BSRData(V=V, Mx=Mx, Sigma=Sigma, Lw=Lw)
    return state, data, hyper


# model variants beyond the paper's: a noise prior of its own, separate noise precisions, a logit prior mean
MODEL_VARIANTS = {
    "paper": {},
    "noise-prior": {"a_xy": 1.5, "b_xy": 0.5},
    "separate": {"noise": "separate", "a_xy": 2.0, "b_xy": 1.0},
    "w-mean": {"w_mean": -1.0},
}


def _copy(state):
    return kern.BSRState(*[np.array(a, copy=True) for a in state])


def _assert_states_close(s1, s2):
    for name, a, b in zip(kern.BSRState._fields, s1, s2):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, err_msg=name)


# ---------------------------------------------------------------------------------------------------------
# kernels == naive reference, same Generator
# ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1])
def test_codes_match_naive(seed):
    s1, data, _ = _problem(seed)
    s2 = _copy(s1)
    p = s1.prec
    kern.update_codes(
        s1.R, s1.D, s1.norms, s1.B, s1.S, s1.W, p[0], p[1], np.random.default_rng(seed + 10)
    )
    naive.update_codes(
        s2.R, s2.D, s2.norms, s2.B, s2.S, s2.W, p[0], p[1], np.random.default_rng(seed + 10)
    )
    _assert_states_close(s1, s2)
    # the in-place residual equals a fresh one
    np.testing.assert_allclose(s1.R, data.V - (s1.B * s1.S) @ s1.D, atol=1e-10)


@pytest.mark.parametrize("K", [kern._CODE_BLOCK + 6, 2 * kern._CODE_BLOCK])
def test_codes_blocked_over_atoms_match_naive(K):
    """More atoms than one block of the code update (a full and a partial block, and two full ones): the
    between-block residual updates and within-block Gram corrections give the point-by-point chain."""
    s1, data, _ = _problem(9, N=13, K=K, Mx=6, My=3)
    s2 = _copy(s1)
    p = s1.prec
    assert 0.05 < s1.B.mean() < 0.95  # both branches of the update are exercised
    kern.update_codes(s1.R, s1.D, s1.norms, s1.B, s1.S, s1.W, p[0], p[1], np.random.default_rng(21))
    naive.update_codes(
        s2.R, s2.D, s2.norms, s2.B, s2.S, s2.W, p[0], p[1], np.random.default_rng(21)
    )
    _assert_states_close(s1, s2)
    np.testing.assert_allclose(s1.R, data.V - (s1.B * s1.S) @ s1.D, atol=1e-10)


@pytest.mark.parametrize("separate", [False, True])
def test_codes_without_residual_draw_the_same_codes(separate):
    """keep_residual=False (the sweep with block atoms, which recompute R): the same codes from the same draws;
    R is left as it was before the last block (over two blocks: after the first block's update)."""
    K = kern._CODE_BLOCK + 6
    s1, data, _ = _problem(9, N=13, K=K, Mx=6, My=3)
    s2, s0 = _copy(s1), _copy(s1)
    p = s1.prec
    if separate:
        args = (p[0], 0.7 * p[1], 1.9 * p[1], data.Mx)
        kern.update_codes_separate(s1.R, s1.D, s1.B, s1.S, s1.W, *args, np.random.default_rng(3))
        kern.update_codes_separate(
            s2.R, s2.D, s2.B, s2.S, s2.W, *args, np.random.default_rng(3), False
        )
    else:
        kern.update_codes(
            s1.R, s1.D, s1.norms, s1.B, s1.S, s1.W, p[0], p[1], np.random.default_rng(3)
        )
        kern.update_codes(
            s2.R, s2.D, s2.norms, s2.B, s2.S, s2.W, p[0], p[1], np.random.default_rng(3), False
        )
    np.testing.assert_array_equal(s1.B, s2.B)
    np.testing.assert_array_equal(s1.S, s2.S)
    if (
        not separate
    ):  # the stale R: the residual of the new codes of the first block, the old ones after it
        blk = kern._CODE_BLOCK
        A = s1.B * s1.S
        A[:, blk:] = (s0.B * s0.S)[:, blk:]
        np.testing.assert_allclose(s2.R, data.V - A @ s1.D, atol=1e-10)


@pytest.mark.parametrize("N, K", [(7, 5), (4, 9)])  # the K x K form and the N x N (Woodbury) form
@pytest.mark.parametrize("My", [3, 0])
def test_atoms_match_naive(My, N, K):
    s1, data, _ = _problem(3, N=N, K=K, My=My)
    s2 = _copy(s1)
    p = s1.prec
    kern.update_atoms(
        data.V,
        s1.R,
        s1.D,
        s1.norms,
        s1.B,
        s1.S,
        p[1],
        p[2],
        p[3],
        data.Mx,
        np.random.default_rng(5),
    )
    naive.update_atoms(
        data.V,
        s2.R,
        s2.D,
        s2.norms,
        s2.B,
        s2.S,
        p[1],
        p[2],
        p[3],
        data.Mx,
        np.random.default_rng(5),
    )
    _assert_states_close(s1, s2)


@pytest.mark.parametrize("My", [3, 0])
def test_single_site_atoms_match_naive(My):
    s1, data, _ = _problem(4, My=My)
    s2 = _copy(s1)
    p = s1.prec
    kern.update_atoms_single(
        s1.R, s1.D, s1.norms, s1.B, s1.S, p[1], p[2], p[3], data.Mx, np.random.default_rng(6)
    )
    naive.update_atoms_single(
        s2.R, s2.D, s2.norms, s2.B, s2.S, p[1], p[2], p[3], data.Mx, np.random.default_rng(6)
    )
    _assert_states_close(s1, s2)
    assert not np.allclose(s1.D, _problem(4, My=My)[0].D)
    # the in-place residual equals a fresh one
    np.testing.assert_allclose(s1.R, data.V - (s1.B * s1.S) @ s1.D, atol=1e-10)


@pytest.mark.parametrize("N", [30, 120])
def test_atoms_large_k(N):
    """Many atoms, in the N x N form (N < K) and the K x K one."""
    s1, data, _ = _problem(4, N=N, K=101, Mx=6, My=5)
    s2 = _copy(s1)
    p = s1.prec
    kern.update_atoms(
        data.V,
        s1.R,
        s1.D,
        s1.norms,
        s1.B,
        s1.S,
        p[1],
        p[2],
        p[3],
        data.Mx,
        np.random.default_rng(6),
    )
    naive.update_atoms(
        data.V,
        s2.R,
        s2.D,
        s2.norms,
        s2.B,
        s2.S,
        p[1],
        p[2],
        p[3],
        data.Mx,
        np.random.default_rng(6),
    )
    _assert_states_close(s1, s2)


@pytest.mark.parametrize("variant", ["paper", "noise-prior", "separate"])
@pytest.mark.parametrize("My", [3, 0])
def test_precisions_match_naive(variant, My):
    s, data, h = _problem(5, My=My, **MODEL_VARIANTS[variant])
    p1, p2 = s.prec.copy(), s.prec.copy()
    a_xy, b_xy = h.noise_ab
    sep = h.noise == "separate"
    kern.update_precisions(
        s.R, s.D, s.S, p1, data.Mx, h.a0, h.b0, np.random.default_rng(1), a_xy, b_xy, sep
    )
    naive.update_precisions(
        s.R, s.D, s.S, p2, data.Mx, h.a0, h.b0, np.random.default_rng(1), a_xy, b_xy, sep
    )
    np.testing.assert_allclose(p1, p2, rtol=1e-12)
    assert not np.allclose(p1[:2], s.prec[:2])
    if sep and My:
        assert p1[4] != p1[5] and p1[1] == pytest.approx(data.V.shape[1] / (4 / p1[4] + My / p1[5]))
    elif sep:  # no output rows: g_ny is not drawn, the pooled precision is g_nx
        assert p1[1] == p1[4] and p1[5] == s.prec[5]
    else:
        assert p1[1] == p1[4] == p1[5]


def test_precisions_reject_a_short_prec_array():
    s, data, h = _problem(5)
    with pytest.raises(ValueError, match="prec must have 6 entries"):
        kern.update_precisions(
            s.R, s.D, s.S, s.prec[:4].copy(), data.Mx, h.a0, h.b0, np.random.default_rng(1)
        )


@pytest.mark.parametrize("seed", [0, 1])
def test_codes_separate_noise_match_naive(seed):
    """The rescaled-copy kernel against the weighted inner products written out."""
    s1, data, _ = _problem(seed, **MODEL_VARIANTS["separate"])
    s2 = _copy(s1)
    p = s1.prec
    kern.update_codes_separate(
        s1.R, s1.D, s1.B, s1.S, s1.W, p[0], p[4], p[5], data.Mx, np.random.default_rng(seed + 10)
    )
    naive.update_codes_separate(
        s2.R, s2.D, s2.B, s2.S, s2.W, p[0], p[4], p[5], data.Mx, np.random.default_rng(seed + 10)
    )
    _assert_states_close(s1, s2)
    np.testing.assert_allclose(s1.R, data.V - (s1.B * s1.S) @ s1.D, atol=1e-10)


@pytest.mark.parametrize("N, K", [(7, 5), (4, 9)])
@pytest.mark.parametrize("single", [False, True])
def test_atoms_separate_noise_match_naive(single, N, K):
    s1, data, _ = _problem(3, N=N, K=K, **MODEL_VARIANTS["separate"])
    s2 = _copy(s1)
    p = s1.prec
    if single:
        kern.update_atoms_single(
            s1.R,
            s1.D,
            s1.norms,
            s1.B,
            s1.S,
            p[4],
            p[2],
            p[3],
            data.Mx,
            np.random.default_rng(5),
            p[5],
        )
        naive.update_atoms_single(
            s2.R,
            s2.D,
            s2.norms,
            s2.B,
            s2.S,
            p[4],
            p[2],
            p[3],
            data.Mx,
            np.random.default_rng(5),
            p[5],
        )
    else:
        kern.update_atoms(
            data.V,
            s1.R,
            s1.D,
            s1.norms,
            s1.B,
            s1.S,
            p[4],
            p[2],
            p[3],
            data.Mx,
            np.random.default_rng(5),
            p[5],
        )
        naive.update_atoms(
            data.V,
            s2.R,
            s2.D,
            s2.norms,
            s2.B,
            s2.S,
            p[4],
            p[2],
            p[3],
            data.Mx,
            np.random.default_rng(5),
            p[5],
        )
    _assert_states_close(s1, s2)


def test_atoms_woodbury_form_is_the_conditional():
    """The N x N form of the block atom draw (N < K) is an exact draw of the K x K Gaussian conditional: it is
    linear in its normals (E1, E2), with mean P^-1 gn A X at E = 0 and covariance T1 T1^T + T2 T2^T = P^-1."""
    rng = np.random.default_rng(31)
    N, K, g, gn = 5, 9, 0.7, 2.3
    A = rng.standard_normal((K, N)) * (rng.random((K, N)) < 0.5)
    X = rng.standard_normal((N, 1))
    P = g * np.eye(K) + gn * A @ A.T
    mean = naive.atoms_woodbury(A, X, g, gn, np.zeros((K, 1)), np.zeros((N, 1)))
    np.testing.assert_allclose(mean, np.linalg.solve(P, gn * A @ X), rtol=1e-10, atol=1e-12)
    T1 = np.column_stack(
        [naive.atoms_woodbury(A, X, g, gn, e[:, None], np.zeros((N, 1)))[:, 0] for e in np.eye(K)]
    )
    T2 = np.column_stack(
        [naive.atoms_woodbury(A, X, g, gn, np.zeros((K, 1)), e[:, None])[:, 0] for e in np.eye(N)]
    )
    T1, T2 = T1 - mean, T2 - mean
    np.testing.assert_allclose(T1 @ T1.T + T2 @ T2.T, np.linalg.inv(P), rtol=1e-9, atol=1e-12)


def test_blas_wrappers_match_numpy():
    """The kernels' syrk, Cholesky, triangular solves and triangular product equal NumPy's on row-major arrays."""
    rng = np.random.default_rng(32)
    A = rng.standard_normal((13, 21))
    G, H = np.empty((21, 21)), np.empty((13, 13))
    kern._syrk_gram(A, G, True)
    kern._syrk_gram(A, H, False)
    np.testing.assert_allclose(G, A.T @ A, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(H, A @ A.T, rtol=1e-12, atol=1e-12)
    L = G + np.eye(21)
    kern._cholesky_lower(L)
    np.testing.assert_allclose(L, np.linalg.cholesky(G + np.eye(21)), rtol=1e-12, atol=1e-12)
    Z = rng.standard_normal((21, 4))
    X = Z.copy()
    kern._tri_solve(L, X, False)
    np.testing.assert_allclose(L @ X, Z, atol=1e-12)
    kern._tri_solve(L, X, True)
    np.testing.assert_allclose(L @ (L.T @ X), Z, atol=1e-12)
    E = rng.standard_normal((3, 21))
    F = E.copy()
    kern._times_lower_t(F, L)
    np.testing.assert_allclose(F, E @ L.T, rtol=1e-12, atol=1e-12)
    F = E.copy()
    kern._times_lower(F, L)
    np.testing.assert_allclose(F, E @ L, rtol=1e-12, atol=1e-12)
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        kern._cholesky_lower(-np.eye(3))
    with pytest.raises(ValueError, match="C-contiguous"):
        kern._tri_solve(np.asfortranarray(L), X, False)


@pytest.mark.parametrize("ratio", ["exact", "printed", "literal"])
@pytest.mark.parametrize("w_mean", [0.0, -1.5])
def test_w_mh_matches_naive(ratio, w_mean):
    s, data, _ = _problem(6, N=6, K=40)
    W1 = s.W + w_mean
    W2 = W1.copy()
    code = {"exact": kern.MH_EXACT, "printed": kern.MH_PRINTED_RATIO, "literal": kern.MH_LITERAL}[
        ratio
    ]
    a1 = kern.update_w_mh(W1, s.B, data.Sigma, data.Lw, np.random.default_rng(2), code, w_mean)
    a2 = naive.update_w_mh(W2, s.B, data.Sigma, data.Lw, np.random.default_rng(2), ratio, w_mean)
    assert a1 == a2
    assert 0 < a1 < 40  # both branches exercised
    np.testing.assert_allclose(W1, W2, rtol=1e-9, atol=1e-12)
    # the accepted count is the number of logit vectors that changed
    assert a1 == np.count_nonzero(np.any(W1 != s.W + w_mean, axis=0))


@pytest.mark.parametrize("w_mean", [0.0, -1.5])
def test_w_ess_matches_naive(w_mean):
    s, data, _ = _problem(7, N=6, K=30)
    W1 = s.W + w_mean
    W2 = W1.copy()
    m1 = kern.update_w_ess(W1, s.B, data.Lw, np.random.default_rng(3), w_mean)
    m2 = naive.update_w_ess(W2, s.B, data.Lw, np.random.default_rng(3), w_mean)
    np.testing.assert_allclose(W1, W2, rtol=1e-9, atol=1e-12)
    assert m1 == m2 == np.count_nonzero(np.any(W1 != s.W + w_mean, axis=0)) == 30


@pytest.mark.parametrize(
    "w_update, atom_update",
    [
        ("mh", "block"),
        ("ess", "block"),
        ("paper-printed-ratio", "block"),
        ("paper-literal", "block"),
        ("ess", "single"),
        ("mh", "single"),
    ],
)
def test_sweeps_match_naive(w_update, atom_update):
    _sweeps_match(_problem(8), w_update, atom_update)


@pytest.mark.parametrize("w_update", ["ess", "mh"])
@pytest.mark.parametrize("variant", ["paper", "separate"])
def test_sweeps_with_fewer_points_than_atoms_match_naive(w_update, variant):
    """N < K: the block atom update in its N x N form."""
    _sweeps_match(_problem(8, N=4, K=9, **MODEL_VARIANTS[variant]), w_update, "block")


@pytest.mark.parametrize("variant", ["noise-prior", "separate", "w-mean"])
@pytest.mark.parametrize("w_update, atom_update", [("ess", "block"), ("mh", "single")])
def test_model_variant_sweeps_match_naive(variant, w_update, atom_update):
    _sweeps_match(_problem(8, **MODEL_VARIANTS[variant]), w_update, atom_update)


def _sweeps_match(problem, w_update, atom_update):
    s1, data, h = problem
    s2 = _copy(s1)
    r1, r2 = np.random.default_rng(9), np.random.default_rng(9)
    for _ in range(3):
        _, st1 = kern.gibbs_sweep(s1, data, h, r1, w_update, atom_update)
        st2 = naive.gibbs_sweep(s2, data, h, r2, w_update, atom_update)
        np.testing.assert_allclose(st1, st2, rtol=1e-9)
        V1, V2 = data.V.copy(), data.V.copy()
        kern.redraw_data(V1, s1.R, s1.D, s1.B, s1.S, s1.prec[4], r1, s1.prec[5], data.Mx)
        naive.redraw_data(V2, s2.R, s2.D, s2.B, s2.S, s2.prec[4], r2, s2.prec[5], data.Mx)
        np.testing.assert_allclose(V1, V2, rtol=1e-10)
    _assert_states_close(s1, s2)


@pytest.mark.parametrize(
    "seed, n_atoms, scale, n_sweeps, stream",
    [
        (11, 6, 1.0, 4, 123),  # one partial block of atoms
        (
            12,
            "block+5",
            0.5,
            3,
            5,
        ),  # more atoms than one block of the prediction kernel (a full and a partial block)
    ],
)
def test_predict_kernel_matches_naive(seed, n_atoms, scale, n_sweeps, stream):
    rng = np.random.default_rng(seed)
    K = kern._PRED_BLOCK + 5 if n_atoms == "block+5" else n_atoms
    L, Mx, My, N, T, j = 3, 4, 2, 9, 5, 3
    Dx, Dy = rng.standard_normal((L, K, Mx)) * scale, rng.standard_normal((L, K, My))
    Ws = rng.standard_normal((L, N, K))
    gs, gxy = rng.gamma(3, 1 / 3, L), rng.gamma(3, 1, L)
    Xtr, Xt = rng.standard_normal((N, Mx)), rng.standard_normal((T, Mx))
    nbr = kern.nearest_neighbours(Xt, Xtr, j)
    seeds = kern.point_seeds(Xt.view(np.uint64), np.uint64(stream))
    out_y, out_ll = np.empty((T, L, My)), np.empty((T, L))
    kern.predict_kernel(Xt, nbr, Dx, Dy, Ws, gs, gxy, n_sweeps, seeds, out_y, out_ll)
    ref_y, ref_ll = naive.predict_draws(Xt, Xtr, j, Dx, Dy, Ws, gs, gxy, n_sweeps, stream)
    np.testing.assert_allclose(out_y, ref_y, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out_ll, ref_ll, rtol=1e-9)
    # a point's stream does not depend on the batch: the same draws alone as in a batch, up to the rounding of
    # the batch's matrix products
    sub_y = np.empty((1, L, My))
    kern.predict_kernel(
        Xt[2:3], nbr[2:3], Dx, Dy, Ws, gs, gxy, n_sweeps, seeds[2:3], sub_y, np.empty((1, L))
    )
    np.testing.assert_allclose(sub_y[0], out_y[2], rtol=1e-12, atol=1e-14)


def test_predict_prior_codes_matches_naive():
    """The paper-text prediction (codes' pattern from the logits alone, weights exactly given x_t)."""
    rng = np.random.default_rng(12)
    L, K, Mx, My, N, T, j = 4, 7, 5, 2, 9, 6, 3
    Dx, Dy = rng.standard_normal((L, K, Mx)), rng.standard_normal((L, K, My))
    Ws = rng.standard_normal((L, N, K))
    Ws[0] -= 30.0  # sample 0: no atom on (empty active set)
    gs, gxy = rng.gamma(3, 1 / 3, L), rng.gamma(3, 1, L)
    Xtr, Xt = rng.standard_normal((N, Mx)), rng.standard_normal((T, Mx))
    nbr = kern.nearest_neighbours(Xt, Xtr, j)
    seeds = kern.point_seeds(Xt.view(np.uint64), np.uint64(321))
    out_y, out_ll = np.empty((T, L, My)), np.empty((T, L))
    kern.predict_kernel_prior_codes(Xt, nbr, Dx, Dy, Ws, gs, gxy, seeds, out_y, out_ll)
    ref_y, ref_ll = naive.predict_draws_prior_codes(Xt, Xtr, j, Dx, Dy, Ws, gs, gxy, 321)
    np.testing.assert_allclose(out_y, ref_y, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out_ll, ref_ll, rtol=1e-9)
    assert np.all(out_y[:, 0] == 0.0) and np.any(out_y[:, 1:] != 0.0)


def test_predict_prior_codes_weights_against_exact_gaussian():
    """Given the pattern (all atoms on: logits +40), s_t | x_t is Gaussian: the mean of many draws of D^y alpha_t
    equals D^y P^-1 g_xy D^x x_t and their covariance D^y P^-1 D^y^T (P = g_s I + g_xy D^x D^x^T)."""
    rng = np.random.default_rng(13)
    K, Mx, My, n = 3, 4, 2, 40000
    Dx1, Dy1 = rng.standard_normal((K, Mx)), rng.standard_normal((K, My))
    g_s, g_xy = 0.7, 2.5
    Dx, Dy = np.broadcast_to(Dx1, (n, K, Mx)).copy(), np.broadcast_to(Dy1, (n, K, My)).copy()
    Ws = np.full((n, 1, K), 40.0)
    x = rng.standard_normal((1, Mx))
    out_y, out_ll = np.empty((1, n, My)), np.empty((1, n))
    kern.predict_kernel_prior_codes(
        x,
        np.zeros((1, 1), dtype=np.int64),
        Dx,
        Dy,
        Ws,
        np.full(n, g_s),
        np.full(n, g_xy),
        np.array([5], dtype=np.uint64),
        out_y,
        out_ll,
    )
    P = g_s * np.eye(K) + g_xy * Dx1 @ Dx1.T
    Pi = np.linalg.inv(P)
    mean = Dy1.T @ Pi @ (g_xy * Dx1 @ x[0])
    cov = Dy1.T @ Pi @ Dy1
    draws = out_y[0]
    diff = draws.mean(axis=0) - mean
    assert diff @ np.linalg.solve(cov / n, diff) < stats.chi2.ppf(1 - 1e-3, My)
    np.testing.assert_allclose(np.cov(draws.T), cov, rtol=0.05, atol=0.02 * np.abs(cov).max())


def test_vectorizable_log_sigmoid_sum_is_exact():
    """The libm-free exp(-a), the sigmoid pair of the MH bound and the sum of log sigmoids of the slice sampler,
    against NumPy/math in float64 (within a few ulps), over the whole range including |x| past the clamp and
    N above one logged product of _LOG_CHUNK terms."""
    a = np.concatenate(
        [np.linspace(0.0, 45.0, 4501), np.linspace(45.0, 720.0, 2701), [1e-300, 36.9, 37.1]]
    )
    exp_neg, sig_pair = (
        njit(lambda v: kern._exp_neg(v)),
        njit(lambda v: kern._sig_pair(v)),
    )  # compiled code
    got = np.array([exp_neg(x) for x in a])
    np.testing.assert_allclose(got, np.exp(-np.minimum(a, kern._EXP_CLAMP)), rtol=5e-16, atol=0)
    x = np.concatenate([-a, a])
    pairs = np.array([sig_pair(v) for v in x])
    np.testing.assert_allclose(pairs[:, 0], expit(np.clip(x, -708, 708)), rtol=1e-15, atol=0)
    np.testing.assert_allclose(pairs[:, 1], expit(-np.clip(x, -708, 708)), rtol=1e-15, atol=0)
    rng = np.random.default_rng(5)
    for scale in (0.01, 1.0, 10.0, 1000.0):
        for n in (1, 200, 3 * kern._LOG_CHUNK + 5):
            z, w = np.sign(rng.standard_normal(n)), rng.standard_normal(n) * scale
            exact = math.fsum(min(x, 0.0) - math.log1p(math.exp(-abs(x))) for x in z * w)
            assert abs(kern._sum_log_sigmoid(z, w) - exact) <= 1e-14 * max(1.0, abs(exact))


def test_splitmix_stream_is_uniform():
    """The prediction stream: uniform on [0, 1) and ziggurat normals are standard normal."""
    s = naive.SplitMix(2024)
    u = np.array([s.uniform() for _ in range(4000)])
    z = np.array([s.normal() for _ in range(4000)])
    assert stats.kstest(u, "uniform").pvalue > 1e-3
    assert stats.kstest(z, "norm").pvalue > 1e-3


def test_ziggurat_normals_are_standard_normal():
    """Kernel normals: equal to the reference draw for draw; KS; mean/variance; the tail beyond the base
    layer's edge r and the wedges (both slow paths) occur at their exact rates."""
    s = naive.SplitMix(77)
    np.testing.assert_allclose(
        kern.stream_normals(77, 3000), [s.normal() for _ in range(3000)], rtol=1e-12
    )
    x_tab, f_tab = kern.ziggurat_tables()
    assert x_tab[1] == kern.ZIG_R and x_tab[-1] == 0.0
    # equal layer areas: x_i (f(x_{i+1}) - f(x_i)) = v for 1 <= i < 255, and the top layer closes at f = 1
    np.testing.assert_allclose(x_tab[1:-2] * np.diff(f_tab[1:-1]), kern.ZIG_V, rtol=1e-9)
    assert abs(x_tab[255] * (1.0 - f_tab[255]) - kern.ZIG_V) < 1e-6 * kern.ZIG_V
    z = kern.stream_normals(2025, 2_000_000)
    assert stats.kstest(z[:200_000], "norm").pvalue > 1e-3
    se = 1 / np.sqrt(z.size)
    assert abs(z.mean()) < 4 * se and abs(z.var() - 1) < 4 * np.sqrt(2) * se
    for edge in (
        1.0,
        2.0,
        kern.ZIG_R,
        4.0,
    ):  # two-sided tail frequencies, |z| < 4 binomial standard errors
        p = 2 * stats.norm.sf(edge)
        count = np.count_nonzero(np.abs(z) > edge)
        assert abs(count - p * z.size) < 4 * np.sqrt(p * (1 - p) * z.size) + 1, (
            edge,
            count,
            p * z.size,
        )


def test_sampler_draws_equal_the_generators_bit_for_bit():
    """The sampler's direct draws from the bit generator are Generator.random() and .standard_normal() exactly:
    3 million normals cover NumPy's wedge (about 1%) and tail (about 0.03%) branches thousands of times each,
    and the stream stays in step (the next draw of either Generator agrees)."""
    for bitgen in (np.random.PCG64, np.random.SFC64, np.random.Philox):
        r1, r2 = np.random.Generator(bitgen(11)), np.random.Generator(bitgen(11))
        z = kern.draw_normals(r1, 3_000_000)
        np.testing.assert_array_equal(z, r2.standard_normal(3_000_000))
        assert np.count_nonzero(np.abs(z) > kern._ZR) > 300  # the tail branch ran
        np.testing.assert_array_equal(kern.draw_uniforms(r1, 1000), r2.random(1000))
        assert r1.standard_normal() == r2.standard_normal()


_FAULTS_PER_CODE_UPDATE = """
import resource, sys
import numpy as np
from bsrbench.models import _bsr_kernels as kern
if sys.argv[1] == "keep":
    assert kern.keep_freed_memory()
rng = np.random.default_rng(0)
N, K, M = 200, 256, 157
D, W = rng.standard_normal((K, M)) / 10, rng.standard_normal((N, K))
B, S = (rng.random((N, K)) < 0.4).astype(np.int8), rng.standard_normal((N, K))
R = rng.standard_normal((N, M))
norms = np.einsum("km,km->k", D, D)
kern.update_codes(R, D, norms, B, S, W, 1.0, 10.0, rng)
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):
    kern.update_codes(R, D, norms, B, S, W, 1.0, 10.0, rng)
print((resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 10)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_keep_freed_memory_stops_page_faults_of_the_temporaries():
    """In a fresh process the code update at N = 200, K = 256 page-faults its few MB of temporaries in again at
    every call (glibc unmaps or trims them when freed); after keep_freed_memory() it reuses them."""
    import subprocess

    def faults(mode):
        out = subprocess.run(
            [sys.executable, "-c", _FAULTS_PER_CODE_UPDATE, mode],
            capture_output=True,
            text=True,
            check=True,
        )
        return float(out.stdout.split()[-1])

    default, kept = faults("default"), faults("keep")
    assert default > 200, default  # the setting is needed (about 570 faults per call here)
    assert kept < 20, kept


# ---------------------------------------------------------------------------------------------------------
# conditionals against brute-force grids (the target written from the model's joint density)
# ---------------------------------------------------------------------------------------------------------
def _grid_cdf(grid, logdens):
    p = np.exp(logdens - logdens.max())
    c = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(grid))])
    c /= c[-1]
    return lambda x: np.interp(x, grid, c)


def test_code_pair_against_grid():
    """(b, s) for one point and atom: the joint p(b, s | -) ∝ sig(z w) N(s; 0, 1/g_s) N(v; d b s, 1/g_xy I)."""
    rng = np.random.default_rng(21)
    M, n_rep = 5, 40000
    d = rng.standard_normal(M) * 0.6
    v = 0.8 * d + 0.3 * rng.standard_normal(M)
    w, g_s, g_xy = -0.4, 1.5, 2.0
    # n_rep identical copies of the same (point, atom): one call gives n_rep independent draws
    R = np.tile(v, (n_rep, 1))
    D = d[None, :].copy()
    B = np.zeros((n_rep, 1), dtype=np.int8)
    S = np.zeros((n_rep, 1))
    W = np.full((n_rep, 1), w)
    kern.update_codes(R, D, np.array([d @ d]), B, S, W, g_s, g_xy, np.random.default_rng(22))

    grid = np.linspace(-6, 6, 20001)

    def log_joint(b, s):
        resid = v[None, :] - b * s[:, None] * d[None, :]
        return (
            np.log(expit((2 * b - 1) * w))
            - 0.5 * g_s * s**2
            + 0.5 * np.log(g_s)
            - 0.5 * g_xy * np.sum(resid**2, axis=1)
        )

    l1, l0 = log_joint(1, grid), log_joint(0, grid)
    m = max(l1.max(), l0.max())
    p1 = np.trapezoid(np.exp(l1 - m), grid) / (
        np.trapezoid(np.exp(l1 - m), grid) + np.trapezoid(np.exp(l0 - m), grid)
    )
    on = B[:, 0] == 1
    assert 0.1 < p1 < 0.9
    assert stats.binomtest(int(on.sum()), n_rep, p1).pvalue > 1e-3
    assert stats.kstest(S[on, 0], _grid_cdf(grid, l1)).pvalue > 1e-3
    assert stats.kstest(S[~on, 0], _grid_cdf(grid, l0)).pvalue > 1e-3
    # residual bookkeeping: r = v - d b s
    np.testing.assert_allclose(R, v - (B * S) * d[None, :], atol=1e-12)


# precision (index in prec) -> the Gaussian factors it scales, written from the joint density
_PREC_FACTORS = {
    "g_s": (0, lambda s, Mx: s.S),
    "g_xy": (1, lambda s, Mx: s.R),
    "g_x": (2, lambda s, Mx: s.D[:, :Mx]),
    "g_y": (3, lambda s, Mx: s.D[:, Mx:]),
    "g_nx": (4, lambda s, Mx: s.R[:, :Mx]),
    "g_ny": (5, lambda s, Mx: s.R[:, Mx:]),
}


@pytest.mark.parametrize(
    "name, variant",
    [
        ("g_s", "paper"),
        ("g_x", "paper"),
        ("g_y", "paper"),
        ("g_xy", "paper"),
        ("g_xy", "noise-prior"),
        ("g_nx", "separate"),
        ("g_ny", "separate"),
    ],
)
def test_precision_against_grid(name, variant):
    """Each precision's conditional ∝ Gamma(g; a, b) prod_j N(u_j; 0, 1/g) over the values u it scales (all N K
    weights s for g_s, the atoms' feature / output parts for g_x / g_y, the residuals for the noise precisions,
    with the noise prior (a_xy, b_xy) and split by rows under separate noise), on a grid vs repeated kernel
    draws."""
    s, data, h = _problem(23, N=4, K=3, Mx=2, My=2, a=2.0, b=1.5, **MODEL_VARIANTS[variant])
    idx, values = _PREC_FACTORS[name]
    a, b = h.noise_ab if idx in (1, 4, 5) else (h.a0, h.b0)
    rng = np.random.default_rng(24)
    draws = np.empty(20000)
    prec = s.prec.copy()
    for t in range(draws.size):
        kern.update_precisions(
            s.R, s.D, s.S, prec, data.Mx, h.a0, h.b0, rng, *h.noise_ab, h.noise == "separate"
        )
        draws[t] = prec[idx]
    u = values(s, data.Mx)
    uu, n = np.sum(u**2), u.size
    grid = np.linspace(1e-9, draws.max() * 3, 40001)
    logd = (a - 1) * np.log(grid) - b * grid + 0.5 * n * np.log(grid) - 0.5 * grid * uu
    assert stats.kstest(draws, _grid_cdf(grid, logd)).pvalue > 1e-3


def test_code_pair_separate_noise_against_grid():
    """(b, s) under separate noise precisions: p(b, s | -) ∝ sig(z w) N(s; 0, 1/g_s) N(x; d^x b s, 1/g_nx I)
    N(y; d^y b s, 1/g_ny I), vs repeated kernel draws."""
    rng = np.random.default_rng(31)
    Mx, My, n_rep = 3, 2, 40000
    d = rng.standard_normal(Mx + My) * 0.6
    v = 0.8 * d + 0.3 * rng.standard_normal(Mx + My)
    w, g_s, g_nx, g_ny = 0.3, 1.5, 0.6, 6.0
    R = np.tile(v, (n_rep, 1))
    B = np.zeros((n_rep, 1), dtype=np.int8)
    S = np.zeros((n_rep, 1))
    kern.update_codes_separate(
        R,
        d[None, :].copy(),
        B,
        S,
        np.full((n_rep, 1), w),
        g_s,
        g_nx,
        g_ny,
        Mx,
        np.random.default_rng(32),
    )
    grid = np.linspace(-6, 6, 20001)
    c = np.where(np.arange(Mx + My) < Mx, g_nx, g_ny)

    def log_joint(b, s):
        resid = v[None, :] - b * s[:, None] * d[None, :]
        return (
            np.log(expit((2 * b - 1) * w)) - 0.5 * g_s * s**2 - 0.5 * np.sum(c * resid**2, axis=1)
        )

    l1, l0 = log_joint(1, grid), log_joint(0, grid)
    m = max(l1.max(), l0.max())
    i1, i0 = np.trapezoid(np.exp(l1 - m), grid), np.trapezoid(np.exp(l0 - m), grid)
    p1 = i1 / (i1 + i0)
    on = B[:, 0] == 1
    assert 0.1 < p1 < 0.9
    assert stats.binomtest(int(on.sum()), n_rep, p1).pvalue > 1e-3
    assert stats.kstest(S[on, 0], _grid_cdf(grid, l1)).pvalue > 1e-3
    assert stats.kstest(S[~on, 0], _grid_cdf(grid, l0)).pvalue > 1e-3
    np.testing.assert_allclose(R, v - (B * S) * d[None, :], atol=1e-12)


@pytest.mark.parametrize("atom_update", ["block", "single"])
@pytest.mark.parametrize("row", ["feature", "output-separate-noise"])
def test_atom_rows_against_grid(atom_update, row):
    """Two atoms, one row: the 2-D conditional of (d_1m, d_2m) on a grid vs kernel draws (chi-square).
    The block update draws it exactly; one-at-a-time updates are a Gibbs chain on it (thinned by 5). A feature
    row uses (g_xy, g_x); an output row under separate noise precisions uses (g_ny, g_y), and must ignore the
    feature rows' g_nx and g_x (set to wrong values here)."""
    rng = np.random.default_rng(25)
    N, K = 6, 2
    B = np.ones((N, K), dtype=np.int8)
    S = rng.standard_normal((N, K))
    V = rng.standard_normal((N, 1))
    g_xy, g_x = 1.7, 0.9  # the row's noise and atom precisions
    if row == "feature":
        Mx, args, g_ny = 1, (g_xy, g_x, 1.0), -1.0
    else:
        Mx, args, g_ny = 0, (50.0, 20.0, g_x), g_xy
    n_rep = 30000
    draws = np.empty((n_rep, K))
    D = np.zeros((K, 1))
    R, norms = V.copy(), np.zeros(K)
    for t in range(n_rep):
        if atom_update == "block":
            kern.update_atoms(V, R, D, norms, B, S, *args, Mx, rng, g_ny)
        else:
            for _ in range(5):
                kern.update_atoms_single(R, D, norms, B, S, *args, Mx, rng, g_ny)
        draws[t] = D[:, 0]
    A = B * S
    lim = 1.2 * np.abs(draws).max()
    g = np.linspace(-lim, lim, 2401)
    d1, d2 = np.meshgrid(g, g, indexing="ij")
    # sum_i (x_i - d1 a_i1 - d2 a_i2)^2 written out as a quadratic form in (d1, d2)
    x = V[:, 0]
    sq = (
        x @ x
        - 2 * d1 * (A[:, 0] @ x)
        - 2 * d2 * (A[:, 1] @ x)
        + d1**2 * (A[:, 0] @ A[:, 0])
        + 2 * d1 * d2 * (A[:, 0] @ A[:, 1])
        + d2**2 * (A[:, 1] @ A[:, 1])
    )
    logd = -0.5 * g_xy * sq - 0.5 * g_x * (d1**2 + d2**2)
    dens = np.exp(logd - logd.max())
    edges = (
        np.quantile(draws[:, 0], np.linspace(0, 1, 7)),
        np.quantile(draws[:, 1], np.linspace(0, 1, 7)),
    )
    for e in edges:
        e[0], e[-1] = -lim, lim
    obs, _, _ = np.histogram2d(draws[:, 0], draws[:, 1], bins=edges)
    i1, i2 = np.digitize(g, edges[0][1:-1]), np.digitize(g, edges[1][1:-1])
    expected = np.zeros_like(obs)
    np.add.at(expected, (i1[:, None].repeat(len(g), 1), i2[None, :].repeat(len(g), 0)), dens)
    expected *= n_rep / expected.sum()
    chi2 = np.sum((obs - expected) ** 2 / expected)
    assert stats.chi2.sf(chi2, obs.size - 1) > 1e-3


@pytest.mark.parametrize("w_update", ["mh", "ess"])
@pytest.mark.parametrize("w_mean", [0.0, -2.0])
def test_w_update_leaves_target_invariant(w_update, w_mean):
    """Exact draws of w_k (rejection from the prior) stay exact after one update: marginal of w_1 vs a grid.

    Target: N(w; m 1, Sigma) prod_i sig(z_i w_i), N = 2, many independent atoms at once.
    """
    rng = np.random.default_rng(26)
    Sigma = np.array([[4.0, 2.0], [2.0, 4.0]])
    Lw = np.linalg.cholesky(Sigma)
    z = np.array([1.0, -1.0])
    K = 30000
    prop = Lw @ rng.standard_normal((2, 8 * K)) + w_mean
    keep = rng.random(8 * K) < np.prod(expit(z[:, None] * prop), axis=0)
    W = np.ascontiguousarray(prop[:, keep][:, :K])
    assert W.shape == (2, K)
    B = np.tile((z > 0).astype(np.int8)[:, None], (1, K))
    if w_update == "mh":
        acc = kern.update_w_mh(W, B, Sigma, Lw, rng, kern.MH_EXACT, w_mean)
        assert 0.05 * K < acc < K
    else:
        kern.update_w_ess(W, B, Lw, rng, w_mean)
    g = np.linspace(-15, 15, 1201)
    w1, w2 = np.meshgrid(g, g, indexing="ij")
    Si = np.linalg.inv(Sigma)
    u1, u2 = w1 - w_mean, w2 - w_mean
    logd = (
        -0.5 * (Si[0, 0] * u1**2 + 2 * Si[0, 1] * u1 * u2 + Si[1, 1] * u2**2)
        + np.log(expit(z[0] * w1))
        + np.log(expit(z[1] * w2))
    )
    dens = np.exp(logd - logd.max())
    marg = np.log(dens.sum(axis=1))
    assert stats.kstest(W[0], _grid_cdf(g, marg)).pvalue > 1e-3
    assert stats.kstest(W[1], _grid_cdf(g, np.log(dens.sum(axis=0)))).pvalue > 1e-3


def test_logit_prior_cov_and_jitter():
    rng = np.random.default_rng(27)
    Y = rng.standard_normal((6, 3))
    Sigma, eta = kern.logit_prior_cov(Y)
    d = np.linalg.norm(Y[:, None] - Y[None], axis=-1)
    iu = np.triu_indices(6, 1)
    assert eta == pytest.approx(2 * np.sum(d[iu] ** 2) / (6 * 5))
    np.testing.assert_allclose(Sigma, np.exp(-d / eta), atol=1e-12)
    # duplicated poses: singular; escalated jitter makes it factorable
    Sig2, eta2 = kern.logit_prior_cov(np.vstack([Y, Y[:1]]))
    L, jit = kern.cholesky_with_jitter(Sig2, eta2)
    assert jit > 0
    np.testing.assert_allclose(L @ L.T, Sig2 + jit * np.eye(7), atol=1e-10)
    bad = Sigma.copy()
    bad[0, 1] = bad[1, 0] = 50.0
    with pytest.raises(kern.SamplerError, match=r"Sigma_w \(N=6, eta=1\.5"):
        kern.cholesky_with_jitter(bad, 1.5)


def test_gibbs_sweep_rejects_unknown_update():
    s, data, h = _problem(0)
    with pytest.raises(ValueError, match="w_update must be one of .* got 'gibbs'"):
        kern.gibbs_sweep(s, data, h, np.random.default_rng(0), "gibbs")
    with pytest.raises(ValueError, match="atom_update must be one of .* got 'joint'"):
        kern.gibbs_sweep(s, data, h, np.random.default_rng(0), "ess", "joint")
