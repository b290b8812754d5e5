"""Whether a published table is still what today's code makes: the staleness check, rerunning rows, re-stamping and
merging a table regenerated in parts (``python -m bsrbench.reporting.published check|verify|restamp|merge``).

Every result row carries the fingerprint of the code its method runs (:func:`bsrbench.results.row_provenance`). A
published table ``reports/published/<study>.csv`` has a provenance file beside it,
``reports/published/<study>.provenance.json``::

    {"study": "paper",
     "methods": {"PM": {"code_fingerprint": "...", "files": {"bsrbench/runs.py": "<sha256>", ...},
                        "git_commit": "...", "date": "...", "restamped": {...}}, ...},
     "historical": "reason"}                      # optional: a table kept knowingly as it is

``configfiles`` (default ``["config/<study>.yaml"]``) are the configuration files the study was run with, read over
``config/config.yaml`` in order as ``--configfile`` reads them (e.g. ``config/ablation.yaml`` then
``config/paper-goal.yaml`` for an overlay study): they give the table's methods and their settings. ``files`` is
the method's per-file digest map when its rows were made (or re-stamped), so that the check can name
the file that changed. A table is *fresh* for a method when every row of the method has today's code fingerprint
and the package versions of today's environment; ``historical`` turns a stale table into a reported, non-failing
one (its README line says so). A provenance of another shape is refused, naming the key (:func:`check_provenance`);
``check`` and ``verify`` need one. ``merge`` takes only current parts (no ``historical`` mark, a
``code_fingerprint`` column) of one study (equal ``configfiles``), and writes nothing until all is read and checked.
"""

import contextlib
import json
import random
import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFileError, InputError
from ..io import atomic_path
from ..methods import repository_file, study_config, study_registry
from ..results import KEY_COLUMNS, code_digests, code_fingerprint, git_commit
from ..safeload import json_text, read_json_file

#: The tolerance of a rerun row against its published value (:mod:`.compare`, ``|a - b| <= atol + rtol |b|``):
#: every fit but the GP's is deterministic and reruns bit for bit; the GP's hyper-parameters come from L-BFGS-B,
#: whose stopping rule (relative objective change 2.2e-9, projected gradient 1e-5) lets another gradient code stop
#: at a slightly other optimum. 1e-4 relative (0.001 deg on a 10 deg error) admits that and nothing of the size
#: of a model change (the sampler change of the previous round moved a PM row by 2%).
ATOL, RTOL = 1e-6, 1e-4
#: The MCMC diagnostics of pooled chains (R-hat, ESS, Monte Carlo standard errors) are compared within
#: :data:`DIAGNOSTICS_RTOL`: they are rank statistics of the chains' draws (ArviZ's rank-normalised, folded split
#: R-hat), which jump when a last-bit difference of two draws reorders a tie (a PM row of ablation-crosstrial.csv
#: reran with every error, score and ESS equal to 1e-14 and R-hat of the test error 1.01400 against 1.01357).
DIAGNOSTICS = ("r_hat_", "ess_", "mcse_")
DIAGNOSTICS_RTOL = 1e-3
#: Package versions compared with today's (the bsrbench version is the code, which the fingerprint covers).
VERSION_KEYS = ("python", "numpy", "scipy", "scikit-learn", "numba")
#: Rows rerun per method by restamp (at least 3, the issue's minimum).
RESTAMP_ROWS = 3


def write_table(df, path, what, provenance=None):
    """Write ``df`` as CSV to ``path`` atomically, with ``provenance`` (a dict) as its provenance file when given:
    both are written to temporary files first and renamed only when both are complete, so that a failure leaves
    neither half-done. DataFileError naming ``path`` and ``what`` it is (e.g. "the merged table") if it cannot be
    written (checked before anything is written where it can be: a folder in the way)."""
    paths = [Path(path)] + ([provenance_path(path)] if provenance is not None else [])
    for p in paths:
        if p.is_dir():
            raise DataFileError(p, f"cannot write {what}: a folder of that name is in the way")
    try:
        with contextlib.ExitStack() as stack:
            # the provenance's context is entered last, so it is renamed first: the table, renamed last, is
            # only replaced when its provenance is in place
            tmp = stack.enter_context(atomic_path(path))
            df.to_csv(tmp, index=False)
            if provenance is not None:
                tmp_prov = stack.enter_context(atomic_path(provenance_path(path)))
                tmp_prov.write_text(_provenance_text(provenance), encoding="utf-8")
    except OSError as exc:
        raise DataFileError(path, f"cannot write {what} ({exc.strerror or exc})") from None


def provenance_path(table):
    """``<study>.provenance.json`` beside the table ``<study>.csv``."""
    table = Path(table)
    return table.with_name(table.name.removesuffix(".csv") + ".provenance.json")


def study_name(table):
    """The study of a published table: its file name without ``.csv`` (``paper.csv`` -> ``paper``)."""
    return Path(table).name.removesuffix(".csv")


def is_derived(table):
    """Whether a published CSV is derived from another one (comparisons, verdicts), not result rows."""
    return study_name(table).endswith(("-comparisons", "-verdict"))


def read_provenance(table, required=False):
    """The provenance of ``table`` (a dict; ``{}`` without a provenance file, unless ``required``). DataFileError
    naming the file when it is missing but ``required``, not a JSON object or not of the shape of the module
    docstring (:func:`check_provenance`)."""
    path = provenance_path(table)
    if not path.exists():
        if required:
            raise DataFileError(
                path,
                f"no such file; expected the provenance of {table} beside it (written by publish, merge or "
                "restamp): its study's configuration files and its methods' code",
            )
        return {}
    try:
        data = read_json_file(path)
    except InputError as exc:
        raise DataFileError(
            path,
            f"cannot read the provenance ({str(exc).removeprefix(f'{path}: ')}); expected a JSON object",
        ) from None
    return check_provenance(data, path)


def _shape_error(path, key, value, expected):
    text = repr(value)
    text = text if len(text) <= 60 else text[:57] + "..."
    return DataFileError(
        path, f"key {key!r} is {text} of type {type(value).__name__}; expected {expected}"
    )


