"""BayesianSR estimator: scikit-learn contract, bad input, predictions on data drawn from the model, diagnostics."""

import logging

import numpy as np
import pytest
from scipy import stats
from sklearn.utils.estimator_checks import parametrize_with_checks

from bsrbench import convergence as diagnostics
from bsrbench.errors import InputError, SamplerError
from bsrbench.models import _bsr_kernels as kern
from bsrbench.models.bsr import BayesianSR

SMALL = dict(
    n_atoms=6, n_neighbors=3, n_iter=30, n_burn_in=15, thin=3, n_predict_sweeps=3, random_state=0
)


# K = 20 atoms: with 6 the 40-sweep fit of sklearn's regression check stays below its R^2 > 0.5 bar
@parametrize_with_checks([BayesianSR(**{**SMALL, "n_atoms": 20, "n_iter": 40, "n_burn_in": 20})])
def test_sklearn_compatible(estimator, check):
    check(estimator)


def _toy(n=40, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 5))
    Y = X[:, :2] @ rng.standard_normal((2, 3)) + 0.1 * rng.standard_normal((n, 3))
    return X, Y


# ---------------------------------------------------------------------------------------------------------
# data drawn from the model
# ---------------------------------------------------------------------------------------------------------
def _simulate(seed, n_train=150, n_test=300, K=8, Mx=12, My=4):
    """(X, Y) from the model: logits smooth in a latent 2-D pose u, codes, dictionaries, noise."""
    rng = np.random.default_rng(seed)
    n = n_train + n_test
    u = rng.uniform(-2, 2, size=(n, 2))
    Sigma, _ = kern.logit_prior_cov(u)
    Lw, _ = kern.cholesky_with_jitter(Sigma)
    W = 2.0 * Lw @ rng.standard_normal((n, K))
    B = (rng.random((n, K)) < 1 / (1 + np.exp(-W))).astype(np.int8)
    g_s, g_xy = 1.0, 25.0
    S = rng.standard_normal((n, K)) / np.sqrt(g_s)
    D = rng.standard_normal((K, Mx + My)) / np.sqrt(Mx + My) * 3
    V = (B * S) @ D + rng.standard_normal((n, Mx + My)) / np.sqrt(g_xy)
    truth = dict(Dx=D[:, :Mx], Dy=D[:, Mx:], W=W[:n_train], g_s=g_s, g_xy=g_xy)
    return V[:n_train, :Mx], V[:n_train, Mx:], V[n_train:, :Mx], V[n_train:, Mx:], truth


def _oracle_predict(Xtr, Xte, truth, j):
    """E[y_t | x_t] under the true dictionaries, precisions and logits (w_t = mean of the j nearest training
    inputs' true logits), exactly, by enumerating all 2^K on/off patterns z (independent of the sampler's code):
    p(z | x_t) ∝ prod_k sig(z_k w_tk) N(x_t; 0, D^x_A^T D^x_A / g_s + I / g_xy) and
    E[s_A | x_t, z] = g_xy P^-1 D^x_A x_t with P = g_s I + g_xy D^x_A D^x_A^T (A = the atoms that are on)."""
    Dx, Dy, g_s, g_xy = truth["Dx"], truth["Dy"], truth["g_s"], truth["g_xy"]
    K, Mx = Dx.shape
    d2 = ((Xte[:, None, :] - Xtr[None, :, :]) ** 2).sum(-1)
    wt = truth["W"][np.argsort(d2, axis=1, kind="stable")[:, :j]].mean(axis=1)  # (T, K)
    logp, ey = [], []
    for bits in range(2**K):
        on = np.array([(bits >> k) & 1 for k in range(K)], dtype=bool)
        prior = np.sum(np.where(on, -np.logaddexp(0, -wt), -np.logaddexp(0, wt)), axis=1)
        A = Dx[on]
        C = A.T @ A / g_s + np.eye(Mx) / g_xy
        logp.append(prior + stats.multivariate_normal(np.zeros(Mx), C).logpdf(Xte))
        if on.any():
            P = g_s * np.eye(on.sum()) + g_xy * A @ A.T
            ey.append((g_xy * np.linalg.solve(P, A @ Xte.T)).T @ Dy[on])
        else:
            ey.append(np.zeros((Xte.shape[0], Dy.shape[1])))
    logp = np.array(logp)
    post = np.exp(logp - logp.max(axis=0))
    post /= post.sum(axis=0)
    return np.einsum("zt,ztm->tm", post, np.array(ey))


