"""The report's section "Today's metrics and baselines": joint-position errors, where PM stands against today's
baselines, and the quality of the predictive distributions (proper scores, PIT, split-conformal coverage).

Joint positions come from forward kinematics of the predicted and true angles on one skeleton per data set
(:mod:`bsrbench.kinematics`): MPJPE is the mean per-joint position error with the root at the origin, PA-MPJPE
the same after a similarity (Procrustes) alignment of the prediction to the truth, both in mm (Ionescu et al.,
TPAMI 2014). The proper scores (:mod:`bsrbench.scores`) exist only for methods with a predictive distribution;
the others have empty cells.
"""

import math

import numpy as np
import pandas as pd

from .comparisons import verdict
from .latex import best_mask, bold, escape, figure, fixed, power_of_ten, table
from .tables import activity_label

#: Columns of the uncertainty table, with their headers.
SCORE_COLUMNS = {
    "error": r"error ($^\circ$)",
    "nlpd": "NLPD",
    "nlpd_median": "NLPD (median)",
    "crps": r"CRPS ($^\circ$)",
    "coverage_90": r"90\% cov.",
    "conformal_coverage": r"conformal 90\% cov.",
}


def _means(df, column):
    """Mean of ``column`` over seeds per (protocol, source, activity, paper_activity, method, n_train)."""
    d = df.copy()
    d["paper_activity"] = d.get("paper_activity", "").fillna("").astype(str)
    keys = ["protocol", "source", "activity", "paper_activity", "method", "n_train"]
    return d.groupby(keys, sort=True)[column].mean().reset_index()


def position_table(df, *, source, protocol, methods, labels, column="mpjpe_mm", digits=1):
    """LaTeX table of the mean ``column`` (mm) over seeds per (activity, N) and method; best of a row in bold.
    None when no row of ``source`` and ``protocol`` has a value."""
    if column not in df.columns:
        return None
    d = df[(df["source"] == source) & (df["protocol"] == protocol) & df[column].notna()]
    if d.empty:
        return None
    m = _means(d, column)
    methods = [x for x in methods if x in set(m["method"])]
    what = "MPJPE" if column == "mpjpe_mm" else "PA-MPJPE"
    caption = (
        f"{what} (mm) on the {escape(source)} data, protocol ``{escape(protocol)}'': mean over "
        "seeds; best of each row in bold."
    )
    body = []
    for activity, g in m.groupby("activity", sort=False):
        if body:
            body.append(r"\midrule")
        name = escape(activity_label(activity, g["paper_activity"].iloc[0]))
        for n, c in g.groupby("n_train", sort=True):
            c = c.set_index("method")[column]
            vals = [float(c[x]) if x in c.index else math.nan for x in methods]
            best = best_mask(vals, digits)
            cells = [
                bold(fixed(v, digits)) if b and np.isfinite(v) else fixed(v, digits)
                for v, b in zip(vals, best)
            ]
            body.append([name, str(int(n))] + cells)
            name = ""
    text = table(
        body,
        spec="@{}lr" + "r" * len(methods) + "@{}",
        head=[["Activity", "N"] + [escape(labels.get(x, x)) for x in methods]],
        caption=caption,
        label=f"tab:{column}-{source}-{protocol}",
        size=r"\scriptsize",
        tabcolsep="2.5pt",
    )
    return text + "\n"


def scores_summary(df, *, methods):
    """Per (protocol, source, method) with a proper score: the means over all its rows of the test error, NLPD,
    CRPS, the 90% coverage of its own interval and of the split-conformal one, the median NLPD (the log score
    punishes an over-confident split without bound, so a few splits can dominate the mean) and the number of
    rows."""
    if "nlpd" not in df.columns:
        return pd.DataFrame(columns=["protocol", "source", "method", *SCORE_COLUMNS, "n"])
    d = df[df["method"].isin(methods) & df["nlpd"].notna()].copy()
    means = [c for c in SCORE_COLUMNS if c != "nlpd_median"]
    for c in means:
        if c not in d.columns:
            d[c] = np.nan
    g = d.groupby(["protocol", "source", "method"], sort=True)
    out = g[means].mean()
    out["nlpd_median"] = g["nlpd"].median()
    out = out[list(SCORE_COLUMNS)]
    out["n"] = g.size()
    out = out.reset_index()
    order = {m: i for i, m in enumerate(methods)}
    return out.sort_values(
        ["protocol", "source", "method"], key=lambda s: s.map(order) if s.name == "method" else s
    ).reset_index(drop=True)


