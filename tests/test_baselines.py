"""Tests of the baseline regressors: scikit-learn conventions, known-answer problems, bad input."""

import naive
import numpy as np
import pytest
from sklearn.utils.estimator_checks import parametrize_with_checks
from threadpoolctl import threadpool_limits

import bsrbench.models.ddl as ddl_module
from bsrbench.errors import InputError
from bsrbench.models.ddl import DDL, _coupled_dictionary_learning, _fista_codes
from bsrbench.models.reference import NearestNeighbourRegressor, RidgeRegressor
from bsrbench.models.rvm import RVM
from bsrbench.models.sr import SR
from bsrbench.models.tgp import TGP, _kld_objective


@pytest.fixture(autouse=True)
def _one_blas_thread():
    """One BLAS thread: the small matrices here gain nothing from threads, and on a loaded machine
    oversubscribed BLAS threads make them many times slower."""
    with threadpool_limits(1):
        yield


# small instances: fewer iterations so the generic checks stay fast
CHECK_INSTANCES = [
    NearestNeighbourRegressor(),
    RidgeRegressor(),
    RVM(max_iter=10),
    TGP(max_iter=3),
    SR(max_iter=200),
    DDL(n_components=4, max_iter=5, random_state=0),
]


def _expected_failed_checks(est):
    # TGP and SR iterate only at prediction time (per-point L-BFGS-B, Lasso coding); fit runs no
    # iterations, so the check that fit sets n_iter_ does not apply to their max_iter.
    if isinstance(est, (TGP, SR)):
        return {
            "check_non_transformer_estimators_n_iter": "max_iter acts in predict; fit runs no iterations"
        }
    return {}


@parametrize_with_checks(CHECK_INSTANCES, expected_failed_checks=_expected_failed_checks)
def test_sklearn_conventions(estimator, check):
    check(estimator)


# ---------------------------------------------------------------------------------------------------------
# known-answer problems


def _linear_data(rng, n, d=3, k=2, noise=0.01):
    X = rng.uniform(-1, 1, size=(n, d))
    W = rng.normal(size=(d, k))
    return X, W


def test_ridge_recovers_linear_map():
    rng = np.random.default_rng(0)
    X, W = _linear_data(rng, 200)
    Y = X @ W + 0.5 + 0.01 * rng.standard_normal((200, 2))
    Xt = rng.uniform(-1, 1, size=(100, 3))
    m = RidgeRegressor(alpha=1e-3).fit(X, Y)
    err = np.sqrt(np.mean((m.predict(Xt) - (Xt @ W + 0.5)) ** 2))
    assert err < 0.01
    assert np.sqrt(np.mean((Xt @ W) ** 2)) > 50 * err  # the signal is far larger than the error


def test_rvm_recovers_linear_map_sparsely_with_calibrated_std():
    rng = np.random.default_rng(1)
    noise = 0.05
    X, W = _linear_data(rng, 150)
    Y = X @ W + noise * rng.standard_normal((150, 2))
    Xt = rng.uniform(-0.9, 0.9, size=(200, 3))
    Yt = Xt @ W + noise * rng.standard_normal((200, 2))
    m = RVM(width_scale=2.0, max_iter=3000, tol=1e-3).fit(X, Y)
    mean, std = m.predict(Xt, return_std=True)
    rmse_f = np.sqrt(np.mean((mean - Xt @ W) ** 2))
    assert rmse_f < 0.5 * noise  # the function is recovered well below the noise level
    assert len(m.relevance_) < 0.2 * X.shape[0]  # most basis functions pruned
    assert m.converged_
    assert np.all(std > 0) and 0.7 * noise < np.median(std) < 1.5 * noise
    cover = np.mean(np.abs(Yt - mean) <= 1.645 * std)
    assert 0.8 < cover < 0.98


def test_rvm_per_output_noise_tracks_output_scales():
    rng = np.random.default_rng(2)
    X = rng.uniform(-1, 1, size=(120, 2))
    f = np.column_stack([np.sin(3 * X[:, 0]), X[:, 1] ** 2])
    Y = f + np.array([0.01, 0.2]) * rng.standard_normal((120, 2))
    m = RVM(noise="per_output", width_scale=0.5).fit(X, Y)
    noise_std = m.y_scale_ / np.sqrt(m.beta_)
    assert noise_std[0] < 0.03 and 0.12 < noise_std[1] < 0.3


