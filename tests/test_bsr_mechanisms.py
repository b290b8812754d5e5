"""The paper's two stated mechanisms as options of BayesianSR: the logit prior kernel and posterior averaging.

``logit_kernel`` / ``eta_scale`` choose Sigma_w; each choice must leave the Gibbs sampler exact (Geweke test and
the grid test of the logit conditional). ``n_predict_samples`` chooses how many retained samples the prediction
averages over. Also: the options are validated before any job runs, and the training-frame error.
"""

import numpy as np
import pytest
from scipy import stats
from scipy.special import expit
from test_bsr_geweke import (
    A0,
    B0,
    MX,
    MY,
    STAT_NAMES,
    K,
    N,
    _batch_se,
    _max_abs_z,
    _moments,
    _report,
    _stats,
    prior_draws,
)
from test_bsr_kernels import _grid_cdf

from bsrbench.config import check_method_settings
from bsrbench.errors import InputError
from bsrbench.models import _bsr_kernels as kern
from bsrbench.models.bsr import BayesianSR, training_error

SMALL = dict(
    n_atoms=6, n_neighbors=3, n_iter=30, n_burn_in=15, thin=3, n_predict_sweeps=3, random_state=0
)

# the ablation's kernel choices beyond the paper's default ("pose", eta_scale = 1)
KERNEL_CHOICES = {
    "input": {"logit_kernel": "input"},
    "identity": {"logit_kernel": "identity"},
    "eta-x0.1": {"eta_scale": 0.1},
    "eta-x10": {"eta_scale": 10.0},
}


def _toy(n=40, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 5))
    Y = X[:, :2] @ rng.standard_normal((2, 3)) + 0.1 * rng.standard_normal((n, 3))
    return X, Y


def _hand_kernel(U, scale):
    """exp(-||u_i - u_j|| / eta) with eta = scale * mean of ||u_i - u_j||^2 over pairs i < j, by loops."""
    n = U.shape[0]
    d = np.array([[np.sqrt(np.sum((U[i] - U[j]) ** 2)) for j in range(n)] for i in range(n)])
    pairs = [d[i, j] ** 2 for i in range(n) for j in range(i + 1, n)]
    eta = scale * float(np.mean(pairs))
    return np.exp(-d / eta), eta


def _sigma(choice, X, Y):
    p = {"logit_kernel": "pose", "eta_scale": 1.0, **KERNEL_CHOICES.get(choice, {})}
    return kern.logit_prior(p["logit_kernel"], X, Y, p["eta_scale"])


# ---------------------------------------------------------------------------------------------------------
# Sigma_w of each choice
# ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("choice", ["pose"] + sorted(KERNEL_CHOICES))
def test_logit_prior_against_hand_computation(choice):
    rng = np.random.default_rng(40)
    X, Y = rng.standard_normal((7, 5)), rng.standard_normal((7, 3))
    Sigma, eta = _sigma(choice, X, Y)
    if choice == "identity":
        assert eta is None
        np.testing.assert_array_equal(Sigma, np.eye(7))
        return
    U = X if choice == "input" else Y
    scale = {"eta-x0.1": 0.1, "eta-x10": 10.0}.get(choice, 1.0)
    Sig_hand, eta_hand = _hand_kernel(U, scale)
    assert eta == pytest.approx(eta_hand, rel=1e-12)
    np.testing.assert_allclose(Sigma, Sig_hand, atol=1e-12)


def test_logit_prior_rejects_an_unknown_kernel():
    with pytest.raises(
        ValueError, match=r"logit_kernel must be one of \['pose', 'input', 'identity'\]"
    ):
        kern.logit_prior("poses", np.zeros((3, 2)), np.zeros((3, 2)))


