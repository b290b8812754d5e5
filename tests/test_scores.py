"""Proper scores, PIT values, split-conformal radius, against hand computations."""

import math

import numpy as np
import pytest
from scipy import integrate
from scipy.stats import kstest, norm

from bsrbench import scores as S
from bsrbench.errors import InputError


def _crps_by_integration(y, mu, sigma):
    """CRPS(N(mu, sigma^2), y) = integral of (F(x) - 1{y <= x})^2 dx, by quadrature on both sides of y."""
    lo = integrate.quad(lambda x: norm.cdf(x, mu, sigma) ** 2, -np.inf, y)[0]
    hi = integrate.quad(lambda x: norm.sf(x, mu, sigma) ** 2, y, np.inf)[0]
    return lo + hi


def test_gaussian_crps_equals_numerical_integration():
    rng = np.random.default_rng(0)
    y = rng.normal(size=(3, 2)) * 20
    mu = rng.normal(size=(3, 2)) * 20
    sd = rng.uniform(0.5, 15, size=(3, 2))
    by_hand = np.mean([_crps_by_integration(*v) for v in zip(y.ravel(), mu.ravel(), sd.ravel())])
    assert S.gaussian_crps(y, mu, sd) == pytest.approx(by_hand, rel=1e-7)


def test_gaussian_nlpd_equals_scipy_logpdf_and_wraps():
    rng = np.random.default_rng(1)
    y = rng.uniform(-90, 90, size=(7, 3))
    mu = y + rng.normal(scale=5, size=y.shape)
    sd = rng.uniform(1, 10, size=y.shape)
    assert S.gaussian_nlpd(y, mu, sd) == pytest.approx(-norm.logpdf(y, mu, sd).mean(), rel=1e-12)
    # 179 and -179 are 2 degrees apart
    assert S.gaussian_nlpd([[179.0]], [[-179.0]], [[1.0]]) == pytest.approx(-norm.logpdf(2.0))
    assert S.gaussian_crps([[179.0]], [[-179.0]], [[1.0]]) == pytest.approx(
        _crps_by_integration(2.0, 0.0, 1.0)
    )


def test_sample_crps_equals_the_fair_estimator_by_hand():
    rng = np.random.default_rng(2)
    y = rng.normal(size=(4, 2))
    draws = rng.normal(size=(4, 6, 2))
    m = draws.shape[1]
    hand = []
    for i in range(4):
        for a in range(2):
            x = draws[i, :, a]
            e_abs = np.mean(np.abs(x - y[i, a]))
            pairs = sum(abs(x[j] - x[k]) for j in range(m) for k in range(m))
            hand.append(e_abs - pairs / (2 * m * (m - 1)))
    assert S.sample_crps(y, draws) == pytest.approx(np.mean(hand), rel=1e-12)


def test_sample_scores_of_many_gaussian_draws_approach_the_closed_forms():
    rng = np.random.default_rng(3)
    n, d, m = 40, 3, 4000
    mu = rng.normal(size=(n, d)) * 10
    sd = rng.uniform(1, 5, size=(n, d))
    y = mu + sd * rng.normal(size=(n, d))
    draws = mu[:, None] + sd[:, None] * rng.normal(size=(n, m, d))
    assert S.sample_crps(y, draws) == pytest.approx(S.gaussian_crps(y, mu, sd), rel=0.02)
    assert S.sample_nlpd(y, draws, mu) == pytest.approx(S.gaussian_nlpd(y, mu, sd), rel=0.02)


def test_sample_nlpd_is_the_moment_matched_gaussian_and_draws_wrap():
    rng = np.random.default_rng(4)
    y = rng.normal(size=(5, 2))
    draws = rng.normal(size=(5, 30, 2)) + 0.5
    m, s = draws.mean(axis=1), draws.std(axis=1)
    assert S.sample_nlpd(y, draws, m) == pytest.approx(-norm.logpdf(y, m, s).mean(), rel=1e-12)
    # draws on either side of +-180 are one cluster around 180
    d = np.array([[[179.0], [-179.0], [178.0], [-178.0]]])
    mean, std = S.moment_match(d, np.array([[180.0]]))
    assert mean[0, 0] == pytest.approx(180.0) and std[0, 0] == pytest.approx(np.sqrt(2.5))


