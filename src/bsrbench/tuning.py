"""Cross-validated hyper-parameter selection scored with the paper's metric.

:func:`tune` runs a K-fold grid search with scikit-learn's machinery (``KFold(shuffle=True,
random_state=...)``, ``ParameterGrid``, ``clone``; folds run through ``joblib.Parallel``). It differs from
``GridSearchCV`` in two ways the study needs:

* the score is :func:`bsrbench.metrics.mean_angle_error` (lower is better) in the *original* pose space:
  with a ``pose_transform`` (an object with ``forward``/``inverse``, e.g.
  :class:`bsrbench.poses.HeadingTransform`) each fold fits on ``forward(Y_train)`` and scores
  ``inverse(prediction)`` against the untransformed ``Y_test``;
* parameters that only act at prediction time are evaluated from one fit: an estimator class may declare
  ``_predict_time_params`` (a tuple of parameter names) and accept them as keyword arguments of
  ``predict``; the grid over those names is then scored from ONE fit per fold per setting of the other
  parameters.
"""

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from joblib import Parallel, delayed
from sklearn.base import clone
from sklearn.model_selection import KFold, ParameterGrid

from .errors import InputError
from .metrics import mean_angle_error


@dataclass
class TuneResult:
    """Outcome of :func:`tune`.

    Attributes
    ----------
    best_params : dict
        The grid point with the lowest mean cross-validated error (first in grid order on ties).
    cv_results : pandas.DataFrame
        One row per grid point: ``param_<name>`` columns, ``params`` (dict), ``split<k>_error``,
        ``mean_error``, ``std_error`` (degrees), ``mean_fit_time``, ``mean_predict_time`` (seconds) and
        ``rank`` (1 = best).
    best_score : float
        Mean cross-validated error (degrees) of ``best_params``.
    n_fits : int
        Number of ``fit`` calls made (lower than folds x grid points when predict-time parameters are shared).
    """

    best_params: dict
    cv_results: pd.DataFrame
    best_score: float
    n_fits: int = field(default=0)


def _normalise_grid(estimator, param_grid):
    if isinstance(param_grid, dict):
        grids = [param_grid]
    elif isinstance(param_grid, (list, tuple)):
        grids = list(param_grid)
    else:
        raise InputError(
            f"param_grid must be a dict or a list of dicts; got {type(param_grid).__name__}"
        )
    if not grids or all(isinstance(g, dict) and not g for g in grids):
        raise InputError("param_grid is empty: give at least one parameter with at least one value")
    valid = set(estimator.get_params(deep=True))
    out = []
    for g in grids:
        if not isinstance(g, dict):
            raise InputError(f"param_grid entries must be dicts; got {type(g).__name__}")
        gg = {}
        for name, values in g.items():
            if name not in valid:
                raise InputError(
                    f"param_grid has unknown parameter {name!r} for {type(estimator).__name__}; "
                    f"valid parameters: {sorted(valid)}"
                )
            if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
                raise InputError(f"param_grid[{name!r}] must be a list of values; got {values!r}")
            values = list(values)
            if not values:
                raise InputError(f"param_grid[{name!r}] is an empty list: give at least one value")
            gg[name] = values
        out.append(gg)
    return out


def _fit_and_score(
    estimator, fit_params, predict_settings, X, Y, Yfit, train, test, pose_transform
):
    """Fit once with ``fit_params``; score each predict-time setting. Returns (fit_time, [(err, t_pred)])."""
    # the fitted instance carries the first predict-time setting, so fit validates a value from the grid
    est = clone(estimator).set_params(**fit_params, **predict_settings[0])
    t0 = time.perf_counter()
    est.fit(X[train], Yfit[train])
    fit_time = time.perf_counter() - t0
    scores = []
    for pp in predict_settings:
        t0 = time.perf_counter()
        P = est.predict(X[test], **pp)
        t_pred = time.perf_counter() - t0
        P = np.asarray(P, dtype=float)
        if P.ndim == 1:
            P = P[:, None]
        if pose_transform is not None:
            P = pose_transform.inverse(P)
        Yt = Y[test]
        if Yt.ndim == 1:
            Yt = Yt[:, None]
        scores.append((mean_angle_error(Yt, P), t_pred))
    return fit_time, scores


