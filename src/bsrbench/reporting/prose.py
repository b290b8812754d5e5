"""Numbers in prose that come from the published tables, generated from them so that none goes stale.

A sentence of the README, of ``docs/`` or of a configuration comment keeps its words by hand and takes each number
from a published table through an inline marker, invisible in rendered markdown::

    PM beats 1-NN in <!-- n:paper.pm_beats_nn -->5<!-- /n --> cells.

The text between the markers is the value of the named claim (:data:`CLAIMS`, a function of the published tables,
:class:`Book`). ``python -m bsrbench.reporting.published prose`` lists every marker whose text differs from its
claim's value today (exit 1), ``--update`` rewrites them; the test suite runs the check, so a regenerated table
that moves a number, or a number edited by hand, fails until the text is regenerated.
"""

import re
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataFileError, InputError
from ..io import atomic_path

ROOT = Path(__file__).resolve().parents[3]
#: The files whose prose may hold markers: the README, the documents, the configuration comments.
FILES = ("README.md", "docs/*.md", "config/*.yaml")
MARKER = re.compile(r"<!-- n:([A-Za-z0-9_.-]+) -->(.*?)<!-- /n -->", re.S)


class Book:
    """The published tables, read once when first asked for (``reports/published`` of ``root``)."""

    def __init__(self, root=ROOT):
        self.root = Path(root)

    def _read(self, name):
        from .tables import read_results

        return read_results(self.root / "reports" / "published" / name)

    @cached_property
    def paper(self):
        return self._read("paper.csv")

    @cached_property
    def comparisons(self):
        return pd.read_csv(self.root / "reports" / "published" / "paper-comparisons.csv")

    @cached_property
    def mechanisms(self):
        return self._read("ablation-mechanisms.csv")

    @cached_property
    def ablation(self):
        return self._read("ablation.csv")

    @cached_property
    def reconcile(self):
        return self._read("reconcile.csv")

    @cached_property
    def reconcile_summary(self):
        """:func:`.reconcile.summary` of reconcile.csv and its nearest variant."""
        from . import reconcile

        s = reconcile.summary(
            reconcile.published_cells(
                self.root / "reports" / "published" / "reconcile.csv",
                self.root / "resources" / "paper-tables.csv",
            )
        )
        return s, reconcile.nearest(s)[0]

    @cached_property
    def verdict(self):
        return pd.read_csv(self.root / "reports" / "published" / "paper-verdict.csv")

    @cached_property
    def paper_tables(self):
        from .tables import read_paper_tables

        return read_paper_tables(self.root / "resources" / "paper-tables.csv")

    def cells(self, protocol="random"):
        """Cell means of paper.csv: (source, activity, paper_activity, n_train) x method."""
        d = self.paper[self.paper["protocol"] == protocol]
        return (
            d.groupby(["source", "activity", "paper_activity", "n_train", "method"])["error"]
            .mean()
            .unstack()
        )


# ------------------------------------------------------------------------------------------------ formats
def fmt(x, digits=2):
    return f"{x:.{digits}f}"


def pct(x):
    return f"{100 * x:.0f}%"


def span(values, digits=2, sep="-"):
    """``lo-hi`` of ``values`` at ``digits`` decimals (one value when they round alike)."""
    lo, hi = fmt(min(values), digits), fmt(max(values), digits)
    return lo if lo == hi else f"{lo}{sep}{hi}"


# ------------------------------------------------------------------------------------------------ claims
#: {name: function(Book) -> str}; filled by :func:`claim`.
CLAIMS = {}


def claim(name):
    def register(f):
        if name in CLAIMS:
            raise ValueError(f"claim {name!r} defined twice")
        CLAIMS[name] = f
        return f

    return register


def _paper_ratio(book, source):
    """Our error over the paper's per tuned baseline (median over the cells), the baselines' range."""
    from ..paper import PAPER_METHODS

    w = book.cells()
    w = w[w.index.get_level_values("source") == source]
    pt = book.paper_tables.set_index(["key", "n_train", "method"])["mean_deg"]
    from .tables import paper_key

    out = []
    for m in [m for m in PAPER_METHODS if m != "PM"]:
        r = [
            w.loc[idx, m] / pt[(paper_key(idx[2]), idx[3], m)]
            for idx in w.index
            if (paper_key(idx[2]), idx[3], m) in pt.index
        ]
        out.append(float(np.median(r)))
    return out


@claim("paper.cells")
def _(book):
    return str(len(book.cells()))


@claim("paper.pm_beats_nn")
def _(book):
    w = book.cells()
    return str(int((w["PM"] < w["NN1"]).sum()))


@claim("paper.ratio_hsc")
def _(book):
    return span(_paper_ratio(book, "hsc"))


@claim("paper.ratio_mocap")
def _(book):
    return span(_paper_ratio(book, "mocap"))


def _mean_by_source(book, column, method, source):
    d = book.paper[(book.paper["protocol"] == "random") & (book.paper["source"] == source)]
    cells = d.groupby(["activity", "n_train", "method"])[column].mean().unstack()
    return float(cells[method].mean())


