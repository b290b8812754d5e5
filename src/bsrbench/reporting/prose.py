"""Numbers in prose that come from the published tables, generated from them so that none goes stale.

A sentence of the README, of ``docs/`` or of a configuration comment keeps its words by hand and takes each number
from a published table through an inline marker, invisible in rendered markdown::

    PM beats 1-NN in <!-- n:paper.pm_beats_nn -->5<!-- /n --> cells.

The text between the markers is the value of the named claim (:data:`CLAIMS`, a function of the published tables,
:class:`Book`). ``python -m bsrbench.reporting.published prose`` lists every marker whose text differs from its
claim's value today (exit 1), ``--update`` rewrites them; the test suite runs the check, so a regenerated table
that moves a number, or a number edited by hand, fails until the text is regenerated. Where a number's words
depend on its value ("the highest", "none"), the claim returns the words too. A marker that is not closed, a tag
that is almost a marker's (``<!--n:x-->``, ``<!-- /n-->``) and an unknown claim are refused, naming the file and
line: a marker the parser skipped would leave its number unchecked.

Numbers that no published table holds (a run's wall time, a measurement against an older table) stay hand-written
and say which run or which table they describe.
"""

import json
import re
from functools import cached_property
from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError

ROOT = Path(__file__).resolve().parents[3]
#: The files whose prose may hold markers: the README, the documents, the configuration comments.
FILES = ("README.md", "docs/*.md", "config/*.yaml")
MARKER = re.compile(r"<!-- n:([A-Za-z0-9_.-]+) -->(.*?)<!-- /n -->", re.S)
#: What looks like a marker's opening or closing tag (``<!--n:x-->``, ``<!-- n: x -->``, ``<!-- /n-->``, ...): each
#: must be exactly one of :data:`MARKER`'s, or its number would go unchecked.
TAG = re.compile(r"<!--\s*/?\s*n\b[^>\n]*>?")
OPEN = re.compile(r"<!-- n:([A-Za-z0-9_.-]+) -->")
CLOSE = "<!-- /n -->"


class Book:
    """The published tables (``reports/published`` of ``root``) and the summaries the claims share, each read or
    computed once when first asked for."""

    def __init__(self, root=ROOT):
        self.root = Path(root)

    def path(self, name):
        return self.root / "reports" / "published" / name

    def _read(self, name):
        from .tables import read_results

        return read_results(self.path(name))

    # ----------------------------------------------------------------------------------------- the tables
    @cached_property
    def paper(self):
        return self._read("paper.csv")

    @cached_property
    def comparisons(self):
        from .comparisons import read_comparisons

        return read_comparisons(self.path("paper-comparisons.csv"))

    @cached_property
    def verdict(self):
        from .verdict import read_verdict

        return read_verdict(self.path("paper-verdict.csv"))

    @cached_property
    def ablation(self):
        return self._read("ablation.csv")

    @cached_property
    def goal(self):
        return self._read("paper-goal.csv")

    @cached_property
    def crosstrial(self):
        return self._read("ablation-crosstrial.csv")

    @cached_property
    def mechanisms(self):
        return self._read("ablation-mechanisms.csv")

    @cached_property
    def reconcile(self):
        return self._read("reconcile.csv")

    @cached_property
    def reconcile_pm(self):
        return self._read("reconcile-pm.csv")

    @cached_property
    def pmfair(self):
        """``(cells, {source: summaries}, across motions)`` of PM with a fair budget beside the headline PM
        (:func:`.budget.published_parts`)."""
        from .budget import published_parts

        return published_parts(
            self.path("paper-pmfair.csv"),
            self.path("paper.csv"),
            self.root / "resources" / "paper-tables.csv",
        )

    @cached_property
    def part_rows(self):
        """{part: rows} of the parts of published tables (``reports/published/parts/*.csv``)."""
        from ..io import read_csv

        parts = sorted(self.path("parts").glob("*.csv"))
        return {p.stem: len(read_csv(p, "a part of a published table")) for p in parts}

    @cached_property
    def paper_tables(self):
        from .tables import read_paper_tables

        return read_paper_tables(self.root / "resources" / "paper-tables.csv")

    @cached_property
    def labels(self):
        """{method: label} of the studies' registries (the paper's labels where two studies name a method)."""
        from ..methods import configured

        studies = ("ablation-mechanisms", "ablation", "paper")
        return {m: r.label for s in studies for m, r in configured(s).items()}

    # ------------------------------------------------------------------------------------ shared summaries
    def cells(self, protocol="random"):
        """Cell means of paper.csv: (source, activity, paper_activity, n_train) x method."""
        d = self.paper[self.paper["protocol"] == protocol]
        return (
            d.groupby(["source", "activity", "paper_activity", "n_train", "method"])["error"]
            .mean()
            .unstack()
        )

    @cached_property
    def reconcile_summary(self):
        """:func:`.reconcile.summary` of reconcile.csv and its nearest variant."""
        from . import reconcile

        s = reconcile.summary(
            reconcile.published_cells(
                self.path("reconcile.csv"), self.root / "resources" / "paper-tables.csv"
            )
        )
        return s, reconcile.nearest(s)[0]

    @cached_property
    def ablation_goal(self):
        """:func:`.ablation.goal_table` of ablation.csv: per variant, the cells converged, below 1-NN and both."""
        from .ablation import goal_table

        return goal_table(self.ablation, variants=chained(self.ablation)).set_index("method")

    @cached_property
    def ablation_best(self):
        """:func:`.ablation.ablation_cells` of ablation.csv: per cell the best variant, 1-NN and the best
        baseline."""
        from .ablation import ablation_cells

        return ablation_cells(self.ablation, variants=chained(self.ablation))

    @cached_property
    def mechanism_tables(self):
        """``(table, pooled, fit)`` of ablation-mechanisms.csv (:mod:`.mechanisms`): each variant against PM per
        cell, the differences averaged over the activities per N, the training and test errors."""
        from . import mechanisms as mech

        df = self.mechanisms
        variants = mech.variants_from_results(df, base="PM")
        table = mech.mechanism_table(df, None, base="PM", variants=variants)
        return table, mech.pooled_by_n(table), mech.fit_table(df, base="PM", variants=variants)


