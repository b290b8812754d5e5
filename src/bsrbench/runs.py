"""The jobs of one split: CV, fit, MCMC chains and their pooling, scored into a result row.

The paper's protocol ("A Bayesian Framework for Sparse Representation-Based 3D Human Pose Estimation",
Section "Experimental Results"): error = mean over the 57 angles of the per-angle RMS (degrees), mean +- std
over 10 random splits. Nothing here reads Snakemake objects or the configuration: the jobs pass plain values.
"""

import functools
import platform
import time
from dataclasses import dataclass
from importlib import metadata

import numpy as np

from . import kinematics, scores
from .convergence import convergence_summary
from .errors import InputError
from .estimators import make_estimator, supports_std
from .io import to_builtin
from .metrics import check_pair, interval_coverage, mean_angle_error, per_angle_rms
from .poses import HeadingTransform, get_pose_transform
from .results import row_key, row_provenance
from .seeds import split_seed

#: Nominal levels of the central predictive intervals whose empirical coverage every job records.
COVERAGE_LEVELS = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95)
_VERSION_PACKAGES = ("bsrbench", "numpy", "scipy", "scikit-learn", "numba")
#: Posterior predictive draws per chain that a chain file keeps for the sample scores of its pooled split
#: (evenly spaced over the chain's retained samples; float32).
SCORE_DRAWS_PER_CHAIN = 25


@dataclass(frozen=True)
class Split:
    """A job's data on its split: features ``X``, angles ``Y``, ``train``/``test`` indices, pose transform and
    the :class:`bsrbench.kinematics.PoseSkeleton` that turns angles into joint positions."""

    X: np.ndarray
    Y: np.ndarray
    train: np.ndarray
    test: np.ndarray
    transform: object
    skeleton: object

    def fit(self, estimator, params, random_state):
        """The estimator at ``estimator`` with ``params``, fitted on the training frames; and the seconds."""
        est = make_estimator(estimator, params, random_state=random_state)
        t0 = time.perf_counter()
        est.fit(self.X[self.train], self.transform.forward(self.Y[self.train]))
        return est, time.perf_counter() - t0


def prepare_split(spec, features):
    """The :class:`Split` of ``spec`` on ``features`` (a :func:`bsrbench.io.load_features` dict)."""
    X, Y = features["X"], features["Y"]
    train, test = spec.split(X.shape[0], features.get("trials"))
    transform = get_pose_transform(spec.pose_transform, column=features.get("heading_column", 2))
    return Split(X, Y, train, test, transform, _skeleton(spec, features))


def _skeleton(spec, features):
    """The pose skeleton of a data set's features; None for bare arrays that name no data source (e.g. the
    tests' synthetic features), which then get no joint-position errors."""
    from .kinematics import features_pose_skeleton

    if "source" not in features.get("meta", {}):
        return None
    records = {**features.get("meta", {}), "Y": features["Y"]}
    if "angle_names" in features:
        records["angle_names"] = features["angle_names"]
    return features_pose_skeleton(records, f"{spec.source}/{spec.activity}")


def angle_draws(transform, draws):
    """Draws (n, S, outputs) in the transformed pose space mapped back to angles (n, S, 57)."""
    n, S, d = draws.shape
    return transform.inverse(draws.reshape(n * S, d)).reshape(n, S, -1)


def _scored_draws(spec, split, est, X_test, draws=None):
    """PM's posterior predictive draws of the test angles and their weights, or ``(None, None)``; ``draws``:
    ``est.predict_draws(X_test)`` if already computed."""
    if not hasattr(est, "predict_draws"):
        return None, None
    from .scores import predictive_draws

    draws, weights = predictive_draws(est, X_test, seed=spec.method_seed, draws=draws)
    if draws.shape[1] < 2:
        # one retained sample: its predictive distribution is the Gaussian of predict(X, return_std=True)
        return None, None
    return angle_draws(split.transform, draws), weights


