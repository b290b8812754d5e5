"""The paper's two reasons for PM's advantage, tested: the mechanism variants of PM against the paper's PM.

The paper (Section III) credits PM's advantage to (1) the pose-kernel logit prior, which ties the codes of training
points with similar poses, and (2) averaging over posterior samples, which guards against overfitting at small N.
Both are options of ``BayesianSR`` (docs/model.md, "Mechanism options"): :data:`MECHANISM_OPTIONS`. A *mechanism
variant* is a run method with the base PM's estimator whose parameters differ from the base's in these options and
in nothing else (:func:`variants_from_config` on the configuration's ``methods``, :func:`variants_from_results` on
the ``params`` recorded in the result rows, which are the configuration's), so no method name is written here.

Per variant and cell (protocol, source, activity, n_train), :func:`mechanism_table` takes the paired comparison
with the base on the same splits from the comparisons table (:mod:`.comparisons`: corrected resampled t-test with
its 95% interval, Holm-adjusted over the cell's comparisons) and the mean errors from the results table;
:func:`verdict_counts` counts the cells where a variant is significantly worse, equal or better;
:func:`pooled_by_n` averages a variant's differences over the activities of each N, with the interval of that
average from the cells' intervals (independent data sets; Welch-Satterthwaite degrees of freedom);
:func:`fit_table` puts the training error (column ``train_error``, when recorded) beside the test error per N.
:func:`section_latex` writes the report section "Do the paper's reasons hold?", :func:`readme_paragraph` the
README's paragraph.
"""

import json
import math

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import InputError
from ..io import atomic_path
from . import comparisons as cmp
from . import latex
from .latex import bold, escape, fixed, general, signed
from .tables import activity_label

#: The options of BayesianSR that switch the paper's two mechanisms, and the reason each one tests.
MECHANISM_OPTIONS = {
    "logit_kernel": "pose",
    "eta_scale": "pose",
    "n_predict_samples": "averaging",
}
#: The reasons, as the report names them.
REASONS = {
    "pose": "the pose-kernel logit prior ties the codes of training points with similar poses",
    "averaging": "averaging over posterior samples makes PM robust to overfitting at small $N$",
}
#: The words for a verdict of the corrected t-test (Holm-adjusted p < ALPHA).
VERDICT_WORDS = {"worse": "worse", "tied": "equal", "better": "better", "untested": "untested"}
#: Columns of :func:`mechanism_table`.
TABLE_COLUMNS = cmp.CELL + [
    "method",
    "versus",
    "reason",
    "change",
    "n_splits",
    "error",
    "base_error",
    "mean_diff",
    "ci_low",
    "ci_high",
    "p_holm",
    "verdict",
]
#: The training-error column of the result rows.
TRAIN_ERROR = "train_error"
NOT_RECORDED = "not recorded"


# --------------------------------------------------------------------------------------- which methods
def _norm(v):
    """A parameter value in a comparable form (1 and 1.0 alike; lists as tuples)."""
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return v
    if isinstance(v, (int, float, np.integer, np.floating)):
        return float(v)
    if isinstance(v, (list, tuple)):
        return tuple(_norm(x) for x in v)
    if isinstance(v, dict):
        return tuple(sorted((k, _norm(x)) for k, x in v.items()))
    return v


def differing_options(base, params, defaults=None):
    """The mechanism options of ``params`` that differ from ``base`` ({option: value}), or None if the two differ
    in any other parameter. A parameter missing from one side takes its value in ``defaults`` (the estimator's
    defaults), so that ``logit_kernel: pose`` written out equals leaving it out."""
    defaults = defaults or {}
    keys = set(base) | set(params)
    out = {}
    for k in sorted(keys):
        a = base.get(k, defaults.get(k))
        b = params.get(k, defaults.get(k))
        if _norm(a) == _norm(b):
            continue
        if k not in MECHANISM_OPTIONS:
            return None
        out[k] = b
    return out