def scores_latex(summary, *, labels):
    """LaTeX table of :func:`scores_summary`; None when no method has a proper score."""
    if summary.empty:
        return None
    caption = (
        r"Predictive distributions: means over all cells and seeds of the test error, NLPD (nats per "
        r"angle, densities per degree; also its median over the splits), CRPS, and the empirical coverage of each method's central 90\% "
        r"interval and of a split-conformal 90\% interval (lower NLPD and CRPS are better; a coverage near "
        r"0.90 is calibrated)."
    )
    rows = [
        [escape(r.protocol), escape(r.source), escape(labels.get(r.method, r.method))]
        + [
            "" if v is None or not np.isfinite(v) else power_of_ten(v)
            for v in (getattr(r, c) for c in SCORE_COLUMNS)
        ]
        for r in summary.itertuples(index=False)
    ]
    text = table(
        rows,
        spec="@{}lll" + "r" * len(SCORE_COLUMNS) + "@{}",
        head=[["Protocol", "Source", "Method", *SCORE_COLUMNS.values()]],
        caption=caption,
        label="tab:uncertainty",
    )
    return text + "\n"


def standing(comp, *, today, pm="PM", alpha=0.05):
    """Per (protocol, source): cells where PM is significantly worse than, tied with, or better than each of
    today's baselines (corrected resampled t-test, Holm-adjusted; ``comp`` from
    :func:`bsrbench.reporting.comparisons.compare_all`). Columns protocol, source, method, worse, tied, better."""
    cols = ["protocol", "source", "method", "worse", "tied", "better"]
    if comp is None or comp.empty:
        return pd.DataFrame(columns=cols)
    c = comp[(comp["versus"] == pm) & comp["method"].isin(today) & comp["p_holm"].notna()]
    rows = []
    for (protocol, source, method), g in c.groupby(["protocol", "source", "method"], sort=True):
        # the baseline's verdict against PM: its "better" is PM's "worse"
        v = [verdict(p, d, alpha=alpha) for p, d in zip(g["p_holm"], g["mean_diff"])]
        rows.append(
            {
                "protocol": protocol,
                "source": source,
                "method": method,
                "worse": v.count("better"),
                "tied": v.count("tied"),
                "better": v.count("worse"),
            }
        )
    return pd.DataFrame(rows, columns=cols)


def standing_sentences(st, *, labels, pm="PM"):
    """One sentence per (protocol, source) from :func:`standing`."""
    out = []
    for (protocol, source), g in st.groupby(["protocol", "source"], sort=True):
        parts = [
            f"{labels.get(r.method, r.method)} {r.worse}/{r.tied}/{r.better}"
            for r in g.itertuples()
        ]
        out.append(
            f"On the {source} data ({protocol} splits), {labels.get(pm, pm)} is significantly worse than / "
            f"tied with / better than today's baselines in this many cells: "
            + "; ".join(parts)
            + "."
        )
    return out