def _predict_test(est, X_test):
    """``(mean, std or None, (draws, weights) or None)`` of the test frames: from one pass of the sampler for an
    estimator with ``predict_with_draws`` (PM: its draws are what the mean and std average), else from
    ``predict`` (with ``return_std`` where supported)."""
    if hasattr(est, "predict_with_draws"):
        mean, std, draws, weights = est.predict_with_draws(X_test)
        return mean, std, (draws, weights)
    if supports_std(est):
        mean, std = est.predict(X_test, return_std=True)
        return mean, std, None
    return est.predict(X_test), None, None


def _train_error(split, z_train):
    """The paper's error on the training frames from their predictions in the transformed space."""
    return mean_angle_error(split.Y[split.train], split.transform.inverse(z_train))


def split_conformal_interval(spec, split, est, settings):
    """Split-conformal radius and test coverage for a method with a predictive std, else None. ``settings``:
    ``{"level", "params"}`` (None: none): the level, and the parameters that replace ``est``'s in the refit on
    part of the training frames (e.g. fewer MCMC sweeps; the coverage guarantee holds for any point predictor)."""
    if settings is None or not supports_std(est):
        return None
    level = float(settings["level"])
    from .scores import split_conformal

    out = split_conformal(
        est,
        split.X[split.train],
        split.Y[split.train],
        split.X[split.test],
        split.Y[split.test],
        transform=split.transform,
        level=level,
        seed=spec.method_seed,
        params=settings.get("params") or {},
    )
    return {**out, "level": level}


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


@functools.cache
def _versions():
    out = {"python": platform.python_version()}
    for name in _VERSION_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def package_versions():
    """Versions of the packages that determine the numbers (and the Python version); read once per process,
    since reading a package's metadata costs milliseconds."""
    return dict(_versions())


def warm_up():
    """Read the package versions once, e.g. in a job server before it forks the jobs."""
    _versions()