def variants_from_config(methods, run, *, base, defaults=None):
    """{method: {option: value}}: the run methods with the estimator of ``base`` whose ``params`` differ from the
    base's in mechanism options only (and in at least one), in the order of ``run``. ``methods``: the
    configuration's ``methods`` mapping; ``defaults``: the estimator's defaults (None: looked up with
    :func:`bsrbench.estimators.estimator_defaults`). {} if ``base`` is not run."""
    if base not in run or base not in methods:
        return {}
    est = methods[base]["estimator"]
    if defaults is None:
        from ..estimators import estimator_defaults

        defaults = estimator_defaults(est)
    bp = methods[base].get("params") or {}
    out = {}
    for m in run:
        if m == base or methods[m].get("estimator") != est:
            continue
        d = differing_options(bp, methods[m].get("params") or {}, defaults)
        if d:
            out[m] = d
    return out


def _row_params(text, where):
    if isinstance(text, dict):
        return text
    try:
        p = json.loads(text)
    except (TypeError, json.JSONDecodeError) as exc:
        raise InputError(
            f"results row {where}: params = {text!r}; expected a JSON object of parameters"
        ) from exc
    if not isinstance(p, dict):
        raise InputError(f"results row {where}: params = {text!r}; expected a JSON object")
    return p


def variants_from_results(df, *, base="PM", defaults=None):
    """:func:`variants_from_config` on the ``estimator`` and ``params`` columns of a results table (the first row
    of each method; the mechanism options are never chosen by CV). {} without those columns or without ``base``."""
    if not {"method", "estimator", "params"} <= set(df.columns) or base not in set(df["method"]):
        return {}
    first = df.drop_duplicates("method")
    methods = {
        r.method: {
            "estimator": r.estimator,
            "params": _row_params(r.params, {"method": r.method}),
        }
        for r in first.itertuples(index=False)
    }
    return variants_from_config(methods, list(methods), base=base, defaults=defaults)


# ------------------------------------------------------------------------------------------ in words
def describe(options):
    """What a variant changes, in words (LaTeX), from its {option: value}."""
    parts = []
    for k, v in options.items():
        if k == "logit_kernel" and v == "identity":
            parts.append(r"removing the pose information ($\Sigma_w = I$)")
        elif k == "logit_kernel" and v == "input":
            parts.append(r"the kernel on the inputs $X$ instead of the poses")
        elif k == "eta_scale":
            parts.append(rf"the kernel bandwidth $\eta$ times {general(v)}")
        elif k == "n_predict_samples" and v is not None and int(v) == 1:
            parts.append("a single posterior sample instead of the posterior average")
        elif k == "n_predict_samples" and v is not None:
            parts.append(f"the average of the last {int(v)} posterior samples only")
        else:
            parts.append(r"\texttt{" + escape(f"{k}={v}").replace("-", "-{}") + "}")
    return " and ".join(parts)


def reason_of(options):
    """The reason (key of :data:`REASONS`) a variant tests: that of its first option."""
    return MECHANISM_OPTIONS[next(iter(options))]


# ------------------------------------------------------------------------------------------- numbers
def _cell_key(r):
    return tuple(r[k] for k in cmp.CELL)