def test_pit_values_by_hand_and_uniform_when_calibrated():
    y = np.array([[0.0, 1.0]])
    draws = np.array([[[-1.0, 2.0], [0.0, 0.0], [1.0, 1.0], [2.0, 5.0]]])
    # angle 0: draws -1, 0, 1, 2 at y = 0: one below, one tied -> (1 + 0.5) / 4
    # angle 1: draws 2, 0, 1, 5 at y = 1: one below, one tied -> 1.5 / 4
    np.testing.assert_allclose(S.sample_pit(y, draws), [[0.375, 0.375]])
    np.testing.assert_allclose(S.gaussian_pit([[1.0]], [[0.0]], [[2.0]]), [[norm.cdf(0.5)]])
    rng = np.random.default_rng(5)
    mu = rng.normal(size=(500, 2))
    yy = mu + 3 * rng.normal(size=mu.shape)
    assert kstest(S.gaussian_pit(yy, mu, np.full_like(mu, 3.0)).ravel(), "uniform").pvalue > 0.01
    assert kstest(S.gaussian_pit(yy, mu, np.full_like(mu, 1.0)).ravel(), "uniform").pvalue < 1e-6


def test_conformal_radius_by_hand_and_its_coverage():
    errors = np.arange(1.0, 10.0)[:, None]  # 9 calibration errors 1 .. 9
    # ceil((9 + 1) 0.9) = 9: the 9th smallest; ceil(10 * 0.5) = 5: the 5th smallest
    assert S.conformal_radius(errors, np.zeros_like(errors), 0.9)[0] == 9.0
    assert S.conformal_radius(errors, np.zeros_like(errors), 0.5)[0] == 5.0
    assert np.isinf(S.conformal_radius(errors[:5], np.zeros((5, 1)), 0.9)[0])  # ceil(5.4) = 6 > 5
    rng = np.random.default_rng(6)
    cover = []
    for _ in range(2000):  # exchangeable errors: mean coverage k / (m + 1) = 18 / 20 for m = 19
        e = rng.standard_t(3, size=(30, 1))
        r = S.conformal_radius(e[:19], np.zeros((19, 1)), 0.9)
        cover.append(S.interval_coverage_radius(e[19:], np.zeros((11, 1)), r))
    assert np.mean(cover) == pytest.approx(0.9, abs=0.012)
    fit, cal = S.calibration_split(40, 0.25, seed=1)
    assert cal.size == 10 and np.union1d(fit, cal).tolist() == list(range(40))


def test_no_std_gives_none_and_non_finite_predictions_are_rejected():
    y = np.zeros((3, 2))
    out = S.proper_scores(y, y)
    assert out == {"nlpd": None, "crps": None, "scores_from": None}
    bad = y.copy()
    bad[2, 1] = np.inf
    with pytest.raises(InputError, match=r"hsc: y_pred contains infinity at row 2, column 1"):
        S.proper_scores(y, bad, std=np.ones_like(y), what="hsc")
    sd = np.ones_like(y)
    sd[0, 0] = np.nan
    with pytest.raises(InputError, match=r"std contains NaN at row 0, column 0"):
        S.proper_scores(y, y, std=sd)
    with pytest.raises(InputError, match=r"std is negative"):
        S.gaussian_nlpd(y, y, -np.ones_like(y))
    draws = np.zeros((3, 4, 2))
    draws[1, 2, 0] = np.nan
    with pytest.raises(InputError, match=r"samples contains NaN at row 1, column 2, index 0"):
        S.proper_scores(y, y, samples=draws)
    # a zero std for an exactly predicted (constant) angle is floored, not an infinite score
    assert math.isfinite(S.gaussian_nlpd(y, y, np.zeros_like(y)))