# ------------------------------------------------------------------------------------------------ formats
def fmt(x, digits=2):
    return f"{x:.{digits}f}"


def pct(x):
    return f"{100 * x:.0f}%"


def span(values, digits=2, sep="-"):
    """``lo-hi`` of ``values`` at ``digits`` decimals (one value when they round alike)."""
    lo, hi = fmt(min(values), digits), fmt(max(values), digits)
    return lo if lo == hi else f"{lo}{sep}{hi}"


def pct_span(fractions):
    """``lo-hi%`` of fractions as whole percentages (one value when they round alike)."""
    return span([100 * f for f in fractions], 0) + "%"


def join(items):
    """``a``, ``a and b``, ``a, b and c``."""
    items = [str(i) for i in items]
    return " and ".join(items) if len(items) < 3 else ", ".join(items[:-1]) + " and " + items[-1]


def count(n, of=None):
    """``n``, or ``n of the m``."""
    return str(int(n)) if of is None else f"{int(n)} of the {int(of)}"


def activity(a):
    return str(a).replace("_", " ")


def cells_text(cells):
    """``acrobatics and run at N = 30; golf at N = 30 and 60`` of (activity, N) pairs; ``none`` for none."""
    ns = {}
    for a, n in cells:
        ns.setdefault(a, []).append(int(n))
    groups = {}
    for a, n in sorted(ns.items(), key=lambda x: (sorted(x[1]), x[0])):
        groups.setdefault(tuple(sorted(n)), []).append(activity(a))
    return "; ".join(f"{join(acts)} at N = {join(n)}" for n, acts in groups.items()) or "none"


def chained(df):
    """The methods of a table run with several chains per split (the PM variants of an ablation)."""
    return sorted(set(df.loc[df["n_chains"].fillna(1) > 1, "method"]))


def converged(rows):
    """Per row: R-hat below :data:`.convergence.RHAT_OK` on the log-likelihood and g_xy."""
    from .convergence import converged as ok

    return ok(rows)


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


def claims(pattern, keys, f):
    """Register ``f(book, *key)`` as the claim ``pattern.format(*key)`` for each key."""
    for key in keys:
        key = key if isinstance(key, tuple) else (key,)
        claim(pattern.format(*key))(lambda book, key=key: f(book, *key))


# ----------------------------------------------------------------------------- paper.csv: the paper's claim
def _paper_ratio(book, source):
    """Our error over the paper's per tuned baseline (median over the cells), the baselines' range."""
    from ..paper import PAPER_METHODS
    from .tables import paper_key

    w = book.cells()
    w = w[w.index.get_level_values("source") == source]
    pt = book.paper_tables.set_index(["key", "n_train", "method"])["mean_deg"]
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


@claim("paper.cells.mocap")
def _(book):
    return str(int((book.cells().index.get_level_values("source") == "mocap").sum()))


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
    return ", ".join(f"{s} {activity(a)} N = {n}" for s, a, _, n in idx)


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
    return f"{first} at N = {ns[0]}, {join(rest)} at N = {join(ns[1:])}"