def mechanism_table(results, comparisons, *, base, variants):
    """One row per (variant, cell) with columns :data:`TABLE_COLUMNS`: the variant's and the base's mean errors
    over the cell's splits, and the paired comparison with the base (mean difference variant - base in degrees,
    its 95% interval, Holm-adjusted p, verdict "worse"/"tied"/"better"/"untested"). ``comparisons``: the
    comparisons table (:func:`.comparisons.comparisons`, with ``pm=base``); None computes it from ``results``.
    InputError if a variant or the base is not in ``results``."""
    have = set(results["method"])
    missing = [m for m in [base, *variants] if m not in have]
    if missing:
        raise InputError(
            f"the results table has no rows of {missing}; expected the base {base!r} and the mechanism "
            f"variants {list(variants)}"
        )
    if comparisons is None or not set(variants) <= set(
        comparisons.loc[comparisons["versus"] == base, "method"]
    ):
        # no comparisons with the base (a base other than the comparisons' PM): those of the whole table
        comparisons = cmp.comparisons(results, pm=base)
    means = results.groupby(cmp.CELL + ["method"], sort=True)["error"].mean()
    c = comparisons[comparisons["versus"] == base].set_index(cmp.CELL + ["method"])
    rows = []
    for m, options in variants.items():
        cells = results.loc[results["method"] == m, cmp.CELL].drop_duplicates()
        for cell in cells.itertuples(index=False):
            key = tuple(cell)
            r = {
                **dict(zip(cmp.CELL, key)),
                "method": m,
                "versus": base,
                "reason": reason_of(options),
                "change": describe(options),
                "error": float(means.get(key + (m,), math.nan)),
                "base_error": float(means.get(key + (base,), math.nan)),
            }
            if key + (m,) in c.index:
                x = c.loc[key + (m,)]
                x = x.iloc[0] if isinstance(x, pd.DataFrame) else x
                r.update(
                    {k: x[k] for k in ("n_splits", "mean_diff", "ci_low", "ci_high", "p_holm")}
                )
            else:
                r.update(
                    n_splits=0,
                    mean_diff=math.nan,
                    ci_low=math.nan,
                    ci_high=math.nan,
                    p_holm=math.nan,
                )
            r["verdict"] = cmp.verdict(r["p_holm"], r["mean_diff"])
            rows.append(r)
    return pd.DataFrame(rows, columns=TABLE_COLUMNS)


def verdict_counts(table):
    """Per variant (in the table's order): cells, and in how many the variant is significantly worse than the base,
    equal (tied), better, or untested (fewer than 2 common splits)."""
    cols = ["method", "reason", "change", "cells", "worse", "tied", "better", "untested"]
    rows = []
    for m, g in table.groupby("method", sort=False):
        v = g["verdict"].value_counts()
        rows.append(
            {
                "method": m,
                "reason": g["reason"].iloc[0],
                "change": g["change"].iloc[0],
                "cells": len(g),
                **{k: int(v.get(k, 0)) for k in ("worse", "tied", "better", "untested")},
            }
        )
    return pd.DataFrame(rows, columns=cols)


def pooled(mean_diff, ci_high, n_splits, level=0.95):
    """The average of independent cells' mean differences and its ``level`` interval: ``(mean, low, high, k)``.

    Each cell's standard error is read back from its corrected-t interval,
    ``se = (ci_high - mean) / t_{(1+level)/2, J-1}``; the average's is ``sqrt(sum se^2) / k`` over the ``k`` cells
    with a test, with Welch-Satterthwaite degrees of freedom ``(sum se^2)^2 / sum(se^4 / (J - 1))``. Cells without
    a test (fewer than 2 splits) are left out; NaN for none."""
    d = np.asarray(mean_diff, float)
    hi = np.asarray(ci_high, float)
    J = np.asarray(n_splits, float)
    ok = np.isfinite(d) & np.isfinite(hi) & (J >= 2)
    k = int(ok.sum())
    if k == 0:
        return math.nan, math.nan, math.nan, 0
    d, hi, J = d[ok], hi[ok], J[ok]
    q = stats.t.ppf(0.5 + level / 2.0, J - 1)
    se2 = ((hi - d) / q) ** 2
    mean = float(d.mean())
    if se2.sum() == 0.0:
        return mean, mean, mean, k
    nu = se2.sum() ** 2 / np.sum(se2**2 / (J - 1))
    h = float(stats.t.ppf(0.5 + level / 2.0, nu)) * math.sqrt(se2.sum()) / k
    return mean, mean - h, mean + h, k


