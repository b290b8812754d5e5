"""Proper scores of predictive distributions of joint angles, PIT values and a split-conformal reference interval.

Scores (Gneiting and Raftery, JASA 2007), per angle and test frame, then averaged over frames and angles (lower
is better; angles in degrees):

* NLPD, the negative log predictive density (the log score), in nats per angle with densities per degree;
* CRPS, the continuous ranked probability score, in degrees (from the scoringrules package).

A prediction is either Gaussian (mean and std per angle, from ``predict(X, return_std=True)``) or a set of
posterior predictive draws of the observed angle, noise included (PM's retained samples plus their noise,
:func:`predictive_draws`), optionally weighted. For a Gaussian both scores are in closed form. For draws the CRPS
is the sample estimate of ``scoringrules.crps_ensemble``: for equal weights the probability-weighted-moment
estimator ("pwm"), equal to the "fair" one and unbiased for the CRPS of the distribution the draws come from
(Ferro 2014; Zamo and Naveau 2018), in O(S log S) per angle where the pairwise "fair" form needs O(S^2) memory;
for weighted draws the CRPS of their weighted empirical distribution ("int"). The NLPD of draws is that of the
Gaussian with their mean and variance: PM's ``predict(X, return_std=True)`` std when given (the exact moments of
the mixture the draws sample), else a moment match of the draws (a kernel density estimate per angle would add a
bandwidth to choose). A sample CRPS and a closed-form CRPS estimate the same quantity but are not strictly
comparable at small sample sizes (Zamo and Naveau, Math. Geosci. 2018).

Angles wrap: the error of a prediction is the wrapped difference ``((y - mu + 180) mod 360) - 180``, and every
draw is first moved by a multiple of 360 degrees to within 180 degrees of the predicted mean.

PIT values (probability integral transform, Gneiting, Balabdaoui and Raftery, JRSS-B 2007) are the predictive
CDF at the observation: uniform on [0, 1] for a calibrated forecast, so their histogram shows over-confidence
(a U shape) or under-confidence (a hump).

The split-conformal interval (Vovk et al. 2005; Lei et al., JASA 2018) is the coverage reference: from absolute
errors of a model fitted without a calibration part of the training set, predicted on that part, the radius of
angle ``a`` is the ``ceil((n + 1) level)``-th smallest of its n calibration errors; ``mean +- radius`` then covers a
new exchangeable frame's angle with probability at least ``level``, whatever the model.
"""

import math

import numpy as np
from scipy.stats import norm

from .errors import InputError
from .metrics import wrap_degrees

#: Predictive std below this (degrees) is taken as this: the angle files' printed resolution. A model that gives
#: a zero std for an angle constant in training would otherwise get an infinite log score for 1e-9 deg of error.
STD_FLOOR = 1e-3


def check_finite(a, name, what):
    """Raise InputError naming ``what``, the array and the first non-finite entry."""
    bad = ~np.isfinite(a)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        where = ", ".join(f"{k} {i}" for k, i in zip(("row", "column", "index"), idx))
        kind = "NaN" if np.isnan(a[idx]) else "infinity"
        raise InputError(
            f"{what}: {name} contains {kind} at {where}; expected finite values (a non-finite prediction "
            f"cannot be scored)"
        )


def check_gaussian(y_true, mean, std, what="scores"):
    """``(y_true, mean, std)`` as float arrays (n, d) after the checks; InputError naming the problem."""
    y_true = np.asarray(y_true, dtype=float)
    mean = np.asarray(mean, dtype=float)
    std = np.asarray(std, dtype=float)
    if y_true.ndim != 2 or mean.shape != y_true.shape or std.shape != y_true.shape:
        raise InputError(
            f"{what}: y_true, mean and std must be 2-D arrays of one shape (frames x angles); got "
            f"{y_true.shape}, {mean.shape} and {std.shape}"
        )
    for name, a in (("y_true", y_true), ("mean", mean), ("std", std)):
        check_finite(a, name, what)
    if (std < 0).any():
        r, c = (int(i) for i in np.argwhere(std < 0)[0])
        raise InputError(
            f"{what}: std is negative ({std[r, c]!r}) at row {r}, column {c}; expected std >= 0"
        )
    return y_true, mean, np.maximum(std, STD_FLOOR)


def check_weights(weights, samples, what="scores"):
    """Draw weights (n, S), non-negative, rows normalized to 1; None stays None (equal weights)."""
    if weights is None:
        return None
    w = np.asarray(weights, dtype=float)
    if w.shape != samples.shape[:2]:
        raise InputError(
            f"{what}: weights must have shape (frames, draws) = {samples.shape[:2]}; got {w.shape}"
        )
    check_finite(w, "weights", what)
    total = w.sum(axis=1, keepdims=True)
    if (w < 0).any() or not (total > 0).all():
        raise InputError(f"{what}: weights must be >= 0 with a positive sum per frame")
    return w / total