def pit_histograms(values, bins=10):
    """Density histogram (bins,) of PIT values on [0, 1] (a flat 1 for a calibrated forecast)."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    h, _ = np.histogram(np.clip(v, 0.0, 1.0), bins=bins, range=(0.0, 1.0))
    return h / max(v.size, 1) * bins


def plot_pit(panels, *, labels, bins=10):
    """Figure of PIT histograms: one row per source, one column per method. ``panels``: {(source, method): PIT
    values}. Returns the matplotlib figure."""
    import matplotlib.pyplot as plt

    sources = sorted({s for s, _ in panels})
    methods = list(dict.fromkeys(m for _, m in panels))
    if not panels:
        # a study without a predictive distribution: the figure says so (the report's section does too)
        fig, ax = plt.subplots(figsize=(3.0, 0.8))
        ax.set_axis_off()
        ax.text(
            0.5,
            0.5,
            "no PIT values: no method with a predictive\ndistribution was run",
            ha="center",
            va="center",
            fontsize=8,
        )
        return fig
    fig, axes = plt.subplots(
        len(sources),
        len(methods),
        figsize=(1.9 * len(methods) + 0.6, 1.7 * len(sources) + 0.5),
        squeeze=False,
        sharex=True,
        sharey=True,
    )
    edges = np.linspace(0, 1, bins + 1)
    for i, s in enumerate(sources):
        for j, m in enumerate(methods):
            ax = axes[i][j]
            if (s, m) in panels:
                ax.bar(
                    edges[:-1],
                    pit_histograms(panels[(s, m)], bins),
                    width=1 / bins,
                    align="edge",
                    color="0.6",
                    edgecolor="0.3",
                    linewidth=0.5,
                )
            else:
                ax.text(0.5, 0.5, "no draws", ha="center", va="center", fontsize=8)
            ax.axhline(1.0, color="k", lw=0.8, ls="--")
            ax.set_xlim(0, 1)
            if i == 0:
                ax.set_title(labels.get(m, m), fontsize=9)
            if j == 0:
                ax.set_ylabel(f"{s}\ndensity", fontsize=8)
            if i == len(sources) - 1:
                ax.set_xlabel("PIT", fontsize=8)
            ax.tick_params(labelsize=7)
    fig.tight_layout()
    return fig


def section_latex(df, comp, *, methods, groups, labels, pit_figure=None, pm="PM"):
    """The LaTeX of the section (MPJPE and PA-MPJPE tables, PM against today's baselines, uncertainty)."""
    today = [m for m in methods if groups.get(m) == "today"]
    out = [
        r"\section{Today's metrics and baselines}",
        "",
        r"Joint positions by forward kinematics of the predicted and the true angles on one skeleton per data "
        r"set (the authors' skeleton for the hsc features, the trial's own for the CMU data), root at the "
        r"origin: MPJPE is the mean per-joint position error, PA-MPJPE the same after a similarity "
        r"(Procrustes) alignment of the prediction to the truth, both in mm.",
        "",
    ]
    if today:
        st = standing(comp, today=today, pm=pm)
        names = ", ".join(labels.get(m, m) for m in today)
        out += [
            rf"Today's baselines ({escape(names)}) are tuned by the same cross-validation as the paper's "
            r"methods (Tables~I--II, second block).",
        ]
        out += [escape(t) for t in standing_sentences(st, labels=labels, pm=pm)]
        out.append("")
    for protocol in sorted(df["protocol"].unique()):
        for source in sorted(df["source"].unique()):
            for column in ("mpjpe_mm", "pa_mpjpe_mm"):
                t = position_table(
                    df,
                    source=source,
                    protocol=protocol,
                    methods=methods,
                    labels=labels,
                    column=column,
                )
                if t:
                    out.append(t)
    out += [r"\subsection{Uncertainty}", ""]
    summary = scores_summary(df, methods=methods)
    t = scores_latex(summary, labels=labels)
    if t is None:
        out.append("No method of this study gives a predictive distribution.")
        return "\n".join(out) + "\n"
    out += [
        r"NLPD and CRPS are proper scores (Gneiting and Raftery, 2007), per angle and test frame, averaged. "
        r"For a Gaussian prediction (a predictive mean and std, e.g. RVM's and the GP's) both are in closed "
        r"form; PM's come from its posterior "
        r"predictive draws (each retained sample's prediction plus its noise): the CRPS is the unbiased sample "
        r"estimate and the NLPD that of the moment-matched Gaussian. A sample CRPS and a closed-form CRPS "
        r"estimate the same quantity but are not strictly comparable at small sample sizes (Zamo and Naveau, "
        r"2018). The split-conformal interval (Lei et al., 2018) refits a method on three quarters of the "
        r"training frames (with its \texttt{cv\_params}, for PM the CV's 300 sweeps: the guarantee holds for "
        r"any point predictor) and takes each angle's radius from its errors on the rest; it is the coverage "
        r"reference beside the Bayesian intervals (methods with \texttt{conformal: false} have none). The log "
        r"score punishes an over-confident split without bound, so the median NLPD is given beside the mean.",
        "",
        t,
    ]
    if pit_figure:
        out.append(
            figure(
                pit_figure,
                r"PIT histograms (all angles and test frames of every activity and seed at the largest "
                r"N): flat at the dashed line for a calibrated forecast, U-shaped for an over-confident one.",
                options=r"width=\linewidth,height=0.35\textheight,keepaspectratio",
                label="fig:pit",
            )
        )
    return "\n".join(out) + "\n"


def pit_panels(arrays, keys):
    """The PIT values of each panel of :func:`plot_pit`: ``{(source, method): values}``, pooled over the saved
    fits ``arrays`` (one mapping per fit, e.g. from :func:`bsrbench.io.read_npz`) whose panels are ``keys``
    (one (source, method) per fit); a fit without PIT values adds none."""
    panels = {}
    for a, key in zip(arrays, keys):
        if "pit" in a:
            panels.setdefault(tuple(key), []).append(np.asarray(a["pit"], dtype=float).ravel())
    return {k: np.concatenate(v) for k, v in panels.items()}