for _source, _methods in (("hsc", ("SR", "TGP", "RVM", "Ridge", "NN1")), ("mocap", ("SR", "TGP"))):
    for _method in _methods:
        CLAIMS[f"paper.mpjpe.{_method}.{_source}"] = lambda book, m=_method, s=_source: fmt(
            _mean_by_source(book, "mpjpe_mm", m, s), 1
        )
for _source in ("hsc", "mocap"):
    CLAIMS[f"paper.coverage.PM.{_source}"] = lambda book, s=_source: pct(
        _mean_by_source(book, "coverage_90", "PM", s)
    )
    CLAIMS[f"paper.conformal.PM.{_source}"] = lambda book, s=_source: pct(
        _mean_by_source(book, "conformal_coverage", "PM", s)
    )


# ------------------------------------------------------------------------------------------- paper.csv, prose
BASELINES = ("RVM", "TGP", "SR", "DDL")


@claim("paper.pm_beats_all_baselines")
def _(book):
    w = book.cells()
    n = int((w["PM"].to_numpy()[:, None] < w[list(BASELINES)].to_numpy()).all(axis=1).sum())
    return "none" if n == 0 else str(n)


@claim("paper.pm_beats_nn_cells")
def _(book):
    w = book.cells()
    idx = w.index[w["PM"] < w["NN1"]]
    return ", ".join(f"{s} {a.replace('_', ' ')} N = {n}" for s, a, _, n in idx)


@claim("paper.nn_minus_pm_n60")
def _(book):
    w = book.cells()
    d = (w["PM"] - w["NN1"]).groupby(level="n_train").median()
    d = d[d.index >= 60]
    return f"{min(d):+.1f} to {max(d):+.1f}"


@claim("paper.ratio_pm_hsc")
def _(book):
    from .tables import paper_key

    w = book.cells()
    w = w[w.index.get_level_values("source") == "hsc"]
    pt = book.paper_tables.set_index(["key", "n_train", "method"])["mean_deg"]
    r = [w.loc[i, "PM"] / pt[(paper_key(i[2]), i[3], "PM")] for i in w.index]
    return fmt(float(np.median(r)))


@claim("paper.golf_pm")
def _(book):
    w = book.cells()
    g = w.xs(("hsc", "golf"), level=("source", "activity"))["PM"].droplevel("paper_activity")
    first, *rest = [fmt(v, 1) for v in g.sort_index()]
    ns = [str(n) for n in g.sort_index().index]
    return f"{first} at N = {ns[0]}, {', '.join(rest[:-1])} and {rest[-1]} at N = {', '.join(ns[1:-1])} and {ns[-1]}"


@claim("paper.pm_mpjpe_highest")
def _(book):
    d = book.paper[book.paper["protocol"] == "random"]
    m = d.groupby(["source", "method"])["mpjpe_mm"].mean().unstack()
    top = [s for s in m.index if m.loc[s].idxmax() == "PM"]
    return " and ".join(f"on {s}" for s in top) or "on no source"


def _ranks(book, source):
    w = book.cells()
    w = w[w.index.get_level_values("source") == source]
    return w.rank(axis=1).mean()


@claim("paper.rank.KRR.hsc")
def _(book):
    return fmt(_ranks(book, "hsc")["KRR"], 1)


@claim("paper.rank.KRR.mocap")
def _(book):
    r = _ranks(book, "mocap")
    return fmt(r["KRR"], 1) + (" and first" if r.idxmin() == "KRR" else "")


@claim("paper.conformal_range")
def _(book):
    d = book.paper[(book.paper["protocol"] == "random") & book.paper["conformal_coverage"].notna()]
    m = d.groupby(["source", "method"])["conformal_coverage"].mean() * 100
    lo, hi = f"{m.min():.0f}", f"{m.max():.0f}"
    return f"{lo}%" if lo == hi else f"{lo}-{hi}%"


@claim("paper.uncertainty_table")
def _(book):
    from ..methods import configured

    labels = {m: r.label for m, r in configured("paper").items()}
    d = book.paper[book.paper["protocol"] == "random"]
    rows = []
    for source in ("hsc", "mocap"):
        for m in ("RVM", "PM", "GP"):
            g = d[(d["source"] == source) & (d["method"] == m)]
            nlpd = float(g["nlpd"].mean())
            conf = g["conformal_coverage"].mean()
            cells = [
                source,
                labels.get(m, m),
                fmt(g["error"].mean()),
                f"{nlpd:.1e}" if nlpd >= 1e3 else fmt(nlpd),
                fmt(g["nlpd"].median()),
                fmt(g["crps"].mean()),
                fmt(g["coverage_90"].mean()),
                "--" if not np.isfinite(conf) else fmt(conf),
            ]
            rows.append("  | " + " | ".join(cells) + " |")
    head = (
        "  | source | method | error (deg) | NLPD (mean) | NLPD (median) | CRPS (deg) | 90% coverage "
        "| split-conformal 90% |\n  |---|---|---|---|---|---|---|---|\n"
    )
    return "\n\n" + head + "\n".join(rows) + "\n\n  "