def pooled_by_n(table):
    """Per (protocol, source, method, n_train): the variant's mean difference to the base averaged over the
    activities, with its 95% interval (:func:`pooled`), the number of activities pooled and the verdict counts."""
    rows = []
    keys = ["protocol", "source", "method", "n_train"]
    for key, g in table.groupby(keys, sort=False):
        mean, lo, hi, k = pooled(g["mean_diff"], g["ci_high"], g["n_splits"])
        v = g["verdict"].value_counts()
        rows.append(
            {
                **dict(zip(keys, key)),
                "mean_diff": mean,
                "ci_low": lo,
                "ci_high": hi,
                "activities": k,
                "cells": len(g),
                **{x: int(v.get(x, 0)) for x in ("worse", "tied", "better", "untested")},
            }
        )
    out = pd.DataFrame(rows)
    return out.sort_values(keys[:2] + ["n_train"], kind="mergesort").reset_index(drop=True)


def fit_table(results, *, base, variants):
    """Training error beside test error per (protocol, source, n_train) for the base and the variants that change
    the posterior averaging: columns protocol, source, n_train, method, train_error, test_error (means over the
    activities and splits). None if the results have no ``train_error`` column or no value for these methods."""
    methods = [base] + [m for m, o in variants.items() if reason_of(o) == "averaging"]
    if TRAIN_ERROR not in results.columns:
        return None
    d = results[results["method"].isin(methods)].copy()
    d[TRAIN_ERROR] = pd.to_numeric(d[TRAIN_ERROR], errors="coerce")
    if d[TRAIN_ERROR].notna().sum() == 0:
        return None
    g = d.groupby(["protocol", "source", "n_train", "method"], sort=True)
    out = g.agg(train_error=(TRAIN_ERROR, "mean"), test_error=("error", "mean")).reset_index()
    order = {m: i for i, m in enumerate(methods)}
    out["_o"] = out["method"].map(order)
    out = out.sort_values(["protocol", "source", "n_train", "_o"], kind="mergesort")
    return out.drop(columns="_o").reset_index(drop=True)


# ---------------------------------------------------------------------------------------- sentences
def _interval(lo, hi):
    return f"95\\% CI {signed(lo)} to {signed(hi)}"


def variant_sentences(table, *, labels, base):
    """One sentence (LaTeX) per variant and (protocol, source): its difference to the base averaged over the
    activities at each N with the interval, and the count of cells where it is significantly worse, equal or
    better."""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    out = []
    pooled_n = pooled_by_n(table)
    for (protocol, source, m), g in pooled_n.groupby(["protocol", "source", "method"], sort=False):
        change = table.loc[table["method"] == m, "change"].iloc[0]
        parts = []
        for r in g.itertuples(index=False):
            if r.activities == 0:
                parts.append(f"is not tested at $N = {int(r.n_train)}$ (fewer than 2 splits)")
                continue
            over = (
                f" (mean over {r.activities} activities)" if r.activities > 1 else " (one activity)"
            )
            parts.append(
                f"{signed(r.mean_diff)} degrees ({_interval(r.ci_low, r.ci_high)}) at $N = {int(r.n_train)}${over}"
            )
        n = int(g["cells"].sum())
        counts = ", ".join(
            f"{VERDICT_WORDS[k]} in {int(g[k].sum())}" for k in ("worse", "tied", "better")
        )
        untested = int(g["untested"].sum())
        tail = f" (no test in {untested})" if untested else ""
        text = (
            f"{L(m)}, {change}: the error against {L(base)} changes by "
            + "; ".join(parts)
            + f". Significantly worse, equal or better than {L(base)} (Holm-adjusted $p < {cmp.ALPHA:g}$): "
            f"{counts} of the {n} (activity, $N$) {'cell' if n == 1 else 'cells'}{tail}."
        )
        if pooled_n["protocol"].nunique() > 1 or pooled_n["source"].nunique() > 1:
            text = (
                f"{escape(protocol.replace('_', '-').capitalize())} protocol, {escape(source)} data: "
                + text
            )
        out.append(text)
    return out


