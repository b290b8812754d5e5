"""Compare two result tables (``results.csv`` or ``reports/published/*.csv``) within a tolerance.

Rows are matched on the job's key (protocol, source, activity, method, n_train, seed); numeric columns are
compared with ``|a - b| <= atol + rtol * |b|``, columns of JSON number lists (``per_angle_rms``) element by element
the same way, other text columns (e.g. the CV's chosen ``params``) for equality. Run-time, version and provenance
columns (fingerprint, commit, time written) are left out: they differ between runs by design.

    python -m bsrbench.reporting.compare A.csv B.csv [--atol 1e-9] [--rtol 0] [--columns error,coverage]

Prints one line per column that differs (rows differing, largest difference, the worst row) and exits 1 when
any row is missing from one table or differs beyond the tolerance, else 0.
"""

import argparse
import sys
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import DataFileError, InputError

KEY = ("protocol", "source", "activity", "method", "n_train", "seed")
IGNORED = (
    "cv_seconds",
    "fit_seconds",
    "predict_seconds",
    "versions",
    "code_fingerprint",
    "git_commit",
    "written_at",
)


@dataclass
class Comparison:
    """What :func:`compare_tables` found: rows only in one table, and per column the rows that differ."""

    only_a: list = field(default_factory=list)
    only_b: list = field(default_factory=list)
    columns: dict = field(
        default_factory=dict
    )  # column -> (n rows differing, largest |a - b|, worst key)
    n_rows: int = 0

    @property
    def equal(self):
        return not (self.only_a or self.only_b or self.columns)


def _read(path):
    try:
        df = pd.read_csv(path, keep_default_na=True)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise DataFileError(path, f"cannot be read as a results table ({exc})") from None
    missing = [k for k in KEY if k not in df.columns]
    if missing:
        raise DataFileError(path, f"has no column(s) {missing}; a results table has {list(KEY)}")
    dup = df.duplicated(list(KEY))
    if dup.any():
        row = df.loc[dup.idxmax(), list(KEY)].to_dict()
        raise DataFileError(path, f"has two rows for the job {row} (line {int(dup.idxmax()) + 2})")
    return df.set_index(list(KEY))


def compare_tables(a, b, *, atol=1e-9, rtol=0.0, columns=None):
    """Compare the results tables at paths ``a`` and ``b``; return a :class:`Comparison`."""
    return compare_frames(_read(a), _read(b), atol=atol, rtol=rtol, columns=columns)


def _number_lists(x):
    """The JSON number lists of the text column ``x`` as a 2-D float array (NaN-padded), or None when a value is
    not such a list."""
    import json

    out = []
    for v in x:
        if not isinstance(v, str) or not v.startswith("["):
            return None
        try:
            a = json.loads(v)
        except ValueError:
            return None
        if not all(isinstance(e, (int, float)) or e is None for e in a):
            return None
        out.append([np.nan if e is None else float(e) for e in a])
    width = max((len(a) for a in out), default=0)
    return np.array([a + [np.nan] * (width - len(a)) for a in out], dtype=float).reshape(
        len(out), width
    )


def _numeric_bad(xv, yv, atol, rtol):
    """Per row: whether ``xv`` and ``yv`` (rows of numbers) differ beyond the tolerance, and the largest
    difference."""
    both_nan = np.isnan(xv) & np.isnan(yv)
    diff = np.where(both_nan, 0.0, np.abs(xv - yv))
    tol = atol + rtol * np.nan_to_num(np.abs(yv))
    bad = ~(diff <= tol)  # a NaN on one side only counts as a difference
    diff = np.where(np.isnan(diff), np.inf, diff)
    if diff.ndim == 2:
        return bad.any(axis=1), (diff.max(axis=1) if diff.shape[1] else np.zeros(len(diff)))
    return bad, diff


def compare_frames(A, B, *, atol=1e-9, rtol=0.0, columns=None):
    """Compare two results tables indexed by the job's key (:data:`KEY`); return a :class:`Comparison`."""
    if not (atol >= 0 and rtol >= 0):
        raise InputError(f"atol and rtol must be >= 0; got atol={atol!r}, rtol={rtol!r}")
    out = Comparison(
        only_a=sorted(map(tuple, A.index.difference(B.index))),
        only_b=sorted(map(tuple, B.index.difference(A.index))),
    )
    common = A.index.intersection(B.index)
    out.n_rows = len(common)
    shared = [c for c in A.columns if c in B.columns and c not in IGNORED]
    if columns is not None:
        unknown = [c for c in columns if c not in shared]
        if unknown:
            raise InputError(
                f"--columns {unknown}: not columns of both tables; they share {shared}"
            )
        shared = list(columns)
    A, B = A.loc[common], B.loc[common]
    for c in shared:
        x, y = A[c], B[c]
        numeric = pd.api.types.is_numeric_dtype(x) and pd.api.types.is_numeric_dtype(y)
        lists = None if numeric else (_number_lists(x), _number_lists(y))
        if numeric or (
            lists[0] is not None and lists[1] is not None and lists[0].shape == lists[1].shape
        ):
            xv, yv = (x.to_numpy(float), y.to_numpy(float)) if numeric else lists
            bad, diff = _numeric_bad(xv, yv, atol, rtol)
            if bad.any():
                worst = int(np.argmax(np.where(bad, diff, -1.0)))
                out.columns[c] = (int(bad.sum()), float(diff[worst]), tuple(common[worst]))
        else:
            bad = ~((x.astype(str) == y.astype(str)) | (x.isna() & y.isna())).to_numpy()
            if bad.any():
                worst = int(np.argmax(bad))
                out.columns[c] = (int(bad.sum()), None, tuple(common[worst]))
    return out


def _key(key):
    return {k: (v.item() if hasattr(v, "item") else v) for k, v in zip(KEY, key)}


def main(argv=None):
    p = argparse.ArgumentParser(
        prog="python -m bsrbench.reporting.compare", description=__doc__.split("\n")[0]
    )
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--atol", type=float, default=1e-9, help="absolute tolerance (default 1e-9)")
    p.add_argument("--rtol", type=float, default=0.0, help="relative tolerance (default 0)")
    p.add_argument("--columns", type=lambda s: [c for c in s.split(",") if c], default=None)
    args = p.parse_args(argv)
    try:
        res = compare_tables(args.a, args.b, atol=args.atol, rtol=args.rtol, columns=args.columns)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(
        f"{res.n_rows} rows in both tables; {len(res.only_a)} only in {args.a}, {len(res.only_b)} only in {args.b}"
    )
    for key in res.only_a[:5]:
        print(f"  only in {args.a}: {_key(key)}")
    for key in res.only_b[:5]:
        print(f"  only in {args.b}: {_key(key)}")
    for c, (n, d, key) in res.columns.items():
        size = "" if d is None else f", largest difference {d:.3g}"
        print(f"  {c}: {n} rows differ{size} (e.g. {_key(key)})")
    print("equal within tolerance" if res.equal else "DIFFERENT")
    return 0 if res.equal else 1


if __name__ == "__main__":
    sys.exit(main())