def check_samples(y_true, samples, what="scores"):
    """``(y_true (n, d), samples (n, S, d))`` after the checks; InputError naming the problem."""
    y_true = np.asarray(y_true, dtype=float)
    samples = np.asarray(samples, dtype=float)
    if y_true.ndim != 2 or samples.ndim != 3 or samples.shape[::2] != y_true.shape:
        raise InputError(
            f"{what}: samples must have shape (frames, draws, angles) = ({y_true.shape[0]}, S, "
            f"{y_true.shape[-1]}); got {samples.shape} for y_true {y_true.shape}"
        )
    if samples.shape[1] < 2:
        raise InputError(f"{what}: samples have {samples.shape[1]} draw per frame; need at least 2")
    check_finite(y_true, "y_true", what)
    check_finite(samples, "samples", what)
    return y_true, samples


def _draws_near(samples, centre):
    """Draws (n, S, d) moved by multiples of 360 deg to within 180 deg of ``centre`` (n, d)."""
    return centre[:, None, :] + wrap_degrees(samples - centre[:, None, :])


def moment_match(samples, centre, weights=None):
    """Mean and std (n, d) of draws (n, S, d), weighted by ``weights`` (n, S) if given, after wrapping them to
    within 180 deg of ``centre`` (n, d)."""
    d = _draws_near(np.asarray(samples, float), np.asarray(centre, float))
    if weights is None:
        return d.mean(axis=1), d.std(axis=1)
    w = np.asarray(weights, dtype=float)[:, :, None]
    m = np.sum(w * d, axis=1)
    return m, np.sqrt(np.sum(w * (d - m[:, None, :]) ** 2, axis=1))


def predictive_draws(estimator, X, seed=0, draws=None):
    """Posterior predictive draws ``(draws (n, S, outputs), weights (n, S))`` of an estimator with
    ``predict_draws(X)`` (e.g. :class:`bsrbench.models.bsr.BayesianSR`), in the units of its fitted Y: each
    retained sample's noise-free prediction plus one Gaussian noise draw of that sample's noise variance.

    For BayesianSR the noise variance of sample t is ``1 / g_ny[t]`` on the standardized outputs (``g_ny``: the
    output rows' noise precision, equal to g_xy unless ``noise="separate"``), times ``y_scale_**2`` per output:
    the same noise that its ``predict(X, return_std=True)`` adds to the spread of the samples. ``seed`` seeds the
    noise (``numpy.random.default_rng``). ``draws``: the ``(draws, weights)`` of ``estimator.predict_draws(X)``
    if already computed.
    """
    draws, weights = estimator.predict_draws(X) if draws is None else draws
    draws = np.asarray(draws, dtype=float)
    g = np.asarray(estimator.samples_["g_ny"], dtype=float).ravel()
    # The prediction uses the last draws.shape[1] retained samples (BayesianSR's n_predict_samples).
    g = g[g.size - draws.shape[1] :] if g.size >= draws.shape[1] else g
    if g.size != draws.shape[1]:
        raise InputError(
            f"{type(estimator).__name__}: {g.size} noise precisions for {draws.shape[1]} draws per frame"
        )
    scale = np.asarray(getattr(estimator, "y_scale_", 1.0), dtype=float)
    sd = np.sqrt(1.0 / g)[None, :, None] * np.broadcast_to(scale, (draws.shape[2],))[None, None, :]
    rng = np.random.default_rng(seed)
    return draws + sd * rng.standard_normal(draws.shape), np.asarray(weights, dtype=float)


# ------------------------------------------------------------------------------------------------ NLPD
def gaussian_nlpd(y_true, mean, std, what="nlpd"):
    """Mean over frames and angles of ``-log N(y; mean, std^2)`` with the wrapped error (nats; per degree)."""
    y_true, mean, std = check_gaussian(y_true, mean, std, what)
    r = wrap_degrees(y_true - mean)
    per_angle = np.mean(0.5 * np.log(2 * np.pi * std * std) + 0.5 * (r / std) ** 2, axis=0)
    return float(per_angle.mean())


def sample_nlpd(y_true, samples, centre, weights=None, what="nlpd"):
    """NLPD of the Gaussian moment match of draws (n, S, d) (weighted by ``weights`` (n, S) if given) wrapped
    around ``centre`` (n, d; the point prediction)."""
    y_true, samples = check_samples(y_true, samples, what)
    m, s = moment_match(samples, centre, check_weights(weights, samples, what))
    return gaussian_nlpd(y_true, m, s, what)