def reason_sentences(table, *, labels, base):
    """Per reason tested: what the variants that switch it off do, summed over their cells."""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    out = []
    counts = verdict_counts(table)
    pooled_n = pooled_by_n(table)
    for reason, g in counts.groupby("reason", sort=False):
        n, worse, better = int(g["cells"].sum()), int(g["worse"].sum()), int(g["better"].sum())
        names = ", ".join(L(m) for m in g["method"])
        splits = sorted({int(j) for j in table.loc[table["reason"] == reason, "n_splits"]})
        pn = pooled_n[pooled_n["method"].isin(g["method"]) & (pooled_n["activities"] > 0)]
        above, below = int((pn["ci_low"] > 0).sum()), int((pn["ci_high"] < 0).sum())
        if worse * 2 > n:
            verdict = "supported: changing it makes PM significantly worse in most cells"
        elif better * 2 > n:
            verdict = "contradicted: changing it makes PM significantly better in most cells"
        elif worse == 0 and better == 0:
            verdict = "not supported: changing it makes no significant difference in any cell"
        else:
            verdict = "not supported in most cells: the difference is significant in few of them"
        out.append(
            f"Reason ``{REASONS[reason]}'' ({names} against {L(base)}; "
            f"{'/'.join(map(str, splits))} splits per cell): significantly worse in {worse}, better in {better} "
            f"of {n} cells; {verdict}. Averaged over the activities, the difference's 95\\% interval lies above "
            f"zero (worse) at {above} and below zero (better) at {below} of the {len(pn)} (variant, $N$) pairs."
        )
    return out


def fit_sentences(results, *, labels, base, variants):
    """Training error against test error per N for the base and the averaging variants; "not recorded" when the
    results have no training error."""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    ft = fit_table(results, base=base, variants=variants)
    names = [base] + [m for m, o in variants.items() if reason_of(o) == "averaging"]
    if ft is None:
        return [
            f"Training error (the error on the training frames) of {', '.join(L(m) for m in names)}: "
            f"{NOT_RECORDED} in these results (no column \\texttt{{train\\_error}}), so overfitting is not measured "
            "here."
        ]
    out = []
    for (protocol, source), g in ft.groupby(["protocol", "source"], sort=False):
        parts = []
        for n, gn in g.groupby("n_train", sort=True):
            parts.append(
                f"$N = {int(n)}$: "
                + ", ".join(
                    f"{L(r.method)} {r.train_error:.2f} against {r.test_error:.2f}"
                    if np.isfinite(r.train_error)
                    else f"{L(r.method)} {NOT_RECORDED} against {r.test_error:.2f}"
                    for r in gn.itertuples(index=False)
                )
            )
        out.append(
            "Training error against test error (degrees, mean over activities and splits"
            + (
                f"; {escape(protocol)} protocol, {escape(source)} data"
                if ft[["protocol", "source"]].drop_duplicates().shape[0] > 1
                else ""
            )
            + "): "
            + "; ".join(parts)
            + ". A training error far below the test error is overfitting (Table~\\ref{tab:mech-fit})."
        )
    return out


# ------------------------------------------------------------------------------------------ LaTeX
def _cell_text(r):
    if not np.isfinite(r.mean_diff):
        return "--"
    if not np.isfinite(r.ci_low):
        return signed(r.mean_diff)
    txt = f"{signed(r.mean_diff)} {{\\scriptsize [{signed(r.ci_low)}, {signed(r.ci_high)}]}}"
    return bold(txt) if r.verdict in ("worse", "better") else txt


