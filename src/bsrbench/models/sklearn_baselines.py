"""Today's baselines: scikit-learn regressors a practitioner would try first, with the baselines' contract.

Kernel ridge regression with an RBF kernel, Gaussian-process regression with an ARD RBF kernel plus white noise,
a random forest and a multilayer perceptron with early stopping (scikit-learn's ``KernelRidge``,
``GaussianProcessRegressor``, ``RandomForestRegressor``, ``MLPRegressor``). Weighted k-NN, the fifth, is
:class:`bsrbench.models.reference.NearestNeighbourRegressor` with a grid over k and the weights.

The thin wrappers add what the study relies on and the scikit-learn estimators lack:

* inputs scaled by :class:`bsrbench.models.scaling.InputScaler` (``"pooled"``, as every scaled baseline), so that
  an RBF width or a network's first layer sees features of one scale;
* predictions clipped to the widened training range (:func:`bsrbench.models.scaling.output_bounds`);
* an error naming the row, the column and the value for a non-finite feature (the random forest would
  otherwise accept NaN as a missing value) and for a bad hyper-parameter (``_check_params``, also called by the
  study's configuration check before any job runs);
* the kernel ridge fits centred outputs (``KernelRidge`` has no intercept) with ``gamma`` relative to the data;
  the MLP fits standardized outputs (angles of a few degrees and of a hundred would otherwise weigh differently
  in its loss and its early-stopping score);
* the GP returns its predictive std per output (``predict(X, return_std=True)``), which the study scores.
"""

from functools import partial
from numbers import Integral, Real

import numpy as np
from scipy.linalg import cho_solve, cholesky
from scipy.optimize import minimize
from sklearn.ensemble import RandomForestRegressor
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Product, Sum, WhiteKernel
from sklearn.kernel_ridge import KernelRidge
from sklearn.neural_network import MLPRegressor
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import Interval, StrOptions

from ..errors import InputError
from .reference import (
    COUNT,
    NON_NEGATIVE,
    POSITIVE,
    PoseRegressor,
    _format_output,
    _median_distance,
    _validate_fit,
    _validate_predict,
    check_params,
)
from .scaling import INPUT_SCALINGS, InputScaler

__all__ = ["KernelRidgeRBF", "GaussianProcessARD", "RandomForest", "MLP"]


class _ScaledRegressor(PoseRegressor):
    """Shared fit/predict: validate, scale inputs, fit ``self._make(X, Y)`` on (optionally standardized)
    outputs, clip predictions."""

    _standardize_y = False

    def fit(self, X, Y):
        X, Y = _validate_fit(self, X, Y)
        self._check_params(n_samples=X.shape[0])
        self.n_outputs_ = Y.shape[1]
        self.scaler_ = InputScaler(self.input_scaling).fit(X)
        Xs = self.scaler_.transform(X)
        self.y_mean_ = Y.mean(axis=0)
        sd = Y.std(axis=0)
        self.y_scale_ = np.where(sd > 0, sd, 1.0) if self._standardize_y else np.ones_like(sd)
        Z = (Y - self.y_mean_) / self.y_scale_
        self.model_ = self._make(Xs, Y).fit(Xs, Z[:, 0] if Z.shape[1] == 1 else Z)
        return self

    def _raw_predict(self, X):
        X = _validate_predict(self, X)
        P = np.asarray(self.model_.predict(self.scaler_.transform(X)), dtype=float)
        return P.reshape(X.shape[0], -1) * self.y_scale_ + self.y_mean_

    def predict(self, X):
        return _format_output(self, self._raw_predict(X))


class KernelRidgeRBF(_ScaledRegressor):
    """Kernel ridge regression with the RBF kernel ``exp(-gamma ||x - x'||^2)`` (``sklearn.kernel_ridge``).

    Parameters
    ----------
    alpha : float > 0
        Ridge penalty.
    gamma_scale : float > 0
        ``gamma = gamma_scale / m^2`` with m the median distance between the scaled training inputs, so the grid
        is free of the features' units (``gamma_scale = 1``: the kernel falls to 1/e at the median distance).
    input_scaling : {"pooled", "bin", "none"}
        Rule of :class:`bsrbench.models.scaling.InputScaler`.

    Outputs are centred on their training mean before the fit (the kernel ridge has no intercept).
    """

    _parameter_constraints = {
        "alpha": [POSITIVE],
        "gamma_scale": [POSITIVE],
        "input_scaling": [StrOptions(set(INPUT_SCALINGS))],
    }

    def __init__(self, alpha=1.0, gamma_scale=1.0, input_scaling="pooled"):
        self.alpha = alpha
        self.gamma_scale = gamma_scale
        self.input_scaling = input_scaling

    def _make(self, Xs, Y):
        self.gamma_ = float(self.gamma_scale) / _median_distance(Xs) ** 2
        return KernelRidge(alpha=float(self.alpha), kernel="rbf", gamma=self.gamma_)