# ---------------------------------------------------------------------- paper.csv: the tests, the verdict
@claim("paper.nt_over_n_max")
def _(book):
    d = book.paper[book.paper["protocol"] == "random"]
    return fmt(float((0.1 + d["n_test"] / d["n_train"]).max()), 1)


@claim("paper.ci_widening_max")
def _(book):
    c = book.comparisons
    r = (c["ci_high"] - c["ci_low"]) / (c["paired_ci_high"] - c["paired_ci_low"])
    return fmt(float(r.max()), 1)


def _motions(book):
    v = book.verdict
    return int(v[(v["unit"] == "motion") & (v["scope"] == "all")]["n_blocks"].max())


@claim("paper.motions")
def _(book):
    return str(_motions(book))


@claim("paper.motion_p")
def _(book):
    from .verdict import smallest_p

    return f"1/{round(1 / smallest_p(_motions(book), 1))}"


# ------------------------------------------------------------------- paper.csv: today's metrics and baselines
def _mean_by_source(book, column, method, source):
    d = book.paper[(book.paper["protocol"] == "random") & (book.paper["source"] == source)]
    cells = d.groupby(["activity", "n_train", "method"])[column].mean().unstack()
    return float(cells[method].mean())


claims(
    "paper.mpjpe.{0}.{1}",
    [("SR", "hsc"), ("TGP", "hsc"), ("RVM", "hsc"), ("Ridge", "hsc"), ("NN1", "hsc")]
    + [("SR", "mocap"), ("TGP", "mocap")],
    lambda book, m, s: fmt(_mean_by_source(book, "mpjpe_mm", m, s), 1),
)
claims(
    "paper.coverage.PM.{0}",
    ["hsc", "mocap"],
    lambda book, s: pct(_mean_by_source(book, "coverage_90", "PM", s)),
)
claims(
    "paper.conformal.PM.{0}",
    ["hsc", "mocap"],
    lambda book, s: pct(_mean_by_source(book, "conformal_coverage", "PM", s)),
)


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


@claim("paper.rank.RF_MLP")
def _(book):
    return span([_ranks(book, s)[m] for s in ("hsc", "mocap") for m in ("RF", "MLP")], 0)


@claim("paper.behind_RF_MLP")
def _(book):
    """The methods whose mean rank is behind both the random forest's and the MLP's, per source."""
    per = {}
    for s in ("hsc", "mocap"):
        r = _ranks(book, s)
        behind = r[r > r[["RF", "MLP"]].max()].sort_values()
        per[s] = join(book.labels.get(m, m) for m in behind.index) or "none"
    if len(set(per.values())) == 1:
        (only,) = set(per.values())
        return f"{only} only" if " and " not in only else only
    return " and of ".join(
        f"{v}{' only' if ' and ' not in v else ''} on {s}" for s, v in per.items()
    )


def _uncertainty(book):
    """Per (source, method) of the methods with a predictive distribution: the means of the scores."""
    d = book.paper[(book.paper["protocol"] == "random") & book.paper["crps"].notna()]
    return d.groupby(["source", "method"])[["crps", "coverage_90"]].mean()


def _per_source(book, best):
    """The label of ``best(scores of a source)``, once if it is the same on both sources."""
    u = _uncertainty(book)
    found = {s: book.labels.get(best(u.xs(s)), best(u.xs(s))) for s in ("hsc", "mocap")}
    if len(set(found.values())) == 1:
        return f"{found['hsc']}, on both sources"
    return ", ".join(f"{m} on {s}" for s, m in found.items())


@claim("paper.best_crps")
def _(book):
    return _per_source(book, lambda u: u["crps"].idxmin())


@claim("paper.best_coverage")
def _(book):
    return _per_source(book, lambda u: (u["coverage_90"] - 0.9).abs().idxmin())


@claim("paper.conformal_range")
def _(book):
    d = book.paper[(book.paper["protocol"] == "random") & book.paper["conformal_coverage"].notna()]
    m = d.groupby(["source", "method"])["conformal_coverage"].mean()
    return pct_span(m)