def differences_latex(results, table, *, labels, base):
    """Per (protocol, source): rows the base's mean error per N, then each variant's mean difference to it with
    the 95% interval per N; one column per activity; bold: significant (Holm-adjusted)."""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    out = []
    pa = (
        results.drop_duplicates("activity").set_index("activity")["paper_activity"].fillna("")
        if "paper_activity" in results.columns
        else {}
    )
    for (protocol, source), g in table.groupby(["protocol", "source"], sort=True):
        acts = list(dict.fromkeys(g["activity"]))
        sizes = sorted(int(n) for n in g["n_train"].unique())
        idx = g.set_index(["method", "activity", "n_train"])
        base_err = g.drop_duplicates(["activity", "n_train"]).set_index(["activity", "n_train"])[
            "base_error"
        ]
        head = ["Method", "$N$"] + [escape(activity_label(a, pa.get(a, ""))) for a in acts]
        caption = (
            rf"The mechanism variants against {L(base)}, {escape(protocol)} protocol, "
            rf"{escape(source)} data: first {L(base)}'s mean error (degrees, over splits), then each variant's "
            rf"mean difference to it on the same splits (variant $-$ {L(base)}; positive: the variant is worse) and "
            r"the 95\% interval of the corrected resampled $t$-test (Nadeau and Bengio 2003). Bold: significant, "
            rf"Holm-adjusted over the cell's comparisons, $p < {cmp.ALPHA:g}$."
        )
        lines = []
        for i, n in enumerate(sizes):
            cells = [fixed(float(base_err.get((a, n), math.nan))) for a in acts]
            lines.append([L(base) if i == 0 else "", str(n)] + cells)
        for m in dict.fromkeys(g["method"]):
            lines.append(r"\midrule")
            for i, n in enumerate(sizes):
                cells = [
                    _cell_text(idx.loc[(m, a, n)]) if (m, a, n) in idx.index else "--" for a in acts
                ]
                lines.append([L(m) if i == 0 else "", str(n)] + cells)
        out.append(
            latex.table(
                lines,
                spec="@{}lr" + "r" * len(acts) + "@{}",
                head=[head],
                caption=caption,
                label=f"tab:mech-diff-{protocol}-{source}",
                tabcolsep="4pt",
            )
        )
    return "\n\n".join(out)


def counts_latex(table, *, labels, base):
    """The verdict counts per variant (:func:`verdict_counts`)."""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    t = verdict_counts(table)
    rows = [
        [L(r.method)] + [str(x) for x in (r.change, r.cells, r.worse, r.tied, r.better, r.untested)]
        for r in t.itertuples(index=False)
    ]
    return latex.table(
        rows,
        width=r"\linewidth",
        spec=r"@{}l>{\raggedright\arraybackslash}Xrrrrr@{}",
        head=[r"Variant & What it changes & cells & worse & equal & better & no test \\"],
        label="tab:mech-counts",
        caption=rf"In how many (activity, $N$) cells each mechanism variant is significantly worse than, equal "
        rf"to or better than {L(base)} (paired by split, corrected resampled $t$-test, Holm-adjusted over the "
        rf"cell's comparisons, $p < {cmp.ALPHA:g}$; no test: fewer than 2 common splits).",
    )


def fit_latex(results, *, labels, base, variants):
    """Training and test error per N of the base and the averaging variants ('' when not recorded)."""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    ft = fit_table(results, base=base, variants=variants)
    if ft is None:
        return ""
    methods = list(dict.fromkeys(ft["method"]))
    caption = (
        r"Training error (on the training frames, each predicted from its input alone) beside the test "
        r"error, degrees, mean over activities and splits. A training error far below the test error is "
        r"overfitting."
    )
    head = [
        ["Protocol", "Source", ""] + [rf"\multicolumn{{2}}{{c}}{{{L(m)}}}" for m in methods],
        ["", "", "$N$"] + ["train", "test"] * len(methods),
    ]
    lines = []
    for (protocol, source, n), g in ft.groupby(["protocol", "source", "n_train"], sort=True):
        g = g.set_index("method")
        cells = []
        for m in methods:
            tr = float(g.at[m, "train_error"]) if m in g.index else math.nan
            te = float(g.at[m, "test_error"]) if m in g.index else math.nan
            cells += [fixed(tr), fixed(te)]
        lines.append([escape(protocol), escape(source), str(int(n))] + cells)
    return latex.table(
        lines,
        spec="@{}llr" + "rr" * len(methods) + "@{}",
        head=head,
        caption=caption,
        label="tab:mech-fit",
    )


