"""Paired comparisons of methods per cell, allowing for overlapping splits, and the ranking across cells.

A cell is one (protocol, source, activity, n_train); its splits are the seeds, and every method of a cell sees the
same split of a seed, so two methods are compared split by split on the differences of their test errors
``d_j = error(method, j) - error(versus, j)`` (degrees; negative: the method is better). The random splits of one
sequence share most of their test frames, so the differences are correlated and the plain t-test is too
confident. Per comparison (:func:`compare_pair`):

- the corrected resampled t-test of Nadeau and Bengio (2003, "Inference for the generalization error"): the
  variance of the mean difference is ``(1/J + n_test/n_train) * s^2`` with ``J`` splits and ``s^2`` the sample
  variance of the ``d_j``; a two-sided p-value and a 95% interval from Student's t with ``J - 1`` degrees of freedom;
- the Wilcoxon signed-rank test of the ``d_j`` (:func:`scipy.stats.wilcoxon`);
- the Bayesian correlated t-test (Corani and Benavoli 2015; Benavoli, Corani, Demsar and Zaffalon 2017): the
  posterior of the mean difference is Student's t with ``J - 1`` degrees of freedom, location the mean, scale
  ``sqrt((1/J + rho/(1 - rho)) * s^2)`` with correlation ``rho = n_test / (n_test + n_train)`` (so
  ``rho/(1 - rho) = n_test/n_train``, the same factor as above); ``p_better``, ``p_rope`` and ``p_worse`` are its
  mass below ``-rope``, in ``[-rope, rope]`` and above ``rope`` (region of practical equivalence, degrees).

In each cell every method is compared with PM and with the cell's best method (lowest mean error over the splits
they share). Holm's correction (:func:`statsmodels.stats.multitest.multipletests`) runs over the family of the
cell: the distinct pairs of methods compared there (a pair compared both ways, PM against the best and the best
against PM, counts once). ``n_test`` is the mean of the result rows' ``n_test`` over the paired splits.

Edge cases: fewer than 2 common splits give no test (NaN, and the ``note`` says so); identical errors give
p = 1, a zero interval and ``p_rope`` = 1, never NaN; a method missing from some splits is paired on the common
splits only and ``n_splits`` says how many.

:func:`cd_ranks` and :func:`cd_diagram` rank the methods across the cells of one source and protocol by their mean
errors, with pairwise Wilcoxon signed-rank tests and Holm's correction (Benavoli, Corani and Mangili 2016, "Should
we really use post-hoc tests based on mean-ranks?"), drawn as a critical-difference diagram (Demsar 2006) by
scikit-posthocs.
"""

import math

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import InputError
from ..io import read_csv

#: Region of practical equivalence of the Bayesian correlated t-test (degrees).
ROPE = 0.5
#: Significance level of the tests (and of the ties marked in the tables).
ALPHA = 0.05
#: The cell of a comparison.
CELL = ["protocol", "source", "activity", "n_train"]
#: Columns of ``reports/published/<study>-comparisons.csv``, in order.
PUBLISHED_COLUMNS = CELL + [
    "method",
    "versus",
    "n_splits",
    "mean_diff",
    "ci_low",
    "ci_high",
    "p_corrected_t",
    "p_wilcoxon",
    "p_holm",
    "paired_ci_low",
    "paired_ci_high",
    "p_paired_t",
    "p_holm_paired",
    "p_better",
    "p_rope",
    "p_worse",
]
#: The aggregate's comparisons.csv: the published columns, the cell's best method and a note.
COLUMNS = PUBLISHED_COLUMNS + ["best", "note"]
NO_TEST = "fewer than 2 common splits: no test"
#: The two per-cell tests, by the question each answers: the Holm-adjusted p-value column, the test's name and the
#: question. ``paired`` is the verdict on a cell's frames; ``corrected`` is the sensitivity to the assumption of a
#: new data set of independent frames.
TESTS = {
    "paired": {
        "column": "p_holm_paired",
        "name": "paired t-test over splits",
        "question": "on these frames",
    },
    "corrected": {
        "column": "p_holm",
        "name": "corrected resampled t-test (Nadeau and Bengio 2003)",
        "question": "on a new data set of independent frames",
    },
}
#: The test of the tie marks of Tables I-II and of the README's counts.
TIE_TEST = "paired"