def cross_validate(spec, features, *, estimator, params, grid, folds=5, cv_params=None):
    """Choose hyper-parameters by ``folds``-fold CV on the training frames of ``spec``'s split.

    ``cv_params`` replace entries of ``params`` in the CV fits only (e.g. fewer MCMC sweeps); the
    returned ``best_params`` are ``params`` updated with the grid's choice.

    Delegates to :func:`bsrbench.tuning.tune` (the grid search shared by all methods) with the pose
    transform of the study. Returns a JSON-ready dict: best_params (merged over ``params``), best_score,
    the CV table, and the seconds it took.
    """
    from .tuning import tune  # imported here: only CV jobs need it

    split = prepare_split(spec, features)
    X, Y, train = split.X, split.Y, split.train
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
            pose_transform=split.transform,
        )
        best, score, n_fits = dict(res.best_params), res.best_score, res.n_fits
        table = res.cv_results.drop(columns=["params"], errors="ignore").to_dict(orient="records")
    else:
        best, score, table, n_fits = {}, None, [], 0
    seconds = time.perf_counter() - t0
    chosen = dict(params or {})
    chosen.update(best)
    return to_builtin(
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


def run_job(spec, features, *, estimator, params, cv_mode="none", cv_seconds=None, conformal=None):
    """Fit ``estimator`` (dotted path) with ``params`` on the training frames of ``spec``'s split.

    Returns ``(row, arrays)``: the tidy result row (JSON-ready dict) and the arrays to save
    (test indices, true and predicted angles, predictive std if any, PIT values if scored, and the sampler
    trace if any). ``conformal``: ``{"level", "params"}`` of the split-conformal reference interval of a
    method with a predictive std (:func:`split_conformal_interval`; None: none).
    """
    split = prepare_split(spec, features)
    est, fit_seconds = split.fit(estimator, params, spec.method_seed)
    X_test = split.X[split.test]
    t0 = time.perf_counter()
    Z_mean, Z_std, noise_free = _predict_test(est, X_test)
    predict_seconds = time.perf_counter() - t0
    samples, weights = _scored_draws(spec, split, est, X_test, draws=noise_free)
    row, arrays = _score(
        spec,
        split,
        estimator=estimator,
        params=params,
        cv_mode=cv_mode,
        cv_seconds=cv_seconds,
        Z_mean=Z_mean,
        Z_std=Z_std,
        fit_seconds=fit_seconds,
        predict_seconds=predict_seconds,
        samples=samples,
        weights=weights,
        train_error=_train_error(split, est.predict(split.X[split.train])),
        conformal=split_conformal_interval(spec, split, est, conformal),
    )
    arrays.update(trace_arrays(est))
    return row, arrays


def _score(
    spec,
    split,
    *,
    estimator,
    params,
    cv_mode,
    cv_seconds,
    Z_mean,
    Z_std,
    fit_seconds,
    predict_seconds,
    samples=None,
    weights=None,
    train_error=None,
    conformal=None,
):
    """The result row and arrays of a split from its predictions ``Z_mean`` (and ``Z_std``) in the
    transformed pose space; ``samples`` (n, S, 57) and ``weights`` (n, S): posterior predictive draws of the
    test angles, scored in place of the Gaussian (:func:`extra_scores`)."""
    test, transform = split.test, split.transform
    Y_true = split.Y[test]
    Z_mean = np.asarray(Z_mean, dtype=float)
    if Z_mean.ndim != 2 or Z_mean.shape[0] != test.size:
        raise InputError(
            f"{spec.method}: predict returned shape {Z_mean.shape}; expected ({test.size}, n_outputs)"
        )
    Y_pred = transform.inverse(Z_mean)
    rms = per_angle_rms(Y_true, Y_pred)
    row = {
        **row_key(spec),
        "cv": cv_mode,
        "estimator": estimator,
        "params": to_builtin(dict(params or {})),
        "n_test": int(test.size),
        "split_seed": split_seed(spec.source, spec.activity, spec.n_train, spec.seed),
        "method_seed": spec.method_seed,
        "error": mean_angle_error(Y_true, Y_pred),
        "error_unwrapped": mean_angle_error(Y_true, Y_pred, wrap=False),
        "train_error": train_error,
        "per_angle_rms": rms.tolist(),
        "fit_seconds": fit_seconds,
        "predict_seconds": predict_seconds,
        "cv_seconds": cv_seconds,
        "versions": package_versions(),
        # what made the row: its method's code fingerprint, the commit, the time (the staleness check's input)
        **row_provenance(estimator),
    }
    arrays = {"train": split.train, "test": test, "y_true": Y_true, "y_pred": Y_pred}
    if Z_std is not None:
        Y_std = inverse_std(transform, Z_mean, np.asarray(Z_std, dtype=float))
        for level in COVERAGE_LEVELS:
            row[f"coverage_{int(round(level * 100))}"] = interval_coverage(
                Y_true, Y_pred, Y_std, level=level
            )
        row["coverage"] = row["coverage_90"]
        arrays["y_std"] = Y_std
    else:
        Y_std = None
        row["coverage"] = None
    row.update(
        extra_scores(
            Y_true,
            Y_pred,
            source=spec.method,
            skeleton=split.skeleton,
            std=Y_std,
            samples=samples,
            weights=weights,
        )
    )
    if row["scores_from"] is not None:
        from .scores import gaussian_pit, sample_pit

        pit = (
            sample_pit(Y_true, samples, weights)
            if samples is not None
            else gaussian_pit(Y_true, Y_pred, Y_std)
        )
        arrays["pit"] = np.asarray(pit, dtype=np.float32)
    if conformal is not None:
        row["conformal_level"] = conformal.get("level")
        row["conformal_coverage"] = conformal["conformal_coverage"]
        arrays["conformal_radius"] = np.asarray(conformal["conformal_radius"], dtype=float)
    else:
        row["conformal_level"] = row["conformal_coverage"] = None
    return to_builtin(row), arrays


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
    y_true, y_pred = check_pair(y_true_angles, y_pred_angles)
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


# --------------------------------------------------------------------------------------------- MCMC chains
def chain_seed(method_seed, chain):
    """Sampler seed of chain ``chain`` (0, 1, ...) of a split: ``(method_seed + chain) mod 2**32``.

    Chain 0 uses the method seed itself, so a one-chain run is the first chain of a several-chain run. The
    estimator turns this seed into its generators' seeds (BayesianSR: ``RandomState(seed)`` draws the seed of
    a PCG64 generator through NumPy's SeedSequence hashing), so neighbouring seeds give unrelated streams.
    """
    return (int(method_seed) + int(chain)) % 2**32


def run_chain(spec, features, *, estimator, params, chain, conformal=None):
    """One MCMC chain of ``spec``'s split: fit with :func:`chain_seed`, predict the test frames.

    Returns a dict of arrays (the chain file): ``train``, ``test``, ``z_mean`` and ``z_var`` (predictive mean
    and variance per test frame in the transformed pose space; ``z_var`` is absent if the estimator gives no
    std), ``z_train`` (prediction of the training frames), ``trace_<name>`` (per-sweep traces), and, when
    the estimator has ``predict_draws(X)`` returning ``(draws (T, L, outputs), weights)`` in the units of the
    fitted Y: ``draw_error`` (test error in degrees of each retained posterior sample) and
    ``score_draws`` / ``score_weights`` (:data:`SCORE_DRAWS_PER_CHAIN` posterior predictive draws of the test
    angles, noise included, and their weights renormalised; every draw where the weights are unequal). Chain 0 of a method with a predictive std also
    holds the split-conformal ``conformal_radius``, ``conformal_coverage`` and ``conformal_level`` when
    ``conformal`` is set. Then ``chain``, ``seed``, ``n_burn_in``, ``fit_seconds``,
    ``predict_seconds``.
    """
    split = prepare_split(spec, features)
    test, X_test = split.test, split.X[split.test]
    seed = chain_seed(spec.method_seed, chain)
    est, fit_seconds = split.fit(estimator, params, seed)
    t0 = time.perf_counter()
    out = {"train": split.train, "test": test}
    z_mean, z_std, noise_free = _predict_test(est, X_test)
    if z_std is not None:
        out["z_var"] = np.square(np.asarray(z_std, dtype=float))
    out["z_mean"] = np.asarray(z_mean, dtype=float)
    if hasattr(est, "predict_draws"):
        noise_free = est.predict_draws(X_test) if noise_free is None else noise_free
        draws = np.asarray(noise_free[0], dtype=float)
        if draws.ndim != 3 or draws.shape[0] != test.size:
            raise InputError(
                f"{spec.method}: predict_draws returned draws of shape {draws.shape}; expected "
                f"({test.size}, n_samples, n_outputs)"
            )
        out["draw_error"] = np.array(
            [
                mean_angle_error(split.Y[test], split.transform.inverse(draws[:, i, :]))
                for i in range(draws.shape[1])
            ]
        )
        samples, weights = _scored_draws(spec, split, est, X_test, draws=noise_free)
        if samples is not None:
            w = np.asarray(weights, dtype=float)
            keep = np.arange(samples.shape[1])
            if np.all(w == w[:, :1]):
                # equally weighted draws: an evenly spaced subset is a smaller sample of the same predictive.
                # Unequal (self-normalized likelihood) weights are all kept: a subset can hold none of the weight.
                keep = np.unique(
                    np.linspace(0, samples.shape[1] - 1, SCORE_DRAWS_PER_CHAIN).round().astype(int)
                )
            w = w[:, keep]
            out["score_draws"] = samples[:, keep, :].astype(np.float32)
            out["score_weights"] = w / w.sum(axis=1, keepdims=True)
    predict_seconds = time.perf_counter() - t0
    out["z_train"] = np.asarray(est.predict(split.X[split.train]), dtype=float)
    conformal = split_conformal_interval(spec, split, est, conformal) if int(chain) == 0 else None
    if conformal is not None:
        out["conformal_radius"] = np.asarray(conformal["conformal_radius"], dtype=float)
        out["conformal_coverage"] = np.float64(conformal["conformal_coverage"])
        out["conformal_level"] = np.float64(conformal["level"])
    out.update(trace_arrays(est))
    out.update(
        chain=np.int64(chain),
        seed=np.int64(seed),
        n_burn_in=np.int64(getattr(est, "n_burn_in", 0) or 0),
        fit_seconds=np.float64(fit_seconds),
        predict_seconds=np.float64(predict_seconds),
    )
    return out


def pool_chains(spec, features, chains, *, estimator, params, cv_mode="none", cv_seconds=None):
    """The result of a split from its MCMC chains (dicts of :func:`run_chain`, same split, one per chain).

    The prediction is the posterior predictive mean over the retained samples of all chains, each chain
    weighted equally (every chain keeps the same number of samples); the predictive variance is the mixture's,
    ``mean_c(var_c + mean_c^2) - mean^2``. The row is :func:`run_job`'s plus ``n_chains``, ``chain_seeds`` and
    the :func:`bsrbench.convergence.convergence_summary`; ``fit_seconds`` and ``predict_seconds`` are summed
    over chains. The arrays are :func:`run_job`'s plus ``chain_trace_<name>`` (chains, sweeps) and
    ``chain_draw_error`` (chains, samples). The proper scores come from the chains' ``score_draws``, each chain
    weighted equally, the training error from the mean of their ``z_train``, and the split-conformal interval
    from chain 0.
    """
    if not chains:
        raise InputError(f"{spec.method}: no chains to pool")
    split = prepare_split(spec, features)
    for c in chains:
        if not (np.array_equal(c["train"], split.train) and np.array_equal(c["test"], split.test)):
            raise InputError(
                f"{spec}: chain {int(c['chain'])} was run on another split (stale chain file?)"
            )
    means = np.stack([np.asarray(c["z_mean"], dtype=float) for c in chains])
    z_mean = means.mean(axis=0)
    z_std = None
    if all("z_var" in c for c in chains):
        variances = np.stack([np.asarray(c["z_var"], dtype=float) for c in chains])
        second = np.mean(variances + means**2, axis=0)
        z_std = np.sqrt(np.maximum(second - z_mean**2, 0.0))
    samples = weights = None
    if all("score_draws" in c for c in chains):
        samples = np.concatenate(
            [np.asarray(c["score_draws"], dtype=float) for c in chains], axis=1
        )
        weights = np.concatenate(
            [np.asarray(c["score_weights"], dtype=float) / len(chains) for c in chains], axis=1
        )
    train_error = None
    if all("z_train" in c for c in chains):
        z_train = np.mean([np.asarray(c["z_train"], dtype=float) for c in chains], axis=0)
        train_error = _train_error(split, z_train)
    first = next((c for c in chains if int(c["chain"]) == 0), None)
    conformal = None
    if first is not None and "conformal_radius" in first:
        conformal = {
            "conformal_radius": first["conformal_radius"],
            "conformal_coverage": float(first["conformal_coverage"]),
            "level": float(first["conformal_level"]),
        }
    row, arrays = _score(
        spec,
        split,
        estimator=estimator,
        params=params,
        cv_mode=cv_mode,
        cv_seconds=cv_seconds,
        Z_mean=z_mean,
        Z_std=z_std,
        fit_seconds=float(sum(float(c["fit_seconds"]) for c in chains)),
        predict_seconds=float(sum(float(c["predict_seconds"]) for c in chains)),
        samples=samples,
        weights=weights,
        train_error=train_error,
        conformal=conformal,
    )
    row["n_chains"] = len(chains)
    row["chain_seeds"] = [int(c["seed"]) for c in chains]
    row.update(to_builtin(convergence_summary(chains)))
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