@pytest.mark.parametrize("atom_update", ["block", "single"])
def test_prediction_on_model_data_approaches_true_dictionaries(atom_update):
    Xtr, Ytr, Xte, Yte, truth = _simulate(0)
    model = BayesianSR(
        n_atoms=8,
        n_iter=400,
        n_burn_in=200,
        thin=4,
        standardize=False,
        atom_update=atom_update,
        random_state=0,  # one chain: its RMSE / oracle ratio ranges 1.06-1.32 over seeds (mean 1.19)
    ).fit(Xtr, Ytr)
    y, sd = model.predict(Xte, return_std=True)
    rmse = np.sqrt(np.mean((y - Yte) ** 2))
    rmse_oracle = np.sqrt(np.mean((_oracle_predict(Xtr, Xte, truth, model.n_neighbors) - Yte) ** 2))
    rmse_mean = np.sqrt(np.mean((Ytr.mean(axis=0) - Yte) ** 2))
    assert rmse_oracle < 0.5 * rmse_mean  # the problem is learnable from x
    assert rmse < 1.25 * rmse_oracle, (rmse, rmse_oracle, rmse_mean)
    inside = np.abs(y - Yte) <= 1.6449 * sd
    assert 0.85 <= inside.mean() <= 0.95, inside.mean()


# ---------------------------------------------------------------------------------------------------------
# behaviour
# ---------------------------------------------------------------------------------------------------------
def test_neighbour_override_equals_refit():
    X, Y = _toy()
    a = BayesianSR(**{**SMALL, "n_neighbors": 3}).fit(X[:30], Y[:30])
    b = BayesianSR(**{**SMALL, "n_neighbors": 7}).fit(X[:30], Y[:30])
    np.testing.assert_array_equal(a.predict(X[30:], n_neighbors=7), b.predict(X[30:]))
    assert not np.allclose(a.predict(X[30:]), b.predict(X[30:]))
    assert BayesianSR._predict_time_params == ("n_neighbors",)


def test_reproducible_and_seed_dependent():
    X, Y = _toy()
    p1 = BayesianSR(**SMALL).fit(X, Y).predict(X[:5])
    p2 = BayesianSR(**SMALL).fit(X, Y).predict(X[:5])
    p3 = BayesianSR(**{**SMALL, "random_state": 1}).fit(X, Y).predict(X[:5])
    np.testing.assert_array_equal(p1, p2)
    assert not np.allclose(p1, p3)


def test_prediction_batch_invariant_and_weighting():
    X, Y = _toy()
    m = BayesianSR(**SMALL).fit(X[:30], Y[:30])
    full, sd = m.predict(X[30:], return_std=True)
    np.testing.assert_array_equal(m.predict(X[33:35]), full[3:5])
    assert full.shape == sd.shape == (10, 3)
    # mean and std from the per-sample draws: weighted mean; spread of the draws plus the noise variance
    draws, wts = m.predict_draws(X[30:])
    assert draws.shape == (10, 5, 3) and wts.shape == (10, 5)
    np.testing.assert_allclose(wts, 0.2)
    np.testing.assert_allclose(full, draws.mean(axis=1), rtol=1e-12)
    noise = np.mean(1.0 / m.samples_["g_xy"]) * m.y_scale_**2
    np.testing.assert_allclose(sd**2, draws.var(axis=1) + noise, rtol=1e-10)
    m.set_params(prediction_weighting="likelihood")
    lw = m.predict(X[30:])
    draws_l, wts_l = m.predict_draws(X[30:])
    np.testing.assert_array_equal(draws_l, draws)  # the weighting changes the weights only
    np.testing.assert_allclose(wts_l.sum(axis=1), 1.0)
    assert np.ptp(wts_l, axis=1).max() > 0.1
    np.testing.assert_allclose(lw, np.einsum("tl,tlm->tm", wts_l, draws_l), rtol=1e-12)


