"""Reference regressors: k-nearest neighbours and ridge regression, with the baselines' contract.

Both are thin wrappers of scikit-learn (``KNeighborsRegressor``, ``Ridge``) so that they are honest,
well-known references. They share the contract of the other baselines of bsrbench: ``fit(X, Y)`` with a
2-D multi-output target (or a 1-D target), ``predict(X)``; hyper-parameters are validated in ``fit`` with an
error naming the parameter, its value and the allowed range.

The module also holds the parameter-validation helpers shared by the baselines (``rvm``, ``tgp``, ``sr``,
``ddl``): scikit-learn's ``_parameter_constraints``, with its errors raised as ``InputError``.
"""

from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.linear_model import Ridge
from sklearn.neighbors import KNeighborsRegressor
from sklearn.utils._param_validation import (
    Interval,
    InvalidParameterError,
    StrOptions,
    validate_parameter_constraints,
)
from sklearn.utils.validation import check_is_fitted, validate_data

from ..errors import InputError
from .scaling import (
    INPUT_SCALINGS,
    InputScaler,
    check_finite_input,
    clip_to_bounds,
    output_bounds,
)

__all__ = ["NearestNeighbourRegressor", "RidgeRegressor"]

# --------------------------------------------------------------------------------------------------------
# shared helpers


# constraints shared by the baselines' ``_parameter_constraints`` (scikit-learn's parameter validation)
POSITIVE = Interval(Real, 0, None, closed="neither")
NON_NEGATIVE = Interval(Real, 0, None, closed="left")
COUNT = Interval(Integral, 1, None, closed="left")
BOOLEAN = ["boolean"]


def check_params(est, values=None):
    """Validate ``est``'s hyper-parameters against its ``_parameter_constraints`` (or only ``values``, a
    mapping of predict-time arguments, against the constraints of the same names).

    Raises ``InputError`` with scikit-learn's message, which names the parameter, the estimator, the allowed
    values and the value given."""
    try:
        if values is None:
            est._validate_params()
        else:
            constraints = {k: est._parameter_constraints[k] for k in values}
            validate_parameter_constraints(constraints, values, caller_name=type(est).__name__)
    except InvalidParameterError as exc:
        raise InputError(str(exc)) from None