def test_tgp_smooth_curve():
    rng = np.random.default_rng(3)
    x = np.sort(rng.uniform(0, 2 * np.pi, 80))[:, None]
    xt = rng.uniform(0.1, 2 * np.pi - 0.1, 60)[:, None]
    Y = np.column_stack([np.cos(x[:, 0]), np.sin(x[:, 0])])
    Yt = np.column_stack([np.cos(xt[:, 0]), np.sin(xt[:, 0])])
    for k in (None, 20):
        P = TGP(width_scale_x=0.2, width_scale_y=0.5, n_neighbors=k).fit(x, Y).predict(xt)
        err = np.sqrt(np.mean((P - Yt) ** 2))
        nn = NearestNeighbourRegressor().fit(x, Y).predict(xt)
        assert err < 0.03
        assert err < 0.7 * np.sqrt(np.mean((nn - Yt) ** 2))  # better than its 1-NN start


def test_tgp_gradient_matches_finite_differences():
    from scipy.optimize import approx_fprime

    rng = np.random.default_rng(4)
    n, d = 25, 4
    Ytr = rng.normal(size=(n, d))
    K = np.exp(-0.5 * ((Ytr[:, None] - Ytr[None]) ** 2).sum(-1)) + 1e-2 * np.eye(n)
    Ainv = np.linalg.inv(K)
    u = rng.uniform(0, 0.2, n)
    for y in (Ytr[0] + 0.3 * rng.normal(size=d), rng.normal(size=d)):
        args = (Ytr, Ainv, u, 0.3, 1.01, 1.0)
        g = _kld_objective(y, *args)[1]
        num = approx_fprime(y, lambda z, args=args: _kld_objective(z, *args)[0], 1e-6)
        assert np.linalg.norm(num - g) < 1e-4 * max(np.linalg.norm(g), 1e-3)


def test_tgp_predict_time_neighbours_equal_refit():
    rng = np.random.default_rng(5)
    X = rng.normal(size=(40, 3))
    Y = np.column_stack([X[:, 0] ** 2, np.tanh(X[:, 1])])
    Xt = rng.normal(size=(10, 3))
    a = TGP().fit(X, Y).predict(Xt, n_neighbors=15, init="ridge")
    b = TGP(n_neighbors=15, init="ridge").fit(X, Y).predict(Xt)
    np.testing.assert_allclose(a, b)


def test_one_nn_exact_on_training_points_and_knn_predict_time():
    rng = np.random.default_rng(6)
    X = rng.normal(size=(50, 5))
    Y = rng.normal(size=(50, 4))
    m = NearestNeighbourRegressor().fit(X, Y)
    np.testing.assert_array_equal(m.predict(X), Y)
    Xt = rng.normal(size=(7, 5))
    np.testing.assert_allclose(
        m.predict(Xt, n_neighbors=4), NearestNeighbourRegressor(4).fit(X, Y).predict(Xt)
    )
    np.testing.assert_array_equal(
        NearestNeighbourRegressor(3, weights="distance").fit(X, Y).predict(X), Y
    )


def _coupled_sparse_data(rng, n, n_atoms=8, dx=30, dy=6, nnz=2):
    Dx = np.abs(rng.normal(size=(n_atoms, dx)))
    Dy = rng.normal(size=(n_atoms, dy))
    C = np.zeros((n, n_atoms))
    for _ in range(nnz):
        C[np.arange(n), rng.integers(n_atoms, size=n)] += rng.uniform(0.5, 1.5, n)
    return C @ Dx, C @ Dy


def _mean_baseline_error(Y, Yt):
    return np.sqrt(np.mean((Yt - Y.mean(0)) ** 2))


def test_sr_recovers_poses_from_shared_sparse_codes():
    rng = np.random.default_rng(7)
    X, Y = _coupled_sparse_data(rng, 260)
    X, Xt, Y, Yt = X[:200], X[200:], Y[:200], Y[200:]
    base = _mean_baseline_error(Y, Yt)
    linear = (
        SR(alpha=1e-6, positive=False, normalize="none", normalize_coef=False).fit(X, Y).predict(Xt)
    )
    assert np.sqrt(np.mean((linear - Yt) ** 2)) < 0.05 * base
    default = SR(alpha=1e-4).fit(X, Y).predict(Xt)
    assert np.sqrt(np.mean((default - Yt) ** 2)) < 0.5 * base
    lars = SR(alpha=1e-4, solver="lars").fit(X, Y).predict(Xt)
    assert np.sqrt(np.mean((lars - Yt) ** 2)) < 0.5 * base


