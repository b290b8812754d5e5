"""All seven estimators on adversarial inputs (issue 14): inputs off the training range must give sane poses.

The data are the authors' acrobatics features (resources/paper-features/x4921.mat, the study's "hsc" source),
a contiguous block of 30 training frames and test frames more than 30 frames away (the contiguous protocol of
:func:`bsrbench.splits.make_split`), heading transform on, as in the study. Before the shared input scaling
(:mod:`bsrbench.models.scaling`), PM and ridge predicted angles of 1e7 deg on such a split.

- a feature constant in training but not in test;
- test inputs 10x outside the training range;
- the contiguous split itself: every method's error within 1.5x of 1-NN's;
- NaN (and infinity) in the test input: an InputError naming the row and column.

"Within a bound" is checked against bounds computed here from the training poses: the range of each output
widened by half its width on each side (what the estimators promise, :data:`scaling.OUTPUT_MARGIN`), and, as
an independent sanity bound, every predicted angle within 360 deg of the training range.
"""

from pathlib import Path

import numpy as np
import pytest

from bsrbench.datasets import load_feature_mat
from bsrbench.errors import InputError
from bsrbench.metrics import mean_angle_error
from bsrbench.models import (
    DDL,
    RVM,
    SR,
    TGP,
    BayesianSR,
    NearestNeighbourRegressor,
    RidgeRegressor,
    scaling,
)
from bsrbench.poses import HeadingTransform
from bsrbench.splits import make_split

ROOT = Path(__file__).resolve().parents[1]
MAT = ROOT / "resources" / "paper-features" / "x4921.mat"

ESTIMATORS = {
    "RVM": lambda: RVM(width_scale=0.5),
    "TGP": lambda: TGP(init="ridge", max_iter=30),  # the ridge start is the one that exploded
    "SR": lambda: SR(alpha=1e-3),
    "DDL": lambda: DDL(n_components=40, alpha=0.03, max_iter=20, random_state=0),
    "PM": lambda: BayesianSR(
        n_atoms=32,
        n_neighbors=5,
        n_iter=80,
        n_burn_in=50,
        thin=3,
        n_predict_sweeps=5,
        random_state=0,
    ),
    "1-NN": lambda: NearestNeighbourRegressor(n_neighbors=1),
    "Ridge": lambda: RidgeRegressor(alpha=10.0),
}


@pytest.fixture(scope="module")
def split():
    """(X_train, Z_train, X_test, Y_train, Y_test, transform): N = 30, every 4th test frame (speed)."""
    fs = load_feature_mat(MAT, n_frames=600, drop_y_columns=3, checksums=MAT.parent / "SHA256SUMS")
    train, test = make_split(600, 30, protocol="contiguous", seed=0, gap=30)
    test = test[::4]
    tf = HeadingTransform(column=2)
    return fs.X[train], tf.forward(fs.Y[train]), fs.X[test], fs.Y[train], fs.Y[test], tf


@pytest.fixture(scope="module")
def fitted(split):
    Xtr, Ztr = split[0], split[1]
    return {name: make().fit(Xtr, Ztr) for name, make in ESTIMATORS.items()}


def _assert_sane(name, Z, Ztr, tf, Ytr):
    assert np.all(np.isfinite(Z)), f"{name}: non-finite prediction"
    lo, hi = Ztr.min(0), Ztr.max(0)
    w = hi - lo
    tol = 1e-9 * (1.0 + np.abs(Ztr).max())
    assert np.all(Z >= lo - scaling.OUTPUT_MARGIN * w - tol) and np.all(
        Z <= hi + scaling.OUTPUT_MARGIN * w + tol
    ), f"{name}: prediction outside the widened training range: {Z.min():.3g} .. {Z.max():.3g}"
    Y = tf.inverse(Z)
    far = np.max(np.maximum(Y - Ytr.max(0), Ytr.min(0) - Y))
    assert far <= 360.0, f"{name}: a predicted angle lies {far:.3g} deg outside the training range"


