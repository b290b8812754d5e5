"""Sparse-representation (SR) pose regression: a test feature as a sparse combination of training features.

Following Huang & Yang, "Estimating human pose from occluded images" (ACCV 2009), the pose-estimation use
of the sparse representation of Wright et al. ("Robust face recognition via sparse representation",
IEEE PAMI 31(2), 2009): the training features, normalized to unit L2 norm, are the columns of an
over-complete dictionary; a test feature x is coded by the L1-regularized least squares

    c = argmin_c  1/(2 n_features) ||x - X_train^T c||^2 + alpha ||c||_1      (c >= 0 if ``positive``)

and the pose is the same combination of the training poses, ``y = Y_train^T c`` (divided by ``sum(c)``
when ``normalize_coef``, i.e. an affine, for positive codes convex, combination of training poses, which
keeps the scale of angle vectors; without it the L1 shrinkage pulls every pose towards 0).

All test points are coded in ONE multi-target scikit-learn fit: ``Lasso`` (coordinate descent, precomputed
Gram matrix) or ``LassoLars`` with ``X_train^T`` as design and the test features as the targets.
If a code is all zeros (``alpha`` above the largest correlation) the pose of the training feature with
the largest correlation is returned, which is the limit of the L1 path as alpha decreases to that value.
"""

import warnings

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import Lasso, LassoLars
from sklearn.utils._param_validation import StrOptions

from .reference import (
    BOOLEAN,
    COUNT,
    POSITIVE,
    PoseRegressor,
    _format_output,
    _validate_fit,
    _validate_predict,
    check_params,
)

__all__ = ["SR"]


def _normalize_rows(X, how):
    if how == "none":
        return X
    norms = np.linalg.norm(X, axis=1, keepdims=True)
    return X / np.where(norms > 0, norms, 1.0)


def _sparse_codes(D, B, alpha, positive, solver, max_iter, tol):
    """Codes C (m, n_atoms) of the rows of B (m, n_features) on the rows of D (n_atoms, n_features)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        if solver == "lasso":
            model = Lasso(
                alpha=alpha,
                fit_intercept=False,
                positive=positive,
                precompute=D @ D.T,
                max_iter=max_iter,
                tol=tol,
            )
        else:
            model = LassoLars(
                alpha=alpha, fit_intercept=False, positive=positive, max_iter=max_iter
            )
        model.fit(D.T, B.T)
    C = np.asarray(model.coef_, dtype=float)
    return C.reshape(B.shape[0], D.shape[0])


def _decode(C, Y, D, B, normalize_coef):
    """Poses from codes C (m, n) on training poses Y (n, d); zero codes fall back to the best-correlated row."""
    s = C.sum(axis=1)
    if normalize_coef:
        ok = np.abs(s) > 1e-12
    else:
        ok = np.any(C != 0, axis=1)
    P = np.empty((C.shape[0], Y.shape[1]))
    P[ok] = C[ok] @ Y
    if normalize_coef:
        P[ok] /= s[ok, None]
    if not ok.all():
        P[~ok] = Y[np.argmax(B[~ok] @ D.T, axis=1)]
    return P


class SR(PoseRegressor):
    """Sparse-representation pose regression (Huang & Yang 2009).

    Parameters
    ----------
    alpha : float > 0
        L1 penalty of the code (scikit-learn's Lasso scaling, ``1/(2 n_features)`` on the squared error).
    positive : bool
        Non-negative codes.
    normalize : {"l2", "none"}
        Scale each feature vector (training and test) to unit L2 norm before coding.
    normalize_coef : bool
        Divide the combination of training poses by the sum of the code.
    solver : {"lasso", "lars"}
        Coordinate descent (``sklearn.linear_model.Lasso``) or LARS (``LassoLars``).
    max_iter : int >= 1
        Iterations of the solver.
    tol : float > 0
        Tolerance of coordinate descent.

    Input scaling: each feature vector is scaled to unit L2 norm (``normalize``), no per-feature scaling, so
    an input off the training range changes only the code, not the scale of the pose. With positive,
    normalized codes the pose is a convex combination of training poses; in any case predictions are clipped
    to the training range of each output widened by half its width on each side
    (:func:`bsrbench.models.scaling.output_bounds`). Raises ``InputError`` for a bad parameter or a
    non-finite feature.
    """

    #: The column of the paper's Tables I-II that this class reproduces (:mod:`bsrbench.methods`).
    paper_name = "SR"

    _predict_time_params = ("alpha",)

    _parameter_constraints = {
        "alpha": [POSITIVE],
        "positive": BOOLEAN,
        "normalize": [StrOptions({"l2", "none"})],
        "normalize_coef": BOOLEAN,
        "solver": [StrOptions({"lasso", "lars"})],
        "max_iter": [COUNT],
        "tol": [POSITIVE],
    }

    def __init__(
        self,
        alpha=1e-4,
        positive=True,
        normalize="l2",
        normalize_coef=True,
        solver="lasso",
        max_iter=2000,
        tol=1e-6,
    ):
        self.alpha = alpha
        self.positive = positive
        self.normalize = normalize
        self.normalize_coef = normalize_coef
        self.solver = solver
        self.max_iter = max_iter
        self.tol = tol

    def fit(self, X, Y):
        X, Y = _validate_fit(self, X, Y)
        self._check_params(n_samples=X.shape[0])
        self.n_outputs_ = Y.shape[1]
        self.dictionary_ = _normalize_rows(X, self.normalize)
        self.Y_train_ = Y
        return self

    def sparse_code(self, X, alpha=None):
        """Codes (n_test, n_train) of the test features on the training features."""
        X = _validate_predict(self, X)
        if alpha is not None:
            check_params(self, {"alpha": alpha})
        a = self.alpha if alpha is None else alpha
        B = _normalize_rows(X, self.normalize)
        return _sparse_codes(
            self.dictionary_, B, a, self.positive, self.solver, int(self.max_iter), self.tol
        ), B

    def predict(self, X, alpha=None):
        """Predict poses; ``alpha`` overrides the fitted penalty for this call."""
        C, B = self.sparse_code(X, alpha=alpha)
        return _format_output(
            self, _decode(C, self.Y_train_, self.dictionary_, B, self.normalize_coef)
        )


DEFAULT_GRID = {"alpha": [3e-4, 1e-3, 3e-3, 6e-3, 9e-3]}
"""Grid of the study: the L1 penalty (unit-norm features, so the code is all zero above alpha ~ 1/n_features)."""
