"""One job of the benchmark study: split, pose transform, (tune,) fit, predict, score, result row.

The paper's protocol ("A Bayesian Framework for Sparse Representation-Based 3D Human Pose Estimation",
Section "Experimental Results"): 600 frames per activity, N in {30, 60, 100, 200} random frames for
training and the rest for testing, error = mean over the 57 angles of the per-angle RMS (degrees),
mean +- std over 10 random splits. A second protocol, ``"contiguous"``, trains on one contiguous block of
frames and tests on the frames farther than ``gap`` frames from it, so that no test frame has a
near-duplicate neighbour in the training set (random frames of one sequence do). A third, ``"cross_trial"``,
needs features that keep the trial of each frame (motion capture: ``trial_index``): whole trials are held
out as test frames and the N training frames are drawn from the other trials.

Nothing here reads Snakemake objects or the configuration: the workflow scripts pass plain values.
Estimators are named by dotted path (``"bsrbench.models.bsr:BayesianSR"``) and imported only when used,
so a missing model module fails only the jobs that need it.
"""

import importlib
import inspect
import json
import math
import platform
import time
import zipfile
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

from .errors import DataFileError, InputError
from .io import atomic_path
from .metrics import interval_coverage, mean_angle_error, per_angle_rms
from .poses import HeadingTransform, get_pose_transform
from .seeds import method_seed, split_seed

PROTOCOLS = ("random", "contiguous", "cross_trial")
CV_MODES = ("per_size", "per_job", "none")
#: Nominal levels of the central predictive intervals whose empirical coverage every job records.
COVERAGE_LEVELS = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95)
_VERSION_PACKAGES = ("bsrbench", "numpy", "scipy", "scikit-learn", "numba")


# --------------------------------------------------------------------------------------------------- loading
def load_estimator_class(path):
    """Import ``"package.module:ClassName"`` and return the class; errors name the path."""
    if not isinstance(path, str) or path.count(":") != 1:
        raise InputError(f"estimator path must look like 'package.module:ClassName'; got {path!r}")
    module_name, class_name = path.split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise InputError(
            f"estimator {path!r}: cannot import module {module_name!r} ({exc})"
        ) from exc
    try:
        return getattr(module, class_name)
    except AttributeError:
        raise InputError(
            f"estimator {path!r}: module {module_name!r} has no attribute {class_name!r}"
        ) from None


def make_estimator(path, params, random_state=None):
    """Instantiate the estimator at ``path`` with ``params``; ``random_state`` is set if the class takes one."""
    cls = load_estimator_class(path)
    params = dict(params or {})
    accepted = set(inspect.signature(cls).parameters)
    unknown = sorted(set(params) - accepted)
    if unknown:
        raise InputError(
            f"estimator {path!r} has no parameter(s) {unknown}; it accepts {sorted(accepted)}"
        )
    if random_state is not None and "random_state" in accepted and "random_state" not in params:
        params["random_state"] = int(random_state)
    return cls(**params)


def estimator_parameters(path):
    """Names of the constructor parameters of the estimator at ``path``, or None if it takes ``**kwargs``.

    scikit-learn estimators (whose ``get_params`` reads the same signature) take exactly these keywords.
    Raises InputError (naming ``path``) if the class cannot be imported.
    """
    cls = load_estimator_class(path)
    sig = inspect.signature(cls)
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in sig.parameters.values()):
        return None
    return sorted(
        n for n, p in sig.parameters.items() if p.kind not in (inspect.Parameter.VAR_POSITIONAL,)
    )


def estimator_defaults(path):
    """``{parameter: default}`` of the estimator at ``path`` (``get_params()`` of a default instance)."""
    cls = load_estimator_class(path)
    try:
        return dict(cls().get_params(deep=False))
    except (TypeError, AttributeError):
        return {
            n: p.default
            for n, p in inspect.signature(cls).parameters.items()
            if p.default is not inspect.Parameter.empty
        }