def check_provenance(data, path):
    """``data`` (a provenance read from ``path``) if it has the shape of the module docstring; DataFileError naming
    ``path``, the key, the value's type and what was expected if not."""
    if not isinstance(data, dict):
        raise DataFileError(path, "expected a JSON object (study, methods, optionally historical)")
    for key in ("study", "historical"):
        if key in data and not isinstance(data[key], str):
            what = "the study's name" if key == "study" else "the reason the table is kept as it is"
            raise _shape_error(path, key, data[key], f"a string ({what})")
    files = data.get("configfiles")
    if "configfiles" in data and not (
        isinstance(files, list) and all(isinstance(f, str) for f in files)
    ):
        raise _shape_error(
            path,
            "configfiles",
            files,
            'a list of configuration files (e.g. ["config/ablation.yaml"])',
        )
    for f in files or []:
        try:
            repository_file(f)
        except InputError as exc:
            raise DataFileError(path, f"key 'configfiles': {exc}") from None
    methods = data.get("methods")
    if "methods" in data and not isinstance(methods, dict):
        raise _shape_error(
            path, "methods", methods, "a mapping of method name to its code's record"
        )
    for m, entry in (methods or {}).items():
        if not isinstance(entry, dict):
            raise _shape_error(
                path,
                f"methods.{m}",
                entry,
                "a mapping (code_fingerprint, files, git_commit, date, optionally restamped)",
            )
        for key in ("code_fingerprint", "git_commit", "date"):
            v = entry.get(key)
            if v is not None and not (
                isinstance(v, str) or (isinstance(v, list) and all(isinstance(x, str) for x in v))
            ):
                raise _shape_error(path, f"methods.{m}.{key}", v, "a string or a list of strings")
        for key in ("files", "restamped"):
            if entry.get(key) is not None and not isinstance(entry[key], dict):
                what = "{file: sha256}" if key == "files" else "the record of restamp"
                raise _shape_error(path, f"methods.{m}.{key}", entry[key], f"a mapping ({what})")
    return data


def _provenance_text(data):
    return json.dumps(data, indent=1, sort_keys=True) + "\n"


def write_provenance(table, data):
    with atomic_path(provenance_path(table)) as tmp:
        tmp.write_text(_provenance_text(data), encoding="utf-8")


def read_table(table):
    """The published table at ``table`` (every column as read). DataFileError naming it when missing, unreadable or
    without the key columns."""
    if not Path(table).is_file():
        what = "is not a file" if Path(table).exists() else "does not exist"
        raise DataFileError(table, f"{what}; expected a published table of result rows (CSV)")
    try:
        df = pd.read_csv(table)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        # the parser's message ends in a newline (e.g. a link to /etc/passwd): one line
        why = " ".join(str(exc).split())
        raise DataFileError(
            table, f"cannot read the published table ({why}); expected a CSV table of result rows"
        ) from None
    missing = [c for c in KEY_COLUMNS + ["error"] if c not in df.columns]
    if missing:
        raise DataFileError(table, f"missing columns {missing}; expected a table of result rows")
    return df


def _has_rows(table, df):
    """``df`` (the rows of the published table ``table``); DataFileError naming the table when it has a header but
    no rows: there is nothing to check or rerun, and a table emptied by mistake must not pass as fresh."""
    if not len(df):
        raise DataFileError(
            table,
            "has no rows (only a header); expected a published table of result rows",
        )
    return df


def today(registry):
    """{method: (code fingerprint, {file: sha256})} of today's code for the methods of ``registry``."""
    out = {}
    for name, m in registry.items():
        digests = code_digests(m.estimator, name)
        out[name] = (code_fingerprint(digests), digests)
    return out


def _versions_today():
    from ..runs import package_versions

    return package_versions()


def _version_changes(table, df):
    """Sentences naming the packages whose version in the rows differs from today's environment. InputError naming
    the line of a ``versions`` value that is not a JSON object of package versions."""
    now = _versions_today()
    seen = {}
    values = df["versions"] if "versions" in df.columns else {}
    first = {}
    for idx, v in values.items():
        if v is None or (isinstance(v, float) and np.isnan(v)) or v in first:
            continue
        first[v] = idx
    for v, idx in first.items():
        where = f"{_line(table, idx)}: column 'versions'"
        got = json_text(v, where) if isinstance(v, str) else None
        if not isinstance(got, dict) or not all(
            isinstance(x, (str, type(None))) for x in got.values()
        ):
            raise InputError(
                f"{where} is {str(v)[:60]!r}; expected a JSON object of package versions"
            )
        for k in VERSION_KEYS:
            if k in got and got[k] != now.get(k):
                seen.setdefault(k, set()).add(got[k])
    return [f"{k} {sorted(map(str, v))} -> {now.get(k)}" for k, v in sorted(seen.items())]


def changed_files(old, new):
    """The files that differ between two {file: sha256} maps: edited, added (+) or removed (-)."""
    out = [f for f in sorted(set(old) & set(new)) if old[f] != new[f]]
    out += [f"+{f}" for f in sorted(set(new) - set(old))]
    out += [f"-{f}" for f in sorted(set(old) - set(new))]
    return out


def check_table(table, *, digests=None):
    """The staleness check of one published table: ``(lines, stale)``, one line per method ("fresh", "stale: ...")
    or one line for the whole table (no fingerprints, historical); DataFileError naming an unreadable table. ``digests``: :func:`today`'s map if
    already computed."""
    name = str(table)
    # DataFileError naming the table: bad input, not a stale table
    df = _has_rows(table, read_table(table))
    prov = read_provenance(table, required=True)
    if prov.get("historical"):
        return [f"{name}: historical: {prov['historical']}"], False
    files = configfiles(table, prov)
    registry = study_registry(study_config(files), " + ".join(files))
    lines, stale = [], False
    _named_methods(name, df, registry, files)
    unknown = sorted(set(df["method"]) - set(registry))
    for m in unknown:
        lines.append(
            f"{name} {m}: unknown method (not run by {' + '.join(files)}); stale: cannot tell its code"
        )
        stale = True
    if "code_fingerprint" not in df.columns:
        lines.append(
            f"{name}: stale: no code fingerprints (made before the fingerprints of issue 36); rerun or restamp it"
        )
        return lines, True
    versions = _version_changes(name, df)
    now = digests if digests is not None else today(registry)
    for m in [m for m in registry if m in set(df["method"])]:
        rows = df[df["method"] == m]
        fps = set(rows["code_fingerprint"].dropna())
        n_old = int((rows["code_fingerprint"] != now[m][0]).sum())
        if not n_old and not versions:
            lines.append(f"{name} {m}: fresh")
            continue
        stale = True
        why = []
        if n_old:
            files = (prov.get("methods") or {}).get(m, {}).get("files")
            changed = changed_files(files, now[m][1]) if isinstance(files, dict) else None
            what = (
                f"changed: {', '.join(changed)}"
                if changed
                else "changed files unknown (no per-file digests in the provenance)"
            )
            why.append(
                f"{n_old} of {len(rows)} rows of other code ({len(fps)} fingerprint(s)); {what}"
            )
        if versions:
            why.append("package versions: " + "; ".join(versions))
        lines.append(f"{name} {m}: stale: " + "; ".join(why))
    return lines, stale


