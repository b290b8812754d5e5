"""Twin Gaussian processes (TGP) for structured prediction, KL-divergence form.

Bo & Sminchisescu, "Twin Gaussian Processes for Structured Prediction", IJCV 87 (2010) 28-52, Section 3
(TGP with the Kullback-Leibler divergence). Gaussian kernels on inputs and outputs,
``K_X(x, x') = exp(-||x - x'||^2 / (2 w_x^2)) + lambda_x [x = x']`` and likewise ``K_Y`` with
``(w_y, lambda_y)``. For a test input x, with ``k_x`` its kernel vector to the training inputs,
``u = (K_X + lambda_x I)^-1 k_x`` and ``eta_x = K_X(x, x) - k_x^T u`` (the input GP's predictive variance),
the prediction minimises the divergence between the output GP and the input GP::

    L(y) = K_Y(y, y) - 2 k_y(y)^T u - eta_x log( K_Y(y, y) - k_y(y)^T (K_Y + lambda_y I)^-1 k_y(y) )

with ``K_Y(y, y) = 1 + lambda_y`` constant for the Gaussian kernel. Its gradient is analytic: with
``w = -2 u + 2 eta_x A k_y / q`` (``A = (K_Y + lambda_y I)^-1``, ``q`` the log's argument),
``dL/dy = -(1 / w_y^2) sum_i w_i k_{y,i} (y - y_i)``. Each test pose is optimised with
``scipy.optimize.minimize(method="L-BFGS-B")``, started at the 1-NN or ridge prediction.

Everything that does not depend on the test pose is computed before the per-point optimisation:
the factorisations of the training kernel matrices (in ``fit``), and ``u``/``eta_x`` of ALL test points by
one matrix solve. The kNN-restricted variant (``n_neighbors=k``, a local approximation for speed) uses,
for each test point, only the k training pairs nearest in feature space; its k x k matrices are factorised
for all test points at once by batched LAPACK calls.
"""

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize
from sklearn.utils._param_validation import StrOptions

from ..errors import InputError
from .reference import (
    COUNT,
    POSITIVE,
    PoseRegressor,
    RidgeRegressor,
    _format_output,
    _median_distance,
    _sq_dists,
    _validate_fit,
    _validate_predict,
    check_params,
)
from .scaling import INPUT_SCALINGS

__all__ = ["TGP"]

_FROM_PARAMS = object()


def _kld_objective(y, Ytr, Ainv, u, eta, c, inv_w2):
    """TGP KL objective and its gradient at the pose ``y`` (Bo & Sminchisescu 2010).

    Ytr (k, d) training poses; Ainv (k, k) inverse of the regularized output kernel matrix; u (k,);
    eta (scalar); c = K_Y(y, y) = 1 + lambda_y; inv_w2 = 1 / w_y^2.
    """
    diff = y[None, :] - Ytr
    ky = np.exp(-0.5 * inv_w2 * np.einsum("ij,ij->i", diff, diff))
    Aky = Ainv @ ky
    q = c - ky @ Aky
    if q <= 0:  # only by round-off: the output GP's variance is >= lambda_y > 0
        q = 1e-300
    f = c - 2.0 * (ky @ u) - eta * np.log(q)
    w = (-2.0 * u + (2.0 * eta / q) * Aky) * ky
    grad = -inv_w2 * (w.sum() * y - w @ Ytr)
    return f, grad


