"""Input scaling and output bounds shared by the estimators: what keeps predictions sane off the training range.

Input scaling (``InputScaler``, a scikit-learn ``StandardScaler`` whose ``scale_`` is set by one of three rules):

- ``"pooled"`` (the default of every estimator that scales inputs): each feature is centred by its training
  mean and ALL features are divided by one scale, the root mean square of the centred training entries.
  A test value ``t`` of any bin becomes ``(t - mean) / s_pooled``: its amplification is the same for every bin
  and is set by the spread of the whole histogram, so a bin that happened to be (nearly) constant in training
  cannot blow up. The relative weights of the histogram bins stay those of the raw counts (the Euclidean
  geometry in which 1-NN, SR, RVM and TGP compare histograms).
- ``"bin"``: per-bin standardization with a variance floor: ``scale_j = max(std_j, floor * median_k std_k)``
  (``floor`` = ``BIN_FLOOR``); a bin's amplification is at most ``1 / (floor * median std)``.
- ``"none"``: the raw features (counts), as the authors used them.

The default, "pooled", was chosen by blocked 5-fold CV on the training frames (``benchmarks/scaling_cv.py``);
the measurements and why an unfloored per-bin scale fails off the training range: docs/scaling.md.

Output bounds (``output_bounds``, ``clip_to_bounds``): a prediction is clipped, per output column, to the
training range widened by ``OUTPUT_MARGIN`` times its width on each side. Methods that return convex
combinations of training poses (1-NN, SR with positive normalized codes) never reach the bound; for the
others it is the limit of what the training data can justify: an extrapolation beyond half the observed range
of a joint angle is not a pose the model has evidence for. A column constant in training is predicted as that
constant.
"""

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.preprocessing import StandardScaler
from sklearn.utils.validation import check_is_fitted

from ..errors import InputError

INPUT_SCALINGS = ("pooled", "bin", "none")
"""Choices of ``input_scaling`` (see the module docstring)."""

BIN_FLOOR = 0.1
"""Variance floor of ``"bin"`` scaling: no bin's scale below this fraction of the median per-bin std."""

OUTPUT_MARGIN = 0.5
"""Predictions are clipped to [min - m * width, max + m * width] of each training output column."""


def check_finite_input(est, X, stage="predict", name="X"):
    """Raise ``InputError`` if the array X (n, n_features) -- or the targets Y with ``name="Y"`` -- has a NaN or
    infinite entry, naming the estimator, the stage (fit or predict), the first offending row and column and the
    value (before scikit-learn's generic message)."""
    A = np.asarray(X)
    if A.dtype.kind not in "fc":
        return
    bad = ~np.isfinite(A)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        where = f"row {idx[0]}, column {idx[1]}" if len(idx) == 2 else f"index {idx}"
        kind = "NaN" if np.isnan(A[idx]) else "infinity"
        what = "features" if name == "X" else "outputs"
        raise InputError(
            f"{type(est).__name__}.{stage}: Input {name} contains {kind} at {where}; expected finite {what} "
            f"(impute or drop the frame first)"
        )


def check_input_scaling(value):
    """Validate an ``input_scaling`` parameter; raise ``InputError`` naming the value and the choices."""
    if not isinstance(value, str) or value not in INPUT_SCALINGS:
        raise InputError(f"input_scaling must be one of {list(INPUT_SCALINGS)}; got {value!r}")
    return value


class InputScaler(TransformerMixin, BaseEstimator):
    """Centre each feature and divide by a scale that cannot explode off the training range.

    A ``sklearn.preprocessing.StandardScaler`` whose ``scale_`` is replaced by the rule of ``kind``.

    Parameters
    ----------
    kind : {"pooled", "bin", "none"}
        Scale rule (module docstring): one pooled scale for all features, per-feature std with a floor of
        ``BIN_FLOOR`` times the median std, or the identity (no centring, no scaling).

    Attributes
    ----------
    scaler_ : StandardScaler
        The fitted scaler: ``mean_`` and ``scale_`` (n_features,); ``transform(X)`` of X (n, n_features)
        returns ``(X - mean_) / scale_``.

    Raises ``InputError`` for an unknown ``kind``.
    """

    def __init__(self, kind="pooled"):
        self.kind = kind

    def fit(self, X, y=None):
        check_input_scaling(self.kind)
        on = self.kind != "none"
        self.scaler_ = StandardScaler(with_mean=on, with_std=on).fit(X)
        if on:
            var = self.scaler_.var_
            if self.kind == "pooled":
                s = float(np.sqrt(np.mean(var)))  # RMS of the centred entries
                scale = np.full_like(var, s if s > 0 else 1.0)
            else:
                std = np.sqrt(var)
                med = float(np.median(std))
                floor = BIN_FLOOR * med if med > 0 else (float(std.max()) if std.max() > 0 else 1.0)
                scale = np.maximum(std, floor)
                scale[scale == 0] = (
                    1.0  # a constant bin (only with BIN_FLOOR = 0): centred, not scaled
                )
            self.scaler_.scale_ = scale
        self.n_features_in_ = self.scaler_.n_features_in_
        return self

    def transform(self, X):
        check_is_fitted(self, "scaler_")
        return self.scaler_.transform(X)


def output_bounds(Y, margin=None):
    """Per-column bounds ``(lo, hi)``, each (n_outputs,), of the training outputs Y (n, n_outputs): the
    column's range widened by ``margin`` (default ``OUTPUT_MARGIN``, read at call time) times its width on
    each side; ``margin = inf`` gives no bound."""
    margin = OUTPUT_MARGIN if margin is None else float(margin)
    Y = np.asarray(Y, dtype=float).reshape(len(Y), -1)
    lo, hi = Y.min(axis=0), Y.max(axis=0)
    if np.isinf(margin):
        return np.full_like(lo, -np.inf), np.full_like(hi, np.inf)
    w = hi - lo
    return lo - margin * w, hi + margin * w


def clip_to_bounds(P, bounds):
    """Predictions P (n, n_outputs) clipped to ``bounds`` from :func:`output_bounds`."""
    lo, hi = bounds
    return np.clip(P, lo, hi)
