"""The paper's error metric on joint angles (degrees).

For each angle, the root mean square over test frames of the wrapped difference
``((a - b + 180) mod 360) - 180``; the error of a test set is the mean of these per-angle values
(paper, Section "Experimental Results"; docs/model.md, section "Error metric").

:func:`extra_scores` adds, per test set, the joint-position errors MPJPE and PA-MPJPE (mm,
:mod:`bsrbench.kinematics`) and the proper scores NLPD and CRPS of a predictive distribution
(:mod:`bsrbench.scores`).
"""

import numpy as np

from .errors import InputError


def wrap_degrees(d):
    """Wrap angle differences (degrees) into [-180, 180)."""
    return np.mod(np.asarray(d, dtype=float) + 180.0, 360.0) - 180.0


def _check_pair(y_true, y_pred):
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


def per_angle_rms(y_true, y_pred):
    """RMS over frames of the wrapped angle difference, one value per angle (degrees)."""
    y_true, y_pred = _check_pair(y_true, y_pred)
    d = wrap_degrees(y_pred - y_true)
    return np.sqrt(np.mean(d * d, axis=0))


def mean_angle_error(y_true, y_pred):
    """The paper's error: mean over angles of the per-angle RMS (degrees)."""
    return float(np.mean(per_angle_rms(y_true, y_pred)))


def interval_coverage(y_true, y_mean, y_std, level=0.9):
    """Fraction of test values inside the central ``level`` Gaussian predictive interval.

    Differences are wrapped, so an interval around 179 degrees covers -179 degrees.
    """
    from scipy.stats import norm

    y_true, y_mean = _check_pair(y_true, y_mean)
    y_std = np.asarray(y_std, dtype=float)
    if y_std.shape != y_mean.shape:
        raise InputError(f"y_std must have shape {y_mean.shape}; got {y_std.shape}")
    if not 0 < level < 1:
        raise InputError(f"level must be in (0, 1); got {level!r}")
    z = norm.ppf(0.5 + level / 2)
    return float(np.mean(np.abs(wrap_degrees(y_true - y_mean)) <= z * y_std))


def extra_scores(
    y_true_angles, y_pred_angles, *, source, skeleton, std=None, samples=None, weights=None
):
    """Joint-position errors and proper scores of one test set, for its result row.

    ``y_true_angles``, ``y_pred_angles`` (n, 57): true and predicted pose angles (degrees, the original pose
    space); ``source``: what is scored (e.g. the data source or the method), named in errors; ``skeleton``: its
    :class:`bsrbench.kinematics.PoseSkeleton` (:func:`bsrbench.kinematics.hsc_pose_skeleton`, or
    :func:`bsrbench.kinematics.mocap_pose_skeleton` of the activity's first trial file), or None for angles of
    no known skeleton (then MPJPE and PA-MPJPE are None); ``std`` (n, 57): the
    predictive std in the same space, if the method gives one; ``samples`` (n, S, 57): posterior predictive draws
    of an observed angle in the same space, noise included (:func:`bsrbench.scores.predictive_draws`), if it
    gives them, with their ``weights`` (n, S) (None: equal); draws take precedence over ``std`` (see
    :mod:`bsrbench.scores`).

    Returns ``{"mpjpe_mm", "pa_mpjpe_mm", "nlpd", "crps", "scores_from"}``: NLPD, CRPS and ``scores_from``
    (``"gaussian"`` or ``"samples"``) are None for a method with neither ``std`` nor ``samples``. Non-finite
    predictions, std or draws raise InputError naming the source and the first bad entry.
    """
    from . import kinematics, scores

    if skeleton is None:
        out = {"mpjpe_mm": None, "pa_mpjpe_mm": None}
        out.update(
            scores.proper_scores(
                y_true_angles, y_pred_angles, std=std, samples=samples, weights=weights, what=source
            )
        )
        return out
    what = f"{source} ({skeleton.source})"
    for name, a in (("y_true", y_true_angles), ("y_pred", y_pred_angles)):
        scores.check_finite(np.asarray(a, dtype=float), name, what)
    y_true, y_pred = _check_pair(y_true_angles, y_pred_angles)
    if y_true.shape[1] != skeleton.n_angles:
        raise InputError(
            f"{what}: rows of {y_true.shape[1]} angles; the skeleton expects {skeleton.n_angles}"
        )
    out = {
        "mpjpe_mm": kinematics.mpjpe(y_true, y_pred, skeleton),
        "pa_mpjpe_mm": kinematics.pa_mpjpe(y_true, y_pred, skeleton),
    }
    out.update(
        scores.proper_scores(y_true, y_pred, std=std, samples=samples, weights=weights, what=what)
    )
    return out