def published_tables(folder="reports/published"):
    """The published tables of result rows in ``folder`` and its ``parts/`` (parts of a study regenerated one at a
    time, before they are merged; the derived tables left out), sorted."""
    tables = [*Path(folder).glob("*.csv"), *Path(folder).glob("parts/*.csv")]
    return sorted(p for p in tables if not is_derived(p))


# ------------------------------------------------------------------------------------------- rerunning rows
def configfiles(table, prov=None):
    """The configuration files of a published table's study (its provenance's ``configfiles``, else
    ``config/<study>.yaml``), paths relative to the project."""
    prov = read_provenance(table) if prov is None else prov
    return list(prov.get("configfiles") or [f"config/{study_name(table)}.yaml"])


def _value(row, col, default=None):
    v = row.get(col, default)
    return default if v is None or (isinstance(v, float) and np.isnan(v)) else v


#: What a published row's columns may hold, checked before a row is rerun (the rest comes from the configuration).
_POSE_TRANSFORMS = ("heading", "none")
_CV_MODES = ("per_size", "per_job", "none")
#: A source or activity name: it becomes a path under the features folder.
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
#: Most chains a published row may pool.
_MAX_CHAINS = 1024


def _same(a, b):
    """Whether a configured value ``a`` and a row's JSON value ``b`` are the same setting (YAML 1.1 leaves ``1e-3``
    a string, which the configuration check reads as the number). A float is not an int (``1.0`` for a configured
    ``1``: scikit-learn's validation refuses a float count), nor a bool an int."""
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int) and isinstance(b, float):
        return False
    return _equal_value(a, b)


def _equal_value(a, b):
    """Whether ``a`` and ``b`` are equal as values, whatever their types (``1 == 1.0 == True``)."""
    if isinstance(a, str) and not isinstance(b, str):
        with contextlib.suppress(ValueError):
            a = float(a)
    return a == b


def row_settings(row, config, where, datasets=None):
    """The checked settings of a published ``row`` (a dict of a table's row) for a rerun: ``{spec, estimator, params,
    n_chains, conformal, cv}``, the estimator and settings from the study's ``config`` (:func:`study_config`), the
    split's key and the CV's choice from the row. InputError naming ``where`` (table and line), the column, its
    value and what was expected when a column is missing, of another type or range, or when the row's
    ``estimator``, ``params`` (values and their types: a float is no int) or ``n_chains`` (``methods.<M>.chains``,
    default 1; an empty cell is one chain) are not what the configuration runs: a published row is data, and only
    the configuration names code. ``datasets``: the study's data sets (:func:`_study_datasets`), whose
    ``paper_activity`` a row's must equal when both are given (an empty cell, as in rows of a data set without a
    paper name, is not compared). A column a row lacks (rows written before it existed) is not compared."""
    from ..estimators import default_grid
    from ..splits import PROTOCOLS, JobSpec

    def bad(col, expected):
        value = row.get(col)
        shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
        return InputError(f"{where}: column {col!r} is {shown}; expected {expected}")

    def integer(col, low, high, default=None):
        v = _value(row, col, default)
        if isinstance(v, str):
            with contextlib.suppress(ValueError):
                v = int(v)
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not low <= v <= high:
            raise bad(col, f"a whole number from {low} to {high}")
        return int(v)

    def choice(col, options, default=None):
        v = _value(row, col, default)
        if v not in options:
            raise bad(col, f"one of {list(options)}")
        return v

    method = _value(row, "method")
    methods = config.get("methods") or {}
    if not isinstance(method, str) or method not in methods:
        raise bad("method", f"a method of the study's configuration ({', '.join(methods)})")
    m = methods[method]
    if row.get("estimator") != m["estimator"]:
        raise bad(
            "estimator",
            f"{m['estimator']!r}, the estimator of method {method} in the configuration",
        )
    for col in ("source", "activity"):
        v = _value(row, col)
        if not isinstance(v, str) or not _NAME.fullmatch(v):
            raise bad(col, "a data set name (letters, digits, '_', '-', '.')")
    params = json_text(_value(row, "params", "{}"), f"{where}: column 'params'")
    if not isinstance(params, dict):
        raise bad("params", "a JSON object {parameter: value}")
    fixed = dict(m.get("params") or {})
    grid = m.get("grid", "default")
    grid = default_grid(m["estimator"]) if grid == "default" else dict(grid or {})
    for k, v in params.items():
        if k in grid and any(_same(g, v) for g in grid[k]):
            continue
        if k in fixed and _same(fixed[k], v):
            continue
        allowed = (
            f"the grid's {grid[k]!r}"
            if k in grid
            else f"{fixed[k]!r}"
            if k in fixed
            else "no such key"
        )
        configured = [*(grid.get(k) or []), *([fixed[k]] if k in fixed else [])]
        types = sorted({type(g).__name__ for g in configured if _equal_value(g, v)})
        if types:  # the value, but of another type (1.0 for 1, true for 1)
            raise InputError(
                f"{where}: column 'params': {k}: {v!r} is of type {type(v).__name__}; expected {allowed} of type "
                f"{' or '.join(types)}, what method {method} is configured with (methods.{method}.params and grid)"
            )
        raise InputError(
            f"{where}: column 'params': {k}: {v!r} is not what method {method} is configured with; expected "
            f"{allowed} (methods.{method}.params and grid)"
        )
    lacking = sorted(set(fixed) - set(params))
    if lacking:
        raise InputError(
            f"{where}: column 'params' lacks {lacking}, which method {method} is configured with "
            f"(methods.{method}.params); expected the configured parameters with the CV's choice"
        )
    level = _value(row, "conformal_level")
    if level is not None:
        try:
            level = float(level)
        except (TypeError, ValueError):
            level = None
        if level is None or not 0.0 < level < 1.0:
            raise bad("conformal_level", "a number between 0 and 1, or empty")
    spec = JobSpec(
        source=row["source"],
        activity=row["activity"],
        method=method,
        n_train=integer("n_train", 1, 10**6),
        seed=integer("seed", 0, 2**31 - 1),
        protocol=choice("protocol", PROTOCOLS),
        pose_transform=choice(
            "pose_transform", _POSE_TRANSFORMS, config.get("pose_transform", "heading")
        ),
        min_test=int(config.get("min_test", 100)),
        gap=int(config.get("gap", 30)),
        paper_activity=str(_value(row, "paper_activity", "") or ""),
    )
    if spec.method_seed != integer("method_seed", 0, 2**32 - 1):
        raise bad("method_seed", f"{spec.method_seed}, the seed today's code derives for {spec}")
    if spec.paper_activity and datasets is not None:
        entry = (datasets.get(spec.source) or {}).get(spec.activity)
        if isinstance(entry, dict) and spec.paper_activity != (entry.get("paper_activity") or ""):
            raise bad(
                "paper_activity",
                f"{entry.get('paper_activity') or ''!r}, the paper_activity of data set {spec.source}/"
                f"{spec.activity} in the configuration (datasets.{spec.source}.{spec.activity}.paper_activity)",
            )
    n_chains = integer("n_chains", 1, _MAX_CHAINS, 1)
    chains = m.get("chains", 1)
    if isinstance(chains, bool) or not isinstance(chains, int) or chains < 1:
        raise InputError(
            f"config key 'methods.{method}.chains' is {chains!r}; expected a whole number of chains, at least 1"
        )
    if "n_chains" in row and n_chains != chains:
        shown = n_chains if _value(row, "n_chains") is not None else "empty (one chain)"
        raise InputError(
            f"{where}: column 'n_chains' is {shown}; expected {chains}, the chains of method {method} in the "
            "configuration"
        )
    return {
        "spec": spec,
        "estimator": m["estimator"],
        "params": params,
        "n_chains": n_chains,
        "conformal": None
        if level is None
        else {"level": level, "params": dict(m.get("cv_params") or {})},
        "cv": choice("cv", _CV_MODES, "none"),
    }