@pytest.mark.parametrize("choice", ["pose"] + sorted(KERNEL_CHOICES))
def test_fit_uses_the_kernel_choice(choice):
    """eta_ of the fit is the bandwidth of the chosen kernel on the fit's own standardized Y (or scaled X)."""
    X, Y = _toy()
    m = BayesianSR(**{**SMALL, **KERNEL_CHOICES.get(choice, {})}).fit(X, Y)
    if choice == "identity":
        assert m.eta_ is None and m.sigma_jitter_ == 0.0
        return
    U = (X - m.x_mean_) / m.x_scale_ if choice == "input" else (Y - m.y_mean_) / m.y_scale_
    scale = {"eta-x0.1": 0.1, "eta-x10": 10.0}.get(choice, 1.0)
    assert m.eta_ == pytest.approx(_hand_kernel(U, scale)[1], rel=1e-10)
    assert np.all(np.isfinite(m.predict(X[:3])))


# ---------------------------------------------------------------------------------------------------------
# exactness of the sampler under each Sigma_w
# ---------------------------------------------------------------------------------------------------------
def geweke_z_sigma(Sigma, w_update, n_iter, seed=0):
    """:func:`test_bsr_geweke.geweke_z` with a given Sigma_w (N x N): z-scores of successive minus marginal."""
    rng = np.random.default_rng(seed)
    Lw, jitter = kern.cholesky_with_jitter(Sigma)
    Sigma = Sigma + jitter * np.eye(
        N
    )  # as BayesianSR.fit: the sampler's prior is the factored matrix
    hyper = kern.BSRHyper(A0, B0)
    mc = _stats(*prior_draws(n_iter, Lw, rng, hyper))
    state, V = kern.draw_from_prior(N, K, MX, MY, Sigma, Lw, A0, B0, rng, hyper)
    data = kern.BSRData(V=V, Mx=MX, Sigma=Sigma, Lw=Lw)
    sc = np.empty_like(mc)
    for t in range(n_iter):
        kern.gibbs_sweep(state, data, hyper, rng, w_update, "block")
        kern.redraw_data(
            V, state.R, state.D, state.B, state.S, state.prec[4], rng, state.prec[5], MX
        )
        sc[t] = _stats(
            state.prec[None], state.D[None], state.B[None], state.S[None], state.W[None], V[None]
        )[0]
    m_mc, m_sc = _moments(mc), _moments(sc)
    se_mc = m_mc.std(axis=0, ddof=1) / np.sqrt(n_iter)
    z = (m_sc.mean(axis=0) - m_mc.mean(axis=0)) / np.sqrt(se_mc**2 + _batch_se(m_sc) ** 2)
    names = list(STAT_NAMES) + [f"{s}^2" for s in STAT_NAMES]
    # one shared noise precision: g_ny is g_nx (reported as g_xy)
    return {
        ("g_xy" + k[4:] if k.startswith("g_nx") else k): v
        for k, v in zip(names, z)
        if not k.startswith("g_ny")
    }


def _geweke_sigma(choice, seed):
    """Sigma_w of a kernel choice on N = 4 random points (X of 5 features, Y of 2 outputs)."""
    rng = np.random.default_rng(seed)
    return _sigma(choice, rng.standard_normal((N, 5)), rng.standard_normal((N, 2)))[0]


@pytest.mark.parametrize("w_update", ["ess", "mh"])
@pytest.mark.parametrize("choice", sorted(KERNEL_CHOICES))
def test_geweke_kernel_choices(choice, w_update):
    # 20k sweeps: the fourth moments of the data can sit near |z| = 4 by a chain excursion (their batch SE
    # is noisy); the slow test runs 200k sweeps of every choice.
    z = geweke_z_sigma(_geweke_sigma(choice, 11), w_update, n_iter=20000, seed=17)
    assert _max_abs_z(z) < 4.0, _report(z)


@pytest.mark.slow
@pytest.mark.parametrize("w_update", ["ess", "mh"])
@pytest.mark.parametrize("choice", sorted(KERNEL_CHOICES))
def test_geweke_kernel_choices_long(choice, w_update):
    z = geweke_z_sigma(_geweke_sigma(choice, 13), w_update, n_iter=200000, seed=14)
    assert _max_abs_z(z) < 4.0, _report(z)