SECTION_TITLE = "Do the paper's reasons hold?"


def section_latex(results, comparisons, *, base, variants, labels):
    """The LaTeX section "Do the paper's reasons hold?" ('' when ``variants`` is empty: a study without mechanism
    variants has no such section)."""
    if not variants:
        return ""
    table = mechanism_table(results, comparisons, base=base, variants=variants)
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    reasons = list(dict.fromkeys(reason_of(o) for o in variants.values()))
    intro = (
        "The paper explains PM's advantage by two reasons (its Section III): "
        + "; ".join(f"({i + 1}) {REASONS[r]}" for i, r in enumerate(REASONS) if r in reasons)
        + ". Each variant below switches one of these mechanisms off and nothing else "
        r"(\texttt{BayesianSR} options \texttt{logit\_kernel}, \texttt{eta\_scale}, \texttt{n\_predict\_samples}; "
        rf"docs/model.md). It is compared with {L(base)} split by split on the same splits: the mean difference of "
        r"the test errors (variant $-$ "
        + L(base)
        + r"; positive: the variant is worse), its 95\% interval "
        r"from the corrected resampled $t$-test of Nadeau and Bengio (2003), which allows for the overlap of the "
        r"random splits, and the Holm-adjusted $p$ over each cell's comparisons. Differences ``at $N$'' are "
        r"averaged over the activities, with the interval of that average (the activities are independent data "
        r"sets; Welch--Satterthwaite degrees of freedom)."
    )
    items = (
        variant_sentences(table, labels=labels, base=base)
        + reason_sentences(table, labels=labels, base=base)
        + fit_sentences(results, labels=labels, base=base, variants=variants)
    )
    lines = [
        "% generated from the study's aggregate and comparisons tables",
        r"\section{" + escape(SECTION_TITLE) + "}",
        "",
        intro,
        "",
        r"\begin{itemize}",
        *[r"\item " + t for t in items],
        r"\end{itemize}",
        "",
        differences_latex(results, table, labels=labels, base=base),
        "",
        counts_latex(table, labels=labels, base=base),
        "",
    ]
    fit = fit_latex(results, labels=labels, base=base, variants=variants)
    if fit:
        lines += [fit, ""]
    return "\n".join(lines) + "\n"


def write_section(path, text):
    """Write the section (an empty fragment, a comment only, for a study without mechanism variants)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text or "% no mechanism variants in this study: no section\n")


def section_and_table(results, comparisons, *, methods, run, base, labels):
    """The section (:func:`section_latex`), its table (:func:`mechanism_table`; no rows without variants) and
    the variants, found in the configuration's ``methods`` and ``run`` (:func:`variants_from_config`)."""
    variants = variants_from_config(methods, run, base=base)
    text = section_latex(results, comparisons, base=base, variants=variants, labels=labels)
    table = (
        mechanism_table(results, comparisons, base=base, variants=variants)
        if variants
        else pd.DataFrame(columns=TABLE_COLUMNS)
    )
    return text, table, variants


# ------------------------------------------------------------------------------------------ README
def _plain(text):
    """LaTeX of :func:`describe` as plain markdown text."""
    return (
        text.replace(r"$\Sigma_w = I$", "Sigma_w = I")
        .replace(r"$\eta$", "eta")
        .replace("$X$", "X")
        .replace(r"\texttt{", "`")
        .replace("-{}", "-")
        .replace("}", "`")
    )