def test_column(test):
    """The Holm-adjusted p-value column of a per-cell test (:data:`TESTS`); InputError for an unknown test."""
    if test not in TESTS:
        raise InputError(f"unknown per-cell test {test!r}; expected one of {sorted(TESTS)}")
    return TESTS[test]["column"]


def _float_array(x, name):
    a = np.asarray(x, dtype=float).ravel()
    if not np.isfinite(a).all():
        raise InputError(f"{name} must be finite numbers; got {a.tolist()}")
    return a


def _t_test(d, factor, level):
    """Mean, ``level`` interval and two-sided p of a t-test of the differences ``d`` whose mean has the variance
    ``factor * s^2`` on ``J - 1`` degrees of freedom (all differences equal: p = 1 if they are 0, else 0)."""
    J = d.size
    mean = float(d.mean())
    se = math.sqrt(factor * float(d.var(ddof=1)))
    if se == 0.0 or not np.isfinite(se):
        return mean, mean, mean, 1.0 if mean == 0.0 else 0.0
    p = float(2.0 * stats.t.sf(abs(mean / se), J - 1))
    h = float(stats.t.ppf(0.5 + level / 2.0, J - 1)) * se
    return mean, mean - h, mean + h, p


def _splits(d, what):
    d = _float_array(d, "d")
    if d.size < 2:
        raise InputError(f"the {what} needs at least 2 paired splits; got {d.size}")
    return d


def paired_t(d, *, level=0.95):
    """Plain paired t-test of the differences ``d`` (one per split): ``(mean, ci_low, ci_high, p)`` with the
    variance ``s^2 / J``. It answers "is the method better on these frames": given the cell's frames the random
    splits are independent draws of a training set, so their differences are independent. InputError for fewer
    than 2 differences."""
    d = _splits(d, "paired t-test")
    return _t_test(d, 1.0 / d.size, level)


def corrected_t(d, *, n_train, n_test, level=0.95):
    """Nadeau-Bengio corrected resampled t-test of paired differences ``d`` (one per split).

    Returns ``(mean, ci_low, ci_high, p)``: the mean difference, its ``level`` interval and the two-sided p-value
    of "mean difference 0", with the variance ``(1/J + n_test/n_train) s^2`` and ``J - 1`` degrees of freedom. It
    targets a new data set drawn from the same population, assuming independent frames (which the frames of one
    motion are not): a sensitivity check, not the verdict. With all differences equal the variance is 0: p = 1 and
    a zero-width interval if they are 0, p = 0 otherwise. InputError for fewer than 2 differences or non-positive
    sizes.
    """
    d = _splits(d, "corrected t-test")
    if not (n_train > 0 and n_test > 0):
        raise InputError(f"n_train and n_test must be > 0; got {n_train}, {n_test}")
    return _t_test(d, 1.0 / d.size + n_test / n_train, level)


def bayes_correlated_t(d, *, n_train, n_test, rope=ROPE):
    """Bayesian correlated t-test (Corani and Benavoli 2015) of paired differences ``d``.

    Returns ``(p_better, p_rope, p_worse)``: the posterior mass of the mean difference below ``-rope``, within
    ``[-rope, rope]`` and above ``rope``. The posterior is Student's t, ``J - 1`` degrees of freedom, location the
    mean and scale ``sqrt((1/J + rho/(1 - rho)) s^2)``, ``rho = n_test / (n_test + n_train)``; with all differences
    equal it is a point mass at their value.
    """
    d = _float_array(d, "d")
    J = d.size
    if J < 2:
        raise InputError(f"the Bayesian correlated t-test needs at least 2 paired splits; got {J}")
    if rope < 0:
        raise InputError(f"rope must be >= 0; got {rope}")
    rho = n_test / (n_test + n_train)
    mean = float(d.mean())
    scale = math.sqrt((1.0 / J + rho / (1.0 - rho)) * float(d.var(ddof=1)))
    if scale == 0.0:
        return float(mean < -rope), float(-rope <= mean <= rope), float(mean > rope)
    lo = float(stats.t.cdf(-rope, J - 1, loc=mean, scale=scale))
    hi = float(stats.t.sf(rope, J - 1, loc=mean, scale=scale))
    return lo, max(0.0, 1.0 - lo - hi), hi


