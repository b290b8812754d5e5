"""The result rows of the study's jobs: their schema, the row of a job, the aggregate table, its reading, and the
checks that the table is exactly the configured study (the ``--report`` checks).

A fit job writes one row (a JSON dict, :func:`bsrbench.runs.run_job`, whose identifying columns come from
:func:`row_key`); the aggregate rule gathers them into ``results/{study}/aggregate/results.csv``
(:func:`aggregate_files`), and every table, figure and finding reads it back through :func:`read_results`. The
configuration (:mod:`bsrbench.config`) and the reporting (:mod:`bsrbench.reporting`) both import this module;
it imports neither.
"""

import json
from datetime import UTC
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import DataFileError, InputError
from .io import atomic_path, read_csv

#: The columns that identify a job in the aggregate table.
KEY_COLUMNS = ["protocol", "source", "activity", "method", "n_train", "seed"]


def row_key(spec):
    """The identifying columns of the result row of the job ``spec`` (:class:`bsrbench.splits.JobSpec`): the
    :data:`KEY_COLUMNS`, the paper's name of the activity and the pose transform, in the row's order."""
    return {
        "source": spec.source,
        "activity": spec.activity,
        "paper_activity": spec.paper_activity or "",
        "method": spec.method,
        "n_train": int(spec.n_train),
        "seed": int(spec.seed),
        "protocol": spec.protocol,
        "pose_transform": spec.pose_transform,
    }


# ------------------------------------------------------------------------------------------------ aggregate
def aggregate_rows(rows):
    """One tidy DataFrame from result rows (dicts as written by :func:`bsrbench.runs.run_job`).

    Nested values (params, per-angle RMS, versions) become JSON strings. Rows are sorted by the key
    columns; a duplicate key raises InputError.
    """
    rows = list(rows)
    if not rows:
        raise InputError("no result rows to aggregate")
    flat = []
    for r in rows:
        missing = [k for k in KEY_COLUMNS + ["error"] if k not in r]
        if missing:
            raise InputError(f"result row lacks {missing}: {str(r)[:200]}")
        flat.append(
            {
                k: (json.dumps(v, sort_keys=True) if isinstance(v, (dict, list)) else v)
                for k, v in r.items()
            }
        )
    df = pd.DataFrame(flat)
    dup = df.duplicated(KEY_COLUMNS, keep=False)
    if dup.any():
        raise InputError(f"duplicate result rows for {df.loc[dup, KEY_COLUMNS].iloc[0].to_dict()}")
    first = [c for c in KEY_COLUMNS + ["error", "coverage"] if c in df.columns]
    df = df[first + sorted(c for c in df.columns if c not in first)]
    return df.sort_values(KEY_COLUMNS, kind="mergesort").reset_index(drop=True)


def aggregate_files(paths):
    """Read result-row JSON files and aggregate them (see :func:`aggregate_rows`)."""
    rows = []
    for p in paths:
        try:
            rows.append(json.loads(Path(p).read_text()))
        except (OSError, json.JSONDecodeError) as exc:
            raise DataFileError(p, f"cannot read result row ({exc})") from exc
    return aggregate_rows(rows)


def write_csv(df, path):
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)


def read_results(path, design=None):
    """Read the aggregate table and check its columns; with ``design``, check it is exactly that study.

    ``design``: the configured study, ``{"protocols": [...], "pairs": [[source, activity], ...],
    "methods": [...], "n_train": [...], "seeds": [...]}`` (see :func:`check_design`).
    """
    df = read_csv(path, "the aggregate table")
    missing = [c for c in KEY_COLUMNS + ["error"] if c not in df.columns]
    if missing:
        raise DataFileError(path, f"missing columns {missing}")
    if design is not None:
        check_design(df, design, path=path)
    check_rows(df, path=path)
    return df


def check_rows(df, *, path):
    """Raise DataFileError unless every row is a valid job result and every cell has all its seeds.

    n_train and seed are whole numbers, ``error`` a finite number >= 0 (degrees), no job appears twice, and each
    (protocol, source, activity, method, n_train) cell holds the same seeds as the whole table: a damaged or
    partial table must never be summarised into means. CSV row numbers in messages count the header as row 1.
    """

    def bad(mask, column, expected):
        if mask.any():
            i = int(np.flatnonzero(mask)[0])
            value = df[column].iloc[i]
            value = value.item() if isinstance(value, np.generic) else value
            raise DataFileError(
                path, f"row {i + 2}, column {column!r}: {value!r}; expected {expected}"
            )

    for col in ("n_train", "seed"):
        v = pd.to_numeric(df[col], errors="coerce")
        bad(~np.isfinite(v) | (v != np.round(v)), col, "a whole number")
    err = pd.to_numeric(df["error"], errors="coerce")
    bad(~np.isfinite(err) | (err < 0), "error", "a finite error >= 0 (degrees)")
    bad(
        df.duplicated(KEY_COLUMNS, keep="first").to_numpy(),
        "seed",
        "one row per job (this job appears twice)",
    )
    seeds = set(df["seed"].astype(int))
    cells = (
        df.assign(seed=df["seed"].astype(int)).groupby(KEY_COLUMNS[:-1], sort=True)["seed"].agg(set)
    )
    for key, got in cells.items():
        if got != seeds:
            cell = dict(zip(KEY_COLUMNS[:-1], key))
            raise DataFileError(
                path, f"cell {cell} has seeds {sorted(got)}; expected all of {sorted(seeds)}"
            )