@pytest.mark.parametrize("w_update", ["mh", "ess"])
@pytest.mark.parametrize("choice", ["pose"] + sorted(KERNEL_CHOICES))
def test_w_conditional_against_grid(choice, w_update):
    """One logit update leaves N(w; 0, Sigma_w) prod_i sig(z_i w_i) invariant for the Sigma_w of each kernel
    choice (N = 2 training points, many independent atoms): exact draws (rejection from the prior) stay exact;
    each marginal against a grid of the target."""
    rng = np.random.default_rng(41)
    X, Y = np.array([[0.0, 0.0, 0.0], [0.9, -0.5, 0.3]]), np.array([[0.0, 0.0], [0.6, 0.8]])
    Sigma, _ = _sigma(choice, X, Y)
    Lw, jitter = kern.cholesky_with_jitter(Sigma)
    Sigma = Sigma + jitter * np.eye(2)
    z = np.array([1.0, -1.0])
    n_atoms = 30000
    prop = Lw @ rng.standard_normal((2, 8 * n_atoms))
    keep = rng.random(8 * n_atoms) < np.prod(expit(z[:, None] * prop), axis=0)
    W = np.ascontiguousarray(prop[:, keep][:, :n_atoms])
    assert W.shape == (2, n_atoms)
    B = np.tile((z > 0).astype(np.int8)[:, None], (1, n_atoms))
    if w_update == "mh":
        acc = kern.update_w_mh(W, B, Sigma, Lw, rng, kern.MH_EXACT, 0.0)
        assert 0.05 * n_atoms < acc < n_atoms
    else:
        kern.update_w_ess(W, B, Lw, rng, 0.0)
    g = np.linspace(-8, 8, 1601)
    w1, w2 = np.meshgrid(g, g, indexing="ij")
    Si = np.linalg.inv(Sigma)
    logd = (
        -0.5 * (Si[0, 0] * w1**2 + 2 * Si[0, 1] * w1 * w2 + Si[1, 1] * w2**2)
        + np.log(expit(z[0] * w1))
        + np.log(expit(z[1] * w2))
    )
    dens = np.exp(logd - logd.max())
    assert stats.kstest(W[0], _grid_cdf(g, np.log(dens.sum(axis=1)))).pvalue > 1e-3
    assert stats.kstest(W[1], _grid_cdf(g, np.log(dens.sum(axis=0)))).pvalue > 1e-3
    # the correlation of the two logits differs between choices: the grid's, and the draws', agree
    p = dens / dens.sum()
    m1, m2 = np.sum(p * w1), np.sum(p * w2)
    corr = np.sum(p * (w1 - m1) * (w2 - m2)) / np.sqrt(
        np.sum(p * (w1 - m1) ** 2) * np.sum(p * (w2 - m2) ** 2)
    )
    assert abs(np.corrcoef(W)[0, 1] - corr) < 4.0 / np.sqrt(n_atoms)


# ---------------------------------------------------------------------------------------------------------
# posterior averaging
# ---------------------------------------------------------------------------------------------------------
def _with_samples(model, index):
    """A copy of a fitted model whose retained samples are ``samples_[k][index]`` (hand-picked)."""
    import copy

    m = copy.deepcopy(model)
    m.samples_ = {k: np.array(v[index]) for k, v in model.samples_.items()}
    m.set_params(n_predict_samples=None)
    return m