@pytest.mark.parametrize("weighting", ["uniform", "likelihood"])
def test_one_prediction_pass_equals_predict_and_predict_draws(weighting, monkeypatch):
    """predict_with_draws: predict(return_std=True) and predict_draws bit for bit (chunked too), from one pass of
    the sampler over the test points; the result row of a PM job passes the test points once."""
    import bsrbench.models.bsr as bsr_module

    X, Y = _toy()
    m = BayesianSR(**SMALL, prediction_weighting=weighting).fit(X[:30], Y[:30])
    monkeypatch.setattr(bsr_module, "_CHUNK", 4)  # three chunks of the 10 test points
    mean, sd = m.predict(X[30:], return_std=True)
    draws, wts = m.predict_draws(X[30:])
    passes = []
    sample = BayesianSR._predict_draws
    monkeypatch.setattr(
        BayesianSR, "_predict_draws", lambda self, X, j: passes.append(len(X)) or sample(self, X, j)
    )
    one = m.predict_with_draws(X[30:])
    assert passes == [4, 4, 2]
    for got, want in zip(one, (mean, sd, draws, wts)):
        np.testing.assert_array_equal(got, want)
    # one output: mean and std flattened as predict's
    m1 = BayesianSR(**SMALL).fit(X[:30], Y[:30, 0])
    got = m1.predict_with_draws(X[30:])
    np.testing.assert_array_equal(got[0], m1.predict(X[30:]))
    assert got[1].shape == (10,) and got[2].shape == (10, 5, 1)


def test_a_pm_job_samples_the_test_points_once(monkeypatch, tmp_path, synthetic_features):
    """run_job predicts PM's test frames in one pass (mean, std and the scored draws) and its training frames in
    another (the training error): two passes, where predict and predict_draws made three."""
    from bsrbench.io import load_features
    from bsrbench.runs import run_job
    from bsrbench.splits import JobSpec

    feats = load_features(synthetic_features(tmp_path, n=80))
    passes = []
    sample = BayesianSR._predict_draws
    monkeypatch.setattr(
        BayesianSR, "_predict_draws", lambda self, X, j: passes.append(len(X)) or sample(self, X, j)
    )
    spec = JobSpec("syn", "act", "PM", 40, 0, min_test=30)
    row, arrays = run_job(
        spec, feats, estimator="bsrbench.models.bsr:BayesianSR", params=dict(SMALL, n_atoms=4)
    )
    assert passes == [arrays["test"].size, arrays["train"].size]
    assert row["scores_from"] == "samples" and "y_std" in arrays


def test_traces_samples_and_logging(caplog):
    X, Y = _toy()
    with caplog.at_level(logging.INFO, logger="bsrbench.models.bsr"):
        m = BayesianSR(
            n_atoms=5, n_iter=200, n_burn_in=100, thin=10, verbose=True, random_state=0
        ).fit(X, Y)
    msgs = [r.getMessage() for r in caplog.records if r.name == "bsrbench.models.bsr"]
    assert any(s.startswith("sweep 100/200") for s in msgs) and any(
        s.startswith("sweep 200/200") for s in msgs
    )
    for name in diagnostics.SCALAR_TRACES:
        assert m.trace_[name].shape == (200,) and np.all(np.isfinite(m.trace_[name]))
    assert m.samples_["W"].shape == (10, 40, 5) and m.samples_["Dx"].shape == (10, 5, 5)
    assert m.samples_["Dy"].shape == (10, 5, 3)
    np.testing.assert_array_equal(m.samples_["g_xy"], m.trace_["g_xy"][109::10])
    assert (
        "g_nx" not in m.trace_ and "g_ny" not in m.trace_
    )  # one shared noise precision, traced as g_xy
    np.testing.assert_array_equal(m.samples_["g_nx"], m.samples_["g_xy"])
    np.testing.assert_array_equal(m.samples_["g_ny"], m.samples_["g_xy"])


@pytest.mark.parametrize("w_update", ["ess", "mh"])
def test_acceptance_trace_counts_moved_logit_vectors(w_update):
    """The traced acceptance is the fraction of logit vectors w_k that changed in the sweep: checked against the
    retained samples (thin=1) of every sweep after burn-in."""
    X, Y = _toy()
    m = BayesianSR(
        n_atoms=6, n_iter=40, n_burn_in=20, thin=1, w_update=w_update, random_state=0
    ).fit(X, Y)
    W = m.samples_["W"]  # sweeps 20 .. 39, in order
    moved = np.any(W[1:] != W[:-1], axis=1).mean(axis=1)
    np.testing.assert_array_equal(moved, m.trace_["acceptance"][21:])
    if (
        w_update == "mh"
    ):  # the global MH proposal is rejected often at N = 40; ESS moves every vector
        assert moved.mean() < 0.9
    else:
        assert moved.mean() == 1.0


