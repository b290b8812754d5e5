"""The GP baseline's summed marginal-likelihood gradient (``_SharedKernelGPR``) against scikit-learn's own
``GaussianProcessRegressor``: the same value, gradient, optimum and test error."""

from pathlib import Path

import numpy as np
import pytest
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import (
    RBF,
    ConstantKernel,
    DotProduct,
    Matern,
    RationalQuadratic,
    WhiteKernel,
)

from bsrbench.datasets import load_feature_mat
from bsrbench.models import sklearn_baselines
from bsrbench.models.sklearn_baselines import (
    GaussianProcessARD,
    _lbfgsb,
    _scaled_rbf_plus_noise,
    _SharedKernelGPR,
)
from bsrbench.runs import run_job
from bsrbench.splits import JobSpec

MAT = Path(__file__).resolve().parents[1] / "resources" / "paper-features" / "x63.mat"
GP_PATH = "bsrbench.models.sklearn_baselines:GaussianProcessARD"


def _study_kernel(d):
    """The GP baseline's kernel shape: c * ARD RBF + white noise."""
    return ConstantKernel(1.0, (1e-3, 1e3)) * RBF(np.full(d, 2.0), (1e-2, 1e3)) + WhiteKernel(
        0.1, (1e-6, 1e1)
    )


KERNELS = {
    "study": _study_kernel,
    "isotropic": lambda d: ConstantKernel(2.0) * RBF(1.5) + WhiteKernel(0.05),
    "matern-ard": lambda d: Matern(np.full(d, 1.0), nu=2.5) + WhiteKernel(0.1),
    "rq+dot": lambda d: RationalQuadratic(1.0, 0.5) + ConstantKernel(0.3) * DotProduct(0.5),
    "study-fixed-noise": lambda d: (
        ConstantKernel(1.0) * RBF(np.full(d, 2.0)) + WhiteKernel(0.1, "fixed")
    ),
}
#: Kernels whose gradient has the closed form of ``_scaled_rbf_plus_noise_gradient``; the others take the
#: general contraction.
CLOSED_FORM = {"study", "isotropic"}


def _data(rng, n, d, m):
    """Non-negative histogram-like inputs and m outputs of a few scales that depend on them smoothly."""
    X = rng.gamma(0.5, size=(n, d))
    T = X @ rng.normal(size=(d, 3)) / np.sqrt(d)
    Y = np.sin(T) @ (rng.normal(size=(3, m)) * [[1.0], [10.0], [100.0]]) + 0.1 * rng.normal(
        size=(n, m)
    )
    return X, Y + rng.normal(scale=50, size=m)


def _pair(kernel, X, y, **kw):
    """Stock and summed-gradient regressors on the same data, not optimized (their ``X_train_``,
    normalized ``y_train_`` and ``kernel_`` are the starting point)."""
    stock = GaussianProcessRegressor(kernel, optimizer=None, **kw).fit(X, y)
    ours = _SharedKernelGPR(kernel, optimizer=None, **kw).fit(X, y)
    return stock, ours


def _points(rng, kernel, k=3):
    """k hyper-parameter points (log scale) scattered around the kernel's start, inside its bounds."""
    lo, hi = kernel.bounds.T
    return [
        np.clip(kernel.theta + rng.normal(scale=0.7, size=kernel.theta.size), lo, hi)
        for _ in range(k)
    ]


@pytest.mark.parametrize("name", sorted(KERNELS))
@pytest.mark.parametrize("outputs", [57, 1, "1-d"])
@pytest.mark.parametrize("normalize_y", [True, False])
def test_log_marginal_likelihood_and_gradient_equal_scikit_learns(name, outputs, normalize_y):
    rng = np.random.default_rng([ord(c) for c in f"{name}/{outputs}/{normalize_y}"])
    X, Y = _data(rng, 40, 6, 57 if outputs == 57 else 1)
    y = Y[:, 0] if outputs == "1-d" else Y
    kernel = KERNELS[name](X.shape[1])
    assert (_scaled_rbf_plus_noise(kernel) is not None) == (name in CLOSED_FORM)
    stock, ours = _pair(kernel, X, y, normalize_y=normalize_y, alpha=1e-8)
    for theta in _points(rng, kernel):
        lml, grad = ours.log_marginal_likelihood(theta, eval_gradient=True)
        lml_ref, grad_ref = stock.log_marginal_likelihood(theta, eval_gradient=True)
        assert np.isfinite(lml) and grad.shape == grad_ref.shape == theta.shape
        assert abs(lml - lml_ref) <= 1e-10 * abs(lml_ref)
        np.testing.assert_allclose(grad, grad_ref, rtol=1e-10, atol=1e-10 * np.abs(grad_ref).max())
        # without the gradient: the value alone, as scikit-learn's
        assert ours.log_marginal_likelihood(theta) == stock.log_marginal_likelihood(theta)


