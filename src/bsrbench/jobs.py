"""Bodies of the study's per-split Snakemake jobs (rules ``fit`` and ``cv``), as functions of plain values.

A job is a dict with the Snakemake job's ``input``, ``output``, ``params`` and ``wildcards`` (dicts of strings, lists
and plain values), ``log`` (list of paths) and ``threads``. The rules' shell commands build it
(:func:`bsrbench.jobserver.job_params`, :func:`bsrbench.jobserver.job_settings`) and hand it to
:func:`bsrbench.jobserver.run`, which runs it in this process or in a fork of a warm job server; the result is the same
either way. Heavy imports (scikit-learn, numba) happen inside the functions.
"""

import sys
from types import SimpleNamespace


def __getattr__(name):
    """``PRELOAD``: the modules a job server imports once before forking the jobs, running their ``warm_up()`` if
    they have one (:mod:`bsrbench.jobserver`), derived from the package's import graph when asked for, since reading
    it takes a while: the job logic and the model modules (:func:`bsrbench.methods.job_preload`), after every module
    of another package that they import, at module level or inside a function
    (:func:`bsrbench.sources.external_imports`). A job then imports nothing itself: e.g. scoringrules compiles its
    numba functions when imported (seconds), ArviZ its ufuncs (which a fork could not keep)."""
    if name == "PRELOAD":
        from .methods import job_preload
        from .sources import external_imports

        own = job_preload()
        return (*external_imports(own), *own)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _ns(d):
    return SimpleNamespace(**d)


def _params(inp, p):
    """The job's estimator parameters and CV seconds: the CV's choice if the job reads one, else the fixed ones."""
    from .io import read_json

    if inp.get("cv"):
        cv = read_json(inp["cv"])
        return cv["best_params"], cv["cv_seconds"]
    return dict(p.fixed), None


def fit(job):
    """Rule fit: one (protocol, source, activity, method, n_train, seed): fit, predict, score, result row."""
    from .io import load_features, write_arrays, write_json
    from .runs import run_job
    from .splits import JobSpec

    w, p, inp, out = _ns(job["wildcards"]), _ns(job["params"]), job["input"], job["output"]
    spec = JobSpec.from_wildcards(w, p)
    params, cv_seconds = _params(inp, p)
    row, arrays = run_job(
        spec,
        load_features(inp["features"]),
        estimator=p.estimator,
        params=params,
        cv_mode=p.cv_mode,
        cv_seconds=cv_seconds,
        conformal=getattr(p, "conformal", None),
    )
    write_arrays(out["predictions"], arrays)
    write_json(out["row"], row)
    print(f"{spec}: error {row['error']:.3f} deg, fit {row['fit_seconds']:.2f} s", file=sys.stderr)


def cv(job):
    """Rule cv: K-fold grid search on the training frames of one split."""
    from .io import load_features, write_json
    from .runs import cross_validate
    from .splits import JobSpec

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
    print(
        f"{spec}: chose {result['best_params']} (CV error {result['best_score']})", file=sys.stderr
    )


def fit_chain(job):
    """Rule fit_chain: one MCMC chain (wildcard ``chain``) of one split; writes the chain file."""
    from .io import load_features, write_arrays
    from .runs import run_chain
    from .splits import JobSpec

    w, p, inp = _ns(job["wildcards"]), _ns(job["params"]), job["input"]
    spec = JobSpec.from_wildcards(w, p)
    params, _ = _params(inp, p)
    arrays = run_chain(
        spec,
        load_features(inp["features"]),
        estimator=p.estimator,
        params=params,
        chain=int(w.chain),
        conformal=getattr(p, "conformal", None),
    )
    write_arrays(job["output"]["chain"], arrays)
    print(
        f"{spec}: chain {w.chain} (seed {int(arrays['seed'])}), fit {float(arrays['fit_seconds']):.2f} s",
        file=sys.stderr,
    )


def pool(job):
    """Rule pool_chains: the result row and predictions of a split from its chain files."""
    from .io import load_features, read_npz, write_arrays, write_json
    from .runs import pool_chains
    from .splits import JobSpec

    w, p, inp, out = _ns(job["wildcards"]), _ns(job["params"]), job["input"], job["output"]
    spec = JobSpec.from_wildcards(w, p)
    params, cv_seconds = _params(inp, p)
    chains = [read_npz(path) for path in inp["chains"]]
    row, arrays = pool_chains(
        spec,
        load_features(inp["features"]),
        chains,
        estimator=p.estimator,
        params=params,
        cv_mode=p.cv_mode,
        cv_seconds=cv_seconds,
    )
    write_arrays(out["predictions"], arrays)
    write_json(out["row"], row)
    print(
        f"{spec}: {len(chains)} chains, error {row['error']:.3f} deg, R-hat(log-lik) "
        f"{row.get('r_hat_log_likelihood')}",
        file=sys.stderr,
    )
