"""Job logic of the study: splits, estimator loading, pose-transform std, one job's result row, CV."""

import json

import numpy as np
import pytest

from bsrbench.errors import DataFileError, InputError
from bsrbench.estimators import (
    default_grid,
    load_estimator_class,
    make_estimator,
)
from bsrbench.io import load_features, write_arrays, write_json
from bsrbench.poses import HeadingTransform
from bsrbench.runs import cross_validate, inverse_std, run_job
from bsrbench.splits import JobSpec, make_split, max_n_train

REF = "bsrbench.models.reference"


@pytest.mark.parametrize("protocol", ["random", "contiguous"])
@pytest.mark.parametrize("n_train", [30, 200])
def test_split_is_disjoint_sized_and_reproducible(protocol, n_train):
    tr, te = make_split(600, n_train, protocol=protocol, seed=7, min_test=100, gap=30)
    assert tr.size == n_train
    assert np.intersect1d(tr, te).size == 0
    assert te.size >= 100
    tr2, te2 = make_split(600, n_train, protocol=protocol, seed=7, min_test=100, gap=30)
    assert np.array_equal(tr, tr2) and np.array_equal(te, te2)
    if protocol == "random":
        assert tr.size + te.size == 600
    else:
        assert np.array_equal(tr, np.arange(tr[0], tr[0] + n_train))
        # every test frame is more than `gap` frames from the training block
        dist = np.minimum(np.abs(te[:, None] - tr[None, :]), 10**9).min(axis=1)
        assert dist.min() > 30


def test_split_differs_between_seeds_and_rejects_too_few_test_frames():
    a, _ = make_split(600, 30, seed=0)
    b, _ = make_split(600, 30, seed=1)
    assert not np.array_equal(a, b)
    with pytest.raises(InputError, match="min_test=100"):
        make_split(600, 550, seed=0, min_test=100)
    with pytest.raises(InputError, match="protocol"):
        make_split(600, 30, protocol="blocks")
    assert max_n_train(600, min_test=100) == 500
    make_split(
        600, max_n_train(600, protocol="contiguous", min_test=100, gap=30), protocol="contiguous"
    )


def test_every_method_sees_the_same_split():
    a = JobSpec("hsc", "golf", "PM", 60, 3).split(600)
    b = JobSpec("hsc", "golf", "RVM", 60, 3).split(600)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert (
        JobSpec("hsc", "golf", "PM", 60, 3).method_seed
        != JobSpec("hsc", "golf", "RVM", 60, 3).method_seed
    )


def test_estimator_loading_errors_name_the_path_and_parameter():
    assert load_estimator_class(f"{REF}:RidgeRegressor").__name__ == "RidgeRegressor"
    with pytest.raises(InputError, match="package.module:ClassName"):
        load_estimator_class("bsrbench.models.reference.RidgeRegressor")
    with pytest.raises(InputError, match="cannot import module 'bsrbench.models.nosuch'"):
        load_estimator_class("bsrbench.models.nosuch:X")
    with pytest.raises(InputError, match="no attribute 'Nope'"):
        load_estimator_class(f"{REF}:Nope")
    with pytest.raises(InputError, match=r"no parameter\(s\) \['alpah'\]"):
        make_estimator(f"{REF}:RidgeRegressor", {"alpah": 1.0})
    assert default_grid(f"{REF}:RidgeRegressor") == {"alpha": [0.1, 1.0, 10.0, 100.0, 1000.0]}


def test_inverse_std_of_heading_matches_monte_carlo():
    rng = np.random.default_rng(0)
    t = HeadingTransform()
    Z_mean = np.array([[1.0, 2.0, 20 * np.sin(0.7), 20 * np.cos(0.7)]])
    Z_std = np.array([[0.5, 0.25, 0.4, 0.3]])
    sd = inverse_std(t, Z_mean, Z_std)
    assert sd.shape == (1, 3)
    assert np.allclose(sd[0, [0, 1]], [0.5, 0.25])
    draws = Z_mean + Z_std * rng.standard_normal((200000, 4))
    heading = t.inverse(draws)[:, 2]
    assert sd[0, 2] == pytest.approx(np.std(heading), rel=0.02)