def rerun_row(row, config, features_folder="results/features", where="the row"):
    """The result row today's code makes for the published ``row`` (a dict of a table's row): the same split and
    method seed, the configured estimator with the row's ``params`` (the CV's choice, so no CV is rerun), pose
    transform and chains, the study's ``min_test``, ``gap`` and split-conformal settings (``config``:
    :func:`study_config`), all checked first (:func:`row_settings`). BLAS runs on one thread, as in the study's
    fit jobs (``threads: 1``): on two it sums in another order, and a last-bit difference can move a test frame
    across its conformal interval's edge (coverage is a count)."""
    from threadpoolctl import threadpool_limits

    settings = row_settings(row, config, where)
    with threadpool_limits(limits=1):
        return _rerun_row(settings, features_folder)


def _rerun_row(settings, features_folder):
    from ..io import load_features
    from ..runs import pool_chains, run_chain, run_job

    spec = settings["spec"]
    path = Path(features_folder) / spec.source / f"{spec.activity}.npz"
    if not path.is_file():
        raise DataFileError(path, "no features to rerun the row on; run the study's features first")
    features = load_features(path)
    kw = dict(estimator=settings["estimator"], params=settings["params"])
    conformal = settings["conformal"]
    if settings["n_chains"] > 1:
        chains = [
            run_chain(spec, features, chain=c, conformal=conformal, **kw)
            for c in range(settings["n_chains"])
        ]
        new, _ = pool_chains(spec, features, chains, cv_mode=settings["cv"], **kw)
    else:
        new, _ = run_job(spec, features, cv_mode=settings["cv"], conformal=conformal, **kw)
    return new


def compare_row(old, new, *, atol=ATOL, rtol=RTOL):
    """``(comparison, largest)``: the :class:`.compare.Comparison` of a published row and its rerun on the columns
    both have, and the largest absolute difference of a numeric column (or number list) and its column,
    ``(0.0, None)`` when they are identical."""
    from ..results import aggregate_rows
    from .compare import compare_frames

    b = aggregate_rows([new])
    a = pd.DataFrame([old])[[c for c in old if c in b.columns]]
    b = b[a.columns]
    # both through a CSV round trip, so that types and float text are those of a published table
    a, b = (pd.read_csv(_csv(x)).set_index(KEY_COLUMNS) for x in (a, b))
    exact = compare_frames(a, b, atol=0.0, rtol=0.0).columns
    diffs = [(d, c) for c, (_, d, _) in exact.items() if d is not None]
    diagnostics = [c for c in a.columns if c.startswith(DIAGNOSTICS)]
    res = compare_frames(
        a.drop(columns=diagnostics), b.drop(columns=diagnostics), atol=atol, rtol=rtol
    )
    if diagnostics:
        diag = compare_frames(a[diagnostics], b[diagnostics], atol=atol, rtol=DIAGNOSTICS_RTOL)
        res.columns.update(diag.columns)
    return res, max(diffs, default=(0.0, None))


def _csv(df):
    import io

    buf = io.StringIO()
    df.to_csv(buf, index=False)
    buf.seek(0)
    return buf