def test_the_old_per_bin_scaling_explodes_on_this_data(split):
    """The data do hold the trap: bins nearly constant in training reach huge standardized test values."""
    Xtr, _, Xte = split[:3]
    old = scaling.InputScaler("bin")
    old_floor = scaling.BIN_FLOOR
    try:
        scaling.BIN_FLOOR = 0.0  # the former unfloored StandardScaler
        z_old = np.abs(old.fit(Xtr).transform(Xte)).max()
    finally:
        scaling.BIN_FLOOR = old_floor
    z_new = np.abs(scaling.InputScaler().fit(Xtr).transform(Xte)).max()
    assert z_old > 1e3
    assert z_new < 50, z_new


@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_feature_constant_in_training_but_not_in_test(name, split):
    Xtr, Ztr, Xte, Ytr, _, tf = split
    Xtr, Xte = Xtr.copy(), Xte.copy()
    j = int(np.argmax(Xtr.std(0)))  # the most informative bin, made constant in training
    Xtr[:, j] = Xtr[0, j]
    Xte[:, j] = Xtr[0, j] + np.linspace(0, 10, Xte.shape[0]) * Xtr.max()
    est = ESTIMATORS[name]().fit(Xtr, Ztr)
    _assert_sane(name, est.predict(Xte), Ztr, tf, Ytr)


@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_inputs_ten_times_outside_the_training_range(name, split, fitted):
    _, Ztr, Xte, Ytr, _, tf = split
    _assert_sane(name, fitted[name].predict(10.0 * Xte), Ztr, tf, Ytr)
    _assert_sane(name, fitted[name].predict(-10.0 * Xte), Ztr, tf, Ytr)


def test_contiguous_split_errors_within_1_5_times_nearest_neighbour(split, fitted):
    _, Ztr, Xte, Ytr, Yte, tf = split
    errors = {}
    for name, est in fitted.items():
        Z = est.predict(Xte)
        _assert_sane(name, Z, Ztr, tf, Ytr)
        errors[name] = mean_angle_error(Yte, tf.inverse(Z))
    bad = {k: round(v, 2) for k, v in errors.items() if v > 1.5 * errors["1-NN"]}
    assert not bad, f"errors above 1.5 x 1-NN's {errors['1-NN']:.2f} deg: {bad}"


@pytest.mark.parametrize("bad", [np.nan, np.inf])
@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_non_finite_test_input_is_a_clear_error(name, bad, split, fitted):
    Xte = split[2][:5].copy()
    Xte[3, 7] = bad
    kind = "NaN" if np.isnan(bad) else "infinity"
    with pytest.raises(
        InputError,
        match=rf"{type(fitted[name]).__name__}\.predict: Input X contains {kind} "
        r"at row 3, column 7",
    ):
        fitted[name].predict(Xte)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_non_finite_training_output_is_a_clear_error(name, bad, split):
    Xtr, Ztr = split[0], split[1].copy()
    Ztr[4, 2] = bad
    est = ESTIMATORS[name]()
    kind = "NaN" if np.isnan(bad) else "infinity"
    with pytest.raises(
        InputError,
        match=rf"{type(est).__name__}\.fit: Input Y contains {kind} at row 4, column 2; "
        r"expected finite outputs",
    ):
        est.fit(Xtr, Ztr)


def test_input_scaler_rules_and_errors():
    rng = np.random.default_rng(0)
    X = rng.random((20, 5)) * np.array([1.0, 2.0, 3.0, 1e-6, 0.0])
    pooled = scaling.InputScaler("pooled").fit(X).scaler_
    assert np.allclose(pooled.scale_, np.sqrt(np.mean(X.var(0))))
    assert np.allclose(pooled.mean_, X.mean(0))
    binned = scaling.InputScaler("bin").fit(X).scaler_
    floor = scaling.BIN_FLOOR * np.median(X.std(0))
    assert np.allclose(binned.scale_, np.maximum(X.std(0), floor))
    raw = scaling.InputScaler("none").fit(X)
    assert np.array_equal(raw.transform(X), X)
    with pytest.raises(
        InputError, match=r"input_scaling must be one of \['pooled', 'bin', 'none'\]; got 'per-bin'"
    ):
        scaling.InputScaler("per-bin").fit(X)
    with pytest.raises(
        InputError, match="The 'input_scaling' parameter of RidgeRegressor must be a str among"
    ):
        RidgeRegressor(input_scaling="std").fit(X, X[:, 0])