def check_estimator_params(path, params, n_samples=None):
    """Build the estimator at ``path`` with ``params`` and run its own parameter validation, without data.

    The estimator's ``_check_params(n_samples=None)`` (the check its ``fit`` makes; bsrbench's estimators have
    one), else scikit-learn's ``_validate_params()`` (the ``_parameter_constraints`` of scikit-learn's own
    estimators); an estimator with neither is only built. ``n_samples``: the number of training rows it will be
    fitted on, for the checks that depend on it (e.g. ``n_neighbors <= N``); None skips those. Raises
    InputError with the estimator's message (naming the parameter, its value and what it expects).
    """
    try:
        est = make_estimator(path, params)
        check = getattr(est, "_check_params", None)
        if callable(check):
            if "n_samples" in inspect.signature(check).parameters:
                check(n_samples=n_samples)
            else:
                check()
        elif callable(getattr(est, "_validate_params", None)) and hasattr(
            est, "_parameter_constraints"
        ):
            est._validate_params()
    except InputError:
        raise
    except (
        ValueError,
        TypeError,
    ) as exc:  # scikit-learn's InvalidParameterError, or a constructor's own check
        raise InputError(str(exc).splitlines()[0] if str(exc) else repr(exc)) from None


def _grid_points(grid):
    """The points of a CV grid ({param: [values]}), in scikit-learn's ParameterGrid order; [{}] for no grid."""
    if not grid:
        return [{}]
    from sklearn.model_selection import ParameterGrid

    return list(ParameterGrid(grid))


def check_method_settings(methods, run, *, n_train=None, cv=None):
    """Check, before any job runs, that every method in ``run`` can be built and fitted as configured.

    ``methods``: the configuration's ``methods`` mapping ({name: {estimator, params, cv_params, grid, ...}});
    ``run``: the names of the methods to run. For each method run, its estimator class must import and every
    key of ``params``, ``cv_params`` and ``grid`` (the module's ``DEFAULT_GRID`` for ``grid: default``) must be
    a constructor parameter of it. Then the VALUES are checked by the estimator's own validation
    (:func:`check_estimator_params`): ``params`` alone; with ``n_train`` (the training-set sizes) and ``cv`` (the
    configuration's ``{"mode", "folds"}``), every setting a job will fit: ``params`` updated with each grid
    point (a CV choice) on the smallest N, and, when CV runs, ``params`` + ``cv_params`` + each grid point on the
    smallest training fold (KFold: N - ceil(N / folds) rows); ``cv.folds`` must not exceed the smallest N.
    Raises InputError naming the configuration key, the method, the value and what was expected.
    """
    for name in run:
        if name not in methods:
            raise InputError(
                f"config key 'run': unknown method {name!r}; defined under 'methods': {sorted(methods)}"
            )
        setting = methods[name] or {}
        path = setting.get("estimator")
        try:
            accepted = estimator_parameters(path)
        except InputError as exc:
            raise InputError(
                f"config key 'methods.{name}.estimator': {path!r} cannot be used ({exc}); expected "
                f"'package.module:ClassName' naming an importable estimator class"
            ) from None
        grid = setting.get("grid", "default")
        where_grid = f"methods.{name}.grid"
        if grid == "default":
            grid = default_grid(path)
            where_grid += f" (default: {load_estimator_class(path).__module__}.DEFAULT_GRID)"
        parts = [
            (f"methods.{name}.params", setting.get("params") or {}),
            (f"methods.{name}.cv_params", setting.get("cv_params") or {}),
            (where_grid, grid or {}),
        ]
        for key, values in parts:
            if not isinstance(values, dict):
                raise InputError(
                    f"config key '{key}': expected a mapping {{parameter: value}}; got {values!r}"
                )
            if accepted is None:
                continue
            for p, v in values.items():
                if p not in accepted:
                    raise InputError(
                        f"config key '{key}': {p}: {v!r} is not a parameter of {path}; "
                        f"expected one of {accepted}"
                    )
        for p, v in (grid or {}).items():
            if not isinstance(v, (list, tuple)) or not v:
                raise InputError(
                    f"config key '{where_grid}': {p}: {v!r}; expected a non-empty list of values"
                )
        _check_method_values(name, setting, path, grid or {}, where_grid, n_train=n_train, cv=cv)