def test_sr_zero_code_falls_back_to_best_correlated_pose():
    rng = np.random.default_rng(8)
    X = np.abs(rng.normal(size=(20, 10)))
    Y = rng.normal(size=(20, 3))
    m = SR(alpha=10.0).fit(X, Y)  # alpha far above the largest correlation: all codes are zero
    C, _ = m.sparse_code(X[:5])
    assert not np.any(C)
    np.testing.assert_array_equal(m.predict(X[:5]), Y[:5])


def test_ddl_recovers_poses_from_shared_sparse_codes():
    rng = np.random.default_rng(9)
    X, Y = _coupled_sparse_data(rng, 260)
    X, Xt, Y, Yt = X[:200], X[200:], Y[:200], Y[200:]
    m = DDL(n_components=8, alpha=0.005, normalize="none", max_iter=100, random_state=0).fit(X, Y)
    err = np.sqrt(np.mean((m.predict(Xt) - Yt) ** 2))
    assert err < 0.3 * _mean_baseline_error(Y, Yt)
    assert np.all(np.linalg.norm(m.components_, axis=1) <= 1 + 1e-9)
    # same seed, same dictionary
    m2 = DDL(n_components=8, alpha=0.005, normalize="none", max_iter=100, random_state=0).fit(X, Y)
    np.testing.assert_array_equal(m.components_, m2.components_)


@pytest.mark.parametrize(("alpha", "warm"), [(0.01, False), (0.1, False), (0.03, True)])
def test_ddl_fista_kernel_matches_numpy_reference(alpha, warm):
    """The numba FISTA gives the codes of the whole-array NumPy loop (tests/naive.py) to 1e-8, sparse and dense
    iterates alike (alpha 0.01: many non-zero codes; 0.1: few), cold and warm started."""
    rng = np.random.default_rng(11)
    D = rng.normal(size=(100, 158))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    Z = rng.normal(size=(300, 100)) @ D * 0.1 + 0.05 * rng.normal(size=(300, 158))
    C0 = naive.fista_codes(Z, D, alpha, n_iter=5) if warm else None
    want = naive.fista_codes(Z, D, alpha, C0=C0, n_iter=1000)
    got = _fista_codes(Z, D, alpha, C0=C0, n_iter=1000)
    assert 0 < np.count_nonzero(want) < want.size
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-8)


@pytest.mark.parametrize(("n_components", "alpha"), [(20, 0.01), (60, 1.5)])
def test_ddl_dictionary_learning_matches_numpy_reference(n_components, alpha):
    """Dictionary learning (FISTA codes and atom updates in numba) gives the dictionary and codes of the NumPy
    reference (tests/naive.py) to 1e-8; with 60 atoms and alpha 1.5 some atoms go unused and are re-drawn."""
    rng = np.random.default_rng(12)
    X, Y = _coupled_sparse_data(rng, 50, n_atoms=12, dx=40, dy=8, nnz=3)
    Z = np.hstack([X + 0.05 * np.abs(rng.normal(size=X.shape)), Y]) / 10
    rng_fit = np.random.default_rng(3)
    got = _coupled_dictionary_learning(Z, n_components, alpha, 20, 1e-5, rng_fit)
    want = naive.coupled_dictionary_learning(
        Z, n_components, alpha, 20, 1e-5, np.random.default_rng(3)
    )
    assert got[2] == want[2]
    np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-8)
    # re-drawn atoms take random numbers beyond the initial dictionary's
    rng_init = np.random.default_rng(3)
    rng_init.choice(Z.shape[0], size=n_components, replace=n_components > Z.shape[0])
    rng_init.standard_normal((n_components, Z.shape[1]))
    redrawn = rng_fit.bit_generator.state != rng_init.bit_generator.state
    assert redrawn == (alpha > 1)