# ----------------------------------------------------------------------------------- the aggregate table
def design_values(design, column):
    """The configured values of one key column (sorted), from a :func:`check_design` design."""
    if column == "source":
        return sorted({s for s, _ in design["pairs"]})
    if column == "activity":
        return sorted({a for _, a in design["pairs"]})
    key = {"protocol": "protocols", "method": "methods", "seed": "seeds"}.get(column, column)
    return sorted(design[key])


def design_changes(df, design):
    """How the jobs of the aggregate table ``df`` differ from the configured study ``design`` (see
    :func:`check_design`): ``(missing, extra, differences)``, the number of configured jobs without a row, the
    number of rows of jobs not configured, and one sentence per key column whose values differ ("n_train: the
    table has [30, 100], the configuration [30, 60]"), or, when every value is there but a job is missing, the
    first missing job. ``(0, 0, [])`` when ``df`` is exactly the configured study. ``df`` needs the key columns
    only (:data:`KEY_COLUMNS`).
    """
    skipped = {(p, s, a, int(n)) for p, s, a, n in design.get("skipped", [])}
    wanted = {
        (p, s, a, m, int(n), int(k))
        for p in design["protocols"]
        for s, a in design["pairs"]
        for m in design["methods"]
        for n in design["n_train"]
        for k in design["seeds"]
        if (p, s, a, int(n)) not in skipped
    }
    have = {
        (p, s, a, m, int(n), int(k))
        for p, s, a, m, n, k in df[KEY_COLUMNS].itertuples(index=False, name=None)
    }
    if wanted == have:
        return 0, 0, []
    differ = []
    for i, col in enumerate(KEY_COLUMNS):
        got = sorted({r[i] for r in have})
        conf = design_values(design, col)
        if got != conf:
            differ.append(f"{col}: the table has {got}, the configuration {conf}")
    if not differ:
        missing = sorted(wanted - have)
        differ.append(f"e.g. no row for {dict(zip(KEY_COLUMNS, missing[0]))}" if missing else "")
    return len(wanted - have), len(have - wanted), differ


def study_of(path):
    """The study name of an aggregate table at ``results/{study}/aggregate/results.csv``; None for another path."""
    parts = Path(path).parts
    if (
        len(parts) >= 4
        and parts[-4:-3] == ("results",)
        and parts[-2:] == ("aggregate", "results.csv")
    ):
        return parts[-3]
    return None


def check_design(df, design, *, path="results/{study}/aggregate/results.csv"):
    """Raise DataFileError unless ``df`` has exactly one row per job of the configured study.

    The jobs are every (protocol, source, activity, method, n_train, seed) of ``design`` (a dict with lists
    ``protocols``, ``pairs`` ([source, activity]), ``methods``, ``n_train``, ``seeds``, and optionally ``skipped``:
    [protocol, source, activity, n_train] cells not run because too few test frames remain). A table of another
    configuration (say, one written before a method was added) must never be reported as this study's. The
    message names what differs (:func:`design_changes`) and what to do.
    """
    missing, extra, differ = design_changes(df, design)
    if not (missing or extra):
        return
    study = study_of(path)
    name = f"study {study!r}" if study else "the study"
    folder = f"results/{study}/" if study else "the study's results folder"
    raise DataFileError(
        path,
        f"does not match the configuration: {missing} configured job(s) without a row, "
        f"{extra} row(s) of jobs not configured; "
        + "; ".join(differ)
        + f". Expected exactly the configured study: the design of {name} has changed since the table was "
        f"written. Run the study first, with the same --configfile/--config options (Snakemake reruns what "
        f"changed; add --forcerun aggregate if it finds nothing to do); or give the new design a study name of its "
        f"own (--config study=NAME) to keep the old results as they are; or delete {folder} to start afresh",
    )


def report_arg(argv):
    """The file of `--report FILE` / `--report=FILE` in ``argv``: None without --report, Snakemake's default
    report.html when no file follows."""
    for k, a in enumerate(argv):
        if a.startswith("--report="):
            return a.split("=", 1)[1]
        if a == "--report":
            nxt = argv[k + 1] if k + 1 < len(argv) else ""
            return nxt if nxt and not nxt.startswith("-") else "report.html"
    return None