def _check_method_values(name, setting, path, grid, where_grid, *, n_train, cv):
    """The value checks of :func:`check_method_settings` for one method (keys already known to be valid)."""
    params = dict(setting.get("params") or {})
    cv_params = dict(setting.get("cv_params") or {})
    cv_runs = bool(cv) and cv.get("mode", "none") != "none" and bool(grid)
    points = _grid_points(grid) if cv_runs else [{}]
    sizes = sorted({int(n) for n in n_train}) if n_train else []

    def fail(key, exc, what):
        raise InputError(f"config key '{key}' (method {name}, {path}): {what}: {exc}") from None

    def shown(d):
        return "{" + ", ".join(f"{k}: {v!r}" for k, v in d.items()) + "}"

    try:
        check_estimator_params(path, params)
    except InputError as exc:
        fail(f"methods.{name}.params", exc, f"params {shown(params)}")
    if cv_params and (cv is None or cv_runs):  # cv_params act in CV fits only
        try:
            check_estimator_params(path, {**params, **cv_params})
        except InputError as exc:
            fail(
                f"methods.{name}.cv_params",
                exc,
                f"cv_params {shown(cv_params)} over params {shown(params)}",
            )
    for point in points:
        if point:
            try:
                check_estimator_params(path, {**params, **point})
            except InputError as exc:
                fail(where_grid, exc, f"grid point {shown(point)} over params {shown(params)}")
    if not sizes:
        return
    n_min = sizes[0]
    for point in points:
        try:
            check_estimator_params(path, {**params, **point}, n_samples=n_min)
        except InputError as exc:
            key = where_grid if point else f"methods.{name}.params"
            what = (
                f"grid point {shown(point)} over params {shown(params)}"
                if point
                else f"params {shown(params)}"
            )
            fail(key, exc, f"{what}, fitted on the smallest n_train N = {n_min}")
    if not cv_runs:
        return
    folds = int(cv.get("folds", 5))
    if folds > n_min:
        raise InputError(
            f"config key 'cv.folds': {folds} folds of the smallest n_train N = {n_min} (method {name} is tuned by "
            f"CV, cv.mode {cv.get('mode')!r}) would leave empty folds; expected cv.folds <= {n_min}"
        )
    n_fold = n_min - math.ceil(n_min / folds)
    for point in points:
        try:
            check_estimator_params(path, {**params, **cv_params, **point}, n_samples=n_fold)
        except InputError as exc:
            key = f"methods.{name}.cv_params" if cv_params and not point else where_grid
            fail(
                key,
                exc,
                f"the CV fits of grid point {shown(point)} over params {shown({**params, **cv_params})} "
                f"on training folds of {n_fold} frames (N = {n_min}, cv.folds = {folds})",
            )


def load_features(path):
    """Read a features file (``X`` frames x features, ``Y`` frames x angles in degrees) and check it."""
    path = Path(path)
    if not path.is_file():
        raise DataFileError(path, "features file does not exist")
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise DataFileError(
            path,
            f"cannot read as .npz ({type(exc).__name__}: {exc}); delete it and rerun to rebuild it",
        ) from exc
    for key in ("X", "Y"):
        if key not in data:
            raise DataFileError(path, f"missing array {key!r}; it has {sorted(data)}")
    X = np.asarray(data["X"], dtype=float)
    Y = np.asarray(data["Y"], dtype=float)
    if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
        raise DataFileError(
            path, f"X and Y must be 2-D with the same number of rows; got {X.shape} and {Y.shape}"
        )
    for key, a in (("X", X), ("Y", Y)):
        if not np.all(np.isfinite(a)):
            row = int(np.argwhere(~np.isfinite(a))[0][0])
            raise DataFileError(path, f"{key} has a non-finite value in row {row}")
    out = {"X": X, "Y": Y}
    out["frames"] = np.asarray(data["frames"]) if "frames" in data else np.arange(X.shape[0])
    if "angle_names" in data:
        out["angle_names"] = [str(a) for a in data["angle_names"]]
    else:
        out["angle_names"] = [f"angle{i}" for i in range(Y.shape[1])]
    # Trial of each frame (motion-capture features of several trials; None for the .mat features).
    out["trials"] = np.asarray(data["trial_index"], dtype=int) if "trial_index" in data else None
    # Column of the root's heading angle (2 for the authors' features, 1 for the CMU BVH joint maps).
    out["heading_column"] = int(data["heading_column"]) if "heading_column" in data else 2
    return out