def _lbfgsb(obj_func, initial_theta, bounds, max_iter=50):
    """scikit-learn's GP optimizer (L-BFGS-B on the log marginal likelihood) with an iteration cap."""
    res = minimize(
        obj_func,
        initial_theta,
        method="L-BFGS-B",
        jac=True,
        bounds=bounds,
        options={"maxiter": int(max_iter)},
    )
    return res.x, res.fun


def _scaled_rbf_plus_noise(kernel):
    """``(constant, rbf, white)`` if ``kernel`` is ``ConstantKernel * RBF + WhiteKernel`` (the GP baseline's
    kernel) with no fixed hyper-parameter, else None."""
    if not (isinstance(kernel, Sum) and isinstance(kernel.k1, Product)):
        return None
    c, rbf, white = kernel.k1.k1, kernel.k1.k2, kernel.k2
    kinds = (type(c), type(rbf), type(white)) == (ConstantKernel, RBF, WhiteKernel)
    if not kinds or any(h.fixed for h in kernel.hyperparameters):
        return None
    return c, rbf, white


def _scaled_rbf_plus_noise_gradient(W, K1, X, parts):
    """``0.5 * sum_ij W_ij dK_ij / dtheta`` for ``K = c * RBF + noise I`` (``K1 = c * RBF`` on ``X``), theta
    = log (c, length scales, noise), without the n x n x (parameters) kernel gradient.

    dK/dlog c = K1; dK/dlog noise = noise I; dK_ij/dlog l_d = K1_ij (x_id - x_jd)^2 / l_d^2, whose sum with
    ``M = W * K1`` is ``sum_i (M 1)_i z_id^2 + (1^T M)_i z_id^2 - 2 z_d^T M z_d`` for ``z = X / l`` (centred:
    the differences do not change and the sums cancel less).
    """
    _, rbf, white = parts
    M = W * K1
    Z = X / rbf.length_scale
    Z = Z - Z.mean(axis=0)
    Z2 = Z * Z
    d_scales = 0.5 * (M.sum(axis=1) @ Z2 + M.sum(axis=0) @ Z2) - np.einsum("id,id->d", Z, M @ Z)
    if not rbf.anisotropic:
        d_scales = d_scales.sum(keepdims=True)
    return np.concatenate(([0.5 * M.sum()], d_scales, [0.5 * white.noise_level * np.trace(W)]))


