"""Job logic of the study: splits, estimator loading, pose-transform std, one job's result row, CV."""

import json

import numpy as np
import pytest

from bsrbench.config import check_method_settings
from bsrbench.errors import DataFileError, InputError
from bsrbench.estimators import (
    default_grid,
    estimator_defaults,
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


@pytest.mark.parametrize(
    "setting, message",
    [
        (
            {"estimator": "bsrbench.models.gpr:GPR"},
            r"'methods\.M\.estimator': 'bsrbench\.models\.gpr:GPR' cannot be used .*cannot import module",
        ),
        ({"estimator": f"{REF}:Nope"}, r"'methods\.M\.estimator'.*no attribute 'Nope'"),
        (
            {"estimator": f"{REF}:RidgeRegressor", "params": {"alpah": 1.0}},
            r"'methods\.M\.params': alpah: 1\.0 is not a parameter of .*RidgeRegressor; expected one of \['alpha'",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "cv_params": {"folds": 3}},
            r"'methods\.M\.cv_params': folds: 3",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "grid": {"lambda": [1.0]}},
            r"'methods\.M\.grid': lambda: \[1\.0\]",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "grid": {"alpha": 1.0}},
            r"'methods\.M\.grid': alpha: 1\.0; expected a non-empty list",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "params": [1.0]},
            r"'methods\.M\.params': expected a mapping",
        ),
    ],
)
def test_method_settings_are_checked_before_any_job(setting, message):
    with pytest.raises(InputError, match=message):
        check_method_settings(
            {"M": setting, "Ok": {"estimator": f"{REF}:RidgeRegressor"}}, ["Ok", "M"]
        )
    check_method_settings(
        {"M": setting, "Ok": {"estimator": f"{REF}:RidgeRegressor"}}, ["Ok"]
    )  # M not run
    with pytest.raises(InputError, match=r"'run': unknown method 'X'"):
        check_method_settings({"M": setting}, ["X"])


PM_PATH = "bsrbench.models.bsr:BayesianSR"
PM_OK = {"n_atoms": 16, "n_neighbors": 5, "n_iter": 40, "n_burn_in": 20}


@pytest.mark.parametrize(
    "setting, cv, message",
    [
        (
            {"params": {**PM_OK, "n_atoms": -3}},
            None,
            r"'methods\.M\.params' \(method M, bsrbench\.models\.bsr:BayesianSR\): params \{.*n_atoms: -3.*\}: "
            r"n_atoms must be >= 1; got -3",
        ),
        (
            {"params": {**PM_OK, "w_update": "foo"}},
            None,
            r"'methods\.M\.params' .*w_update must be one of \['ess', 'mh', .*\]; got 'foo'",
        ),
        (
            {"params": {**PM_OK, "n_burn_in": 40}},
            None,
            r"'methods\.M\.params' .*n_burn_in must be smaller than n_iter=40 .*got n_burn_in=40",
        ),
        (
            {"params": {**PM_OK, "thin": 25}},
            None,
            r"'methods\.M\.params' .*thin=25 retains no sweep of the n_iter - n_burn_in = 20 after burn-in; "
            r"expected thin <= 20",
        ),
        (
            {"params": {**PM_OK, "n_neighbors": 31}},
            None,
            r"'methods\.M\.params' .*fitted on the smallest n_train N = 30: BayesianSR needs at least "
            r"max\(2, n_neighbors=31\) training rows; got n_samples = 30",
        ),
        (
            {"params": PM_OK, "grid": {"n_neighbors": [3, 40]}},
            {"mode": "per_size", "folds": 5},
            r"'methods\.M\.grid' .*grid point \{n_neighbors: 40\} .*smallest n_train N = 30: .*n_neighbors=40",
        ),
        (
            {"params": PM_OK, "grid": {"n_neighbors": [3, 27]}},
            {"mode": "per_job", "folds": 5},
            r"'methods\.M\.grid' .*CV fits of grid point \{n_neighbors: 27\} .*training folds of 24 frames "
            r"\(N = 30, cv\.folds = 5\): .*n_neighbors=27\) training rows; got n_samples = 24",
        ),
        (
            {"params": PM_OK, "grid": {"n_atoms": [8, -1]}},
            {"mode": "per_size", "folds": 5},
            r"'methods\.M\.grid' .*grid point \{n_atoms: -1\}.*n_atoms must be >= 1; got -1",
        ),
        (
            {"params": PM_OK, "cv_params": {"n_iter": 10}, "grid": {"n_atoms": [8]}},
            {"mode": "per_size", "folds": 5},
            r"'methods\.M\.cv_params' .*cv_params \{n_iter: 10\} over params .*n_burn_in must be smaller than n_iter=10",
        ),
        (
            {"params": PM_OK, "grid": {"n_atoms": [8]}},
            {"mode": "per_size", "folds": 31},
            r"'cv\.folds': 31 folds of the smallest n_train N = 30 .*would leave empty folds; expected cv\.folds <= 30",
        ),
        (
            {"estimator": f"{REF}:NearestNeighbourRegressor", "params": {"n_neighbors": 31}},
            None,
            r"'methods\.M\.params' .*NearestNeighbourRegressor\).*N = 30: n_neighbors=31 exceeds .* n_samples = 30",
        ),
        (
            {"estimator": f"{REF}:NearestNeighbourRegressor", "params": {"weights": ["uniform"]}},
            None,
            r"weights must be one of \['distance', 'uniform'\]; got \['uniform'\]",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "params": {"alpha": "1e-3"}},
            None,
            r"'methods\.M\.params' .*alpha must be a finite real number in \[0, inf\]; got '1e-3'",
        ),
        (
            {"estimator": "bsrbench.models.tgp:TGP", "params": {"lambda_x": 0}},
            None,
            r"lambda_x must be a finite real number in \(0, inf\]; got 0",
        ),
        (
            {"estimator": "sklearn.linear_model:Ridge", "params": {"alpha": -1.0}},
            None,
            r"'methods\.M\.params' \(method M, sklearn\.linear_model:Ridge\).*The 'alpha' parameter of Ridge must be",
        ),
    ],
    ids=[
        "n_atoms",
        "w_update",
        "burn-in",
        "thin",
        "n_neighbors>N",
        "grid-n_neighbors>N",
        "grid-n_neighbors>fold",
        "grid-value",
        "cv_params",
        "folds>N",
        "1-NN-k>N",
        "unhashable-choice",
        "string-number",
        "TGP",
        "sklearn",
    ],
)
def test_method_values_are_checked_before_any_job(setting, cv, message):
    """Before: every one of these passed the configuration check and failed (or, thin, silently kept one sweep)
    only when a fit or CV job ran; now the error names the key, the method, the value and what was expected."""
    setting = {"estimator": PM_PATH, "grid": None, **setting}
    with pytest.raises(InputError, match=message):
        check_method_settings(
            {"M": setting}, ["M"], n_train=[100, 30], cv=cv or {"mode": "none", "folds": 5}
        )