def test_one_sample_prediction_is_the_last_draw():
    X, Y = _toy()
    m = BayesianSR(**SMALL).fit(X[:30], Y[:30])
    assert m.samples_["g_xy"].size == 5
    all_mean, all_sd = m.predict(X[30:], return_std=True)
    m.set_params(n_predict_samples=1)
    one, one_sd = m.predict(X[30:], return_std=True)
    picked = _with_samples(m, slice(4, 5))  # the last retained sample, alone
    np.testing.assert_array_equal(one, picked.predict(X[30:]))
    draws, wts = m.predict_draws(X[30:])
    assert draws.shape == (10, 1, 3) and np.all(wts == 1.0)
    # one draw: no spread between samples, the std is the noise std of that sample
    noise_sd = np.sqrt(1.0 / m.samples_["g_xy"][-1]) * m.y_scale_
    np.testing.assert_allclose(one_sd, np.broadcast_to(noise_sd, one_sd.shape), rtol=1e-12)
    np.testing.assert_allclose(one, draws[:, 0, :], rtol=1e-12)
    assert not np.allclose(one, all_mean)
    # a hand-picked other sample gives another prediction: the choice of the last one matters
    assert not np.allclose(one, _with_samples(m, slice(0, 1)).predict(X[30:]))


def test_last_samples_and_all_samples():
    X, Y = _toy()
    m = BayesianSR(**SMALL).fit(X[:30], Y[:30])
    default = m.predict(X[30:])
    draws, _ = m.predict_draws(X[30:])
    # all (None, the default) is the uniform mean of every retained sample's draw, as before the option
    np.testing.assert_allclose(default, draws.mean(axis=1), rtol=1e-12)
    m.set_params(n_predict_samples=5)
    np.testing.assert_array_equal(m.predict(X[30:]), default)
    m.set_params(n_predict_samples=3)
    np.testing.assert_array_equal(m.predict(X[30:]), _with_samples(m, slice(2, 5)).predict(X[30:]))
    m.set_params(n_predict_samples=6)
    with pytest.raises(
        InputError, match=r"n_predict_samples=6 exceeds the 5 retained samples of the fit"
    ):
        m.predict(X[30:])
    m.set_params(n_predict_samples="last")
    with pytest.raises(InputError, match=r"'n_predict_samples' parameter .* or None. Got 'last'"):
        m.predict(X[30:])


def test_training_error_against_hand_computation():
    X, Y = _toy()
    m = BayesianSR(**SMALL).fit(X[:30], Y[:30])
    pred = m.predict(X[:30])
    per_angle = np.sqrt(
        np.mean((pred - Y[:30]) ** 2, axis=0)
    )  # toy outputs: no wrap at 180 degrees
    assert training_error(m, X[:30], Y[:30]) == pytest.approx(per_angle.mean(), rel=1e-12)
    # with an output transform: errors in the original space
    assert training_error(m, X[:30], 2 * Y[:30], inverse=lambda z: 2 * z) == pytest.approx(
        2 * per_angle.mean(), rel=1e-12
    )


# ---------------------------------------------------------------------------------------------------------
# the job layer rejects unknown values before any job runs
# ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "params, match",
    [
        ({"logit_kernel": "poses"}, r"'logit_kernel' parameter of BayesianSR must be a str among"),
        ({"eta_scale": -1.0}, r"'eta_scale' parameter of BayesianSR must be a float in the range"),
        ({"n_predict_samples": 0}, r"'n_predict_samples' parameter of BayesianSR must be an int"),
        ({"n_predict_samples": 60}, r"n_predict_samples=60 exceeds the 50 retained samples"),
    ],
)
def test_method_settings_reject_bad_mechanism_options(params, match):
    methods = {
        "PMbad": {
            "estimator": "bsrbench.models.bsr:BayesianSR",
            "params": {"n_atoms": 64, "n_neighbors": 3, **params},
            "grid": None,
        }
    }
    with pytest.raises(
        InputError, match=r"config key 'methods\.PMbad\.params' \(method PMbad"
    ) as e:
        check_method_settings(methods, ["PMbad"], n_train=[30], cv={"mode": "none"})
    assert e.match(match)
    if "logit_kernel" in params:
        assert e.match(r"among \['identity', 'input', 'pose'\]. Got 'poses' instead")