def verdict(key, res, largest=(0.0, None)):
    """One line: the row's key and "equal" (with the largest difference) or what differs."""
    cell = " ".join(f"{k}={key[k]}" for k in KEY_COLUMNS)
    if res.equal:
        d, c = largest
        size = "identical" if c is None else f"largest |diff| {d:.3g} ({c})"
        return f"{cell}: equal within atol {ATOL:g}, rtol {RTOL:g} (diagnostics {DIAGNOSTICS_RTOL:g}); {size}"
    parts = [
        f"{c} ({'text differs' if d is None else f'|diff| {d:.3g}'})"
        for c, (_, d, _) in res.columns.items()
    ]
    return f"{cell}: DIFFERENT: {', '.join(parts)}"


def sample_rows(df, k, seed, methods=None):
    """``k`` rows drawn at random per method of ``methods`` (``random.Random(f"{seed}:{method}")``, so that each
    method gets cells of its own), or ``k`` from the whole table (``random.Random(seed)``) when ``methods`` is None;
    in the table's order."""
    if methods is None:
        idx = random.Random(seed).sample(range(len(df)), min(k, len(df)))
    else:
        idx = []
        for m in methods:
            rows = list(np.flatnonzero((df["method"] == m).to_numpy()))
            idx += random.Random(f"{seed}:{m}").sample(rows, min(k, len(rows)))
    return df.iloc[sorted(idx)]


def _line(table, idx):
    """Where a row of a published table is: its line in the CSV file (the header is line 1)."""
    return f"{table} line {int(idx) + 2}"


def _named_methods(table, df, registry, files):
    """Refuse a table with a row without a method name."""
    blank = [i for i, v in df["method"].items() if not isinstance(v, str) or not v]
    if blank:
        raise InputError(
            f"{_line(table, blank[0])}: column 'method' is empty; expected a method of {' + '.join(files)} "
            f"({', '.join(registry)})"
        )


def _known_methods(table, df, registry, files):
    """Refuse a table with a row without a method or with rows of a method that its study's configuration does not
    run: such a row cannot be rerun (its estimator and settings are not configured)."""
    _named_methods(table, df, registry, files)
    unknown = sorted(set(df["method"]) - set(registry))
    if unknown:
        raise InputError(
            f"{table}: methods {unknown} are not run by {' + '.join(files)} "
            f"(it runs {', '.join(registry)}); such rows cannot be rerun"
        )


def _study_datasets(files):
    """The data sets of a study, ``{source: {activity: entry}}``: ``config/datasets.yaml`` with the ``datasets`` of
    ``files`` (:func:`study_config`'s files) merged over it entry by entry, as Snakemake merges the configuration
    files (:func:`bsrbench.methods.study_datasets`, whose reading this checks first). DataFileError naming the
    file and the key whose value is not a mapping; ``{}`` without a ``config/datasets.yaml``."""
    from .. import methods
    from ..safeload import read_yaml

    folder = Path(methods.CONFIG)
    paths = [folder / "datasets.yaml", *(repository_file(f, folder) for f in files)]
    for path in paths:
        data = read_yaml(path) if path.is_file() else None
        sources = data.get("datasets") if isinstance(data, dict) else None
        if not isinstance(sources, (dict, type(None))):
            raise DataFileError(
                path,
                f"key 'datasets' is a {type(sources).__name__}; expected a mapping {{source: {{activity: entry}}}}",
            )
        for source, acts in (sources or {}).items():
            if not isinstance(acts, (dict, type(None))):
                raise DataFileError(
                    path,
                    f"key 'datasets.{source}' is a {type(acts).__name__}; expected a mapping {{activity: entry}}",
                )
    if not paths[0].is_file():
        return {}
    return methods.study_datasets(files, folder)


def _checked_table(table, required_provenance):
    """``(rows, provenance, configfiles, config, registry)`` of a table to rerun rows of, every row checked against
    its study's configuration (:func:`row_settings`) before any is rerun."""
    df = _has_rows(table, read_table(table))
    prov = read_provenance(table, required=required_provenance)
    files = configfiles(table, prov)
    config = study_config(files)
    registry = study_registry(config, " + ".join(files))
    _known_methods(table, df, registry, files)
    datasets = _study_datasets(files)
    for idx, row in df.iterrows():
        row_settings(row.to_dict(), config, _line(table, idx), datasets=datasets)
    return df, prov, files, config, registry


def verify(table, k, seed=0, *, log=print, features_folder="results/features"):
    """Rerun ``k`` random rows of ``table`` with today's code and print one verdict per row; True if all equal."""
    df, _, _, config, _ = _checked_table(table, required_provenance=True)
    ok = True
    for idx, row in sample_rows(df, k, seed).iterrows():
        row = row.to_dict()
        new = rerun_row(row, config, features_folder, _line(table, idx))
        res, largest = compare_row(row, new)
        ok &= res.equal
        log(verdict(row, res, largest))
    return ok


def restamp(table, k=RESTAMP_ROWS, seed=0, *, log=print, features_folder="results/features"):
    """For each method of ``table`` whose rows are not all of today's code fingerprint, rerun ``k`` random rows of
    it; if every one equals its published value within the tolerance, write today's fingerprint into the method's
    rows and its digests, commit and the rows rerun into the provenance. Methods with a differing row stay stale.
    Returns {method: (restamped?, largest difference over the rerun rows' numeric columns)}."""
    df, prov, files, config, registry = _checked_table(table, required_provenance=False)
    now = today(registry)
    prov.setdefault("study", study_name(table))
    prov.setdefault("configfiles", files)
    methods_prov = prov.setdefault("methods", {})
    if "code_fingerprint" not in df.columns:
        df["code_fingerprint"] = None
    if "git_commit" not in df.columns:
        df["git_commit"] = None
    todo = [
        m
        for m in registry
        if m in set(df["method"])
        and (df.loc[df["method"] == m, "code_fingerprint"] != now[m][0]).any()
    ]
    commit, date = git_commit(), datetime.now(UTC).isoformat(timespec="seconds")
    out = {}
    for m in todo:
        rows = sample_rows(df, k, seed, methods=[m])
        equal, worst, rerun = True, 0.0, []
        for idx, row in rows.iterrows():
            row = row.to_dict()
            res, (d, _) = compare_row(
                row, rerun_row(row, config, features_folder, _line(table, idx))
            )
            log(verdict(row, res, (d, _)))
            equal &= res.equal
            worst = max(worst, d)
            rerun.append({c: _plain(row[c]) for c in KEY_COLUMNS})
        out[m] = (equal, worst)
        if not equal:
            log(f"{table} {m}: not restamped (a rerun row differs); stays stale")
            continue
        sel = df["method"] == m
        df.loc[sel, "code_fingerprint"] = now[m][0]
        methods_prov[m] = {
            "code_fingerprint": now[m][0],
            "files": now[m][1],
            "git_commit": commit,
            "date": date,
            "restamped": {
                "rows_rerun": rerun,
                "tolerance": {"atol": ATOL, "rtol": RTOL, "diagnostics_rtol": DIAGNOSTICS_RTOL},
                "largest_difference": worst,
                "row_commits_before": sorted(set(map(str, df.loc[sel, "git_commit"].dropna()))),
            },
        }
        log(f"{table} {m}: restamped ({len(rerun)} rows rerun, largest difference {worst:.3g})")
    if any(ok for ok, _ in out.values()):
        write_table(df, table, "the restamped table", prov)
    return out