def wilcoxon_p(d):
    """Two-sided p-value of the Wilcoxon signed-rank test of ``d`` (zero differences dropped); 1 if all are 0."""
    d = _float_array(d, "d")
    if d.size < 2:
        raise InputError(f"the Wilcoxon test needs at least 2 paired splits; got {d.size}")
    if not np.any(d != 0):
        return 1.0
    return float(stats.wilcoxon(d).pvalue)


def compare_pair(a, b, *, n_train, n_test, rope=ROPE):
    """Every statistic of one comparison of errors ``a`` (the method) with ``b`` (the one compared with), paired
    by position: a dict with n_splits, mean_diff, ci_low, ci_high, p_corrected_t, p_wilcoxon, p_better, p_rope,
    p_worse and note (NaN and :data:`NO_TEST` with fewer than 2 pairs)."""
    d = _float_array(a, "a") - _float_array(b, "b")
    out = {"n_splits": int(d.size), "note": ""}
    if d.size < 2:
        out["mean_diff"] = float(d.mean()) if d.size else math.nan
        for k in (
            "ci_low",
            "ci_high",
            "p_corrected_t",
            "paired_ci_low",
            "paired_ci_high",
            "p_paired_t",
            "p_wilcoxon",
            "p_better",
            "p_rope",
            "p_worse",
        ):
            out[k] = math.nan
        out["note"] = NO_TEST
        return out
    mean, lo, hi, p = corrected_t(d, n_train=n_train, n_test=n_test)
    _, plo, phi, pp = paired_t(d)
    pb, pr, pw = bayes_correlated_t(d, n_train=n_train, n_test=n_test, rope=rope)
    out.update(
        mean_diff=mean,
        ci_low=lo,
        ci_high=hi,
        p_corrected_t=p,
        paired_ci_low=plo,
        paired_ci_high=phi,
        p_paired_t=pp,
        p_wilcoxon=wilcoxon_p(d),
        p_better=pb,
        p_rope=pr,
        p_worse=pw,
    )
    return out