def test_split_conformal_of_a_fitted_model_covers_new_frames():
    from bsrbench.models.reference import RidgeRegressor

    rng = np.random.default_rng(8)
    W = rng.normal(size=(4, 3))
    covers = []
    for rep in range(40):
        X = rng.normal(size=(140, 4))
        Y = X @ W * 10 + rng.standard_t(4, size=(140, 3))
        out = S.split_conformal(
            RidgeRegressor(alpha=1e-3), X[:40], Y[:40], X[40:], Y[40:], seed=rep
        )
        assert out["conformal_radius"].shape == (3,)
        covers.append(out["conformal_coverage"])
    # 10 calibration rows: radius = the ceil(11 * 0.9) = 10th smallest error, coverage 10 / 11 on average
    assert np.mean(covers) == pytest.approx(10 / 11, abs=0.03)


def test_weighted_draws_by_hand():
    y = np.array([[0.0]])
    draws = np.array([[[-1.0], [1.0], [3.0]]])
    w = np.array([[0.5, 0.25, 0.25]])
    # weighted moments: mean 0.5, var 0.5*2.25 + 0.25*0.25 + 0.25*6.25 = 2.75
    m, s = S.moment_match(draws, np.zeros((1, 1)), w)
    assert m[0, 0] == pytest.approx(0.5) and s[0, 0] == pytest.approx(np.sqrt(2.75))
    np.testing.assert_allclose(S.sample_pit(y, draws, w), [[0.5]])
    # CRPS of the weighted empirical distribution: sum w|x - y| - 1/2 sum w_i w_j |x_i - x_j|
    x, ww = draws[0, :, 0], w[0]
    hand = np.sum(ww * np.abs(x)) - 0.5 * np.sum(
        ww[:, None] * ww[None] * np.abs(x[:, None] - x[None])
    )
    assert S.sample_crps(y, draws, w) == pytest.approx(hand, rel=1e-12)
    with pytest.raises(InputError, match=r"weights must have shape \(frames, draws\) = \(1, 3\)"):
        S.sample_crps(y, draws, w[:, :2])


def test_predictive_draws_of_pm_carry_its_noise():
    from bsrbench.models.bsr import BayesianSR

    rng = np.random.default_rng(9)
    X = np.abs(rng.normal(size=(40, 6)))
    Y = X[:, :3] @ rng.normal(size=(3, 2)) * 5 + rng.normal(size=(40, 2))
    est = BayesianSR(n_atoms=8, n_neighbors=3, n_iter=400, n_burn_in=100, thin=1, random_state=0)
    est.fit(X, Y)
    Xt = np.abs(rng.normal(size=(30, 6)))
    mean, std = est.predict(Xt, return_std=True)
    draws, w = S.predictive_draws(est, Xt, seed=1)
    assert draws.shape == (30, 300, 2) and w.shape == (30, 300)
    m, s = S.moment_match(draws, mean, w)
    # one noise draw per sample: the draws' spread is predict's std (samples' spread + noise) up to MC error
    assert np.median(s / std) == pytest.approx(1.0, abs=0.05)
    noise_free, _ = est.predict_draws(Xt)
    assert np.median(np.std(noise_free, axis=1) / std) < 0.9


def test_split_conformal_refits_with_the_given_params():
    from bsrbench.models.reference import RidgeRegressor

    rng = np.random.default_rng(5)
    X = rng.normal(size=(60, 4))
    Y = X @ rng.normal(size=(4, 3)) * 10 + rng.normal(size=(60, 3))
    args = (X[:40], Y[:40], X[40:], Y[40:])
    heavy = S.split_conformal(RidgeRegressor(alpha=1e6), *args, seed=1)
    swapped = S.split_conformal(RidgeRegressor(alpha=1e-3), *args, seed=1, params={"alpha": 1e6})
    light = S.split_conformal(RidgeRegressor(alpha=1e-3), *args, seed=1)
    np.testing.assert_array_equal(swapped["conformal_radius"], heavy["conformal_radius"])
    assert (
        light["conformal_radius"] < heavy["conformal_radius"]
    ).all()  # a better fit, narrower interval