class TGP(PoseRegressor):
    """Twin Gaussian process regression (KL-divergence form, Bo & Sminchisescu 2010).

    Parameters
    ----------
    width_scale_x, width_scale_y : float > 0
        Kernel widths as multiples of the median pairwise Euclidean distance of the training features
        (resp. poses); the widths used are stored as ``width_x_`` and ``width_y_``.
    lambda_x, lambda_y : float > 0
        Regularizers added to the diagonals of the input and output kernel matrices.
    n_neighbors : int >= 1 or None
        None: use all training pairs; k: for each test point only the k nearest training pairs (in
        feature space). Only acts at prediction time (``predict(X, n_neighbors=...)``).
    init : {"knn", "ridge"}
        Start of the optimisation: the pose of the nearest training feature, or a ridge regression
        prediction (``RidgeRegressor(alpha=1.0, input_scaling=input_scaling)``). Only acts at prediction
        time.
    input_scaling : {"pooled", "bin", "none"}
        Input scaling of the ridge start (:class:`bsrbench.models.scaling.InputScaler`).
    max_iter : int >= 1
        Maximum L-BFGS-B iterations per test point.
    tol : float > 0
        L-BFGS-B ``ftol`` and ``gtol``.

    Input scaling: the kernels act on the raw features (widths relative to the median pairwise distance);
    the ridge start is ``RidgeRegressor`` with the shared input scaling (``input_scaling``, default "pooled")
    (:mod:`bsrbench.models.scaling`), which cannot explode off the training range. Predictions are clipped to the training
    range of each output widened by half its width on each side (:func:`bsrbench.models.scaling.output_bounds`).
    Raises ``InputError`` for a bad parameter or a non-finite feature.
    """

    #: The column of the paper's Tables I-II that this class reproduces (:mod:`bsrbench.methods`).
    paper_name = "TGP"

    _predict_time_params = ("n_neighbors", "init")
    _parameter_constraints = {
        "width_scale_x": [POSITIVE],
        "width_scale_y": [POSITIVE],
        "lambda_x": [POSITIVE],
        "lambda_y": [POSITIVE],
        "n_neighbors": [COUNT, None],
        "init": [StrOptions({"knn", "ridge"})],
        "input_scaling": [StrOptions(set(INPUT_SCALINGS))],
        "max_iter": [COUNT],
        "tol": [POSITIVE],
    }

    def __init__(
        self,
        width_scale_x=1.0,
        width_scale_y=1.0,
        lambda_x=1e-3,
        lambda_y=1e-3,
        n_neighbors=None,
        init="knn",
        input_scaling="pooled",
        max_iter=100,
        tol=1e-6,
    ):
        self.width_scale_x = width_scale_x
        self.width_scale_y = width_scale_y
        self.lambda_x = lambda_x
        self.lambda_y = lambda_y
        self.n_neighbors = n_neighbors
        self.init = init
        self.input_scaling = input_scaling
        self.max_iter = max_iter
        self.tol = tol

    def _check_k(self, k, n):
        check_params(self, {"n_neighbors": k})
        if k is not None and k > n:
            raise InputError(f"n_neighbors={k} exceeds the number of training rows n_samples = {n}")
        return None if k is None else int(k)

    def _check_params(self, n_samples=None):
        """Validate the hyper-parameters (and, given ``n_samples``, that N training rows suffice for them); called
        by :meth:`fit` and by the study's configuration check before any job runs. Raises InputError."""
        check_params(self)
        if n_samples is not None:
            self._check_k(self.n_neighbors, n_samples)

    def fit(self, X, Y):
        X, Y = _validate_fit(self, X, Y)
        n = X.shape[0]
        self._check_params(n_samples=n)
        self.n_outputs_ = Y.shape[1]
        self.width_x_ = float(self.width_scale_x) * _median_distance(X)
        self.width_y_ = float(self.width_scale_y) * _median_distance(Y)
        self.X_train_ = X
        self.Y_train_ = Y
        # regularized training kernel matrices (independent of the test points)
        self.Kx_ = np.exp(-_sq_dists(X, X) / (2.0 * self.width_x_**2)) + self.lambda_x * np.eye(n)
        self.Ky_ = np.exp(-_sq_dists(Y, Y) / (2.0 * self.width_y_**2)) + self.lambda_y * np.eye(n)
        self._Kx_cho = cho_factor(self.Kx_, lower=True)
        Ky_cho = cho_factor(self.Ky_, lower=True)
        self.Ky_inv_ = cho_solve(Ky_cho, np.eye(n))
        self.ridge_ = RidgeRegressor(alpha=1.0, input_scaling=self.input_scaling).fit(X, Y)
        return self

    def predict(self, X, n_neighbors=_FROM_PARAMS, init=_FROM_PARAMS):
        """Predict poses; ``n_neighbors`` and ``init`` override the fitted settings for this call."""
        X = _validate_predict(self, X)
        n = self.X_train_.shape[0]
        k = self._check_k(self.n_neighbors if n_neighbors is _FROM_PARAMS else n_neighbors, n)
        init = self.init if init is _FROM_PARAMS else init
        check_params(self, {"init": init})
        d2 = _sq_dists(X, self.X_train_)
        kx = np.exp(-d2 / (2.0 * self.width_x_**2))
        if init == "ridge":
            Y0 = np.asarray(self.ridge_.predict(X), dtype=float).reshape(X.shape[0], -1)
        else:
            Y0 = self.Y_train_[np.argmin(d2, axis=1)]
        cx = 1.0 + self.lambda_x
        if k is None:
            U = cho_solve(self._Kx_cho, kx.T).T  # (m, n): all test points in one solve
            eta = cx - np.einsum("ij,ij->i", kx, U)
            nbr = None
            Ainv = None
        else:
            nbr = np.argsort(d2, axis=1, kind="stable")[:, :k]  # (m, k)
            kxs = np.take_along_axis(kx, nbr, axis=1)
            Kxs = self.Kx_[nbr[:, :, None], nbr[:, None, :]]  # (m, k, k)
            U = np.linalg.solve(Kxs, kxs[:, :, None])[:, :, 0]
            eta = cx - np.einsum("ij,ij->i", kxs, U)
            Ainv = np.linalg.inv(self.Ky_[nbr[:, :, None], nbr[:, None, :]])  # (m, k, k)
        eta = np.maximum(eta, 0.0)
        return _format_output(self, self._optimise(Y0, U, eta, nbr, Ainv))

    def _optimise(self, Y0, U, eta, nbr, Ainv):
        """The per-test-point L-BFGS-B minimisation (the only per-point loop).

        Poses are optimised in units of the output kernel width (``z = y / w_y``), which leaves the
        minimiser unchanged and makes the tolerances independent of the units of the poses.
        """
        c = 1.0 + self.lambda_y
        s = self.width_y_
        Z = self.Y_train_ / s
        opts = {"maxiter": int(self.max_iter), "ftol": float(self.tol), "gtol": float(self.tol)}
        out = np.empty_like(Y0)
        for i in range(Y0.shape[0]):
            if nbr is None:
                Zi, Ai = Z, self.Ky_inv_
            else:
                Zi, Ai = Z[nbr[i]], Ainv[i]
            res = minimize(
                _kld_objective,
                Y0[i] / s,
                args=(Zi, Ai, U[i], eta[i], c, 1.0),
                jac=True,
                method="L-BFGS-B",
                options=opts,
            )
            out[i] = res.x * s if np.all(np.isfinite(res.x)) else Y0[i]
        return out


DEFAULT_GRID = {
    "width_scale_x": [1.0, 2.0, 4.0, 8.0],
    "width_scale_y": [0.25, 0.5, 1.0],
}
"""Grid of the study: input and output kernel widths (multiples of the median pairwise distances);
``lambda_x = lambda_y = 1e-3``, full training set, 1-NN start."""