def _check_complete(results, base, variants):
    """InputError naming the method and the cells if ``base`` or a variant lacks a cell that another of them has:
    a per-N mean over fewer activities would be read as the whole study's."""

    def cells(m):
        return set(
            map(tuple, results.loc[results["method"] == m, cmp.CELL].drop_duplicates().values)
        )

    have = {m: cells(m) for m in [base, *variants]}
    want = set().union(*have.values())
    for m, got in have.items():
        lack = sorted(want - got, key=str)
        if lack:
            shown = ", ".join("/".join(str(v) for v in c) for c in lack[:4]) + (
                " ..." if len(lack) > 4 else ""
            )
            raise InputError(
                f"{'base' if m == base else 'variant'} {m!r} has no rows in {len(lack)} of the {len(want)} "
                f"cells of {base!r} and its variants ({'/'.join(cmp.CELL)}: {shown}); expected each of them in "
                "every cell"
            )


def readme_paragraph(results, comparisons=None, *, base="PM", labels=None, variants=None):
    """The README's paragraph (markdown) on the paper's reasons, from a published table: a bullet per variant with
    its difference to ``base`` per N, the interval and the cell counts; then the training and test errors.
    ``variants`` None: found from the table's ``params`` (:func:`variants_from_results`). InputError if there is
    no mechanism variant."""
    labels = labels or {}
    if not (results["method"] == base).any():
        raise InputError(
            f"no rows of the base method {base!r} in the table; expected its mechanism variants beside it"
        )
    if variants is None:
        variants = variants_from_results(results, base=base)
    if not variants:
        raise InputError(
            f"no mechanism variant of {base!r} in the table (methods with its estimator whose params differ from "
            f"its own only in {sorted(MECHANISM_OPTIONS)}); expected a study like config/ablation-mechanisms.yaml"
        )
    _check_complete(results, base, variants)
    table = mechanism_table(results, comparisons, base=base, variants=variants)
    lab = lambda m: labels.get(m, m)  # noqa: E731
    sentences = []
    for (protocol, source, m), g in pooled_by_n(table).groupby(
        ["protocol", "source", "method"], sort=False
    ):
        change = _plain(table.loc[table["method"] == m, "change"].iloc[0])
        at = "; ".join(
            f"{r.mean_diff:+.2f} deg (95% CI {r.ci_low:+.2f} to {r.ci_high:+.2f}) at N = {int(r.n_train)}"
            for r in g.itertuples(index=False)
            if r.activities
        )
        n = int(g["cells"].sum())
        sentences.append(
            f"{lab(m)}, {change}: {lab(base)}'s error changes by {at or 'nothing testable'}; "
            f"it is significantly worse in {int(g['worse'].sum())}, equal in {int(g['tied'].sum())} and better "
            f"in {int(g['better'].sum())} of {n} cells ({protocol} protocol, {source} data)."
        )
    ft = fit_table(results, base=base, variants=variants)
    if ft is None:
        fit = f"Training error: {NOT_RECORDED}."
    else:
        methods = list(dict.fromkeys(ft["method"]))
        fit = (
            "Training vs test error (deg, means over the activities and splits):\n\n| N | "
            + " | ".join(f"{lab(m)} train / test" for m in methods)
            + " |\n|---:|"
            + "---:|" * len(methods)
        )
        for n, g in ft.groupby("n_train", sort=True):
            by = {r.method: r for r in g.itertuples(index=False)}
            fit += (
                f"\n| {int(n)} | "
                + " | ".join(
                    f"{by[m].train_error:.2f} / {by[m].test_error:.2f}" if m in by else ""
                    for m in methods
                )
                + " |"
            )
    legend = (
        "Differences are variant minus PM on the same splits (positive: the variant is worse), averaged over the "
        "activities at each N; intervals and significance from the corrected resampled t-test (Nadeau and Bengio "
        "2003), Holm-adjusted over each cell's comparisons, p < 0.05."
    )
    return "\n".join(f"- {s}" for s in sentences) + "\n\n" + fit + "\n\n" + legend