def test_chain_summary_and_plot(tmp_path):
    X, Y = _toy()
    fits = [
        BayesianSR(n_atoms=5, n_iter=120, n_burn_in=60, random_state=s).fit(X, Y) for s in range(3)
    ]
    tab = diagnostics.chain_summary(fits)
    assert list(tab.index[:3]) == ["log_likelihood", "g_xy", "g_s"]
    assert (tab.loc["g_xy", "n_chains"], tab.loc["g_xy", "n_draws"]) == (3, 60)
    assert np.isfinite(tab.loc["g_s", "r_hat"])
    # ESS and R-hat of chains with a known answer: AR(1) chains with rho = 0.8 have ESS about
    # n (1 - rho) / (1 + rho) per chain (4 x 4000 draws: 1778)
    rng = np.random.default_rng(0)
    rho, n = 0.8, 4000
    ar = np.empty((4, n))
    ar[:, 0] = rng.standard_normal(4)
    for t in range(1, n):
        ar[:, t] = rho * ar[:, t - 1] + np.sqrt(1 - rho**2) * rng.standard_normal(4)
    ar_tab = diagnostics.chain_summary([{"g_s": a} for a in ar], burn_in=0, names=("g_s",))
    assert abs(ar_tab.loc["g_s", "ess_bulk"] / (4 * n * (1 - rho) / (1 + rho)) - 1) < 0.25
    assert ar_tab.loc["g_s", "r_hat"] < 1.01
    # a chain stuck elsewhere gives a large R-hat
    shifted = [dict(f.trace_) for f in fits]
    shifted[0]["g_s"] = shifted[0]["g_s"] + 10 * shifted[0]["g_s"].std()
    assert diagnostics.chain_summary(shifted, burn_in=60).loc["g_s", "r_hat"] > 1.5
    # the report's trace figure draws the fits as chains
    from bsrbench.reporting.convergence import plot_chain_traces

    arrays = {f"chain_trace_{n}": np.stack([f.trace_[n] for f in fits]) for n in fits[0].trace_}
    fig = plot_chain_traces(arrays, title="chains", n_burn_in=60)
    out = tmp_path / "traces.png"
    fig.savefig(out)
    assert out.stat().st_size > 1000 and len(fig.axes) >= 3
    with pytest.raises(InputError, match="chain 0: expected a fitted BayesianSR"):
        diagnostics.chain_summary([42])


def test_separate_noise_precisions():
    """noise="separate": g_nx and g_ny are traced apart and g_xy is their pooled precision; on data whose outputs
    are far less noisy than its inputs, g_ny ends far above g_nx; the predictive std uses the output noise."""
    rng = np.random.default_rng(3)
    X = rng.standard_normal((60, 6))
    Y = X[:, :2] @ rng.standard_normal((2, 3)) + 0.01 * rng.standard_normal((60, 3))
    X = X + 1.0 * rng.standard_normal(
        X.shape
    )  # noisy inputs, nearly exact outputs given the latent
    m = BayesianSR(
        n_atoms=4, n_iter=150, n_burn_in=100, thin=5, noise="separate", random_state=0
    ).fit(X, Y)
    tr = m.trace_
    np.testing.assert_allclose(tr["g_xy"], 9 / (6 / tr["g_nx"] + 3 / tr["g_ny"]), rtol=1e-12)
    assert np.median(tr["g_ny"][100:]) > 3 * np.median(tr["g_nx"][100:])
    _, sd = m.predict(X[:5], return_std=True)
    draws, _ = m.predict_draws(X[:5])
    np.testing.assert_allclose(
        sd**2, draws.var(axis=1) + np.mean(1 / m.samples_["g_ny"]) * m.y_scale_**2, rtol=1e-10
    )