# ------------------------------------------------------------------------------------------------ CRPS
def gaussian_crps(y_true, mean, std, what="crps"):
    """Mean over frames and angles of the closed-form CRPS of ``N(mean, std^2)`` (degrees, wrapped error)."""
    import scoringrules as sr

    y_true, mean, std = check_gaussian(y_true, mean, std, what)
    obs = mean + wrap_degrees(y_true - mean)
    return float(np.mean(np.asarray(sr.crps_normal(obs, mean, std, backend="numpy"), dtype=float)))


def sample_crps(y_true, samples, weights=None, what="crps"):
    """Mean over frames and angles of the sample CRPS of draws (n, S, d) (degrees; each draw wrapped to within
    180 deg of the observation): the unbiased PWM estimator for equally weighted draws; with ``weights``
    (n, S) the CRPS of the weighted empirical distribution (scoringrules' "int" estimator, ``ens_w``), which
    exceeds the unbiased one by about ``E|X - X'| / (2 S)``."""
    import scoringrules as sr

    y_true, samples = check_samples(y_true, samples, what)
    weights = check_weights(weights, samples, what)
    fct = np.moveaxis(_draws_near(samples, y_true), 1, -1)
    if weights is None:
        c = sr.crps_ensemble(y_true, fct, m_axis=-1, estimator="pwm", backend="numpy")
    else:
        w = np.broadcast_to(weights[:, None, :], fct.shape)
        c = sr.crps_ensemble(y_true, fct, m_axis=-1, ens_w=w, estimator="int", backend="numpy")
    return float(np.mean(np.asarray(c, dtype=float)))


# ------------------------------------------------------------------------------------------------ PIT
def gaussian_pit(y_true, mean, std, what="pit"):
    """PIT values (n, d): the Gaussian predictive CDF at the observation (wrapped error)."""
    y_true, mean, std = check_gaussian(y_true, mean, std, what)
    return norm.cdf(wrap_degrees(y_true - mean) / std)


def sample_pit(y_true, samples, weights=None, what="pit"):
    """PIT values (n, d) from draws (n, S, d): the (weighted) fraction of draws below the observation, ties
    counted half (draws wrapped to within 180 deg of the observation)."""
    y_true, samples = check_samples(y_true, samples, what)
    weights = check_weights(weights, samples, what)
    e = wrap_degrees(samples - y_true[:, None, :])
    if weights is None:
        return np.mean(e < 0, axis=1) + 0.5 * np.mean(e == 0, axis=1)
    w = weights[:, :, None]
    return np.sum(w * (e < 0), axis=1) + 0.5 * np.sum(w * (e == 0), axis=1)


# ------------------------------------------------------------------------------------------- split conformal
def min_calibration_frames(level):
    """The fewest calibration frames with a finite split-conformal radius at ``level``: the smallest m with
    ``ceil((m + 1) level) <= m``, i.e. ``ceil(level / (1 - level))`` (9 at 0.9)."""
    return math.ceil(level / (1.0 - level) - 1e-9)


def calibration_split(n, fraction=0.25, seed=0, min_calibration=5):
    """Indices ``(fit, calibration)`` into ``range(n)`` training rows: a random ``fraction`` held out for
    calibration (at least ``min_calibration`` rows, and at least 1 row left to fit)."""
    n = int(n)
    if not 0 < fraction < 1:
        raise InputError(f"calibration fraction must be in (0, 1); got {fraction!r}")
    n_cal = max(int(min_calibration), int(round(fraction * n)))
    if n_cal >= n:
        raise InputError(
            f"cannot hold out {n_cal} calibration rows from {n} training rows; need at least {n_cal + 1}"
        )
    perm = np.random.default_rng(seed).permutation(n)
    return np.sort(perm[n_cal:]), np.sort(perm[:n_cal])


def conformal_radius(cal_true, cal_pred, level=0.9, what="conformal"):
    """Per-angle radius (d,) of the split-conformal interval from calibration truths and predictions (m, d).

    The ``ceil((m + 1) level)``-th smallest absolute wrapped error of each angle; ``inf`` when m is too small for
    ``level`` (``ceil((m + 1) level) > m``): no finite interval then has the guarantee.
    """
    cal_true = np.asarray(cal_true, dtype=float)
    cal_pred = np.asarray(cal_pred, dtype=float)
    if cal_true.ndim != 2 or cal_true.shape != cal_pred.shape or cal_true.shape[0] < 1:
        raise InputError(
            f"{what}: calibration truths and predictions must be 2-D of one shape with >= 1 row; got "
            f"{cal_true.shape} and {cal_pred.shape}"
        )
    if not 0 < level < 1:
        raise InputError(f"{what}: level must be in (0, 1); got {level!r}")
    check_finite(cal_true, "calibration truths", what)
    check_finite(cal_pred, "calibration predictions", what)
    m = cal_true.shape[0]
    k = math.ceil((m + 1) * level)
    if k > m:
        return np.full(cal_true.shape[1], np.inf)
    err = np.sort(np.abs(wrap_degrees(cal_true - cal_pred)), axis=0)
    return err[k - 1]


