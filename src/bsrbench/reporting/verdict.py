"""The verdict across cells and across activities: Friedman, mean ranks and PM against each method.

The per-cell tests (:mod:`.comparisons`) compare methods on the splits of one cell, i.e. on the frames of one motion;
they say nothing about another motion. The question "is PM worse than method M on motions like these?" is asked with
the motions as the unit (Demsar 2006, "Statistical comparisons of classifiers over multiple data sets"; Benavoli,
Corani and Mangili 2016): each block is one data set, the mean error over the splits its score.

Two units of analysis (:data:`UNITS`):

- ``cell``: a block per (source, activity, n_train) cell. The cells of one activity share their frames, so they are
  not independent data sets; this is the finer, more powerful level.
- ``motion``: a block per distinct motion (the data sets' ``motion`` key of config/datasets.yaml: the authors'
  features and ours of the same CMU trials are one motion), the mean of its cells: the conservative unit. With
  ``b`` blocks the smallest one-sided Wilcoxon p-value is ``2**-b`` (:func:`smallest_p`), so a few motions can
  never reach significance after Holm's adjustment over many comparisons: the effect size and its bootstrap
  interval over the motions (:func:`bootstrap_interval`) say what they can.

Per unit and scope (each source alone and all sources together), :func:`verdict` gives the Friedman test over the
methods with complete blocks (:func:`scipy.stats.friedmanchisquare`) and the Iman-Davenport F form of it, each
method's mean rank (rank 1: lowest error), the Nemenyi critical difference of the mean ranks, and PM against each
other method: the Wilcoxon signed-rank test of the blocks' differences ``PM - M`` (:func:`scipy.stats.wilcoxon`),
two-sided and one-sided ("PM worse"), Holm-adjusted over PM's comparisons of that unit and scope
(:func:`statsmodels.stats.multitest.multipletests`). A comparison that cannot be made (fewer than 2 blocks; fewer
than 3 methods for Friedman) has an empty p-value and says so in ``note``: never a NaN claim.
"""

import math

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import InputError
from ..io import read_csv
from .comparisons import holm

#: Units of analysis: the block of the tests, and the columns that name a block.
UNITS = {"cell": ["source", "activity", "n_train"], "motion": ["motion"]}
#: Confidence of the bootstrap interval of PM's mean difference over the motions, and its resamples.
CONFIDENCE, RESAMPLES = 0.95, 10_000
#: Scope of all sources together.
ALL = "all"
ALPHA = 0.05
NO_BLOCKS = "fewer than 2 complete blocks: no test"
NO_FRIEDMAN = "fewer than 3 methods: no Friedman test"
#: Columns of ``results/{study}/aggregate/verdict.csv`` and ``reports/published/<study>-verdict.csv``.
COLUMNS = [
    "protocol",
    "unit",
    "scope",
    "n_blocks",
    "n_methods",
    "friedman_chi2",
    "friedman_p",
    "iman_davenport_f",
    "iman_davenport_p",
    "nemenyi_cd",
    "method",
    "mean_rank",
    "mean_error",
    "versus",
    "mean_diff",
    "versus_worse_blocks",
    "diff_ci_low",
    "diff_ci_high",
    "p_wilcoxon",
    "p_wilcoxon_holm",
    "p_wilcoxon_worse",
    "p_wilcoxon_worse_holm",
    "note",
]


def with_motions(df, motions=None):
    """``df`` with a ``motion`` column: ``motions[(source, activity)]`` (:func:`bsrbench.datasets.motion_map`), the
    activity's name where the map has none."""
    motions = motions or {}
    out = df.copy()
    out["motion"] = [motions.get((s, a), a) for s, a in zip(df["source"], df["activity"])]
    return out


def block_means(df, unit):
    """Blocks x methods table of mean errors for one protocol's rows ``df`` (with a ``motion`` column,
    :func:`with_motions`): per ``unit`` (:data:`UNITS`) block, the mean over seeds of each cell, then (unit
    ``motion``) the mean over the motion's cells (its sizes N and data sets). Only blocks where every method has a
    value in every cell are kept (the tests need complete blocks)."""
    if unit not in UNITS:
        raise InputError(f"unit {unit!r} is not one of {sorted(UNITS)}")
    cells = df.groupby(["motion", *UNITS["cell"], "method"], sort=True)["error"].mean()
    w = cells.unstack("method")
    if unit == "motion":
        # a motion whose cells miss a method somewhere is incomplete, not averaged over fewer cells
        complete = w.notna().groupby(level="motion").all()
        w = w.groupby(level="motion", sort=True).mean().where(complete)
    else:
        w = w.droplevel("motion")
    return w.dropna(axis=0, how="any")