def _validate_fit(est, X, Y, min_samples=1):
    """Validate training data; return (X, Y as 2-D float arrays).

    Records whether the target was 1-D and the output bounds ``y_bounds_`` (:func:`.scaling.output_bounds`)
    that :func:`_format_output` clips predictions to."""
    check_finite_input(est, X, "fit")
    check_finite_input(est, Y, "fit", name="Y")
    X, Y = validate_data(est, X, Y, multi_output=True, y_numeric=True, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    est._y_was_1d = Y.ndim == 1
    if Y.ndim == 1:
        Y = Y[:, None]
    est.y_bounds_ = output_bounds(Y)
    if X.shape[0] < min_samples:
        raise InputError(
            f"{type(est).__name__} needs at least {min_samples} training rows; got n_samples = {X.shape[0]}"
        )
    return X, Y


def _validate_predict(est, X):
    check_is_fitted(est)
    check_finite_input(est, X)
    return validate_data(est, X, reset=False, dtype=np.float64)


def _format_output(est, P, clip=True):
    """Predictions as (n, n_outputs), or (n,) if the model was fitted on a 1-D target.

    With ``clip`` (predicted means; not standard deviations) they are clipped to the training output range
    widened by :data:`.scaling.OUTPUT_MARGIN` (``est.y_bounds_``, recorded by :func:`_validate_fit`)."""
    P = np.asarray(P, dtype=np.float64).reshape(P.shape[0], -1)
    if clip and hasattr(est, "y_bounds_"):
        P = clip_to_bounds(P, est.y_bounds_)
    return P[:, 0] if getattr(est, "_y_was_1d", False) else P


def _sq_dists(A, B):
    """Squared Euclidean distances between the rows of A and B (clipped at 0)."""
    d = (A * A).sum(1)[:, None] + (B * B).sum(1)[None, :] - 2.0 * (A @ B.T)
    return np.maximum(d, 0.0)


def _median_distance(A):
    """Median Euclidean distance between distinct rows of A (1.0 if all rows coincide or n < 2)."""
    n = A.shape[0]
    if n < 2:
        return 1.0
    d = np.sqrt(_sq_dists(A, A)[np.triu_indices(n, 1)])
    m = float(np.median(d))
    if not m > 0:
        m = float(d.max()) if d.max() > 0 else 1.0
    return m


def _regressor_tags(tags):
    tags.target_tags.required = True
    tags.target_tags.single_output = True
    tags.target_tags.multi_output = True
    return tags


class PoseRegressor(RegressorMixin, BaseEstimator):
    """The base of the study's pose regressors: scikit-learn regressor tags for rows of several outputs (the pose
    angles), and ``_check_params(n_samples=None)``, which validates the hyper-parameters against the class's
    ``_parameter_constraints`` and which :meth:`fit` and the study's configuration check (before any job runs)
    call. A class with more to check (e.g. that N training rows suffice) overrides it. Raises InputError."""

    def __sklearn_tags__(self):
        return _regressor_tags(super().__sklearn_tags__())

    def _check_params(self, n_samples=None):
        check_params(self)


# --------------------------------------------------------------------------------------------------------


class NearestNeighbourRegressor(PoseRegressor):
    """k-nearest-neighbour regression (Euclidean distance on the features).

    With ``n_neighbors=1`` the pose of the closest training frame is returned: a memory-based reference that
    every learned method must beat. ``n_neighbors`` only affects prediction, so it can be changed per call
    (``predict(X, n_neighbors=k)``) and cross-validated from one fit per fold (see
    :func:`bsrbench.tuning.tune`).

    Parameters
    ----------
    n_neighbors : int >= 1
        Number of neighbours averaged; must not exceed the number of training rows.
    weights : {"uniform", "distance"}
        Uniform average or inverse-distance weighting (as in ``sklearn.neighbors.KNeighborsRegressor``).

    Input scaling: none (Euclidean distance on the raw features, as the histograms' own metric); the
    prediction is an average of training poses, so it never leaves their range (the shared clip to the
    widened training range, :func:`bsrbench.models.scaling.output_bounds`, is a no-op). Raises
    ``InputError`` for a bad parameter or a non-finite feature.
    """

    _predict_time_params = ("n_neighbors",)
    _parameter_constraints = {
        "n_neighbors": [COUNT],
        "weights": [StrOptions({"uniform", "distance"})],
    }

    def __init__(self, n_neighbors=1, weights="uniform"):
        self.n_neighbors = n_neighbors
        self.weights = weights

    def _check_k(self, k, n):
        check_params(self, {"n_neighbors": k})
        if k > n:
            raise InputError(f"n_neighbors={k} exceeds the number of training rows n_samples = {n}")
        return int(k)

    def _check_params(self, n_samples=None):
        """Validate the hyper-parameters (and, given ``n_samples``, that N training rows suffice for them); called
        by :meth:`fit` and by the study's configuration check before any job runs. Raises InputError."""
        check_params(self)
        if n_samples is not None:
            self._check_k(self.n_neighbors, n_samples)

    def fit(self, X, Y):
        X, Y = _validate_fit(self, X, Y)
        self._check_params(n_samples=X.shape[0])
        self.n_outputs_ = Y.shape[1]
        # one index for any k: the wrapped model is queried with the k of the call
        self.knn_ = KNeighborsRegressor(n_neighbors=1, weights=self.weights).fit(X, Y)
        self.Y_train_ = Y
        return self

    def predict(self, X, n_neighbors=None):
        """Predict; ``n_neighbors`` overrides the fitted setting for this call."""
        X = _validate_predict(self, X)
        k = self._check_k(
            self.n_neighbors if n_neighbors is None else n_neighbors, self.Y_train_.shape[0]
        )
        dist, ind = self.knn_.kneighbors(X, n_neighbors=k)
        Yn = self.Y_train_[ind]  # (n, k, d)
        if self.weights == "uniform":
            P = Yn.mean(axis=1)
        else:
            with np.errstate(divide="ignore"):
                w = 1.0 / dist
            exact = ~np.isfinite(w)
            rows = exact.any(axis=1)
            w[rows] = exact[rows].astype(float)  # an exact match gets all the weight
            P = np.einsum("nk,nkd->nd", w, Yn) / w.sum(axis=1, keepdims=True)
        return _format_output(self, P)


class RidgeRegressor(PoseRegressor):
    """Linear ridge regression of the pose on the features (``sklearn.linear_model.Ridge``).

    Inputs are scaled by :class:`bsrbench.models.scaling.InputScaler` (``input_scaling``, default "pooled":
    each feature centred, all divided by one pooled scale; chosen by blocked 5-fold CV on training frames:
    4.34 deg at N = 30 against 4.63 for floored per-bin scaling and 4.51 for raw counts, see
    :mod:`bsrbench.models.scaling`), which keeps predictions bounded off the training range. Predictions are clipped to the training output range widened by half its width on each side
    (:func:`bsrbench.models.scaling.output_bounds`).

    Parameters
    ----------
    alpha : float >= 0
        L2 penalty (on the scaled features if ``standardize``).
    standardize : bool
        Scale the features with ``input_scaling`` before the regression (False: the raw features).
    input_scaling : {"pooled", "bin", "none"}
        Scaling rule of :class:`bsrbench.models.scaling.InputScaler`.

    Raises ``InputError`` for a bad parameter or a non-finite feature (naming the row and column).
    """

    _parameter_constraints = {
        "alpha": [NON_NEGATIVE],
        "standardize": BOOLEAN,
        "input_scaling": [StrOptions(set(INPUT_SCALINGS))],
    }

    def __init__(self, alpha=1.0, standardize=True, input_scaling="pooled"):
        self.alpha = alpha
        self.standardize = standardize
        self.input_scaling = input_scaling

    def fit(self, X, Y):
        X, Y = _validate_fit(self, X, Y)
        self._check_params(n_samples=X.shape[0])
        self.n_outputs_ = Y.shape[1]
        self.scaler_ = InputScaler(self.input_scaling).fit(X) if self.standardize else None
        Xs = self.scaler_.transform(X) if self.standardize else X
        self.ridge_ = Ridge(alpha=float(self.alpha)).fit(Xs, Y)
        return self

    def predict(self, X):
        X = _validate_predict(self, X)
        Xs = self.scaler_.transform(X) if self.standardize else X
        return _format_output(self, self.ridge_.predict(Xs))


DEFAULT_GRID = {
    "NearestNeighbourRegressor": {
        "n_neighbors": [1, 2, 3, 5, 8],
        "weights": ["uniform", "distance"],
    },
    "RidgeRegressor": {"alpha": [0.1, 1.0, 10.0, 100.0, 1000.0]},
}
"""Hyper-parameter grids used by the study for the two references (keyed by class name)."""


def warm_up():
    """A tiny nearest-neighbour fit and prediction, e.g. in a job server before it forks the jobs: scikit-learn's
    neighbour search builds its thread-pool controller (a scan of the loaded libraries) once, on first use."""
    X = np.arange(6.0).reshape(3, 2)
    NearestNeighbourRegressor().fit(X, X).predict(X[:1])