def holm(p):
    """Holm-adjusted p-values (Holm 1979, step-down: the i-th smallest of m times ``m - i + 1``, then the running
    maximum, capped at 1; equal to statsmodels' ``multipletests(method="holm")``, whose Holm branch collects
    garbage on every call, which made a table's comparisons several times slower); NaN entries stay NaN."""
    p = np.asarray(p, dtype=float)
    out = np.full(p.shape, math.nan)
    ok = np.flatnonzero(np.isfinite(p))
    if ok.size:
        order = ok[np.argsort(p[ok], kind="mergesort")]
        m = order.size
        scaled = p[order] * (m - np.arange(m))
        out[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return out


def _plain(v):
    return v.item() if isinstance(v, np.generic) else v


def _check(df):
    need = CELL + ["method", "seed", "error", "n_test"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise InputError(
            f"the results table lacks columns {missing} needed for the paired comparisons; expected the "
            "aggregate table (results/{study}/aggregate/results.csv)"
        )
    for c in ("error", "n_test"):
        v = pd.to_numeric(df[c], errors="coerce")
        bad = ~np.isfinite(v) | (v <= 0 if c == "n_test" else v < 0)
        if bad.any():
            row = {k: _plain(v) for k, v in df.loc[bad].iloc[0].items()}
            where = {k: row[k] for k in CELL + ["method", "seed"]}
            raise InputError(
                f"results row {where}: {c} = {row[c]!r}; "
                f"expected a finite number {'> 0' if c == 'n_test' else '>= 0'}"
            )


def cell_comparisons(cell, *, n_train, pm="PM", rope=ROPE):
    """The comparisons of one cell: a list of dicts (method, versus, best and :func:`compare_pair`'s keys, with
    p_holm over the cell's distinct pairs).

    ``cell``: rows of one (protocol, source, activity, n_train) with method, seed, error and n_test.
    """
    errors = cell.pivot_table(index="seed", columns="method", values="error", aggfunc="first")
    n_test = cell.pivot_table(index="seed", columns="method", values="n_test", aggfunc="first")
    methods = list(errors.columns)
    means = errors.mean()
    best = str(means.idxmin())
    refs = [r for r in dict.fromkeys([pm, best]) if r in methods]
    rows, pairs = [], {}
    for ref in refs:
        for m in methods:
            if m == ref:
                continue
            common = errors[[m, ref]].dropna().index
            nt = float(n_test.loc[common, [m, ref]].to_numpy().mean()) if len(common) else math.nan
            r = {"method": m, "versus": ref, "best": best}
            r.update(
                compare_pair(
                    errors.loc[common, m],
                    errors.loc[common, ref],
                    n_train=float(n_train),
                    n_test=nt,
                    rope=rope,
                )
            )
            key = frozenset((m, ref))
            pairs.setdefault(key, (r["p_corrected_t"], r["p_paired_t"]))
            r["_pair"] = key
            rows.append(r)
    keys = list(pairs)
    corrected = dict(zip(keys, holm([pairs[k][0] for k in keys])))
    plain = dict(zip(keys, holm([pairs[k][1] for k in keys])))
    for r in rows:
        key = r.pop("_pair")
        r["p_holm"] = float(corrected[key])
        r["p_holm_paired"] = float(plain[key])
    return rows


def comparisons(df, *, pm="PM", rope=ROPE):
    """Every cell's comparisons (:func:`cell_comparisons`) as one DataFrame with columns :data:`COLUMNS`, sorted
    by cell, then versus PM before versus the best, then method.

    ``df``: the aggregate table (one row per job with protocol, source, activity, n_train, method, seed, error and
    n_test). InputError naming the row and column for a missing or invalid value.
    """
    _check(df)
    rows = []
    for key, g in df.groupby(CELL, sort=True):
        for r in cell_comparisons(g, n_train=key[3], pm=pm, rope=rope):
            rows.append({**dict(zip(CELL, key)), **r})
    out = pd.DataFrame(rows, columns=COLUMNS)
    if out.empty:
        return out
    out["_ref"] = (out["versus"] != pm).astype(int)
    out = out.sort_values(CELL + ["_ref", "method"], kind="mergesort").drop(columns="_ref")
    return out.reset_index(drop=True)


def published(comp):
    """The published comparisons: exactly :data:`PUBLISHED_COLUMNS`."""
    return comp[PUBLISHED_COLUMNS].reset_index(drop=True)


# ----------------------------------------------------------------------------------------- verdicts and ties
def tied_with_best(comp, *, alpha=ALPHA, test=TIE_TEST):
    """{(protocol, source, activity, n_train): {method, ...}}: the cell's best method and the methods statistically
    indistinguishable from it (Holm-adjusted p of ``test`` >= ``alpha`` against it, :data:`TESTS`). Methods of a cell with no test
    (fewer than 2 common splits) are left out: nothing is claimed for them, and a cell with no test at all has no
    entry."""
    out = {}
    if comp.empty:
        return out
    col = test_column(test)
    c = comp[(comp["versus"] == comp["best"]) & comp[col].notna()]
    for key, g in c.groupby(CELL, sort=False):
        out[tuple(key)] = set(g.loc[g[col] >= alpha, "method"]) | {g["best"].iloc[0]}
    return out


def verdict(p_holm, mean_diff, *, alpha=ALPHA):
    """ "better", "worse", "tied" (Holm-adjusted p >= ``alpha``) or "untested" (NaN p) of a comparison, from the
    method's point of view (``mean_diff`` < 0: lower error)."""
    if p_holm is None or not np.isfinite(p_holm):
        return "untested"
    if p_holm >= alpha:
        return "tied"
    return "better" if mean_diff < 0 else "worse"


def pm_counts(comp, *, pm="PM", nn="NN1", alpha=ALPHA, test=TIE_TEST):
    """Per (protocol, source) and opponent ("best", ``nn``): in how many cells PM is significantly worse, tied or
    better (Holm-adjusted p of ``test``, :data:`TESTS`), and untested; against the best, cells where PM is the
    best count as ``pm_best``. ``worse_corrected``, ``tied_corrected`` and ``better_corrected``: the same counts by
    the corrected resampled t-test, the sensitivity to the assumption of a new data set of independent frames. A
    DataFrame with protocol, source, versus, cells, worse, tied, better, untested, pm_best and those three."""
    cols = [
        "protocol",
        "source",
        "versus",
        "cells",
        "worse",
        "tied",
        "better",
        "untested",
        "pm_best",
        "worse_corrected",
        "tied_corrected",
        "better_corrected",
    ]
    col, corrected = test_column(test), test_column("corrected")
    if comp.empty:
        return pd.DataFrame(columns=cols)
    rows = []
    for (protocol, source), g in comp.groupby(["protocol", "source"], sort=True):
        cells = g.drop_duplicates(CELL)
        for what in ("best", nn):
            counts = dict.fromkeys(cols[4:], 0)
            n = 0
            for _, c in cells.iterrows():
                key = tuple(c[k] for k in CELL)
                gc = g[(g[CELL] == pd.Series(dict(zip(CELL, key)))).all(axis=1)]
                opp = c["best"] if what == "best" else nn
                if what == "best" and c["best"] == pm:
                    counts["pm_best"] += 1
                    n += 1
                    continue
                r, sign = gc[(gc["method"] == pm) & (gc["versus"] == opp)], 1.0
                if r.empty:
                    r, sign = gc[(gc["method"] == opp) & (gc["versus"] == pm)], -1.0
                    if r.empty:
                        continue
                r = r.iloc[0]
                counts[verdict(r[col], sign * r["mean_diff"], alpha=alpha)] += 1
                v = verdict(r[corrected], sign * r["mean_diff"], alpha=alpha)
                if v != "untested":
                    counts[f"{v}_corrected"] += 1
                n += 1
            if n:
                rows.append(
                    {"protocol": protocol, "source": source, "versus": what, "cells": n, **counts}
                )
    return pd.DataFrame(rows, columns=cols)


# --------------------------------------------------------------------------------------- across the cells
def cell_means(df, *, protocol, source):
    """The cells (activity, n_train) x methods table of mean errors over splits for one protocol and source, the
    cells where every method ran only (a critical-difference diagram needs complete blocks)."""
    d = df[(df["protocol"] == protocol) & (df["source"] == source)]
    w = d.pivot_table(
        index=["activity", "n_train"], columns="method", values="error", aggfunc="mean"
    )
    return w.dropna(axis=0, how="any")


def cd_ranks(means, *, alpha=ALPHA):
    """``(ranks, p)``: the mean rank of each method over the cells (rank 1: lowest error; ties averaged) and the
    Holm-adjusted p-values of pairwise Wilcoxon signed-rank tests over the cells (scikit-posthocs
    ``posthoc_wilcoxon``, a methods x methods DataFrame, diagonal 1). Needs at least 2 cells and 2 methods."""
    import scikit_posthocs as sp

    if means.shape[0] < 2 or means.shape[1] < 2:
        raise InputError(
            f"a critical-difference diagram needs at least 2 cells and 2 methods; got {means.shape[0]} cells and "
            f"{means.shape[1]} methods"
        )
    ranks = means.rank(axis=1, method="average").mean(axis=0)
    long = means.reset_index(drop=True).melt(
        var_name="method", value_name="error", ignore_index=False
    )
    long = long.reset_index().rename(columns={"index": "cell"}).sort_values(["method", "cell"])
    p = sp.posthoc_wilcoxon(long, val_col="error", group_col="method", p_adjust="holm", sort=True)
    p = p.loc[list(means.columns), list(means.columns)].astype(float)
    for m in means.columns:
        p.loc[m, m] = 1.0
    return ranks, p.fillna(1.0)


def cd_axis(ax, df, *, protocol, source, labels=None, alpha=ALPHA):
    """Draw the critical-difference diagram of one protocol and source on ``ax`` (scikit-posthocs
    ``critical_difference_diagram``): methods at their mean rank over the cells, bars joining methods whose
    pairwise Wilcoxon-Holm p >= ``alpha``. With fewer than 2 complete cells the axis says so instead."""
    import scikit_posthocs as sp

    labels = labels or {}
    means = cell_means(df, protocol=protocol, source=source)
    title = f"{protocol.replace('_', '-')} protocol: mean rank over {means.shape[0]} (activity, N) cells"
    if means.shape[0] < 2 or means.shape[1] < 2:
        ax.text(
            0.5,
            0.5,
            f"{means.shape[0]} cell(s) with every method: no ranking test (at least 2 needed)",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
        ax.set_axis_off()
        ax.set_title(title, fontsize=8)
        return
    ranks, p = cd_ranks(means, alpha=alpha)
    names = {m: labels.get(m, m) for m in means.columns}
    sp.critical_difference_diagram(
        ranks.rename(index=names),
        p.rename(index=names, columns=names),
        ax=ax,
        alpha=alpha,
        label_fmt_left="{label} ({rank:.2f})  ",
        label_fmt_right="  ({rank:.2f}) {label}",
        label_props={"fontsize": 7},
        crossbar_props={"linewidth": 2},
    )
    ax.set_title(title + f"; bars: Wilcoxon-Holm $p \\geq {alpha:g}$", fontsize=8)


def cd_diagram(df, *, source, protocols, labels=None, alpha=ALPHA):
    """The critical-difference diagrams of one source, one panel per protocol (:func:`cd_axis`). Returns the
    figure."""
    # pyplot as .plots sets it up (Agg backend, the report's fonts)
    from .plots import TEXT_WIDTH, plt

    protocols = list(protocols)
    if not protocols:
        raise InputError("cd_diagram needs at least one protocol")
    fig, axes = plt.subplots(
        len(protocols), 1, figsize=(min(TEXT_WIDTH, 6.0), 1.9 * len(protocols)), squeeze=False
    )
    for ax, protocol in zip(axes[:, 0], protocols):
        cd_axis(ax, df, protocol=protocol, source=source, labels=labels, alpha=alpha)
    fig.suptitle(f"Critical-difference diagram, {source} data", fontsize=9)
    fig.tight_layout()
    return fig


def read_comparisons(path):
    """Read a comparisons table (``results/{study}/aggregate/comparisons.csv`` or the published
    ``reports/published/<study>-comparisons.csv``); DataFileError naming the file if it cannot be read or lacks a
    column of :data:`PUBLISHED_COLUMNS`. A published table (no ``best`` column) gets ``best`` back: the
    ``versus`` of a cell that is not PM, else PM."""
    from ..errors import DataFileError

    c = read_csv(path, "the comparisons", keep_default_na=True)
    missing = [k for k in PUBLISHED_COLUMNS if k not in c.columns]
    if missing:
        raise DataFileError(path, f"missing columns {missing}; expected {PUBLISHED_COLUMNS}")
    if "best" not in c.columns:
        other = c[c["versus"] != "PM"].groupby(CELL)["versus"].first()
        c["best"] = [other.get(tuple(k), "PM") for k in c[CELL].itertuples(index=False)]
    if "note" not in c.columns:
        c["note"] = np.where(c["n_splits"] < 2, NO_TEST, "")
    c["note"] = c["note"].fillna("")
    return c