# ----------------------------------------------------------------------------------------------------- split
def make_split(n_frames, n_train, *, protocol="random", seed=0, min_test=100, gap=30, trials=None):
    """Indices ``(train, test)`` of one split, both sorted.

    ``random``: ``n_train`` frames drawn without replacement, the rest are test (the paper's protocol).
    ``contiguous``: the training frames are one block ``[s, s + n_train)`` with a random start ``s``;
    the test frames are those more than ``gap`` frames away from the block.
    ``cross_trial``: ``trials`` (the trial of each frame) is required; the trials are shuffled and held out
    in that order until at least ``min_test`` frames are test frames (all frames of those trials); the
    ``n_train`` training frames are drawn without replacement from the other trials' frames, so that no
    test frame has a training frame of its own trial.
    Raises InputError if fewer than ``min_test`` test frames remain (or, cross_trial, too few training frames).
    """
    n_frames, n_train, min_test, gap = int(n_frames), int(n_train), int(min_test), int(gap)
    if protocol not in PROTOCOLS:
        raise InputError(f"protocol must be one of {PROTOCOLS}; got {protocol!r}")
    if n_train < 2:
        raise InputError(f"n_train must be >= 2; got {n_train}")
    if gap < 0:
        raise InputError(f"gap must be >= 0; got {gap}")
    rng = np.random.default_rng(seed)
    if protocol == "cross_trial":
        return _cross_trial_split(n_frames, n_train, rng, min_test, trials)
    if protocol == "random":
        if n_frames - n_train < min_test:
            raise InputError(
                f"n_train={n_train} leaves {n_frames - n_train} test frames of {n_frames}; at least min_test={min_test} needed"
            )
        perm = rng.permutation(n_frames)
        return np.sort(perm[:n_train]), np.sort(perm[n_train:])
    # contiguous: choose among starts that leave enough test frames
    starts = np.arange(0, n_frames - n_train + 1)
    n_test = n_frames - (np.minimum(starts + n_train + gap, n_frames) - np.maximum(starts - gap, 0))
    ok = starts[n_test >= min_test]
    if ok.size == 0:
        raise InputError(
            f"contiguous protocol: n_train={n_train} with gap={gap} leaves fewer than min_test={min_test} "
            f"test frames of {n_frames} for every block position"
        )
    s = int(rng.choice(ok))
    train = np.arange(s, s + n_train)
    frames = np.arange(n_frames)
    test = frames[(frames < s - gap) | (frames >= s + n_train + gap)]
    return train, test


def _cross_trial_split(n_frames, n_train, rng, min_test, trials):
    if trials is None:
        raise InputError(
            "protocol 'cross_trial' needs the trial of each frame (array 'trial_index' of a motion-capture "
            "features file); these features have none (use protocol 'random' or 'contiguous')"
        )
    trials = np.asarray(trials)
    if trials.shape != (n_frames,):
        raise InputError(
            f"cross_trial: trial_index has shape {trials.shape}; expected ({n_frames},)"
        )
    ids = np.unique(trials)
    if ids.size < 2:
        raise InputError(f"cross_trial: the features hold {ids.size} trial; at least 2 are needed")
    held, n_test = [], 0
    for t in rng.permutation(ids):
        if n_test >= min_test:
            break
        held.append(t)
        n_test += int(np.sum(trials == t))
    test = np.flatnonzero(np.isin(trials, held))
    pool = np.flatnonzero(~np.isin(trials, held))
    if n_test < min_test or pool.size < n_train:
        raise InputError(
            f"cross_trial: holding out trials {sorted(int(t) for t in held)} gives {n_test} test frames "
            f"(min_test={min_test}) and leaves {pool.size} frames of {ids.size - len(held)} trials for "
            f"n_train={n_train}"
        )
    return np.sort(rng.choice(pool, size=n_train, replace=False)), test


def max_n_train(n_frames, *, protocol="random", min_test=100, gap=30):
    """Largest n_train that :func:`make_split` accepts (used to check configurations before running;
    for ``cross_trial`` an upper bound, since it depends on the trial lengths)."""
    if protocol == "contiguous":
        return int(n_frames - min_test - gap)  # block at one end, gap on one side
    return int(n_frames - min_test)


# ------------------------------------------------------------------------------------------- pose transform
def inverse_std(transform, Z_mean, Z_std):
    """Predictive std in the original angle space from the std in the transformed space.

    The heading angle ``atan2(s, c)`` gets the first-order (delta-method) std
    ``sqrt(c^2 sd_s^2 + s^2 sd_c^2) / (s^2 + c^2)`` in degrees; other columns are unchanged.
    """
    Z_mean = np.asarray(Z_mean, dtype=float)
    Z_std = np.asarray(Z_std, dtype=float)
    if not isinstance(transform, HeadingTransform):
        return Z_std
    s, c = Z_mean[:, -2], Z_mean[:, -1]
    ss, sc = Z_std[:, -2], Z_std[:, -1]
    r2 = np.maximum(s * s + c * c, 1e-12)
    sd_heading = np.rad2deg(np.sqrt(c * c * ss * ss + s * s * sc * sc) / r2)
    return np.insert(Z_std[:, :-2], transform.column, sd_heading, axis=1)


def _supports_std(estimator):
    try:
        return "return_std" in inspect.signature(estimator.predict).parameters
    except (TypeError, ValueError):
        return False