def interval_coverage_radius(y_true, y_pred, radius):
    """Fraction of test angles within ``radius`` (d,) of the prediction (wrapped): the coverage of
    ``y_pred +- radius``."""
    y_true = np.asarray(y_true, dtype=float)
    y_pred = np.asarray(y_pred, dtype=float)
    radius = np.asarray(radius, dtype=float)
    if y_true.shape != y_pred.shape or y_true.ndim != 2 or radius.shape != (y_true.shape[1],):
        raise InputError(
            f"y_true {y_true.shape}, y_pred {y_pred.shape} and radius {radius.shape} do not match "
            f"(frames x angles, angles)"
        )
    check_finite(y_pred, "y_pred", "conformal coverage")
    return float(np.mean(np.abs(wrap_degrees(y_true - y_pred)) <= radius))


def split_conformal(
    estimator,
    X,
    Y,
    X_test,
    Y_test,
    *,
    transform=None,
    level=0.9,
    fraction=0.25,
    seed=0,
    params=None,
):
    """Split-conformal ``level`` intervals of a method on one split: returns ``{"conformal_radius" (d,),
    "conformal_coverage"}``.

    A clone of ``estimator`` (with ``params`` set, if given) is fitted on the training rows ``X, Y`` less a
    random ``fraction`` held out, and at least :func:`min_calibration_frames` of them, below which the radius
    is infinite (:func:`calibration_split`, ``seed``), the radius per angle comes from its errors on the held-out rows
    (:func:`conformal_radius`), and the coverage is that of its test predictions ``+- radius`` on ``Y_test``.
    ``Y`` and ``Y_test`` are angles (degrees); ``transform`` (``forward``/``inverse``, e.g.
    :class:`bsrbench.poses.HeadingTransform`) maps them to the space the estimator is fitted in and back.
    """
    from sklearn.base import clone

    X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
    fwd = transform.forward if transform is not None else (lambda a: a)
    inv = transform.inverse if transform is not None else (lambda a: np.asarray(a, dtype=float))
    fit, cal = calibration_split(
        X.shape[0], fraction, seed, min_calibration=max(5, min_calibration_frames(level))
    )
    est = clone(estimator).set_params(**(params or {})).fit(X[fit], fwd(Y[fit]))
    radius = conformal_radius(Y[cal], inv(est.predict(X[cal])), level)
    cover = interval_coverage_radius(
        Y_test, inv(est.predict(np.asarray(X_test, dtype=float))), radius
    )
    return {"conformal_radius": radius, "conformal_coverage": cover}


# ------------------------------------------------------------------------------------------------ one call
def proper_scores(y_true, y_pred, *, std=None, samples=None, weights=None, what="scores"):
    """``{"nlpd", "crps", "scores_from"}`` of one test set: from ``samples`` (n, S, d) if given (sample CRPS;
    the NLPD of the Gaussian ``(y_pred, std)`` if ``std`` is given, else moment-matched around ``y_pred``),
    else from the Gaussian ``(y_pred, std)``; all None (not NaN, not 0)
    when neither is given. ``weights`` (n, S): the draws' weights (None: equal). ``scores_from`` is
    ``"samples"``, ``"gaussian"`` or None.

    The draws must be of the posterior predictive distribution of an observed angle, i.e. include the
    observation noise (:func:`predictive_draws`), as the Gaussian std of ``predict(X, return_std=True)`` does;
    draws of the noise-free mean would be scored as over-confident."""
    y_true = np.asarray(y_true, dtype=float)
    y_pred = np.asarray(y_pred, dtype=float)
    if y_true.ndim != 2 or y_pred.shape != y_true.shape:
        raise InputError(
            f"{what}: y_true and y_pred must be 2-D arrays of one shape; got {y_true.shape} and "
            f"{y_pred.shape}"
        )
    check_finite(y_true, "y_true", what)
    check_finite(y_pred, "y_pred", what)
    if samples is not None:
        # With both, the NLPD takes the std: the exact moments of the mixture the draws sample (PM's
        # predict(X, return_std=True)), where a moment match of few draws would be noisy.
        nlpd = (
            gaussian_nlpd(y_true, y_pred, std, what)
            if std is not None
            else sample_nlpd(y_true, samples, y_pred, weights, what)
        )
        return {
            "nlpd": nlpd,
            "crps": sample_crps(y_true, samples, weights, what),
            "scores_from": "samples",
        }
    if std is not None:
        return {
            "nlpd": gaussian_nlpd(y_true, y_pred, std, what),
            "crps": gaussian_crps(y_true, y_pred, std, what),
            "scores_from": "gaussian",
        }
    return {"nlpd": None, "crps": None, "scores_from": None}