def test_logit_prior_mean_and_noise_prior_reach_the_sampler():
    """A strongly negative logit prior mean pulls the retained logits down and switches most codes off; a tight
    proper Gamma prior on g_xy alone holds g_xy near its prior mean."""
    X, Y = _toy()
    base = BayesianSR(n_atoms=6, n_iter=60, n_burn_in=30, thin=3, random_state=0).fit(X, Y)
    neg = BayesianSR(
        n_atoms=6, n_iter=60, n_burn_in=30, thin=3, w_prior_mean=-4.0, random_state=0
    ).fit(X, Y)
    assert neg.samples_["W"].mean() < -2.0 < base.samples_["W"].mean()
    tight = BayesianSR(
        n_atoms=6, n_iter=60, n_burn_in=30, thin=3, a_xy=1e5, b_xy=1e5 / 0.5, random_state=0
    ).fit(X, Y)
    np.testing.assert_allclose(tight.trace_["g_xy"][30:], 0.5, rtol=0.02)
    assert not np.allclose(base.trace_["g_xy"][30:], 0.5, rtol=0.2)


@pytest.mark.parametrize("weighting", ["uniform", "likelihood"])
def test_paper_text_prediction(weighting):
    """prediction="paper-text": draws from the same posterior samples differ from the conditional prediction,
    are finite, and the weighted mean of predict_draws is predict's output."""
    X, Y = _toy()
    m = BayesianSR(**{**SMALL, "prediction_weighting": weighting}).fit(X[:30], Y[:30])
    cond, _ = m.predict_draws(X[30:])
    m.set_params(prediction="paper-text")
    draws, wts = m.predict_draws(X[30:])
    assert np.all(np.isfinite(draws)) and not np.allclose(draws, cond)
    np.testing.assert_allclose(m.predict(X[30:]), np.einsum("tl,tlm->tm", wts, draws), rtol=1e-12)
    np.testing.assert_array_equal(
        m.predict(X[33:35]), m.predict(X[30:])[3:5]
    )  # batch-invariant streams


# ---------------------------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------------------------
def test_rows_mismatch():
    X, Y = _toy()
    with pytest.raises(InputError, match="same number of rows; got X with 40 and Y with 39"):
        BayesianSR(**SMALL).fit(X, Y[:39])


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_input(bad):
    X, Y = _toy()
    X[3, 1] = bad
    with pytest.raises(ValueError, match="Input X contains (NaN|infinity)"):
        BayesianSR(**SMALL).fit(X, Y)
    X, Y = _toy()
    Y[2, 0] = bad
    with pytest.raises(
        InputError, match=r"BayesianSR\.fit: Input Y contains (NaN|infinity) at row 2, column 0"
    ):
        BayesianSR(**SMALL).fit(X, Y)


def test_fewer_rows_than_neighbours():
    X, Y = _toy(n=4)
    with pytest.raises(InputError, match=r"n_neighbors=5\) training rows; got n_samples = 4"):
        BayesianSR(**{**SMALL, "n_neighbors": 5}).fit(X, Y)
    m = BayesianSR(**SMALL).fit(X, Y)
    with pytest.raises(
        InputError,
        match=r"'n_neighbors' parameter of BayesianSR.predict must be an int in the range \[1, 4\]. Got 9",
    ):
        m.predict(X, n_neighbors=9)


def _bad(name, what, got):
    """scikit-learn's message for a parameter outside its constraints: parameter, allowed values, value."""
    return rf"The '{name}' parameter of BayesianSR must be {what}. Got {got} instead"


def _among(name, options, got):
    """The message for a string outside its options (listed sorted)."""
    listed = ", ".join(f"'{o}'" for o in sorted(options))
    return (
        rf"The '{name}' parameter of BayesianSR must be a str among \[{listed}\]. Got {got} instead"
    )