def test_method_values_checked_only_where_they_apply():
    """A grid is fitted only when CV runs; the smallest N and fold bound only the settings that are fitted."""
    grid = {"n_neighbors": [3, 27]}  # 27 > the 24 rows of a training fold of N = 30, <= N
    setting = {"estimator": PM_PATH, "params": PM_OK, "grid": grid}
    check_method_settings(
        {"M": setting}, ["M"], n_train=[30], cv={"mode": "none", "folds": 5}
    )  # no CV: no grid
    check_method_settings(
        {"M": setting}, ["M"], n_train=[40], cv={"mode": "per_size", "folds": 5}
    )  # folds of 32
    check_method_settings({"M": setting}, ["M"])  # no sizes given: values alone
    with pytest.raises(InputError, match="training folds of 24 frames"):
        check_method_settings(
            {"M": setting}, ["M"], n_train=[30, 40], cv={"mode": "per_size", "folds": 5}
        )
    # cv_params act in CV fits only
    bad_cv = {**setting, "cv_params": {"n_iter": 10}}  # n_burn_in 20 >= 10 in the CV fits
    check_method_settings({"M": bad_cv}, ["M"], n_train=[40], cv={"mode": "none", "folds": 5})
    with pytest.raises(InputError, match=r"'methods\.M\.cv_params'"):
        check_method_settings(
            {"M": bad_cv}, ["M"], n_train=[40], cv={"mode": "per_size", "folds": 5}
        )
    # cv.folds > N matters only when a method is tuned
    check_method_settings(
        {"M": {**setting, "grid": None}}, ["M"], n_train=[30], cv={"mode": "per_size", "folds": 31}
    )


def test_method_settings_accept_the_shipped_configurations_and_report_defaults():
    from pathlib import Path

    import yaml

    root = Path(__file__).resolve().parents[1]
    base = yaml.safe_load((root / "config" / "config.yaml").read_text())
    check_method_settings(
        base["methods"], base["run"], n_train=base["n_train"], cv=base["cv"]
    )  # default grids
    for name in ("paper.yaml", "ci.yaml", "ablation.yaml"):
        over = yaml.safe_load((root / "config" / name).read_text())
        methods = {m: {**base["methods"].get(m, {}), **s} for m, s in over["methods"].items()}
        check_method_settings(
            {**base["methods"], **methods},
            over.get("run", base["run"]),
            n_train=over.get("n_train", base["n_train"]),
            cv={**base["cv"], **over.get("cv", {})},
        )
    d = estimator_defaults(f"{REF}:RidgeRegressor")
    assert d == {"alpha": 1.0, "standardize": True, "input_scaling": "pooled"}


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