@claim("paper.uncertainty_table")
def _(book):
    d = book.paper[book.paper["protocol"] == "random"]
    rows = []
    for source in ("hsc", "mocap"):
        for m in ("RVM", "PM", "GP"):
            g = d[(d["source"] == source) & (d["method"] == m)]
            nlpd = float(g["nlpd"].mean())
            conf = g["conformal_coverage"].mean()
            cells = [
                source,
                book.labels.get(m, m),
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


def _golf200(book, method, column):
    d = book.paper
    d = d[(d["protocol"] == "random") & (d["source"] == "hsc") & (d["activity"] == "golf")]
    d = d[(d["n_train"] == 200) & (d["method"] == method)]
    return fmt(float(d[column].mean()), 1)


claims(
    "paper.golf200.{0}.{1}",
    [(m, c) for m in ("PM", "Ridge") for c in ("train", "test")],
    lambda book, m, c: _golf200(book, m, "train_error" if c == "train" else "error"),
)


# ------------------------------------------------------------------------ paper.csv: the study's shape
@claim("paper.rows")
def _(book):
    return f"{len(book.paper):,}"


@claim("paper.methods")
def _(book):
    return str(book.paper["method"].nunique())


@claim("paper.seeds")
def _(book):
    return str(book.paper["seed"].nunique())


@claim("paper.fit_jobs")
def _(book):
    """One fit job per (cell, method): the seeds of a cell run in one job."""
    return (
        f"{book.paper.groupby(['protocol', 'source', 'activity', 'n_train', 'method']).ngroups:,}"
    )


@claim("paper.cv_jobs")
def _(book):
    """One CV job per (cell, method) with a CV (``cv_seconds`` recorded)."""
    g = book.paper.groupby(["protocol", "source", "activity", "n_train", "method"])
    return f"{int(g['cv_seconds'].first().notna().sum()):,}"


# ------------------------------------------------- paper.csv: PM's CV choices (the mechanisms' fixed setting)
def _pm_choices(book, key):
    """PM's CV choice of ``key`` per hsc (activity, N) of paper.csv, and the value ablation-mechanisms.csv's PM
    is fixed at."""
    d = book.paper
    d = d[(d["protocol"] == "random") & (d["source"] == "hsc") & (d["method"] == "PM")]
    chosen = d.groupby(["activity", "n_train"])["params"].first().map(lambda p: json.loads(p)[key])
    m = book.mechanisms
    fixed = json.loads(m.loc[m["method"] == "PM", "params"].iloc[0])[key]
    return chosen, fixed


@claim("paper.cv.K_fixed_count")
def _(book):
    chosen, fixed = _pm_choices(book, "n_atoms")
    return count((chosen == fixed).sum(), len(chosen))


@claim("paper.cv.K_others")
def _(book):
    chosen, fixed = _pm_choices(book, "n_atoms")
    other = chosen[chosen != fixed]
    return (
        ", ".join(f"{k} for {activity(a)} N = {n}" for (a, n), k in other.items()) or "none other"
    )


@claim("paper.cv.j_fixed_count")
def _(book):
    chosen, fixed = _pm_choices(book, "n_neighbors")
    return count((chosen == fixed).sum())


@claim("paper.cv.j_others")
def _(book):
    chosen, fixed = _pm_choices(book, "n_neighbors")
    other = chosen[chosen != fixed].value_counts().sort_index()
    return ", ".join(f"{j} in {n}" for j, n in other.items()) or "none other"


# ------------------------------------------------------------------------------------------- ablation.csv
def _ablation_converged(book, method):
    rows = book.ablation[book.ablation["method"] == method]
    return float(converged(rows).mean())


@claim("ablation.rows")
def _(book):
    return f"{len(book.ablation):,}"


@claim("ablation.part_rows")
def _(book):
    """The rows of each activity's part (all equal, else each named)."""
    rows = {
        k[len("ablation-") :]: n for k, n in book.part_rows.items() if k.startswith("ablation-")
    }
    rows.pop("inexact", None)
    if len(set(rows.values())) == 1:
        return f"{next(iter(rows.values())):,} rows each"
    return ", ".join(f"{activity(a)} {n:,} rows" for a, n in rows.items())


@claim("ablation.inexact_rows")
def _(book):
    return f"{book.part_rows['ablation-inexact']:,}"


@claim("ablation.variants")
def _(book):
    return str(len(chained(book.ablation)))


@claim("ablation.cells")
def _(book):
    return str(len(book.ablation_best))


@claim("ablation.all_converged")
def _(book):
    """How many variants converged in every split, with the verb."""
    a = book.ablation
    a = a[a["method"].isin(chained(a))]
    n = int(converged(a).groupby(a["method"]).all().sum())
    return {0: "No variant has", 1: "One variant has"}.get(n, f"{n} variants have")


claims(
    "ablation.converged.{0}",
    ["PMK8", "PMK8s5000", "PMK8s5000text", "PMK16", "PMs5000", "PMtext"],
    lambda book, m: pct(_ablation_converged(book, m)),
)


@claim("ablation.converged.exact_k64")
def _(book):
    """The range of the converged splits over the exact variants with K >= 64 (the paper's grid)."""
    g = book.ablation_goal
    a = book.ablation
    k = a.groupby("method")["params"].first().map(lambda p: json.loads(p).get("n_atoms", 0))
    ms = [m for m in g.index if g.at[m, "exact"] and k[m] >= 64]
    return pct_span([_ablation_converged(book, m) for m in ms])


@claim("ablation.best_beats_nn")
def _(book):
    b = book.ablation_best
    return str(int((b["best_variant_error"] < b["nn_error"]).sum()))


@claim("ablation.best_beats_baseline")
def _(book):
    b = book.ablation_best
    return str(int((b["best_variant_error"] < b["best_baseline_error"]).sum()))


@claim("ablation.best_is.PMtext")
def _(book):
    return str(int((book.ablation_best["best_variant"] == "PMtext").sum()))


@claim("ablation.best_is.text_5000")
def _(book):
    """The cells whose best variant is the paper-text prediction with K = 8 or 16 and 5000 sweeps."""
    return str(
        int(book.ablation_best["best_variant"].isin(["PMK8s5000text", "PMK16s5000text"]).sum())
    )


@claim("ablation.goal_top")
def _(book):
    """The exact variant nearest the goal (:func:`.ablation.goal_table`'s first)."""
    g = book.ablation_goal
    return book.labels.get(g[g["exact"]].index[0], g[g["exact"]].index[0])


@claim("ablation.goal_top_both")
def _(book):
    g = book.ablation_goal
    return str(int(g[g["exact"]]["both"].iloc[0]))


claims(
    "ablation.goal.{1}.{0}",
    [(m, w) for m in ("PMK8", "PMK16s5000text") for w in ("converged", "beats_nn", "both")],
    lambda book, m, w: str(int(book.ablation_goal.at[m, w])),
)


# ----------------------------------------------------------------------------------------- paper-goal.csv
def _goal_cells(book, method, what):
    """The (activity, N) cells of paper-goal.csv where ``method`` is below 1-NN, has every split converged, or
    both."""
    g = book.goal
    means = g.groupby(["activity", "n_train", "method"])["error"].mean().unstack()
    below = means[method] < means["NN1"]
    rows = g[g["method"] == method]
    conv = converged(rows).groupby([rows["activity"], rows["n_train"]]).all()
    ok = {"below": below, "converged": conv, "both": below & conv}[what]
    return list(ok[ok].index)


GOAL_VARIANTS = ("PMK8", "PMK16s5000text")
claims(
    "goal.{1}.{0}",
    [(m, w) for m in GOAL_VARIANTS for w in ("below", "converged", "both")],
    lambda book, m, w: str(len(_goal_cells(book, m, w))),
)
claims(
    "goal.{1}_cells.{0}",
    [(m, w) for m in GOAL_VARIANTS for w in ("below", "converged", "both")],
    lambda book, m, w: cells_text(_goal_cells(book, m, w)),
)


@claim("goal.cells")
def _(book):
    return str(book.goal.groupby(["activity", "n_train"]).ngroups)


def _goal_nn(book):
    """1-NN's rows of paper-goal.csv beside the same splits' rows of paper.csv."""
    key = ["protocol", "source", "activity", "n_train", "seed"]
    g = book.goal[book.goal["method"] == "NN1"]
    p = book.paper[book.paper["method"] == "NN1"]
    return g.merge(p, on=key, how="left", suffixes=("", "_paper"))


@claim("goal.nn_rows")
def _(book):
    return str(len(_goal_nn(book)))


@claim("goal.nn_equal")
def _(book):
    m = _goal_nn(book)
    d = (m["error"] - m["error_paper"]).abs()
    where = "those of `reports/published/paper.csv`"
    if d.isna().any():
        return f"are not all in `reports/published/paper.csv` ({int(d.isna().sum())} missing)"
    return (
        f"equal {where} to the last digit"
        if d.max() == 0
        else f"differ from {where} by up to {d.max():.1e} deg"
    )


# ---------------------------------------------------------------------------------- ablation-crosstrial.csv
def _cross(book, n):
    """The cross-trial means at N = ``n``: variants, 1-NN, the baselines (Series each)."""
    x = book.crosstrial
    means = x[x["n_train"] == n].groupby("method")["error"].mean()
    variants = chained(x)
    baselines = [m for m in means.index if m not in variants and m != "NN1"]
    return means[variants], float(means["NN1"]), means[baselines]


@claim("crosstrial.variants")
def _(book):
    return str(len(chained(book.crosstrial)))


@claim("crosstrial.above_nn_names.30")
def _(book):
    v, nn, _ = _cross(book, 30)
    return join(book.labels.get(m, m) for m in v[v >= nn].index) or "none"


@claim("crosstrial.above_nn.30")
def _(book):
    v, nn, _ = _cross(book, 30)
    return ", ".join(f"{book.labels.get(m, m)} {fmt(e)}" for m, e in v[v >= nn].items()) or "none"


@claim("crosstrial.below_nn.30")
def _(book):
    v, nn, _ = _cross(book, 30)
    return span(v[v < nn]) if (v < nn).any() else "none"


claims("crosstrial.nn.{0}", [30, 100, 200], lambda book, n: fmt(_cross(book, n)[1]))
claims("crosstrial.best_variant.{0}", [100, 200], lambda book, n: fmt(_cross(book, n)[0].min()))


def _best_baseline(book, n):
    b = _cross(book, n)[2]
    return f"{book.labels.get(b.idxmin(), b.idxmin())} {fmt(b.min())}"


claims("crosstrial.best_baseline.{0}", [30, 100, 200], _best_baseline)


# ---------------------------------------------------------------------------------- ablation-mechanisms.csv
def _pooled(book, reason):
    table, pooled, _ = book.mechanism_tables
    methods = set(table.loc[table["reason"] == reason, "method"])
    return table[table["method"].isin(methods)], pooled[pooled["method"].isin(methods)]


@claim("mech.rows")
def _(book):
    return f"{len(book.mechanisms):,}"


@claim("mech.pose.max_change")
def _(book):
    return fmt(float(_pooled(book, "pose")[1]["mean_diff"].abs().max()))


@claim("mech.pose.intervals")
def _(book):
    p = _pooled(book, "pose")[1]
    out = int(((p["ci_low"] > 0) | (p["ci_high"] < 0)).sum())
    return "all contain zero" if out == 0 else f"exclude zero in {out} of {len(p)} cases"


@claim("mech.pose.comparisons")
def _(book):
    return str(len(_pooled(book, "pose")[0]))


@claim("mech.pose.significant")
def _(book):
    n = int(_pooled(book, "pose")[0]["verdict"].isin(["worse", "better"]).sum())
    return "none" if n == 0 else str(n)


@claim("mech.one.range")
def _(book):
    return span(_pooled(book, "averaging")[1]["mean_diff"], 1)


@claim("mech.one.above_zero")
def _(book):
    p = _pooled(book, "averaging")[1]
    ns = [str(int(n)) for n in p.loc[p["ci_low"] > 0, "n_train"]]
    return f"N = {join(ns)}" if ns else "no N"


@claim("mech.one.significant")
def _(book):
    return str(int(_pooled(book, "averaging")[0]["verdict"].isin(["worse", "better"]).sum()))


@claim("mech.one.cells")
def _(book):
    return str(len(_pooled(book, "averaging")[0]))


def _fit(book, method):
    fit = book.mechanism_tables[2]
    return fit[fit["method"] == method].set_index("n_train")


claims("mech.train.{0}", ["PM", "PMone"], lambda book, m: span(_fit(book, m)["train_error"], 1))
claims(
    "mech.gap.{0}.{1}",
    [(m, n) for m in ("PMone", "PM") for n in (30, 200)],
    lambda book, m, n: fmt(
        _fit(book, m).at[n, "test_error"] - _fit(book, m).at[n, "train_error"], 1
    ),
)


# -------------------------------------------------------------------------------------------- reconcile.csv
def _reconcile_variant(book, splits, nearest=False):
    s, best = book.reconcile_summary
    s = s[s["splits"] == splits]
    if nearest:
        for f in ("frames", "setting", "metric"):
            s = s[s[f] == best[f]]
    return s


def _reconcile_ratios(book, splits, method=None, nearest=False):
    s = _reconcile_variant(book, splits, nearest)
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


@claim("reconcile.nearest_nn")
def _(book):
    return _reconcile_ratios(book, book.reconcile_summary[1]["splits"], "1-NN", nearest=True)


@claim("reconcile.nearest_within")
def _(book):
    """The cells where a baseline's mean lies within the paper's std, under the nearest variant."""
    s = _reconcile_variant(book, book.reconcile_summary[1]["splits"], nearest=True)
    s = s[s["method"] != "1-NN"]
    return count(s["within"].sum(), s["cells"].sum())


@claim("reconcile.blocked_nn")
def _(book):
    return _reconcile_ratios(book, "blocked", "1-NN")


# ----------------------------------------------------------------------------------------- paper-pmfair.csv
def _pmfair(book, source, pm=None):
    """The summary of PM ``pm`` (default: the fair-budget PM, not the headline one) on ``source``'s cells."""
    from .reconcile import PM

    by_name = {r["method"]: r for r in book.pmfair[1][source]}
    (fair,) = [n for n in by_name if n != PM]
    return by_name[pm or fair]


def _pmfair_cells(book, source):
    c = book.pmfair[0]
    return c[c["source"] == source]


_SOURCES = ("hsc", "mocap")
claims("paper_pmfair.{}.error.PM", _SOURCES, lambda book, s: fmt(_pmfair(book, s, "PM")["error"]))
claims("paper_pmfair.{}.error.fair", _SOURCES, lambda book, s: fmt(_pmfair(book, s)["error"]))
claims(
    "paper_pmfair.{}.ratio",
    _SOURCES,
    lambda book, s: fmt(float(np.median(_pmfair(book, s)["ratios"]))),
)
claims(
    "paper_pmfair.{}.vs_pm",
    _SOURCES,
    lambda book, s: count(
        (_pmfair_cells(book, s)["fair_vs_pm"] == "better").sum(), len(_pmfair_cells(book, s))
    ),
)
claims(
    "paper_pmfair.{}.b1",
    _SOURCES,
    lambda book, s: count(
        _pmfair_cells(book, s)["choice"].str.endswith(", b 1").sum(), len(_pmfair_cells(book, s))
    ),
)
claims(
    "paper_pmfair.{}.beats_nn",
    _SOURCES,
    lambda book, s: count(_pmfair(book, s)["counts"]["1-NN"][0], _pmfair(book, s)["cells"]),
)
claims(
    "paper_pmfair.{}.worse_sr",
    _SOURCES,
    lambda book, s: count(_pmfair(book, s)["counts"]["SR"][2], _pmfair(book, s)["cells"]),
)
claims(
    "paper_pmfair.{}.converged",
    _SOURCES,
    lambda book, s: count(
        _pmfair_cells(book, s)["converged"].sum(), _pmfair_cells(book, s)["splits"].sum()
    ),
)


@claim("paper_pmfair.motions")
def _(book):
    return str(int(book.pmfair[2]["n_blocks"].iloc[0]))


@claim("paper_pmfair.motions_vs_sr")
def _(book):
    """The fair PM minus SR over the motions, with its bootstrap interval."""
    r = book.pmfair[2].loc["SR"]
    return f"{r['mean_diff']:+.2f} [{r['diff_ci_low']:+.2f}, {r['diff_ci_high']:+.2f}]"


# ----------------------------------------------------------------------------------------- reconcile-pm.csv
def _disagree(book, method):
    """The share of ``method``'s splits of reconcile-pm.csv whose chains disagree (split R-hat of the test error
    above :data:`.convergence.RHAT_STRICT`)."""
    from .convergence import RHAT_STRICT

    r = book.reconcile_pm
    return pct(float((r.loc[r["method"] == method, "r_hat_test_error"] > RHAT_STRICT).mean()))


claims("reconcile_pm.disagree.{0}", ["PM", "PMfair"], _disagree)


# ------------------------------------------------------------------------------------------------ files
def files(root=ROOT):
    """The files that may hold markers (:data:`FILES`), sorted."""
    out = set()
    for pattern in FILES:
        out.update(Path(root).glob(pattern))
    return sorted(out)


def _read_text(path):
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise DataFileError(path, f"cannot be read ({why}); expected a UTF-8 text file") from None


def markers(path):
    """``[(line, name, text)]`` of the markers of ``path``; InputError naming ``path:line`` of a malformed one: a
    tag like a marker's that is not exactly ``<!-- n:CLAIM -->`` or ``<!-- /n -->`` (:data:`TAG`), a marker not
    closed before the next one or the end of the file, a closing tag that closes none."""
    text = _read_text(path)

    def line(t):
        return text.count("\n", 0, t.start()) + 1

    out, opened = [], None  # opened: the TAG and OPEN matches of the marker not closed yet
    for t in TAG.finditer(text):
        m = OPEN.fullmatch(t.group())
        if m is None and t.group() != CLOSE:
            raise InputError(
                f"{_shown(path)}:{line(t)}: malformed marker {t.group()!r}; expected exactly "
                f"'<!-- n:CLAIM -->' or {CLOSE!r} (CLAIM: letters, digits, '_', '.', '-')"
            )
        if m is not None and opened is not None:
            raise InputError(
                f"{_shown(path)}:{line(opened[0])}: marker {opened[0].group()!r} is not closed before the "
                f"next one (line {line(t)}); expected {CLOSE!r} after its number"
            )
        if m is None and opened is None:
            raise InputError(
                f"{_shown(path)}:{line(t)}: {CLOSE!r} closes no marker; expected '<!-- n:CLAIM -->' before it"
            )
        if m is not None:
            opened = (t, m)
            continue
        out.append((line(opened[0]), opened[1].group(1), text[opened[0].end() : t.start()]))
        opened = None
    if opened is not None:
        raise InputError(
            f"{_shown(path)}:{line(opened[0])}: marker {opened[0].group()!r} is not closed; expected "
            f"{CLOSE!r} after its number"
        )
    return out


def _known(found):
    """InputError naming ``path:line`` of the first marker of ``found`` (``[(path, line, name, text)]``) whose claim
    :data:`CLAIMS` does not define."""
    unknown = [(p, line, n) for p, line, n, _ in found if n not in CLAIMS]
    if unknown:
        (p, line, n), more = unknown[0], len(unknown) - 1
        raise InputError(
            f"{_shown(p)}:{line}: unknown claim {n!r}{f' (and {more} more)' if more else ''}; expected a claim "
            f"of bsrbench.reporting.prose.CLAIMS ({len(CLAIMS)} defined)"
        )


def values(names, book):
    """{name: today's value} of the claims ``names``; InputError naming an unknown claim."""
    unknown = sorted(set(names) - set(CLAIMS))
    if unknown:
        raise InputError(
            f"unknown claims {unknown}; bsrbench.reporting.prose.CLAIMS defines {len(CLAIMS)}"
        )
    out = {}
    for n in sorted(set(names)):
        try:
            out[n] = CLAIMS[n](book)
        except InputError:
            raise
        except (KeyError, IndexError, ValueError, TypeError, ZeroDivisionError) as exc:
            # a table without the rows or columns the claim reads: one line naming the claim
            raise InputError(
                f"claim {n!r} cannot be computed from the published tables in {book.path('')}: "
                f"{type(exc).__name__}: {exc}"
            ) from None
    return out


def check(paths=None, book=None, root=ROOT):
    """``[(path, line, name, written, today)]`` of the markers whose text is not their claim's value today."""
    paths = files(root) if paths is None else paths
    book = book or Book(root)
    found = [(p, *m) for p in paths for m in markers(p)]
    _known(found)
    now = values([n for *_, n, _ in found], book)
    return [(p, line, n, t, now[n]) for p, line, n, t in found if t != now[n]]


def update(paths=None, book=None, root=ROOT):
    """Rewrite every marker of ``paths`` with its claim's value today; the files changed. Every file to change is
    checked (:func:`.headline.check_update_target`) before any is written."""
    from .headline import check_update_target, write_update

    paths = files(root) if paths is None else paths
    book = book or Book(root)
    new = {}
    for p in paths:
        found = [(p, *m) for m in markers(p)]
        _known(found)
        text = _read_text(p)
        now = values([n for _, _, n, _ in found], book)
        new[p] = MARKER.sub(
            lambda m, now=now: f"<!-- n:{m.group(1)} -->{now[m.group(1)]}<!-- /n -->", text
        )
        if new[p] == text:
            del new[p]
    for p in new:
        check_update_target(p)
    for p, text in new.items():
        write_update(p, text)
    return list(new)


def used(root=ROOT):
    """The claims that some file's marker names."""
    return {n for p in files(root) for _, n, _ in markers(p)}


def _shown(path):
    """``path`` relative to the checkout where it is inside it."""
    path = Path(path)
    return path.relative_to(ROOT) if path.is_relative_to(ROOT) else path


def run_command(args):
    """``prose``: list the markers that differ from their claims (exit 1), or ``--update`` them (exit 0)."""
    import sys

    if args.update:
        for p in update():
            print(f"{_shown(p)}: updated", file=sys.stderr)
        return 0
    bad = check()
    for p, line, name, written, today in bad:
        print(
            f"{_shown(p)}:{line}: {name} is {written!r} in the text, {today!r} from the tables today"
        )
    per_file = [len(markers(p)) for p in files()]
    print(
        f"{sum(per_file)} numbers from the published tables in {sum(n > 0 for n in per_file)} files; "
        f"{len(bad)} differ",
        file=sys.stderr,
    )
    return 1 if bad else 0


__all__ = ["CLAIMS", "Book", "check", "claim", "markers", "update", "used"]
