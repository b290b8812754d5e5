"""The paper's error metric on joint angles (degrees).

For each angle, the root mean square over test frames of the wrapped difference
``((a - b + 180) mod 360) - 180``; the error of a test set is the mean of these per-angle values
(paper, Section "Experimental Results"; docs/model.md, section "Error metric").

The angle primitives (:func:`wrap_degrees`) live here; the scores of a job's predictive distribution are in
:mod:`bsrbench.scores`, and the scoring of a job's test set in :mod:`bsrbench.runs`.
"""

import numpy as np

from .errors import InputError


def wrap_degrees(d):
    """Wrap angle differences (degrees) into [-180, 180)."""
    return np.mod(np.asarray(d, dtype=float) + 180.0, 360.0) - 180.0


def check_pair(y_true, y_pred):
    y_true = np.asarray(y_true, dtype=float)
    y_pred = np.asarray(y_pred, dtype=float)
    if y_true.ndim != 2 or y_true.shape != y_pred.shape:
        raise InputError(
            f"y_true and y_pred must be 2-D arrays of the same shape (frames x angles); "
            f"got {y_true.shape} and {y_pred.shape}"
        )
    if y_true.shape[0] == 0:
        raise InputError("y_true has no rows: cannot score an empty test set")
    for name, a in (("y_true", y_true), ("y_pred", y_pred)):
        if not np.all(np.isfinite(a)):
            bad = np.argwhere(~np.isfinite(a))[0]
            raise InputError(f"{name} has a non-finite value at row {bad[0]}, column {bad[1]}")
    return y_true, y_pred


def per_angle_rms(y_true, y_pred, wrap=True):
    """RMS over frames of the wrapped angle difference, one value per angle (degrees); ``wrap=False``: of the
    plain difference, as a metric that ignores the circle scores it (a sensitivity of the error's definition)."""
    y_true, y_pred = check_pair(y_true, y_pred)
    d = wrap_degrees(y_pred - y_true) if wrap else y_pred - y_true
    return np.sqrt(np.mean(d * d, axis=0))


def mean_angle_error(y_true, y_pred, wrap=True):
    """The paper's error: mean over angles of the per-angle RMS (degrees)."""
    return float(np.mean(per_angle_rms(y_true, y_pred, wrap)))


def interval_coverage(y_true, y_mean, y_std, level=0.9):
    """Fraction of test values inside the central ``level`` Gaussian predictive interval.

    Differences are wrapped, so an interval around 179 degrees covers -179 degrees.
    """
    from scipy.stats import norm

    y_true, y_mean = check_pair(y_true, y_mean)
    y_std = np.asarray(y_std, dtype=float)
    if y_std.shape != y_mean.shape:
        raise InputError(f"y_std must have shape {y_mean.shape}; got {y_std.shape}")
    if not 0 < level < 1:
        raise InputError(f"level must be in (0, 1); got {level!r}")
    z = norm.ppf(0.5 + level / 2)
    return float(np.mean(np.abs(wrap_degrees(y_true - y_mean)) <= z * y_std))