class _SharedKernelGPR(GaussianProcessRegressor):
    """``GaussianProcessRegressor`` whose log-marginal-likelihood gradient sums over the outputs first.

    The m outputs (columns of the normalized y) share one kernel K, so the gradient of the summed log marginal
    likelihood (Rasmussen & Williams 2006, eq. 5.9, summed over the outputs) is one contraction,
    ``0.5 * sum_ij W_ij dK_ij/dtheta_k`` with ``W = alpha alpha^T - m K^-1`` and ``alpha = K^-1 y``,
    instead of scikit-learn's m contractions of the n x n x (parameters) kernel gradient (most of a fit's
    time with the study's 58 outputs). The value, the jitter ``alpha`` on K's diagonal, the normalization, the
    optimizer and its restarts are scikit-learn's; only the gradient's arithmetic (the order of the sums)
    differs. For the baseline's kernel ``c * RBF + noise`` the contraction is in closed form
    (:func:`_scaled_rbf_plus_noise_gradient`), without forming the kernel gradient.
    """

    def log_marginal_likelihood(self, theta=None, eval_gradient=False, clone_kernel=True):
        """As ``GaussianProcessRegressor.log_marginal_likelihood``; the gradient summed over the outputs first."""
        if theta is None or not eval_gradient:
            return super().log_marginal_likelihood(theta, eval_gradient, clone_kernel)
        if clone_kernel:
            kernel = self.kernel_.clone_with_theta(theta)
        else:
            kernel = self.kernel_
            kernel.theta = theta
        parts = _scaled_rbf_plus_noise(kernel)
        if parts is None:
            K, dK = kernel(self.X_train_, eval_gradient=True)
        else:  # the same K as kernel(X); its gradient below, in closed form
            K1 = kernel.k1(self.X_train_)
            K = K1 + kernel.k2(self.X_train_)
        K[np.diag_indices_from(K)] += self.alpha
        try:
            L = cholesky(K, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            return -np.inf, np.zeros_like(theta)
        y = self.y_train_.reshape(K.shape[0], -1)
        n, m = y.shape
        a = cho_solve((L, True), y, check_finite=False)
        # log N(y_k | 0, K) per output k: -y_k^T K^-1 y_k / 2 - log|K| / 2 - n log(2 pi) / 2
        per_output = (
            -0.5 * np.einsum("ik,ik->k", y, a)
            - np.log(np.diag(L)).sum()
            - 0.5 * n * np.log(2 * np.pi)
        )
        W = a @ a.T - m * cho_solve((L, True), np.eye(n), check_finite=False)
        if parts is None:
            grad = 0.5 * (W.reshape(-1) @ dK.reshape(n * n, -1))
        else:
            grad = _scaled_rbf_plus_noise_gradient(W, K1, self.X_train_, parts)
        return per_output.sum(), grad


class GaussianProcessARD(_ScaledRegressor):
    """Gaussian-process regression, kernel ``c * RBF(length scale per feature) + white noise``, its
    hyper-parameters by maximum marginal likelihood (``sklearn.gaussian_process.GaussianProcessRegressor``,
    L-BFGS-B, one kernel shared by all outputs, each output normalized to zero mean and unit variance).

    The length scales start at the median distance between the scaled training inputs; the predictive std
    (``predict(X, return_std=True)``, one per output) includes the white noise, i.e. it is the std of a new
    observed angle.
    The marginal likelihood's gradient is summed over the outputs before its contraction with the kernel's
    gradient (:class:`_SharedKernelGPR`): scikit-learn's optimum at a fraction of the cost.

    Parameters
    ----------
    optimizer_max_iter : int >= 1
        L-BFGS-B iterations per optimizer start. With 100 length scales the optimizer's own tolerance takes
        long to meet (N = 100, acrobatics features, seed 0: 620 evaluations, 21 s CPU, test error 7.25 deg);
        30 iterations took 1.3 s for 6.98 deg, 100 took 4.4 s for 7.22 deg (the marginal likelihood gains
        little more and the extra iterations shrink some length scales and the noise).
    n_restarts_optimizer : int >= 0
        Extra optimizer starts from random hyper-parameters (``random_state``).
    noise_level : float > 0
        Initial white-noise variance (of the normalized outputs).
    input_scaling : {"pooled", "bin", "none"}
        Rule of :class:`bsrbench.models.scaling.InputScaler`.
    random_state : int, RandomState or None
        Seed of the restarts.
    """

    _parameter_constraints = {
        "optimizer_max_iter": [COUNT],
        "n_restarts_optimizer": [Interval(Integral, 0, None, closed="left")],
        "noise_level": [POSITIVE],
        "input_scaling": [StrOptions(set(INPUT_SCALINGS))],
        "random_state": ["random_state"],
    }

    def __init__(
        self,
        optimizer_max_iter=50,
        n_restarts_optimizer=0,
        noise_level=0.1,
        input_scaling="pooled",
        random_state=None,
    ):
        self.optimizer_max_iter = optimizer_max_iter
        self.n_restarts_optimizer = n_restarts_optimizer
        self.noise_level = noise_level
        self.input_scaling = input_scaling
        self.random_state = random_state

    def _make(self, Xs, Y):
        m = _median_distance(Xs)
        kernel = ConstantKernel(1.0, (1e-3, 1e3)) * RBF(
            np.full(Xs.shape[1], m), (1e-2 * m, 1e3 * m)
        ) + WhiteKernel(float(self.noise_level), (1e-6, 1e1))
        return _SharedKernelGPR(
            kernel=kernel,
            optimizer=partial(_lbfgsb, max_iter=int(self.optimizer_max_iter)),
            normalize_y=True,
            n_restarts_optimizer=int(self.n_restarts_optimizer),
            random_state=check_random_state(self.random_state),
        )

    def predict(self, X, return_std=False):
        """Predictive mean (clipped to the widened training range); with ``return_std`` also the predictive
        std (n, n_outputs)."""
        if not return_std:
            return super().predict(X)
        Xv = _validate_predict(self, X)
        mean, std = self.model_.predict(self.scaler_.transform(Xv), return_std=True)
        mean = np.asarray(mean, dtype=float).reshape(Xv.shape[0], -1) + self.y_mean_
        std = np.asarray(std, dtype=float).reshape(Xv.shape[0], -1) * self.y_scale_
        return _format_output(self, mean), _format_output(self, std, clip=False)


class RandomForest(_ScaledRegressor):
    """Random forest of regression trees (``sklearn.ensemble.RandomForestRegressor``, multi-output trees).

    Parameters
    ----------
    n_estimators : int >= 1
    max_features : float in (0, 1]
        Fraction of the features tried at each split.
    min_samples_leaf : int >= 1
    random_state : int, RandomState or None

    Trees are invariant to monotone input scaling, so the inputs are used as they are (``input_scaling`` is
    fixed to "none").
    """

    input_scaling = "none"

    _parameter_constraints = {
        "n_estimators": [COUNT],
        "max_features": [Interval(Real, 0, 1, closed="right")],
        "min_samples_leaf": [COUNT],
        "random_state": ["random_state"],
    }

    def __init__(self, n_estimators=100, max_features=1.0, min_samples_leaf=1, random_state=None):
        self.n_estimators = n_estimators
        self.max_features = max_features
        self.min_samples_leaf = min_samples_leaf
        self.random_state = random_state

    def _make(self, Xs, Y):
        return RandomForestRegressor(
            n_estimators=int(self.n_estimators),
            max_features=float(self.max_features),
            min_samples_leaf=int(self.min_samples_leaf),
            random_state=check_random_state(self.random_state),
            n_jobs=1,
        )


class MLP(_ScaledRegressor):
    """Multilayer perceptron (``sklearn.neural_network.MLPRegressor``, Adam, ReLU) with early stopping on a
    held-out ``validation_fraction`` of the training rows, on standardized outputs.

    Parameters
    ----------
    hidden_units : int >= 1
        Width of the one hidden layer.
    alpha : float >= 0
        L2 penalty.
    learning_rate_init : float > 0
    max_iter : int >= 1
        Maximum epochs.
    validation_fraction : float in (0, 1)
        Rows held out for early stopping (at least 2 rows are needed).
    batch_size : int >= 1
        Minibatch size (capped at the number of rows): small, so that an epoch of 30 frames is more than one
        optimizer step.
    n_iter_no_change : int >= 1
        Epochs without improvement of the validation score before stopping.
    input_scaling : {"pooled", "bin", "none"}
    random_state : int, RandomState or None
        Seed of the initial weights, the shuffling and the validation split.
    """

    _standardize_y = True

    _parameter_constraints = {
        "hidden_units": [COUNT],
        "alpha": [NON_NEGATIVE],
        "learning_rate_init": [POSITIVE],
        "max_iter": [COUNT],
        "validation_fraction": [Interval(Real, 0, 1, closed="neither")],
        "batch_size": [COUNT],
        "n_iter_no_change": [COUNT],
        "input_scaling": [StrOptions(set(INPUT_SCALINGS))],
        "random_state": ["random_state"],
    }

    def __init__(
        self,
        hidden_units=64,
        alpha=1e-3,
        learning_rate_init=1e-3,
        max_iter=2000,
        validation_fraction=0.2,
        batch_size=16,
        n_iter_no_change=50,
        input_scaling="pooled",
        random_state=None,
    ):
        self.hidden_units = hidden_units
        self.alpha = alpha
        self.learning_rate_init = learning_rate_init
        self.max_iter = max_iter
        self.validation_fraction = validation_fraction
        self.batch_size = batch_size
        self.n_iter_no_change = n_iter_no_change
        self.input_scaling = input_scaling
        self.random_state = random_state

    def _check_params(self, n_samples=None):
        """Validate the hyper-parameters (and that ``n_samples`` leave 2 validation rows); raises InputError."""
        check_params(self)
        if n_samples is not None and int(self.validation_fraction * n_samples) < 2:
            raise InputError(
                f"MLP: validation_fraction={self.validation_fraction} of n_samples = {n_samples} leaves "
                f"fewer than 2 rows for early stopping; expected n_samples >= "
                f"{int(np.ceil(2 / self.validation_fraction))}"
            )

    def _make(self, Xs, Y):
        return MLPRegressor(
            hidden_layer_sizes=(int(self.hidden_units),),
            alpha=float(self.alpha),
            learning_rate_init=float(self.learning_rate_init),
            max_iter=int(self.max_iter),
            early_stopping=True,
            validation_fraction=float(self.validation_fraction),
            n_iter_no_change=int(self.n_iter_no_change),
            batch_size=min(int(self.batch_size), Xs.shape[0]),
            random_state=check_random_state(self.random_state),
        )

    def fit(self, X, Y):
        super().fit(X, Y)
        self.n_iter_ = int(self.model_.n_iter_)
        return self


DEFAULT_GRID = {
    "KernelRidgeRBF": {"alpha": [0.01, 0.1, 1.0], "gamma_scale": [0.25, 0.5, 1.0, 2.0]},
    "GaussianProcessARD": {},
    "RandomForest": {"max_features": [0.3, 1.0], "min_samples_leaf": [1, 5]},
    "MLP": {"alpha": [0.01, 0.1, 1.0], "hidden_units": [64, 256]},
}
"""CV grids of the study (keyed by class name); the GP's hyper-parameters come from its marginal likelihood."""
