"""Tests of bsrbench.tuning.tune: selection, the predict-time shortcut, scoring space, errors."""

import numpy as np
import pytest
from joblib import parallel_config
from sklearn.model_selection import KFold
from threadpoolctl import threadpool_limits

from bsrbench.errors import InputError
from bsrbench.metrics import mean_angle_error
from bsrbench.models.reference import NearestNeighbourRegressor, RidgeRegressor
from bsrbench.poses import HeadingTransform
from bsrbench.tuning import TuneResult, tune


@pytest.fixture(autouse=True)
def _one_blas_thread():
    """One BLAS thread: the small matrices here gain nothing from threads, and on a loaded machine
    oversubscribed BLAS threads make them many times slower."""
    with threadpool_limits(1):
        yield


class CountingNN(NearestNeighbourRegressor):
    """k-NN that counts its fits (class-level counter, survives clone)."""

    n_fit_calls = 0

    def fit(self, X, Y):
        type(self).n_fit_calls += 1
        return super().fit(X, Y)


class CountingNNRefit(CountingNN):
    """Same estimator without the predict-time declaration: every grid point is refitted."""

    _predict_time_params = ()
    n_fit_calls = 0


def _curve(n, seed):
    """A wiggly noise-free map sampled densely: 1-NN is clearly the best k."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0, 1, size=(n, 1))
    Y = np.column_stack([40 * np.sin(12 * x[:, 0]), 30 * np.cos(9 * x[:, 0])])
    return x, Y


def test_tune_selects_one_nearest_neighbour_when_it_is_best():
    X, Y = _curve(120, 0)
    res = tune(NearestNeighbourRegressor(), {"n_neighbors": [1, 3, 8, 20]}, X, Y, cv=4)
    assert isinstance(res, TuneResult)
    assert res.best_params == {"n_neighbors": 1}
    df = res.cv_results
    assert list(df["param_n_neighbors"]) == [1, 3, 8, 20]
    assert np.all(np.diff(df["mean_error"].to_numpy()) > 0)  # error grows with k on this curve
    assert res.best_score == df["mean_error"].min()
    assert df.loc[df["rank"] == 1, "param_n_neighbors"].item() == 1


def test_tune_selects_ridge_penalty_on_noisy_linear_data():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(80, 30))
    Y = X[:, :2] @ np.array([[5.0, -3.0], [2.0, 4.0]]) + 3.0 * rng.standard_normal((80, 2))
    res = tune(RidgeRegressor(), {"alpha": [1e-6, 10.0, 1e6]}, X, Y, cv=5)
    assert res.best_params == {
        "alpha": 10.0
    }  # neither no penalty (30 noisy features) nor a constant


def test_predict_time_grid_equals_refit_grid_with_fewer_fits():
    X, Y = _curve(60, 2)
    grid = {"n_neighbors": [1, 2, 4, 6], "weights": ["uniform", "distance"]}
    CountingNN.n_fit_calls = 0
    CountingNNRefit.n_fit_calls = 0
    fast = tune(CountingNN(), grid, X, Y, cv=3, random_state=7)
    slow = tune(CountingNNRefit(), grid, X, Y, cv=3, random_state=7)
    assert CountingNN.n_fit_calls == fast.n_fits == 3 * 2  # one fit per fold per weights value
    assert CountingNNRefit.n_fit_calls == slow.n_fits == 3 * 8  # one fit per fold per grid point
    np.testing.assert_allclose(
        fast.cv_results["mean_error"], slow.cv_results["mean_error"], rtol=1e-12
    )
    assert fast.best_params == slow.best_params
    assert list(fast.cv_results["params"]) == list(slow.cv_results["params"])


def test_scores_in_original_pose_space_with_transform():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(50, 4))
    Y = np.column_stack([10 * X[:, 0], 5 * X[:, 1], np.rad2deg(np.arctan2(X[:, 2], X[:, 3]))])
    H = HeadingTransform(column=2)
    res = tune(RidgeRegressor(), {"alpha": [0.5]}, X, Y, cv=5, random_state=11, pose_transform=H)
    errs = []
    for tr, te in KFold(5, shuffle=True, random_state=11).split(X):
        m = RidgeRegressor(alpha=0.5).fit(X[tr], H.forward(Y[tr]))
        errs.append(mean_angle_error(Y[te], H.inverse(m.predict(X[te]))))
    assert res.best_score == pytest.approx(np.mean(errs), rel=1e-12)
    plain = tune(RidgeRegressor(), {"alpha": [0.5]}, X, Y, cv=5, random_state=11)
    assert plain.best_score != pytest.approx(res.best_score)  # the transform changes what is fitted


def test_parallel_jobs_give_the_same_result():
    X, Y = _curve(40, 4)
    a = tune(NearestNeighbourRegressor(), {"n_neighbors": [1, 2, 3]}, X, Y, cv=3, n_jobs=1)
    with parallel_config(
        backend="threading"
    ):  # the parallel code path without process start-up cost
        b = tune(NearestNeighbourRegressor(), {"n_neighbors": [1, 2, 3]}, X, Y, cv=3, n_jobs=2)
    np.testing.assert_allclose(a.cv_results["mean_error"], b.cv_results["mean_error"])


def test_errors_are_clear():
    X, Y = _curve(3, 5)
    with pytest.raises(InputError, match=r"cv=5 folds need at least 5 rows; X has 3 rows"):
        tune(NearestNeighbourRegressor(), {"n_neighbors": [1]}, X, Y, cv=5)
    X, Y = _curve(20, 5)
    with pytest.raises(InputError, match=r"unknown parameter 'n_neigbors'"):
        tune(NearestNeighbourRegressor(), {"n_neigbors": [1]}, X, Y)
    with pytest.raises(InputError, match="param_grid is empty"):
        tune(NearestNeighbourRegressor(), {}, X, Y)
    with pytest.raises(InputError, match="param_grid is empty"):
        tune(NearestNeighbourRegressor(), [], X, Y)
    with pytest.raises(InputError, match=r"param_grid\['n_neighbors'\] is an empty list"):
        tune(NearestNeighbourRegressor(), {"n_neighbors": []}, X, Y)
    with pytest.raises(
        InputError, match=r"param_grid\['weights'\] must be a list of values; got 'uniform'"
    ):
        tune(NearestNeighbourRegressor(), {"weights": "uniform"}, X, Y)
    with pytest.raises(InputError, match=r"cv must be an integer >= 2 .*; got 1"):
        tune(NearestNeighbourRegressor(), {"n_neighbors": [1]}, X, Y, cv=1)
    with pytest.raises(InputError, match="same number of rows; got 20 and 19"):
        tune(NearestNeighbourRegressor(), {"n_neighbors": [1]}, X, Y[:19])
    # too few rows in a training fold for the neighbours: the estimator's own error surfaces
    with pytest.raises(InputError, match=r"n_neighbors=18 exceeds .* n_samples = 16"):
        tune(NearestNeighbourRegressor(), {"n_neighbors": [18]}, X, Y, cv=5)


def test_predict_time_values_come_from_the_grid_not_the_base_estimator():
    # the base estimator's n_neighbors=50 would not fit on 16-row folds; the grid's values do
    X, Y = _curve(20, 6)
    res = tune(NearestNeighbourRegressor(n_neighbors=50), {"n_neighbors": [1, 2]}, X, Y, cv=5)
    ref = tune(NearestNeighbourRegressor(), {"n_neighbors": [1, 2]}, X, Y, cv=5)
    np.testing.assert_array_equal(res.cv_results["mean_error"], ref.cv_results["mean_error"])
    assert res.best_params == ref.best_params