def test_gradient_equals_central_differences_of_the_value():
    rng = np.random.default_rng(3)
    X, Y = _data(rng, 30, 4, 57)
    kernel = _study_kernel(X.shape[1])
    _, ours = _pair(kernel, X, Y, normalize_y=True)
    h = 1e-5
    for theta in _points(rng, kernel, k=4):
        _, grad = ours.log_marginal_likelihood(theta, eval_gradient=True)
        fd = np.array(
            [
                (
                    ours.log_marginal_likelihood(theta + h * e)
                    - ours.log_marginal_likelihood(theta - h * e)
                )
                / (2 * h)
                for e in np.eye(theta.size)
            ]
        )
        np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_per_sample_jitter_clone_kernel_and_a_matrix_that_is_not_positive_definite_as_scikit_learns():
    rng = np.random.default_rng(4)
    X, Y = _data(rng, 25, 3, 5)
    kernel = _study_kernel(X.shape[1])
    jitter = rng.uniform(1e-3, 1e-1, size=25)
    stock, ours = _pair(kernel, X, Y, normalize_y=True, alpha=jitter)
    theta = _points(rng, kernel, k=1)[0]
    # clone_kernel=False sets the fitted kernel's theta in place, as scikit-learn's
    lml, grad = ours.log_marginal_likelihood(theta, eval_gradient=True, clone_kernel=False)
    lml_ref, grad_ref = stock.log_marginal_likelihood(theta, eval_gradient=True, clone_kernel=False)
    np.testing.assert_array_equal(ours.kernel_.theta, stock.kernel_.theta)
    np.testing.assert_allclose(ours.kernel_.theta, theta, rtol=1e-14)  # exp then log
    assert abs(lml - lml_ref) <= 1e-10 * abs(lml_ref)
    np.testing.assert_allclose(grad, grad_ref, rtol=1e-10)
    # theta=None: the fitted value; a gradient needs a theta
    assert ours.log_marginal_likelihood() == ours.log_marginal_likelihood_value_
    with pytest.raises(ValueError, match="Gradient can only be evaluated for theta!=None"):
        ours.log_marginal_likelihood(eval_gradient=True)
    # a negative jitter makes K indefinite: -inf and a zero gradient, as scikit-learn's
    stock.alpha = ours.alpha = -10.0
    for gp in (stock, ours):
        lml, grad = gp.log_marginal_likelihood(theta, eval_gradient=True)
        assert lml == -np.inf
        np.testing.assert_array_equal(grad, np.zeros_like(theta))


def test_fitted_optimum_and_predictions_equal_scikit_learns_on_a_study_sized_problem(monkeypatch):
    """N = 60, 100-D inputs, 57 outputs, the study's settings and one random restart (the RNG draws the same
    starting point): the optimizer ends where scikit-learn's stock class does."""
    rng = np.random.default_rng(5)
    X, Y = _data(rng, 90, 100, 57)
    X, Xt, Y = X[:60], X[60:], Y[:60]

    def fit(n_restarts):
        return GaussianProcessARD(n_restarts_optimizer=n_restarts, random_state=7).fit(X, Y)

    ours = fit(1)
    assert isinstance(ours.model_, _SharedKernelGPR)
    monkeypatch.setattr(sklearn_baselines, "_SharedKernelGPR", GaussianProcessRegressor)
    stock = fit(1)
    assert type(stock.model_) is GaussianProcessRegressor
    np.testing.assert_allclose(
        ours.model_.kernel_.theta, stock.model_.kernel_.theta, rtol=0, atol=1e-6
    )
    lml, lml_ref = (
        ours.model_.log_marginal_likelihood_value_,
        stock.model_.log_marginal_likelihood_value_,
    )
    assert abs(lml - lml_ref) <= 1e-9 * abs(lml_ref)
    mean, std = ours.predict(Xt, return_std=True)
    mean_ref, std_ref = stock.predict(Xt, return_std=True)
    scale = Y.std(axis=0)
    np.testing.assert_allclose(mean, mean_ref, rtol=0, atol=1e-6 * scale.max())
    np.testing.assert_allclose(std, std_ref, rtol=1e-6)


