"""Bodies of the study's per-split Snakemake jobs (rules ``fit`` and ``cv``), as functions of plain values.

A job is a dict with the Snakemake job's ``input``, ``output``, ``params`` and ``wildcards`` (dicts of
strings, lists and plain values), ``log`` (list of paths) and ``threads``. The rule scripts build it and hand
it to :func:`bsrbench.jobserver.run`, which runs it in this process or in a fork of a warm job server; the
result is the same either way. Heavy imports (scikit-learn, numba) happen inside the functions.
"""

import sys
from types import SimpleNamespace


def _ns(d):
    return SimpleNamespace(**d)


def fit(job):
    """Rule fit: one (protocol, source, activity, method, n_train, seed): fit, predict, score, result row."""
    from .study import JobSpec, load_features, read_json, run_job, write_arrays, write_json

    w, p, inp, out = _ns(job["wildcards"]), _ns(job["params"]), job["input"], job["output"]
    spec = JobSpec.from_wildcards(w, p)
    params, cv_seconds = dict(p.fixed), None
    if inp.get("cv"):
        cv = read_json(inp["cv"])
        params, cv_seconds = cv["best_params"], cv["cv_seconds"]
    row, arrays = run_job(
        spec,
        load_features(inp["features"]),
        estimator=p.estimator,
        params=params,
        cv_mode=p.cv_mode,
        cv_seconds=cv_seconds,
    )
    write_arrays(out["predictions"], arrays)
    write_json(out["row"], row)
    print(f"{spec}: error {row['error']:.3f} deg, fit {row['fit_seconds']:.2f} s", file=sys.stderr)


def cv(job):
    """Rule cv: K-fold grid search on the training frames of one split."""
    from .study import JobSpec, cross_validate, load_features, write_json

    w, p, inp = _ns(job["wildcards"]), _ns(job["params"]), job["input"]
    spec = JobSpec.from_wildcards(w, p)
    result = cross_validate(
        spec,
        load_features(inp["features"]),
        estimator=p.estimator,
        params=p.fixed,
        cv_params=p.cv_params,
        grid=p.grid,
        folds=p.folds,
    )
    write_json(job["output"]["json"], result)
    print(f"{spec}: chose {result['best_params']} (CV error {result['best_score']})", file=sys.stderr)