def _synthetic_features(tmp_path, n=200):
    rng = np.random.default_rng(1)
    X = rng.normal(size=(n, 6))
    Y = np.column_stack(
        [X[:, :3] @ rng.normal(size=(3, 4)) * 10, np.rad2deg(np.arctan2(X[:, 4], X[:, 5]))]
    )
    Y = Y[:, [0, 1, 4, 2, 3]]  # heading in column 2, as in the data
    path = tmp_path / "f.npz"
    np.savez(path, X=X, Y=Y, frames=np.arange(n), angle_names=np.array([f"a{i}" for i in range(5)]))
    return path


def test_load_features_checks_the_file(tmp_path):
    f = load_features(_synthetic_features(tmp_path))
    assert f["X"].shape == (200, 6) and f["Y"].shape == (200, 5) and len(f["angle_names"]) == 5
    with pytest.raises(DataFileError, match="does not exist"):
        load_features(tmp_path / "none.npz")
    bad = tmp_path / "bad.npz"
    np.savez(bad, X=np.ones((3, 2)), Y=np.ones((4, 2)))
    with pytest.raises(DataFileError, match="same number of rows"):
        load_features(bad)
    nan = tmp_path / "nan.npz"
    np.savez(nan, X=np.array([[1.0, np.nan]]), Y=np.ones((1, 2)))
    with pytest.raises(DataFileError, match=r"non-finite value\(s\), first at row 0"):
        load_features(nan)
    # a truncated file (an interrupted copy): numpy raises zipfile.BadZipFile, which used to reach the job's log
    good = _synthetic_features(tmp_path)
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[:100])
    with pytest.raises(DataFileError, match=r"cut\.npz.*cannot read as \.npz.*delete it and rerun"):
        load_features(cut)


def test_run_job_scores_in_degrees_after_undoing_the_transform(tmp_path):
    feats = load_features(_synthetic_features(tmp_path))
    spec = JobSpec("syn", "act", "NN1", 50, 0, min_test=50, paper_activity="Act")
    row, arrays = run_job(
        spec, feats, estimator=f"{REF}:NearestNeighbourRegressor", params={"n_neighbors": 1}
    )
    train, test = spec.split(200)
    assert np.array_equal(arrays["test"], test) and np.array_equal(arrays["train"], train)
    # independent check of the error: 1-NN in feature space, wrapped degrees, RMS per angle, mean
    d2 = ((feats["X"][test][:, None] - feats["X"][train][None]) ** 2).sum(-1)
    pred = feats["Y"][train][d2.argmin(1)]
    diff = (pred - feats["Y"][test] + 180) % 360 - 180
    assert row["error"] == pytest.approx(np.sqrt((diff**2).mean(0)).mean(), rel=1e-9)
    assert row["coverage"] is None and row["n_test"] == test.size and row["paper_activity"] == "Act"
    assert {"fit_seconds", "predict_seconds", "versions", "per_angle_rms", "split_seed"} <= set(row)
    json.dumps(row)  # JSON-ready
    write_json(tmp_path / "r.json", row)
    write_arrays(tmp_path / "p.npz", arrays)
    assert json.loads((tmp_path / "r.json").read_text())["error"] == row["error"]


def test_cross_validate_picks_from_the_grid_and_keeps_fixed_params(tmp_path):
    feats = load_features(_synthetic_features(tmp_path))
    spec = JobSpec("syn", "act", "Ridge", 60, 0, min_test=50)
    res = cross_validate(
        spec,
        feats,
        estimator=f"{REF}:RidgeRegressor",
        params={"standardize": True},
        grid={"alpha": [0.01, 1e6]},
        folds=3,
    )
    assert res["best_params"] == {"standardize": True, "alpha": 0.01}
    assert len(res["cv_results"]) == 2 and res["best_score"] > 0