def check_report_is_current(study, argv):
    """On a `snakemake --report` command line: refuse an aggregate table of another design, and an HTML file
    in another study's report folder. `snakemake --report` embeds the outputs as they are on disk without
    checking that they are current, and a Snakefile gets no flag saying that a report is being built."""
    html = report_arg(argv)
    if html is None:
        return
    target, reports = Path(html).resolve(), Path("reports").resolve()
    if target.is_relative_to(reports) and not target.is_relative_to(Path(study.reports).resolve()):
        raise ValueError(
            f"--report {html}: the HTML report of study {study.name!r} goes to its report folder "
            f"{study.reports}/ (e.g. --report {study.reports}/report.html), not to a folder of reports/ shared "
            f"with or owned by another study"
        )
    aggregate = Path(f"{study.results}/aggregate/results.csv")
    if aggregate.exists():
        read_results(aggregate, design=study.design)


def design_change_message(study):
    """A message naming what changed and what to do when the study's aggregate table holds another design than
    the configured one (a method, size, seed, protocol or activity added or removed under the same study name);
    None otherwise, or when the table cannot be read (the aggregate and report rules handle that)."""
    aggregate = Path(f"{study.results}/aggregate/results.csv")
    if not aggregate.is_file():
        return None
    try:
        missing, extra, differ = design_changes(
            pd.read_csv(aggregate, usecols=KEY_COLUMNS), study.design
        )
    except (OSError, UnicodeDecodeError, ValueError, TypeError):
        return None  # unreadable or damaged (pandas' parser errors are ValueErrors)
    if not (missing or extra):
        return None
    name, results, reports = study.name, study.results, study.reports
    return (
        f"study {name!r}: the configuration differs from the design of its results in {results}/ ({aggregate}: "
        f"{'; '.join(differ)}; {missing} job(s) to add, {extra} no longer configured). Snakemake reruns what "
        f"this needs and rebuilds the aggregate table and the report of study {name!r} for the configuration as "
        f"it is now, replacing the old report (fits no longer configured stay unused in {results}/fit/). To keep "
        f"the old study's table and report instead, run this design under a study name of its own (--config "
        f"study=NAME, or the key 'study' of your configuration file); to start study {name!r} afresh, delete "
        f"{results}/ and {reports}/."
    )


# --------------------------------------------------------------------------------------------- provenance
#: The provenance columns a job writes into its row: the fingerprint of the code its method runs, the project's
#: commit ("unknown" outside a git checkout; "+dirty" when tracked files differ from it) and the time it was written.
PROVENANCE_COLUMNS = ("code_fingerprint", "git_commit", "written_at")
#: The project's checkout (src/bsrbench/results.py -> the folder holding src/).
PROJECT = Path(__file__).resolve().parents[2]


def code_digests(estimator, method=None):
    """{relative path: sha256 of its bytes} of the source files a method's jobs run: the files of
    :meth:`bsrbench.methods.Method.source_files` for the estimator at ``estimator`` ("module:Class"), paths relative
    to the folder holding the package (``bsrbench/runs.py``), an estimator module outside the package by its file
    name. Read afresh on every call: a job must fingerprint the code on disk, not a cached copy. ``method``: the
    method's name, for the message of an estimator that cannot be found."""
    import hashlib

    from .methods import Method
    from .sources import ROOT

    files = Method(
        name=method or estimator, label="", group="", order=0, estimator=estimator
    ).source_files()
    out = {}
    for f in map(Path, files):
        rel = f.relative_to(ROOT).as_posix() if f.is_relative_to(ROOT) else f.name
        out[rel] = hashlib.sha256(f.read_bytes()).hexdigest()
    return dict(sorted(out.items()))


def code_fingerprint(digests):
    """The code fingerprint of a method: sha256 over its sorted (relative path, sha256 of the file's bytes) pairs
    (:func:`code_digests`), so that an edit, addition or removal of any of its files changes it."""
    import hashlib

    h = hashlib.sha256()
    for path, digest in sorted(digests.items()):
        h.update(f"{path}\0{digest}\n".encode())
    return h.hexdigest()


def git_commit(folder=PROJECT):
    """``git rev-parse HEAD`` of the checkout at ``folder`` with "+dirty" appended when a tracked file differs from
    it (``git diff --quiet HEAD``); "unknown" where git or the checkout is missing."""
    import subprocess

    def git(*args):
        return subprocess.run(
            ["git", "-C", str(folder), *args], capture_output=True, text=True, timeout=30
        )

    try:
        head = git("rev-parse", "HEAD")
        if head.returncode != 0:
            return "unknown"
        dirty = git("diff", "--quiet", "HEAD").returncode != 0
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head.stdout.strip() + ("+dirty" if dirty else "")


def row_provenance(estimator):
    """The :data:`PROVENANCE_COLUMNS` of a result row of the method with the estimator at ``estimator``."""
    from datetime import datetime

    return {
        "code_fingerprint": code_fingerprint(code_digests(estimator)),
        "git_commit": git_commit(),
        "written_at": datetime.now(UTC).isoformat(timespec="microseconds"),
    }