def test_ddl_fit_and_codes_match_numpy_reference(monkeypatch):
    """A whole DDL fit and its test codes are those of the NumPy reference to 1e-8 (a well-conditioned problem:
    fewer atoms than features; with more, the Lasso solution is not unique and FISTA's iterates amplify a
    rounding-level change of the dictionary, see benchmarks/bench_ddl.py)."""
    rng = np.random.default_rng(13)
    X, Y = _coupled_sparse_data(rng, 260, n_atoms=12, dx=40, dy=8, nnz=3)
    X = X + 0.05 * np.abs(rng.normal(size=X.shape))
    fast = DDL(n_components=20, alpha=0.01, max_iter=20, random_state=3).fit(X[:200], Y[:200])
    codes = fast.sparse_code(X[200:])
    monkeypatch.setattr(ddl_module, "_fista_codes", naive.fista_codes)
    monkeypatch.setattr(
        ddl_module, "_coupled_dictionary_learning", naive.coupled_dictionary_learning
    )
    slow = DDL(n_components=20, alpha=0.01, max_iter=20, random_state=3).fit(X[:200], Y[:200])
    assert fast.n_iter_ == slow.n_iter_
    np.testing.assert_allclose(fast.components_, slow.components_, rtol=0, atol=1e-8)
    np.testing.assert_allclose(codes, slow.sparse_code(X[200:]), rtol=0, atol=1e-8)


# ---------------------------------------------------------------------------------------------------------
# bad input

ALL = [
    NearestNeighbourRegressor,
    RidgeRegressor,
    lambda: RVM(max_iter=20),
    lambda: TGP(max_iter=5),
    SR,
    lambda: DDL(n_components=3, max_iter=3, random_state=0),
]