def _plain(v):
    return v.item() if hasattr(v, "item") else v


# ----------------------------------------------------------------------------------------- provenance of new
def method_provenance(df, registry, now=None):
    """The ``methods`` entry of a table's provenance: per method its rows' fingerprint and, when that is today's,
    today's per-file digests (else None: the check then cannot name the file), the commits and the newest time."""
    now = now if now is not None else today(registry)
    out = {}
    for m, rows in df.groupby("method"):
        fps = sorted(set(rows["code_fingerprint"].dropna())) if "code_fingerprint" in rows else []
        entry = {
            "code_fingerprint": fps[0] if len(fps) == 1 else fps,
            "files": now[m][1] if m in now and fps == [now[m][0]] else None,
            "git_commit": sorted(set(rows["git_commit"].dropna())) if "git_commit" in rows else [],
            "date": str(rows["written_at"].dropna().max()) if "written_at" in rows else None,
        }
        out[m] = entry
    return out


def table_provenance(table, df, files=None, records=None):
    """The provenance of a newly published table ``table`` of rows ``df`` (no ``historical`` mark); ``files``: the
    study's configuration files (default: those of the table's provenance, else ``config/<study>.yaml``).
    ``records``: provenances whose ``restamped`` records carry over (default: the table's own, as it is before
    it is replaced): a method keeps the newest record made for the fingerprint all its rows have. Reads
    everything it needs, the table's old provenance too (DataFileError naming one that cannot be read); writes
    nothing."""
    # read even when it is replaced: one that cannot be read is refused, before anything is written
    own = read_provenance(table)
    records = [own] if records is None else records
    files = files or configfiles(table, own)
    try:
        now = today(study_registry(study_config(files), " + ".join(files)))
    except (
        InputError
    ):  # an overlay study not yet named in its provenance: no digests, the check says so
        now = {}
    methods = method_provenance(df, None, now)
    for m, entry in methods.items():
        # a re-stamped method keeps the record of its rerun rows while its rows keep that fingerprint
        made = [
            old
            for prov in records
            for old in [(prov.get("methods") or {}).get(m) or {}]
            if old.get("restamped") and old.get("code_fingerprint") == entry["code_fingerprint"]
        ]
        if made:
            old = max(made, key=lambda e: str(e.get("date") or ""))
            entry["restamped"] = old["restamped"]
            entry["files"] = entry["files"] or old.get("files")
    return {"study": study_name(table), "configfiles": files, "methods": methods}


def write_table_provenance(table, df, files=None):
    """Write the provenance of a newly published table (:func:`table_provenance`)."""
    write_provenance(table, table_provenance(table, df, files))


def read_part(part):
    """``(rows, provenance, configfiles)`` of a part to merge; InputError naming the part (or its provenance
    file) when it is historical, has no provenance file, no ``code_fingerprint`` column, no rows, or rows whose
    fingerprint its provenance does not list for their method: a merged table must be of current parts of one
    study, each row with its code's fingerprint."""
    df = read_table(part)
    prov = read_provenance(part, required=True)
    if "historical" in prov:
        raise InputError(
            f"{part}: historical (the 'historical' mark of {provenance_path(part)}); a merge needs current "
            "parts: regenerate it, or remove the mark from its provenance deliberately"
        )
    if "code_fingerprint" not in df.columns:
        raise DataFileError(
            part,
            "no column 'code_fingerprint' (rows made before the code fingerprints); a merge needs parts whose "
            "rows carry their code's fingerprint: restamp it first",
        )
    if not len(df):
        raise DataFileError(
            part, "has no rows (only a header); expected a published table of result rows"
        )
    _check_part_values(part, df)
    listed = prov.get("methods") or {}
    for method, rows in df.groupby("method", sort=True):
        have = sorted(set(rows["code_fingerprint"].dropna().astype(str)))
        fps = (listed.get(method) or {}).get("code_fingerprint")
        said = sorted({fps} if isinstance(fps, str) else set(fps or []))
        if not set(have) <= set(said):
            raise InputError(
                f"{part}: the rows of {method} have code fingerprints {[f[:12] for f in have]}, its provenance "
                f"({provenance_path(part)}) lists {[f[:12] for f in said]}; expected a part and its provenance "
                "written together (publish it again)"
            )
    return df, prov, configfiles(part, prov)


#: The largest mean angle error of a row (degrees): a wrapped angle error is at most 180.
MAX_ERROR = 180.0


def _check_part_values(part, df):
    """Refuse a part whose ``error`` is not a finite number in [0, :data:`MAX_ERROR`] (a mean wrapped angle error
    in degrees) or whose ``written_at`` (when present) is not an ISO 8601 date-time: InputError naming the part's
    line, the column, the value and what was expected (the merge keeps the newest row by ``written_at``)."""
    error = pd.to_numeric(df["error"], errors="coerce").to_numpy(dtype=float)
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~(np.isfinite(error) & (error >= 0) & (error <= MAX_ERROR)))
    if len(bad):
        raise InputError(
            f"{_line(part, bad[0])}: column 'error' is {_plain(df['error'].iloc[bad[0]])!r}; expected a finite "
            f"number in [0, {MAX_ERROR:g}] (the mean wrapped angle error in degrees)"
        )
    if "written_at" not in df.columns:
        return
    for i, v in enumerate(df["written_at"]):
        if v is None or (isinstance(v, float) and np.isnan(v)):
            continue
        try:
            ok = (
                isinstance(v, str)
                and re.match(r"\s*\d{4}", v) is not None  # pandas also takes 'now' and 'today'
                and not pd.isna(pd.to_datetime(v, utc=True, format="ISO8601"))
            )
        except (ValueError, TypeError, OverflowError):
            ok = False
        if not ok:
            raise InputError(
                f"{_line(part, i)}: column 'written_at' is {_plain(v)!r}; expected an ISO 8601 date-time "
                "(e.g. 2024-05-01T12:00:00+00:00: when the row was written)"
            )