def smallest_p(n_blocks, n_comparisons, one_sided=True):
    """The smallest Holm-adjusted Wilcoxon signed-rank p-value that ``n_blocks`` blocks can give over
    ``n_comparisons`` comparisons: ``n_comparisons * 2**-b`` one-sided (every block the same sign), twice that
    two-sided, at most 1."""
    p = 2.0 ** -int(n_blocks) * (1 if one_sided else 2)
    return min(1.0, p * int(n_comparisons))


def bootstrap_interval(d, *, confidence=CONFIDENCE, resamples=RESAMPLES, seed=0):
    """Percentile bootstrap interval of the mean of the block differences ``d`` (the blocks resampled with
    replacement, :func:`scipy.stats.bootstrap`, a fixed seed so that a table regenerates identically); (nan, nan)
    with fewer than 3 blocks."""
    d = np.asarray(d, dtype=float)
    if d.size < 3:
        return math.nan, math.nan
    if np.all(d == d[0]):
        return float(d[0]), float(d[0])
    res = stats.bootstrap(
        (d,),
        np.mean,
        confidence_level=confidence,
        n_resamples=resamples,
        method="percentile",
        random_state=np.random.default_rng(seed),
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def friedman(means, *, alpha=ALPHA):
    """Friedman's test over the methods (columns) with the blocks (rows) of ``means``: a dict with n_blocks,
    n_methods, friedman_chi2 and friedman_p (scipy), the Iman-Davenport statistic
    ``F = (b - 1) chi2 / (b (k - 1) - chi2)`` on (k - 1, (k - 1)(b - 1)) degrees of freedom with its p-value, the
    Nemenyi critical difference ``q_alpha sqrt(k (k + 1) / (6 b))`` of the mean ranks (``q_alpha`` the studentized
    range quantile over sqrt 2), and a note when no test can be made."""
    b, k = means.shape
    out = {"n_blocks": int(b), "n_methods": int(k), "note": ""}
    nan = dict.fromkeys(
        ["friedman_chi2", "friedman_p", "iman_davenport_f", "iman_davenport_p", "nemenyi_cd"],
        math.nan,
    )
    out.update(nan)
    if b < 2:
        out["note"] = NO_BLOCKS
        return out
    if k < 3:
        out["note"] = NO_FRIEDMAN
        return out
    res = stats.friedmanchisquare(*[means[c].to_numpy(float) for c in means.columns])
    chi2, p = float(res.statistic), float(res.pvalue)
    df1, df2 = k - 1, (k - 1) * (b - 1)
    denom = b * (k - 1) - chi2
    if denom > 0:
        f = (b - 1) * chi2 / denom
        p_f = float(stats.f.sf(f, df1, df2))
    else:  # every block ranks the methods identically: the F form is infinite
        f, p_f = math.inf, 0.0
    q = float(stats.studentized_range.ppf(1 - alpha, k, np.inf)) / math.sqrt(2.0)
    out.update(
        friedman_chi2=chi2,
        friedman_p=p,
        iman_davenport_f=float(f),
        iman_davenport_p=p_f,
        nemenyi_cd=q * math.sqrt(k * (k + 1) / (6.0 * b)),
    )
    return out


def _wilcoxon(d, alternative):
    d = np.asarray(d, dtype=float)
    if not np.any(d != 0):
        return 1.0
    return float(stats.wilcoxon(d, alternative=alternative).pvalue)


def against(means, pm="PM", interval=False):
    """PM against each other method over the blocks of ``means``: a DataFrame indexed by method with mean_diff
    (mean over blocks of PM - method; positive: PM worse), versus_worse_blocks (blocks where PM's error is higher),
    with ``interval`` the bootstrap interval of mean_diff over the blocks (:func:`bootstrap_interval`; blocks
    that are independent data sets only), p_wilcoxon (two-sided), p_wilcoxon_worse (one-sided, PM worse) and their
    Holm-adjusted values over the methods. Empty if PM is not a column; p-values NaN (with a note) with fewer than
    2 blocks."""
    cols = COLUMNS[COLUMNS.index("mean_diff") :]
    others = [m for m in means.columns if m != pm]
    if pm not in means.columns or not others:
        return pd.DataFrame(columns=cols)
    rows = {}
    for m in others:
        d = (means[pm] - means[m]).to_numpy(float)
        r = {"mean_diff": float(d.mean()) if d.size else math.nan}
        r["versus_worse_blocks"] = int((d > 0).sum())
        low, high = bootstrap_interval(d) if interval else (math.nan, math.nan)
        r.update(diff_ci_low=low, diff_ci_high=high)
        if d.size < 2:
            r.update(p_wilcoxon=math.nan, p_wilcoxon_worse=math.nan, note=NO_BLOCKS)
        else:
            r.update(
                p_wilcoxon=_wilcoxon(d, "two-sided"),
                p_wilcoxon_worse=_wilcoxon(d, "greater"),
                note="",
            )
        rows[m] = r
    out = pd.DataFrame.from_dict(rows, orient="index")
    out["p_wilcoxon_holm"] = holm(out["p_wilcoxon"])
    out["p_wilcoxon_worse_holm"] = holm(out["p_wilcoxon_worse"])
    return out[cols]


def verdict(df, *, motions=None, pm="PM", alpha=ALPHA):
    """The verdict table (:data:`COLUMNS`) of an aggregate or published results table ``df``: per protocol, unit
    (:data:`UNITS`) and scope (each source, then :data:`ALL` when there are several), one row per method with its
    mean rank and, for the other methods, PM against it (with the bootstrap interval of the difference for the
    motions); the Friedman columns repeat on the rows of a unit and scope. ``motions``: {(source, activity):
    motion} (:func:`bsrbench.datasets.motion_map`; default: the activity's name)."""
    need = ["protocol", "source", "activity", "n_train", "method", "seed", "error"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise InputError(
            f"the results table lacks columns {missing} needed for the verdict across cells; expected the "
            "aggregate table (results/{study}/aggregate/results.csv)"
        )
    df = with_motions(df, motions)
    rows = []
    for protocol, dp in df.groupby("protocol", sort=True):
        sources = sorted(dp["source"].unique())
        scopes = sources + ([ALL] if len(sources) > 1 else [])
        for unit in UNITS:
            for scope in scopes:
                d = dp if scope == ALL else dp[dp["source"] == scope]
                means = block_means(d, unit)
                if means.shape[1] == 0:
                    continue
                fr = friedman(means, alpha=alpha)
                ranks = means.rank(axis=1, method="average").mean(axis=0)
                vs = against(means, pm, interval=unit == "motion")
                for m in sorted(means.columns, key=lambda m: (ranks[m], m)):
                    r = {"protocol": protocol, "unit": unit, "scope": scope, **fr}
                    r.update(method=m, mean_rank=float(ranks[m]))
                    r["mean_error"] = float(means[m].mean()) if len(means) else math.nan
                    if m in vs.index:
                        r.update(vs.loc[m].to_dict())
                        r["versus"] = pm
                        r["note"] = "; ".join(
                            dict.fromkeys(x for x in (fr["note"], vs.loc[m, "note"]) if x)
                        )
                    rows.append(r)
    out = pd.DataFrame(rows, columns=COLUMNS)
    out["versus_worse_blocks"] = out["versus_worse_blocks"].astype("Int64")
    for col in ("versus", "note"):
        out[col] = out[col].astype(object).fillna("")
    return out


def p_text(p):
    """A p-value as the README and the report print it: 3 decimals from 0.001, else one significant digit
    (``8e-08``); "no test" for a missing one."""
    if p is None or not np.isfinite(p):
        return "no test"
    return f"{p:.3f}" if p >= 0.001 else f"{p:.0e}"


def read_verdict(path):
    """Read a verdict table; DataFileError naming the file if it cannot be read or lacks a column."""
    from ..errors import DataFileError

    v = read_csv(path, "the verdict table", dtype={"note": str, "versus": str})
    missing = [c for c in COLUMNS if c not in v.columns]
    if missing:
        raise DataFileError(path, f"missing columns {missing}; expected {COLUMNS}")
    v["note"] = v["note"].fillna("")
    v["versus"] = v["versus"].fillna("")
    return v


def section_latex(v, *, labels, pm="PM", alpha=ALPHA):
    """The report's section "The verdict across cells and motions" (LaTeX): per protocol and unit, a table of the
    methods by mean rank with, per scope, the mean rank and PM's Holm-adjusted Wilcoxon p against the method
    (two-sided and one-sided), the Friedman test in the caption; one line if nothing can be tested."""
    from .latex import escape, fixed, table

    L = lambda m: escape(labels.get(m, m))  # noqa: E731

    def p(x):
        if x is None or not np.isfinite(x):
            return "--"
        return rf"\textbf{{{p_text(x)}}}" if x < alpha else p_text(x)

    out = [
        r"\section{The verdict across cells and motions}",
        "The tests of each cell compare methods on the frames of one motion. Whether "
        + L(pm)
        + " is worse than another method on motions like these is asked with the motions as the unit (Demsar "
        "2006): each block is a (source, activity, $N$) cell, or a distinct motion with its cells "
        "averaged over $N$ and data sets (the conservative unit, since the cells of a motion share its frames). Friedman's "
        "test over the methods (with the Iman-Davenport $F$) and, for "
        + L(pm)
        + " against each other method, the Wilcoxon signed-rank test of the blocks' differences, "
        "Holm-adjusted over the comparisons; bold: $p < 0.05$.",
    ]
    if v.empty:
        return "\n\n".join(out + ["No complete blocks: nothing to test."])
    if pm not in set(v["method"]):
        out.append(
            f"{L(pm)} was not run in this study: the tables give the mean ranks and Friedman's test only."
        )
    for protocol, vp in v.groupby("protocol", sort=True):
        for unit in UNITS:
            vu = vp[vp["unit"] == unit]
            if vu.empty:
                continue
            scopes = list(dict.fromkeys(vu["scope"]))
            words = "(source, activity, $N$) cells" if unit == "cell" else "distinct motions"
            if (vu["n_blocks"] < 2).all():
                out.append(
                    f"{escape(protocol.replace('_', '-').capitalize())} protocol, blocks {words}: "
                    f"{int(vu['n_blocks'].max())} complete block, so no test across blocks."
                )
                continue
            first = vu[vu["scope"] == scopes[-1]]
            methods = list(first["method"])
            caption = (
                f"{escape(protocol.replace('_', '-').capitalize())} protocol, blocks: {words}. "
            )
            for sc in scopes:
                r = vu[vu["scope"] == sc].iloc[0]
                if np.isfinite(r["friedman_p"]):
                    caption += (
                        rf"{escape(sc)}: {int(r['n_blocks'])} blocks, Friedman $\chi^2 = "
                        rf"{r['friedman_chi2']:.1f}$, $p = {p(r['friedman_p']).replace(chr(92) + 'textbf', '')}$, "
                        rf"Iman-Davenport $F = {r['iman_davenport_f']:.1f}$, CD {fixed(r['nemenyi_cd'])}. "
                    )
                else:
                    caption += f"{escape(sc)}: {int(r['n_blocks'])} block(s), {escape(r['note'])}. "
            head = [
                ["method"] + [rf"\multicolumn{{3}}{{c}}{{{escape(sc)}}}" for sc in scopes],
                [""] + ["rank", "$p$", r"$p_{\rm worse}$"] * len(scopes),
            ]
            rows = []
            for m in methods:
                cells = [L(m)]
                for sc in scopes:
                    r = vu[(vu["scope"] == sc) & (vu["method"] == m)]
                    if r.empty:
                        cells += ["--"] * 3
                        continue
                    r = r.iloc[0]
                    cells += [
                        fixed(r["mean_rank"]),
                        p(r["p_wilcoxon_holm"]) if r["versus"] else "",
                        p(r["p_wilcoxon_worse_holm"]) if r["versus"] else "",
                    ]
                rows.append(cells)
            out.append(
                table(
                    rows,
                    spec="@{}l" + "rrr" * len(scopes) + "@{}",
                    head=head,
                    caption=caption
                    + rf"Rank: mean rank (1: best); $p$, $p_{{\rm worse}}$: {L(pm)} against the method, "
                    "two-sided and one-sided (PM worse), Holm-adjusted.",
                    label=f"tab:verdict-{protocol}-{unit}",
                    tabcolsep="3pt",
                )
            )
    return "\n\n".join(out)