def tune(estimator, param_grid, X, Y, *, cv=5, random_state=0, pose_transform=None, n_jobs=1):
    """Grid search by K-fold cross-validation, scored by the paper's mean angle error (degrees).

    Parameters
    ----------
    estimator : scikit-learn style regressor
        Cloned for each fit; its other parameters are kept.
    param_grid : dict or list of dicts
        ``{name: [values, ...]}`` as for ``sklearn.model_selection.ParameterGrid``.
    X : array (n, n_features); Y : array (n, n_angles)
        Training features and poses in degrees (original pose space).
    cv : int >= 2
        Number of folds (``KFold(cv, shuffle=True, random_state=random_state)``).
    random_state : int
        Seed of the fold assignment.
    pose_transform : object with ``forward(Y)`` and ``inverse(Z)``, optional
        Fit on ``forward(Y)``; score ``inverse(prediction)`` against ``Y``.
    n_jobs : int
        Parallel jobs over (fold, fit setting) pairs (``joblib``).

    Returns
    -------
    TuneResult
    """
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    if X.ndim != 2 or Y.ndim not in (1, 2):
        raise InputError(f"X must be 2-D and Y 1-D or 2-D; got X {X.shape}, Y {Y.shape}")
    if X.shape[0] != Y.shape[0]:
        raise InputError(
            f"X and Y must have the same number of rows; got {X.shape[0]} and {Y.shape[0]}"
        )
    if isinstance(cv, bool) or not isinstance(cv, (int, np.integer)) or cv < 2:
        raise InputError(f"cv must be an integer >= 2 (number of folds); got {cv!r}")
    n = X.shape[0]
    if n < cv:
        raise InputError(f"cv={cv} folds need at least {cv} rows; X has {n} rows")
    grids = _normalise_grid(estimator, param_grid)

    Yfit = pose_transform.forward(Y) if pose_transform is not None else Y
    pt_names = set(getattr(type(estimator), "_predict_time_params", ()))

    # group grid points: one fit per (fit-time setting), all its predict-time settings scored from it
    points = []  # list of full param dicts in grid order
    groups = {}  # key(fit params) -> (fit_params, [index into points])
    for g in grids:
        for p in ParameterGrid(g):
            i = len(points)
            points.append(p)
            fp = {k: v for k, v in p.items() if k not in pt_names}
            key = repr(sorted(fp.items()))
            groups.setdefault(key, (fp, []))[1].append(i)

    splits = list(KFold(n_splits=cv, shuffle=True, random_state=random_state).split(X))
    tasks = []
    for fp, idx in groups.values():
        psettings = [{k: v for k, v in points[i].items() if k in pt_names} for i in idx]
        for f, (tr, te) in enumerate(splits):
            tasks.append((idx, f, fp, psettings, tr, te))
    out = Parallel(n_jobs=n_jobs)(
        delayed(_fit_and_score)(estimator, fp, ps, X, Y, Yfit, tr, te, pose_transform)
        for (idx, f, fp, ps, tr, te) in tasks
    )

    err = np.full((len(points), cv), np.nan)
    fit_t = np.zeros((len(points), cv))
    pred_t = np.zeros((len(points), cv))
    for (idx, f, *_), (ft, scores) in zip(tasks, out):
        for i, (e, tp) in zip(idx, scores):
            err[i, f] = e
            fit_t[i, f] = ft
            pred_t[i, f] = tp

    rows = []
    names = sorted({k for p in points for k in p})
    for i, p in enumerate(points):
        row = {f"param_{k}": p.get(k, None) for k in names}
        row["params"] = p
        for f in range(cv):
            row[f"split{f}_error"] = err[i, f]
        row["mean_error"] = float(err[i].mean())
        row["std_error"] = float(err[i].std())
        row["mean_fit_time"] = float(fit_t[i].mean())
        row["mean_predict_time"] = float(pred_t[i].mean())
        rows.append(row)
    df = pd.DataFrame(rows)
    df["rank"] = df["mean_error"].rank(method="min").astype(int)
    best = int(np.argmin(df["mean_error"].to_numpy()))
    return TuneResult(
        best_params=dict(points[best]),
        cv_results=df,
        best_score=float(df["mean_error"].iloc[best]),
        n_fits=len(tasks),
    )