@pytest.mark.parametrize(
    "params, match",
    [
        (
            {"n_burn_in": 30, "n_iter": 30},
            "n_burn_in must be smaller than n_iter=30.*got n_burn_in=30",
        ),
        ({"n_atoms": 0}, _bad("n_atoms", r"an int in the range \[1, inf\)", "0")),
        ({"n_atoms": 2.5}, _bad("n_atoms", r"an int in the range \[1, inf\)", "2.5")),
        ({"thin": 0}, _bad("thin", r"an int in the range \[1, inf\)", "0")),
        ({"n_atoms": True}, _bad("n_atoms", r"an int in the range \[1, inf\)", "True")),
        ({"a0": True}, _bad("a0", r"a float in the range \(0.0, inf\)", "True")),
        (
            {
                "n_iter": 30,
                "n_burn_in": 15,
                "thin": 16,
            },  # before: silently kept the last sweep only
            r"thin=16 retains no sweep of the n_iter - n_burn_in = 15 after burn-in; expected thin <= 15",
        ),
        ({"w_update": "gibbs"}, _among("w_update", kern.W_UPDATES, "'gibbs'")),
        ({"atom_update": "joint"}, _among("atom_update", kern.ATOM_UPDATES, "'joint'")),
        (
            {"prediction_weighting": "max"},
            _among("prediction_weighting", ["uniform", "likelihood"], "'max'"),
        ),
        ({"a0": -1.0}, _bad("a0", r"a float in the range \(0.0, inf\)", "-1.0")),
        (
            {"w_update": "paper-as-printed"},
            _among("w_update", kern.W_UPDATES, "'paper-as-printed'"),
        ),
        ({"prediction": "prior"}, _among("prediction", ["conditional", "paper-text"], "'prior'")),
        ({"a_xy": 0.0}, _bad("a_xy", r"a float in the range \(0.0, inf\) or None", "0.0")),
        ({"b_xy": "1"}, _bad("b_xy", r"a float in the range \(0.0, inf\) or None", "'1'")),
        (
            {"w_prior_mean": np.inf},
            _bad("w_prior_mean", r"a float in the range \(-inf, inf\)", "inf"),
        ),
        (
            {"w_prior_mean": None},
            _bad("w_prior_mean", r"a float in the range \(-inf, inf\)", "None"),
        ),
        ({"noise": "split"}, _among("noise", ["separate", "shared"], "'split'")),
        ({"standardize": "yes"}, _bad("standardize", "an instance of 'bool'.*", "'yes'")),
        ({"input_scaling": "std"}, _among("input_scaling", ["pooled", "bin", "none"], "'std'")),
        (
            {"logit_kernel": "poses"},
            _among("logit_kernel", ["pose", "input", "identity"], "'poses'"),
        ),
        ({"eta_scale": 0.0}, _bad("eta_scale", r"a float in the range \(0.0, inf\)", "0.0")),
        (
            {"logit_kernel": "identity", "eta_scale": 10.0},
            r"eta_scale=10.0 has no effect with logit_kernel='identity'.*expected eta_scale=1.0",
        ),
        (
            {"n_predict_samples": 0},
            _bad("n_predict_samples", r"an int in the range \[1, inf\) or None", "0"),
        ),
        (
            {"n_predict_samples": 6},  # SMALL retains (30 - 15) // 3 = 5 samples
            r"n_predict_samples=6 exceeds the 5 retained samples .*expected an integer in \[1, 5\] or None",
        ),
    ],
)
def test_bad_parameters(params, match):
    X, Y = _toy()
    with pytest.raises(InputError, match=match):
        BayesianSR(**{**SMALL, **params}).fit(X, Y)


def test_non_finite_state_names_the_sweep(monkeypatch):
    X, Y = _toy()
    X[0, 0] = 1e300  # finite input whose square overflows without standardization
    with pytest.raises(
        SamplerError, match=r"non-finite or degenerate sampler state at sweep 0 \(initial state\)"
    ):
        BayesianSR(**{**SMALL, "standardize": False}).fit(X, Y)
    # force a huge atom just before sweep 5: the real sweep then produces a non-finite state
    real_sweep, calls = kern.gibbs_sweep, []

    def sweep_with_blowup(state, data, hyper, rng, *updates):
        if len(calls) == 5:
            state.D[0, :] = 1e300
            state.norms[0] = np.inf
        calls.append(1)
        return real_sweep(state, data, hyper, rng, *updates)

    monkeypatch.setattr(kern, "gibbs_sweep", sweep_with_blowup)
    X, Y = _toy()
    with pytest.raises(SamplerError, match=r"non-finite or degenerate sampler state at sweep 5\b"):
        BayesianSR(**SMALL).fit(X, Y)


def test_degenerate_logit_prior_uses_jitter():
    X, Y = _toy()
    Y[1] = Y[0]  # duplicate poses make Sigma_w singular
    m = BayesianSR(**SMALL).fit(X, Y)
    assert m.sigma_jitter_ > 0 and np.all(np.isfinite(m.predict(X[:3])))


def test_predict_before_fit_and_wrong_width():
    X, Y = _toy()
    from sklearn.exceptions import NotFittedError

    with pytest.raises(NotFittedError):
        BayesianSR(**SMALL).predict(X)
    m = BayesianSR(**SMALL).fit(X, Y)
    with pytest.raises(ValueError, match="X has 4 features, but BayesianSR is expecting 5"):
        m.predict(X[:, :4])