def _check_destination(dest, files):
    """Refuse ``dest`` (the merged table) before anything is written: a symbolic link or a read-only file, of the
    table or of its provenance (:func:`.headline.check_update_target`), or an existing table of another study (its
    provenance's ``configfiles`` other than the parts' ``files``), which the merge would replace by the parts'
    rows. DataFileError naming the file."""
    from .headline import check_update_target

    for p in (Path(dest), provenance_path(dest)):
        check_update_target(p, "the merge")
    if Path(dest).is_file():  # a folder in the way: refused when written
        own = configfiles(dest, read_provenance(dest))
        if own != files:
            raise DataFileError(
                dest,
                f"is a table of another study (configfiles {own}), the parts are of configfiles {files}; "
                "expected a new destination or a table of the parts' study (the merge would replace its rows "
                "by the parts')",
            )


def _job_keys(df):
    """The job keys of ``df``'s rows, numbers compared as numbers (an N written 30.0 is the job of N 30)."""
    cols = [
        pd.to_numeric(df[c], errors="coerce").astype(float)
        if c in ("n_train", "seed")
        else df[c].astype(str)
        for c in KEY_COLUMNS
    ]
    return list(zip(*cols))


def _check_nothing_dropped(dest, merged):
    """InputError naming ``dest`` (an existing table that is not among the parts) if it holds a job that the
    ``merged`` rows lack: the merge would drop those rows."""
    old = read_table(dest)
    keys = set(_job_keys(merged))
    lost = [i for i, k in enumerate(_job_keys(old)) if k not in keys]
    if lost:
        example = {c: _plain(old[c].iloc[lost[0]]) for c in KEY_COLUMNS}
        raise InputError(
            f"{dest}: {len(lost)} of its {len(old)} rows are jobs that no part holds (e.g. {example}), and the "
            f"merge would drop them; expected {dest} among the parts (a table grows by a new part) or parts that "
            "hold all its jobs (a regeneration)"
        )


def merge(parts, dest):
    """Merge published tables of parts of one study into ``dest``: one row per job key, the newest row
    (``written_at``) where parts overlap; two different rows of one key and equal age is an InputError naming the
    key. The parts must be current (:func:`read_part`) and of one study (equal ``configfiles``). Reads and checks
    everything first, then writes ``dest`` and its provenance (configfiles of the parts, the parts' restamp
    records where they hold, :func:`table_provenance`) together; returns the merged DataFrame."""
    if Path(dest).suffix != ".csv":
        raise DataFileError(dest, "cannot write the merged table: expected a path ending in .csv")
    seen = {}  # the destination may be a part: a table grows by a new part
    frames, provs, files = [], [], None
    for p in parts:
        real = Path(p).resolve()
        if real in seen:
            raise InputError(f"{p}: given twice (also as {seen[real]}); expected each part once")
        seen[real] = p
        d, prov, f = read_part(p)
        if files is not None and f != files:
            raise InputError(
                f"{parts[0]} and {p} are parts of different studies: configfiles {files} and {f}; expected "
                "parts of one study (the same configuration files)"
            )
        files = f
        if "written_at" not in d.columns:
            d["written_at"] = None
        d["_part"] = str(p)
        frames.append(d)
        provs.append(prov)
    _check_destination(dest, files)
    df = pd.concat(frames, ignore_index=True)
    df["_age"] = pd.to_datetime(df["written_at"], utc=True, errors="coerce", format="ISO8601")
    df = df.sort_values("_age", kind="mergesort", na_position="first")
    dup = df.duplicated(KEY_COLUMNS, keep=False)
    for key, g in df[dup].groupby(KEY_COLUMNS, sort=False):
        newest = g[g["_age"] == g["_age"].max()] if g["_age"].notna().any() else g
        body = newest.drop(columns=["_part", "_age"]).astype(str).drop_duplicates()
        if len(newest) > 1 and len(body) > 1:
            raise InputError(
                f"{dict(zip(KEY_COLUMNS, map(_plain, key)))}: different rows of equal age in "
                f"{sorted(set(newest['_part']))}; expected one newest row per job (rerun one part)"
            )
    df = df.drop_duplicates(KEY_COLUMNS, keep="last").drop(columns=["_part", "_age"])
    df = df.sort_values(KEY_COLUMNS, kind="mergesort").reset_index(drop=True)
    if Path(dest).is_file() and Path(dest).resolve() not in seen:
        _check_nothing_dropped(dest, df)
    if not Path(dest).parent.is_dir():
        raise DataFileError(dest, "cannot write the merged table: its folder does not exist")
    prov = table_provenance(dest, df, files, records=provs)
    write_table(df, dest, "the merged table", prov)
    return df