@pytest.mark.parametrize("make", ALL)
def test_row_mismatch_and_nan_are_rejected(make):
    rng = np.random.default_rng(10)
    X = np.abs(rng.normal(size=(12, 4)))
    Y = rng.normal(size=(12, 3))
    with pytest.raises(ValueError, match="inconsistent numbers of samples"):
        make().fit(X, Y[:10])
    Xn = X.copy()
    Xn[3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        make().fit(Xn, Y)
    Yn = Y.copy()
    Yn[0, 0] = np.inf
    with pytest.raises(ValueError, match="infinity"):
        make().fit(X, Yn)
    m = make().fit(X, Y)
    with pytest.raises(ValueError, match="NaN"):
        m.predict(Xn)
    with pytest.raises(ValueError, match="4 features"):
        m.predict(X[:, :3])


@pytest.mark.parametrize(
    "est, match",
    [
        (
            NearestNeighbourRegressor(n_neighbors=0),
            r"The 'n_neighbors' parameter of NearestNeighbourRegressor must be an int in the range \[1, inf\)\. Got 0 instead",
        ),
        (NearestNeighbourRegressor(n_neighbors=13), r"n_neighbors=13 exceeds .* n_samples = 12"),
        (
            NearestNeighbourRegressor(weights="gauss"),
            r"The 'weights' parameter of NearestNeighbourRegressor must be a str among .*'distance'.*Got 'gauss' instead",
        ),
        (
            RidgeRegressor(alpha=-1.0),
            r"The 'alpha' parameter of RidgeRegressor must be a float in the range \[0.0, inf\)\. Got -1.0",
        ),
        (
            RVM(width_scale=0),
            r"The 'width_scale' parameter of RVM must be a float in the range \(0.0, inf\)\. Got 0 instead",
        ),
        (
            RVM(noise="diag"),
            r"The 'noise' parameter of RVM must be a str among .*Got 'diag' instead",
        ),
        (
            RVM(max_iter=2.5),
            r"The 'max_iter' parameter of RVM must be an int in the range \[1, inf\)\. Got 2.5 instead",
        ),
        (
            TGP(lambda_y=0.0),
            r"The 'lambda_y' parameter of TGP must be a float in the range \(0.0, inf\)\. Got 0.0 instead",
        ),
        (
            TGP(init="zeros"),
            r"The 'init' parameter of TGP must be a str among .*Got 'zeros' instead",
        ),
        (TGP(n_neighbors=50), r"n_neighbors=50 exceeds .* n_samples = 12"),
        (
            TGP(width_scale_y=np.inf),
            r"The 'width_scale_y' parameter of TGP must be a float in the range \(0.0, inf\)\. Got inf instead",
        ),
        (
            SR(alpha=0.0),
            r"The 'alpha' parameter of SR must be a float in the range \(0.0, inf\)\. Got 0.0 instead",
        ),
        (SR(solver="omp"), r"The 'solver' parameter of SR must be a str among .*Got 'omp' instead"),
        (
            DDL(n_components=0),
            r"The 'n_components' parameter of DDL must be an int in the range \[1, inf\)\. Got 0 instead",
        ),
        (DDL(coding="cd"), r"The 'coding' parameter of DDL must be a str among .*Got 'cd' instead"),
    ],
)
def test_bad_parameters_name_parameter_and_value(est, match):
    rng = np.random.default_rng(11)
    X = np.abs(rng.normal(size=(12, 4)))
    Y = rng.normal(size=(12, 3))
    before = est.get_params()
    with pytest.raises(InputError, match=match):
        est.fit(X, Y)
    assert est.get_params() == before  # parameters are never overwritten


def test_predict_time_overrides_are_validated():
    rng = np.random.default_rng(12)
    X = rng.normal(size=(12, 4))
    Y = rng.normal(size=(12, 3))
    with pytest.raises(InputError, match=r"n_neighbors=20 exceeds .* n_samples = 12"):
        NearestNeighbourRegressor().fit(X, Y).predict(X, n_neighbors=20)
    with pytest.raises(
        InputError,
        match=r"The 'n_neighbors' parameter of TGP must be an int in the range \[1, inf\) or None\. Got -2",
    ):
        TGP().fit(X, Y).predict(X, n_neighbors=-2)
    with pytest.raises(
        InputError,
        match=r"The 'alpha' parameter of SR must be a float in the range \(0.0, inf\)\. Got -1 instead",
    ):
        SR().fit(np.abs(X), Y).predict(np.abs(X), alpha=-1)


# ---------------------------------------------------------------------------------------------------------
# today's baselines (bsrbench.models.sklearn_baselines; weighted k-NN is NearestNeighbourRegressor)

from bsrbench.models.sklearn_baselines import (  # noqa: E402
    MLP,
    GaussianProcessARD,
    KernelRidgeRBF,
    RandomForest,
)

TODAY_CHECK_INSTANCES = [
    KernelRidgeRBF(),
    GaussianProcessARD(),
    RandomForest(n_estimators=5),
    MLP(max_iter=50),
]


@parametrize_with_checks(TODAY_CHECK_INSTANCES)
def test_sklearn_conventions_todays_baselines(estimator, check):
    check(estimator)


def _curve(rng, n, noise=0.05):
    X = rng.uniform(-2, 2, size=(n, 2))
    Y = np.column_stack([np.sin(2 * X[:, 0]), np.cos(X[:, 0]) * 10 + 50])
    return X, Y + noise * rng.normal(size=Y.shape)


@pytest.mark.parametrize(
    "make, tol",
    [
        (lambda: KernelRidgeRBF(alpha=1e-3, gamma_scale=1.0), 0.05),
        (lambda: GaussianProcessARD(random_state=0), 0.05),
        (lambda: RandomForest(n_estimators=100, random_state=0), 0.3),
        (lambda: MLP(hidden_units=64, alpha=1e-4, max_iter=3000, random_state=0), 0.3),
    ],
)
def test_todays_baselines_fit_a_smooth_curve(make, tol):
    rng = np.random.default_rng(20)
    X, Y = _curve(rng, 200)
    Xt, Yt = _curve(rng, 100, noise=0.0)
    P = make().fit(X, Y).predict(Xt)
    # RMS error per output relative to the output's spread (sin: 0.7, 10 cos: 2.5 around 50)
    rel = np.sqrt(np.mean((P - Yt) ** 2, axis=0)) / Yt.std(axis=0)
    assert np.all(rel < tol), rel


def test_gp_std_is_the_gaussian_posterior_of_its_fitted_kernel_and_ard_finds_the_relevant_input():
    rng = np.random.default_rng(21)
    X = rng.uniform(-2, 2, size=(60, 3))
    Y = np.column_stack([np.sin(2 * X[:, 0]), 3 * np.sin(2 * X[:, 0])]) + 0.1 * rng.normal(
        size=(60, 2)
    )
    gp = GaussianProcessARD(random_state=0).fit(X, Y)
    Xt = rng.uniform(-2, 2, size=(5, 3))
    mean, std = gp.predict(Xt, return_std=True)
    # independent computation: c exp(-0.5 sum ((x - x') / l)^2) + noise on the scaled inputs, normalized outputs
    k = gp.model_.kernel_
    c, ls, noise = k.k1.k1.constant_value, k.k1.k2.length_scale, k.k2.noise_level
    A, B = gp.scaler_.transform(X) / ls, gp.scaler_.transform(Xt) / ls
    K_ = c * np.exp(-0.5 * ((A[:, None] - A[None]) ** 2).sum(-1)) + noise * np.eye(60)
    Ks = c * np.exp(-0.5 * ((B[:, None] - A[None]) ** 2).sum(-1))
    mu_y, sd_y = Y.mean(axis=0), Y.std(axis=0)
    alpha = np.linalg.solve(K_, (Y - mu_y) / sd_y)
    var = c + noise - np.einsum("ij,ji->i", Ks, np.linalg.solve(K_, Ks.T))
    np.testing.assert_allclose(mean, Ks @ alpha * sd_y + mu_y, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(std, np.sqrt(var)[:, None] * sd_y, rtol=1e-5)
    assert ls[0] < ls[1] / 5 and ls[0] < ls[2] / 5  # the irrelevant inputs get long length scales
    # calibrated on fresh noisy data: about 90% inside the central 90% interval
    Xn = rng.uniform(-2, 2, size=(400, 3))
    Yn = np.column_stack([np.sin(2 * Xn[:, 0]), 3 * np.sin(2 * Xn[:, 0])]) + 0.1 * rng.normal(
        size=(400, 2)
    )
    m, s = gp.predict(Xn, return_std=True)
    assert 0.8 < np.mean(np.abs(Yn - m) <= 1.645 * s) < 0.97


TODAY = [
    KernelRidgeRBF,
    GaussianProcessARD,
    lambda: RandomForest(n_estimators=5),
    lambda: MLP(max_iter=20, validation_fraction=0.2),
]


@pytest.mark.parametrize("make", TODAY)
def test_todays_baselines_reject_row_mismatch_and_nan(make):
    test_row_mismatch_and_nan_are_rejected(make)


@pytest.mark.parametrize(
    "est, match",
    [
        (
            KernelRidgeRBF(alpha=0.0),
            r"The 'alpha' parameter of KernelRidgeRBF must be a float in the range \(0\.0, inf\)\. Got 0\.0",
        ),
        (
            KernelRidgeRBF(gamma_scale=-1),
            r"The 'gamma_scale' parameter of KernelRidgeRBF must be .*Got -1 instead",
        ),
        (
            KernelRidgeRBF(input_scaling="std"),
            r"The 'input_scaling' parameter of KernelRidgeRBF must be a str among .*Got 'std'",
        ),
        (
            GaussianProcessARD(n_restarts_optimizer=-1),
            r"The 'n_restarts_optimizer' parameter of GaussianProcessARD must be an int in the range \[0, inf\)\. Got -1",
        ),
        (
            RandomForest(max_features=2.0),
            r"The 'max_features' parameter of RandomForest must be a float in the range \(0\.0, 1\.0\]\. Got 2\.0",
        ),
        (
            RandomForest(min_samples_leaf=0),
            r"The 'min_samples_leaf' parameter of RandomForest must be an int in the range \[1, inf\)\. Got 0",
        ),
        (
            MLP(hidden_units=0),
            r"The 'hidden_units' parameter of MLP must be an int in the range \[1, inf\)\. Got 0",
        ),
        (
            MLP(validation_fraction=1.0),
            r"The 'validation_fraction' parameter of MLP must be a float in the range \(0\.0, 1\.0\)\. Got 1\.0",
        ),
        (
            MLP(validation_fraction=0.1),
            r"validation_fraction=0.1 of n_samples = 12 leaves fewer than 2",
        ),
    ],
)
def test_todays_baselines_name_bad_parameters(est, match):
    test_bad_parameters_name_parameter_and_value(est, match)