def test_the_optimizer_protocol_is_scikit_learns():
    """A custom optimizer receives scikit-learn's objective (the negated value and gradient) and bounds."""
    rng = np.random.default_rng(6)
    X, Y = _data(rng, 30, 5, 57)
    seen = []

    def record(obj_func, theta0, bounds):
        seen.append((obj_func(theta0), bounds))
        return _lbfgsb(obj_func, theta0, bounds, max_iter=5)

    kernel = _study_kernel(X.shape[1])
    ours = _SharedKernelGPR(kernel, optimizer=record, normalize_y=True).fit(X, Y)
    stock = GaussianProcessRegressor(kernel, optimizer=None, normalize_y=True).fit(X, Y)
    (neg_lml, neg_grad), bounds = seen[0]
    lml, grad = stock.log_marginal_likelihood(kernel.theta, eval_gradient=True)
    assert neg_lml == pytest.approx(-lml, rel=1e-12)
    np.testing.assert_allclose(neg_grad, -grad, rtol=1e-10, atol=1e-10 * np.abs(grad).max())
    np.testing.assert_array_equal(bounds, kernel.bounds)
    assert ours.log_marginal_likelihood_value_ == pytest.approx(
        stock.log_marginal_likelihood(ours.kernel_.theta), rel=1e-12
    )


def test_a_golf_gp_job_scores_the_error_of_scikit_learns_stock_gp(monkeypatch):
    """A real GP job (the authors' golf features, N = 30, heading transform) through ``run_job``: its test
    error and predictive std equal those of the same job fitted by scikit-learn's stock class."""
    fs = load_feature_mat(MAT, n_frames=600, drop_y_columns=3, checksums=MAT.parent / "SHA256SUMS")
    features = {"X": fs.X, "Y": fs.Y, "heading_column": 2}
    spec = JobSpec("hsc", "golf", "GP", 30, 0)
    row, arrays = run_job(spec, features, estimator=GP_PATH, params={})
    monkeypatch.setattr(sklearn_baselines, "_SharedKernelGPR", GaussianProcessRegressor)
    row_ref, arrays_ref = run_job(spec, features, estimator=GP_PATH, params={})
    assert 1 < row["error"] < 60
    assert abs(row["error"] - row_ref["error"]) < 1e-6
    # the angles (degrees, up to about 100) to the optimizer's tolerance: at its cap of 50 iterations the
    # rounding of the gradient's sums moves the hyper-parameters by about 1e-6
    for key in ("y_pred", "y_std"):
        np.testing.assert_allclose(arrays[key], arrays_ref[key], rtol=0, atol=1e-3)


def test_closed_form_gradient_keeps_its_precision_for_inputs_far_from_the_origin():
    """The length scales' gradient expands squared differences into sums of squares; far from the origin
    (inputs about 1e4 length scales away) those sums would cancel all digits unless the inputs are centred."""
    rng = np.random.default_rng(7)
    X, Y = _data(rng, 40, 6, 57)
    kernel = _study_kernel(X.shape[1])
    stock, ours = _pair(kernel, X + 2e4, Y, normalize_y=True)
    for theta in _points(rng, kernel):
        _, grad = ours.log_marginal_likelihood(theta, eval_gradient=True)
        _, grad_ref = stock.log_marginal_likelihood(theta, eval_gradient=True)
        np.testing.assert_allclose(grad, grad_ref, rtol=1e-8, atol=1e-8 * np.abs(grad_ref).max())