def cell_shifts(old, new, column="error", names=("the old table", "the new table")):
    """How far each cell's mean of ``column`` moved from table ``old`` to table ``new`` (a regeneration), in units
    of the standard error of the old cell's mean (std over its seeds / sqrt(seeds)): one row per cell (the key
    columns but the seed) that both tables hold, largest |z| first. A table without rows, without the cells' key
    columns or without a numeric ``column`` is a DataFileError naming it (``names``: the tables' files)."""
    cells = [c for c in KEY_COLUMNS if c != "seed"]
    for name, df in zip(names, (old, new)):
        if not len(df):
            raise DataFileError(
                name, "has no rows (only a header); expected a table of result rows"
            )
        if column not in df.columns:
            raise DataFileError(
                name, f"no column {column!r}; expected a numeric column for --column, such as error"
            )
        missing = sorted(set(cells) - set(df.columns))
        if missing:
            raise DataFileError(name, f"no columns {missing}; expected a table of result rows")
        if not pd.api.types.is_numeric_dtype(df[column]):
            raise DataFileError(
                name,
                f"column {column!r} is not numeric (e.g. {str(df[column].iloc[0])[:40]!r}); expected "
                "a numeric column for --column, such as error",
            )
    # count: the seeds with a value (NaN left out), so that a cell with a missing or NaN seed is named
    a = old.groupby(cells)[column].agg(["mean", "std", "count"])
    b = new.groupby(cells)[column].agg(["mean", "count"])
    out = a.add_suffix("_old").join(b.add_suffix("_new"), how="inner")
    out["se_old"] = out["std_old"] / np.sqrt(out["count_old"])
    out["z"] = (out["mean_new"] - out["mean_old"]) / out["se_old"]
    out = out.drop(columns="std_old").reset_index()
    return out.reindex(out["z"].abs().sort_values(ascending=False, na_position="last").index)


def shift_report(old_table, new_table, column="error", top=5):
    """Lines: the cells compared, the largest shift in standard errors and the ``top`` cells that moved most."""
    old, new = read_table(old_table), read_table(new_table)
    out = cell_shifts(old, new, column, names=(old_table, new_table))
    cells = [c for c in KEY_COLUMNS if c != "seed"]
    n_old, n_new = (len(df.groupby(cells)) for df in (old, new))
    lines = [
        f"{new_table} against {old_table}: {len(out)} cells in both ({n_old} in the old table, {n_new} in the "
        f"new); column {column}, change of the cell's mean in standard errors of the old cell's mean"
    ]
    if not len(out):
        raise InputError(f"{old_table} and {new_table} have no cell in common")
    z = out["z"].abs()
    lines.append(
        f"largest |z| {z.max():.2f}; median |z| {z.median():.2f}; cells with |z| > 2: {(z > 2).sum()}"
    )
    uneven = out[(out["count_old"] != out["count_new"]) | out["z"].isna()]
    if len(uneven):
        lines.append(
            f"WARNING: {len(uneven)} cell(s) have no z (NaN values or one seed) or other seeds with a value "
            "in the two tables, e.g. "
            + " ".join(f"{c}={uneven.iloc[0][c]}" for c in cells)
            + f" ({int(uneven.iloc[0]['count_old'])} old, {int(uneven.iloc[0]['count_new'])} new)"
        )
    for _, r in out.head(top).iterrows():
        cell = " ".join(f"{c}={r[c]}" for c in cells)
        lines.append(
            f"  {cell}: {r['mean_old']:.4g} -> {r['mean_new']:.4g} (SE {r['se_old']:.3g}, z {r['z']:+.2f})"
        )
    return lines


# ------------------------------------------------------------------------------------------ command line
COMMANDS = ("check", "verify", "restamp", "merge", "shift")


def add_commands(sub):
    """The subcommands of this module on the ``published`` command line's subparsers ``sub``."""
    c = sub.add_parser(
        "check",
        help="per published table and method: fresh (today's code fingerprint) or stale and the files changed",
    )
    c.add_argument(
        "tables",
        nargs="*",
        help="published tables (default: reports/published/*.csv of result rows)",
    )
    v = sub.add_parser("verify", help="rerun random rows of a published table with today's code")
    v.add_argument("table")
    v.add_argument("--rows", type=int, default=3, help="rows to rerun (default 3)")
    v.add_argument("--seed", type=int, default=0, help="seed of the random choice (default 0)")
    r = sub.add_parser(
        "restamp",
        help="rerun rows of each method whose fingerprint changed; stamp today's if all rerun equal",
    )
    r.add_argument("table")
    r.add_argument("--rows", type=int, default=RESTAMP_ROWS, help="rows per method (at least 3)")
    r.add_argument("--seed", type=int, default=0)
    s = sub.add_parser(
        "shift",
        help="how far each cell's mean moved between two versions of a table, in standard errors",
    )
    s.add_argument(
        "old", help="the table before (e.g. git show HEAD:reports/published/X.csv > old.csv)"
    )
    s.add_argument("new", help="the regenerated table")
    s.add_argument("--column", default="error", help="the column compared (default error)")
    s.add_argument("--top", type=int, default=5, help="cells listed (default 5)")
    m = sub.add_parser(
        "merge", help="merge the published tables of a study's parts (newest row per job key)"
    )
    m.add_argument("parts", nargs="+", help="the parts' tables")
    m.add_argument("dest", help="reports/published/<study>.csv")


def run_command(args):
    """Run a subcommand of :data:`COMMANDS`; the exit status (check: 1 if anything is stale; verify: 1 if a row
    differs; restamp: 1 if a method stays stale; 2: bad input, one line naming the file)."""
    import sys

    try:
        if args.cmd == "check":
            tables = args.tables or published_tables()
            stale = False
            for t in tables:
                lines, bad = check_table(t)
                print("\n".join(lines))
                stale |= bad
            return 1 if stale else 0
        if args.cmd == "verify":
            if args.rows < 1:
                raise InputError(f"--rows {args.rows}: expected at least 1")
            return 0 if verify(args.table, args.rows, args.seed) else 1
        if args.cmd == "restamp":
            if args.rows < RESTAMP_ROWS:
                raise InputError(f"--rows {args.rows}: expected at least {RESTAMP_ROWS}")
            out = restamp(args.table, args.rows, args.seed)
            if not out:
                print(
                    f"{args.table}: every method has today's code fingerprint; nothing to restamp"
                )
            return 0 if all(ok for ok, _ in out.values()) else 1
        if args.cmd == "shift":
            if args.top < 0:
                raise InputError(f"--top {args.top}: expected 0 or more")
            lines = shift_report(args.old, args.new, args.column, args.top)
            print("\n".join(lines))
            return 1 if any(line.startswith("WARNING") for line in lines) else 0
        df = merge(args.parts, args.dest)
        print(f"{args.dest}: {len(df)} rows from {len(args.parts)} part(s)", file=sys.stderr)
        return 0
    except InputError as exc:  # DataFileError is one: it names the file
        print(f"error: {exc}", file=sys.stderr)
        return 2