@claim("paper.nt_over_n_max")
def _(book):
    d = book.paper[book.paper["protocol"] == "random"]
    return fmt(float((0.1 + d["n_test"] / d["n_train"]).max()), 1)


@claim("paper.ci_widening_max")
def _(book):
    c = book.comparisons
    r = (c["ci_high"] - c["ci_low"]) / (c["paired_ci_high"] - c["paired_ci_low"])
    return fmt(float(r.max()), 1)


@claim("paper.motions")
def _(book):
    v = book.verdict
    return str(int(v[(v["unit"] == "motion") & (v["scope"] == "all")]["n_blocks"].max()))


@claim("paper.motion_p")
def _(book):
    v = book.verdict
    n = int(v[(v["unit"] == "motion") & (v["scope"] == "all")]["n_blocks"].max())
    return f"1/{2**n}"


# -------------------------------------------------------------------------------------------- reconcile.csv
def _reconcile_ratios(book, splits, method=None, nearest=False):
    s, best = book.reconcile_summary
    s = s[s["splits"] == splits]
    if nearest:
        for f in ("frames", "setting", "metric"):
            s = s[s[f] == best[f]]
    s = s[s["method"] == method] if method else s[s["method"] != "1-NN"]
    return span(s["median_ratio"].astype(float))


@claim("reconcile.rows")
def _(book):
    return f"{len(book.reconcile):,}"


@claim("reconcile.random_baselines")
def _(book):
    return _reconcile_ratios(book, "random")


@claim("reconcile.random_nn")
def _(book):
    return _reconcile_ratios(book, "random", "1-NN")


@claim("reconcile.nearest_baselines")
def _(book):
    return _reconcile_ratios(book, book.reconcile_summary[1]["splits"], nearest=True)


@claim("reconcile.blocked_nn")
def _(book):
    return _reconcile_ratios(book, "blocked", "1-NN")


# ------------------------------------------------------------------------------------------------ files
def files(root=ROOT):
    """The files that may hold markers (:data:`FILES`), sorted."""
    out = set()
    for pattern in FILES:
        out.update(Path(root).glob(pattern))
    return sorted(out)


def markers(path):
    """``[(line, name, text)]`` of the markers of ``path``."""
    text = Path(path).read_text(encoding="utf-8")
    return [
        (text.count("\n", 0, m.start()) + 1, m.group(1), m.group(2)) for m in MARKER.finditer(text)
    ]


def values(names, book):
    """{name: today's value} of the claims ``names``; InputError naming an unknown claim."""
    unknown = sorted(set(names) - set(CLAIMS))
    if unknown:
        raise InputError(
            f"unknown claims {unknown}; bsrbench.reporting.prose.CLAIMS defines {len(CLAIMS)}"
        )
    return {n: CLAIMS[n](book) for n in sorted(set(names))}


def check(paths=None, book=None, root=ROOT):
    """``[(path, line, name, written, today)]`` of the markers whose text is not their claim's value today."""
    paths = files(root) if paths is None else paths
    book = book or Book(root)
    found = [(p, *m) for p in paths for m in markers(p)]
    now = values([n for *_, n, _ in found], book)
    return [(p, line, n, t, now[n]) for p, line, n, t in found if t != now[n]]


def update(paths=None, book=None, root=ROOT):
    """Rewrite every marker of ``paths`` with its claim's value today; the files changed."""
    paths = files(root) if paths is None else paths
    book = book or Book(root)
    changed = []
    for p in paths:
        text = Path(p).read_text(encoding="utf-8")
        now = values([m.group(1) for m in MARKER.finditer(text)], book)
        new = MARKER.sub(
            lambda m, now=now: f"<!-- n:{m.group(1)} -->{now[m.group(1)]}<!-- /n -->", text
        )
        if new != text:
            try:
                with atomic_path(p) as tmp:
                    Path(tmp).write_text(new, encoding="utf-8")
            except OSError as exc:
                raise DataFileError(p, f"cannot be written ({exc.strerror})") from None
            changed.append(p)
    return changed


def used(root=ROOT):
    """The claims that some file's marker names."""
    return {n for p in files(root) for _, n, _ in markers(p)}


def run_command(args):
    """``prose``: list the markers that differ from their claims (exit 1), or ``--update`` them (exit 0)."""
    import sys

    if args.update:
        for p in update():
            print(f"{p}: updated", file=sys.stderr)
        return 0
    bad = check()
    for p, line, name, written, today in bad:
        print(f"{p}:{line}: {name} is {written!r} in the text, {today!r} from the tables today")
    n = sum(len(markers(p)) for p in files())
    print(
        f"{n} numbers from the published tables in {len(files())} files; {len(bad)} differ",
        file=sys.stderr,
    )
    return 1 if bad else 0


__all__ = ["CLAIMS", "Book", "check", "claim", "markers", "update", "used"]