def _to_builtin(v):
    """JSON-friendly copy of numbers, arrays, dicts and lists."""
    if isinstance(v, dict):
        return {str(k): _to_builtin(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_to_builtin(x) for x in v]
    if isinstance(v, np.ndarray):
        return _to_builtin(v.tolist())
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def package_versions():
    """Versions of the packages that determine the numbers (and the Python version)."""
    out = {"python": platform.python_version()}
    for name in _VERSION_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


# ------------------------------------------------------------------------------------------------------ tune
@dataclass
class JobSpec:
    """What identifies one job of the study."""

    source: str
    activity: str
    method: str
    n_train: int
    seed: int
    protocol: str = "random"
    pose_transform: str = "heading"
    min_test: int = 100
    gap: int = 30
    paper_activity: str = ""

    @classmethod
    def from_wildcards(cls, wildcards, params):
        """The spec of a workflow job: identity from its wildcards, settings from its params
        (``pose_transform``, ``min_test``, ``gap`` and, if present, ``paper_activity``)."""
        return cls(
            source=wildcards.source,
            activity=wildcards.activity,
            method=wildcards.method,
            n_train=int(wildcards.n_train),
            seed=int(wildcards.seed),
            protocol=wildcards.protocol,
            pose_transform=params.pose_transform,
            min_test=int(params.min_test),
            gap=int(params.gap),
            paper_activity=getattr(params, "paper_activity", "") or "",
        )

    def split(self, n_frames, trials=None):
        """``(train, test)`` of this job's split (``trials``: the trial of each frame, for cross_trial)."""
        return make_split(
            n_frames,
            self.n_train,
            protocol=self.protocol,
            seed=split_seed(self.source, self.activity, self.n_train, self.seed),
            min_test=self.min_test,
            gap=self.gap,
            trials=trials,
        )

    @property
    def method_seed(self):
        return method_seed(self.source, self.activity, self.n_train, self.seed, self.method)


def cross_validate(spec, features, *, estimator, params, grid, folds=5, cv_params=None):
    """Choose hyper-parameters by ``folds``-fold CV on the training frames of ``spec``'s split.

    ``cv_params`` replace entries of ``params`` in the CV fits only (e.g. fewer MCMC sweeps); the
    returned ``best_params`` are ``params`` updated with the grid's choice.

    Delegates to :func:`bsrbench.tuning.tune` (the grid search shared by all methods) with the pose
    transform of the study. Returns a JSON-ready dict: best_params (merged over ``params``), best_score,
    the CV table, and the seconds it took.
    """
    from .tuning import tune  # imported here: only CV jobs need it

    X, Y = features["X"], features["Y"]
    train, _ = spec.split(X.shape[0], features.get("trials"))
    grid = {k: list(v) for k, v in (grid or {}).items()}
    est = make_estimator(
        estimator, {**(params or {}), **(cv_params or {})}, random_state=spec.method_seed
    )
    t0 = time.perf_counter()
    if grid:
        res = tune(
            est,
            grid,
            X[train],
            Y[train],
            cv=int(folds),
            random_state=spec.method_seed,
            pose_transform=get_pose_transform(
                spec.pose_transform, column=features.get("heading_column", 2)
            ),
        )
        best, score, n_fits = dict(res.best_params), res.best_score, res.n_fits
        table = res.cv_results.drop(columns=["params"], errors="ignore").to_dict(orient="records")
    else:
        best, score, table, n_fits = {}, None, [], 0
    seconds = time.perf_counter() - t0
    chosen = dict(params or {})
    chosen.update(best)
    return _to_builtin(
        {
            "source": spec.source,
            "activity": spec.activity,
            "method": spec.method,
            "n_train": spec.n_train,
            "cv_seed": spec.seed,
            "protocol": spec.protocol,
            "folds": int(folds),
            "grid": grid,
            "cv_params": dict(cv_params or {}),
            "best_params": chosen,
            "best_score": score,
            "cv_results": table,
            "n_fits": n_fits,
            "cv_seconds": seconds,
        }
    )


# ------------------------------------------------------------------------------------------------------- run
def trace_arrays(est):
    """``{"trace_<name>": array}`` of the numeric per-sweep traces a fitted estimator saved in ``trace_`` (a
    dict, e.g. :class:`bsrbench.models.bsr.BayesianSR`); empty for estimators without one."""
    trace = getattr(est, "trace_", None)
    if not isinstance(trace, dict):
        return {}
    out = {}
    for key, value in trace.items():
        a = np.asarray(value)
        if a.dtype.kind in "biuf":
            out[f"trace_{key}"] = a
    return out


def run_job(spec, features, *, estimator, params, cv_mode="none", cv_seconds=None):
    """Fit ``estimator`` (dotted path) with ``params`` on the training frames of ``spec``'s split.

    Returns ``(row, arrays)``: the tidy result row (JSON-ready dict) and the arrays to save
    (test indices, true and predicted angles, predictive std if any, and the sampler trace if any).
    """
    X, Y = features["X"], features["Y"]
    train, test = spec.split(X.shape[0], features.get("trials"))
    transform = get_pose_transform(spec.pose_transform, column=features.get("heading_column", 2))
    est = make_estimator(estimator, params, random_state=spec.method_seed)

    t0 = time.perf_counter()
    est.fit(X[train], transform.forward(Y[train]))
    fit_seconds = time.perf_counter() - t0

    with_std = _supports_std(est)
    t0 = time.perf_counter()
    if with_std:
        Z_mean, Z_std = est.predict(X[test], return_std=True)
    else:
        Z_mean, Z_std = est.predict(X[test]), None
    predict_seconds = time.perf_counter() - t0
    row, arrays = _score(
        spec,
        estimator=estimator,
        params=params,
        cv_mode=cv_mode,
        cv_seconds=cv_seconds,
        transform=transform,
        train=train,
        test=test,
        Y_true=Y[test],
        Z_mean=Z_mean,
        Z_std=Z_std,
        fit_seconds=fit_seconds,
        predict_seconds=predict_seconds,
    )
    arrays.update(trace_arrays(est))
    return row, arrays


def _score(
    spec,
    *,
    estimator,
    params,
    cv_mode,
    cv_seconds,
    transform,
    train,
    test,
    Y_true,
    Z_mean,
    Z_std,
    fit_seconds,
    predict_seconds,
):
    """The result row and arrays of a split from its predictions ``Z_mean`` (and ``Z_std``) in the
    transformed pose space."""
    Z_mean = np.asarray(Z_mean, dtype=float)
    if Z_mean.ndim != 2 or Z_mean.shape[0] != test.size:
        raise InputError(
            f"{spec.method}: predict returned shape {Z_mean.shape}; expected ({test.size}, n_outputs)"
        )
    Y_pred = transform.inverse(Z_mean)
    rms = per_angle_rms(Y_true, Y_pred)
    row = {
        "source": spec.source,
        "activity": spec.activity,
        "paper_activity": spec.paper_activity or "",
        "method": spec.method,
        "n_train": int(spec.n_train),
        "seed": int(spec.seed),
        "protocol": spec.protocol,
        "pose_transform": spec.pose_transform,
        "cv": cv_mode,
        "estimator": estimator,
        "params": _to_builtin(dict(params or {})),
        "n_test": int(test.size),
        "split_seed": split_seed(spec.source, spec.activity, spec.n_train, spec.seed),
        "method_seed": spec.method_seed,
        "error": mean_angle_error(Y_true, Y_pred),
        "per_angle_rms": rms.tolist(),
        "fit_seconds": fit_seconds,
        "predict_seconds": predict_seconds,
        "cv_seconds": cv_seconds,
        "versions": package_versions(),
    }
    arrays = {"train": train, "test": test, "y_true": Y_true, "y_pred": Y_pred}
    if Z_std is not None:
        Y_std = inverse_std(transform, Z_mean, np.asarray(Z_std, dtype=float))
        for level in COVERAGE_LEVELS:
            row[f"coverage_{int(round(level * 100))}"] = interval_coverage(
                Y_true, Y_pred, Y_std, level=level
            )
        row["coverage"] = row["coverage_90"]
        arrays["y_std"] = Y_std
    else:
        row["coverage"] = None
    return _to_builtin(row), arrays


# --------------------------------------------------------------------------------------------- MCMC chains
#: Per-sweep traces whose split R-hat and bulk ESS across chains go into the result row of a split
#: (those a method does not record are skipped), plus ``test_error``: the test error of each retained
#: posterior sample (from the estimator's ``predict_draws``, when it has one).
CONVERGENCE_TRACES = ("log_likelihood", "g_xy", "g_s", "g_nx", "g_ny")
CONVERGENCE_SERIES = CONVERGENCE_TRACES + ("test_error",)


def chain_seed(method_seed, chain):
    """Sampler seed of chain ``chain`` (0, 1, ...) of a split: ``(method_seed + chain) mod 2**32``.

    Chain 0 uses the method seed itself, so a one-chain run is the first chain of a several-chain run. The
    estimator turns this seed into its generators' seeds (BayesianSR: ``RandomState(seed)`` draws the seed of
    a PCG64 generator through NumPy's SeedSequence hashing), so neighbouring seeds give unrelated streams.
    """
    return (int(method_seed) + int(chain)) % 2**32


def run_chain(spec, features, *, estimator, params, chain):
    """One MCMC chain of ``spec``'s split: fit with :func:`chain_seed`, predict the test frames.

    Returns a dict of arrays (the chain file): ``train``, ``test``, ``z_mean`` and ``z_var`` (predictive mean
    and variance per test frame in the transformed pose space; ``z_var`` is absent if the estimator gives no
    std), ``trace_<name>`` (per-sweep traces), ``draw_error`` (test error in degrees of each retained
    posterior sample, when the estimator has ``predict_draws(X)`` returning ``(draws (T, L, outputs),
    weights)`` in the units of the fitted Y), ``chain``, ``seed``, ``n_burn_in``, ``fit_seconds``,
    ``predict_seconds``.
    """
    X, Y = features["X"], features["Y"]
    train, test = spec.split(X.shape[0], features.get("trials"))
    transform = get_pose_transform(spec.pose_transform, column=features.get("heading_column", 2))
    seed = chain_seed(spec.method_seed, chain)
    est = make_estimator(estimator, params, random_state=seed)
    t0 = time.perf_counter()
    est.fit(X[train], transform.forward(Y[train]))
    fit_seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = {"train": train, "test": test}
    if _supports_std(est):
        z_mean, z_std = est.predict(X[test], return_std=True)
        out["z_var"] = np.square(np.asarray(z_std, dtype=float))
    else:
        z_mean = est.predict(X[test])
    out["z_mean"] = np.asarray(z_mean, dtype=float)
    if hasattr(est, "predict_draws"):
        draws = np.asarray(est.predict_draws(X[test])[0], dtype=float)
        if draws.ndim != 3 or draws.shape[0] != test.size:
            raise InputError(
                f"{spec.method}: predict_draws returned draws of shape {draws.shape}; expected "
                f"({test.size}, n_samples, n_outputs)"
            )
        out["draw_error"] = np.array(
            [
                mean_angle_error(Y[test], transform.inverse(draws[:, i, :]))
                for i in range(draws.shape[1])
            ]
        )
    predict_seconds = time.perf_counter() - t0
    out.update(trace_arrays(est))
    out.update(
        chain=np.int64(chain),
        seed=np.int64(seed),
        n_burn_in=np.int64(getattr(est, "n_burn_in", 0) or 0),
        fit_seconds=np.float64(fit_seconds),
        predict_seconds=np.float64(predict_seconds),
    )
    return out


def convergence_summary(chains):
    """Split R-hat and bulk ESS (ArviZ, rank-normalized; Vehtari et al. 2021) across chains.

    ``chains``: chain dicts of :func:`run_chain`. The per-sweep traces of :data:`CONVERGENCE_TRACES` are used
    after each chain's burn-in; ``test_error`` is the series of per-retained-sample test errors
    (``draw_error``). Returns ``{"r_hat_<name>": float, "ess_bulk_<name>": float}`` for every series of
    :data:`CONVERGENCE_SERIES`, NaN where it was not recorded, with fewer than 2 chains, or with fewer than 4
    draws per chain.
    """
    from .models.diagnostics import chain_summary  # imported here: only pooling jobs need ArviZ

    out = {
        f"{stat}_{name}": math.nan for name in CONVERGENCE_SERIES for stat in ("r_hat", "ess_bulk")
    }
    if len(chains) < 2:
        return out
    burn_in = min(int(c.get("n_burn_in", 0)) for c in chains)
    series = {}
    for name in CONVERGENCE_TRACES:
        if all(f"trace_{name}" in c for c in chains):
            arrs = [np.asarray(c[f"trace_{name}"], dtype=float) for c in chains]
            if min(a.size for a in arrs) - burn_in >= 4:
                series[name] = [a[burn_in:] for a in arrs]
    if (
        all("draw_error" in c for c in chains)
        and min(np.size(c["draw_error"]) for c in chains) >= 4
    ):
        series["test_error"] = [np.asarray(c["draw_error"], dtype=float) for c in chains]
    for name, arrs in series.items():
        s = chain_summary([{name: a} for a in arrs], burn_in=0, names=(name,))
        out[f"r_hat_{name}"] = float(s.at[name, "r_hat"])
        out[f"ess_bulk_{name}"] = float(s.at[name, "ess_bulk"])
    return out


def pool_chains(spec, features, chains, *, estimator, params, cv_mode="none", cv_seconds=None):
    """The result of a split from its MCMC chains (dicts of :func:`run_chain`, same split, one per chain).

    The prediction is the posterior predictive mean over the retained samples of all chains, each chain
    weighted equally (every chain keeps the same number of samples); the predictive variance is the mixture's,
    ``mean_c(var_c + mean_c^2) - mean^2``. The row is :func:`run_job`'s plus ``n_chains``, ``chain_seeds`` and
    the :func:`convergence_summary`; ``fit_seconds`` and ``predict_seconds`` are summed over chains. The arrays
    are :func:`run_job`'s plus ``chain_trace_<name>`` (chains, sweeps) and ``chain_draw_error`` (chains, samples).
    """
    if not chains:
        raise InputError(f"{spec.method}: no chains to pool")
    X, Y = features["X"], features["Y"]
    train, test = spec.split(X.shape[0], features.get("trials"))
    for c in chains:
        if not (np.array_equal(c["train"], train) and np.array_equal(c["test"], test)):
            raise InputError(
                f"{spec}: chain {int(c['chain'])} was run on another split (stale chain file?)"
            )
    transform = get_pose_transform(spec.pose_transform, column=features.get("heading_column", 2))
    means = np.stack([np.asarray(c["z_mean"], dtype=float) for c in chains])
    z_mean = means.mean(axis=0)
    z_std = None
    if all("z_var" in c for c in chains):
        variances = np.stack([np.asarray(c["z_var"], dtype=float) for c in chains])
        second = np.mean(variances + means**2, axis=0)
        z_std = np.sqrt(np.maximum(second - z_mean**2, 0.0))
    row, arrays = _score(
        spec,
        estimator=estimator,
        params=params,
        cv_mode=cv_mode,
        cv_seconds=cv_seconds,
        transform=transform,
        train=train,
        test=test,
        Y_true=Y[test],
        Z_mean=z_mean,
        Z_std=z_std,
        fit_seconds=float(sum(float(c["fit_seconds"]) for c in chains)),
        predict_seconds=float(sum(float(c["predict_seconds"]) for c in chains)),
    )
    row["n_chains"] = len(chains)
    row["chain_seeds"] = [int(c["seed"]) for c in chains]
    row.update(_to_builtin(convergence_summary(chains)))
    names = sorted({k for c in chains for k in c if k.startswith("trace_")})
    for k in names:
        if all(k in c for c in chains):
            arrs = [np.asarray(c[k]) for c in chains]
            n = min(a.shape[0] for a in arrs)
            arrays[f"chain_{k}"] = np.stack([a[:n] for a in arrs])
    if all("draw_error" in c for c in chains):
        n = min(np.size(c["draw_error"]) for c in chains)
        arrays["chain_draw_error"] = np.stack(
            [np.asarray(c["draw_error"], dtype=float)[:n] for c in chains]
        )
    arrays["n_burn_in"] = np.int64(min(int(c.get("n_burn_in", 0)) for c in chains))
    return row, arrays


def write_json(path, obj):
    """Write ``obj`` as sorted, indented JSON, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(_to_builtin(obj), indent=1, sort_keys=True) + "\n")


def write_arrays(path, arrays):
    """Write arrays to ``path`` (.npz, compressed), atomically."""
    with atomic_path(path) as tmp:
        np.savez_compressed(tmp, **arrays)


def read_json(path):
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DataFileError(path, f"cannot read JSON ({exc})") from exc


def default_grid(path):
    """The hyper-parameter grid a model module publishes as ``DEFAULT_GRID`` for the class at ``path``.

    A module may publish one grid (``{param: [values]}``) or one per class (``{ClassName: {param: [values]}}``).
    Returns ``{}`` if the module publishes none.
    """
    cls = load_estimator_class(path)
    grid = getattr(importlib.import_module(cls.__module__), "DEFAULT_GRID", None) or {}
    if cls.__name__ in grid and isinstance(grid[cls.__name__], dict):
        grid = grid[cls.__name__]
    if not all(isinstance(v, (list, tuple)) for v in grid.values()):
        raise InputError(
            f"{cls.__module__}.DEFAULT_GRID for {cls.__name__} is not a {{param: [values]}} dict"
        )
    return {k: list(v) for k, v in grid.items()}
