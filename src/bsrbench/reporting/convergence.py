"""Convergence of the MCMC methods and the PM ablation: tables, figures and the report section
"Why PM trails the paper here", all computed from the aggregate table.

A method run with several chains per split (config key ``methods.<M>.chains``) has, in its rows of the
aggregate, ``n_chains`` and the split R-hat and bulk ESS across chains (ArviZ; Vehtari, Gelman, Simpson,
Carpenter & Buerkner 2021) of the log-likelihood, g_xy, g_s (g_nx, g_ny with separate noise precisions)
and the test error of each retained posterior sample (see :func:`bsrbench.convergence.convergence_summary`).
Rows of one-chain methods have NaN there. The ablation runs PM variants as methods of their own
(``config/ablation.yaml``); the variants of a study are the methods with the estimator of the trace method.
"""

import json
import math

import numpy as np
import pandas as pd

from ..convergence import CONVERGENCE_SERIES
from ..io import atomic_path
from .tables import activity_label, best_mask, format_cell, latex_escape, paper_key, summarize

#: Columns the aggregate always has (NaN where not computed): chains per split, R-hat and bulk ESS.
CONVERGENCE_COLUMNS = ["n_chains"] + [
    f"{s}_{n}" for n in CONVERGENCE_SERIES for s in ("r_hat", "ess_bulk")
]
#: R-hat below this counts as converged in the goal (the ablation's threshold) ...
RHAT_OK = 1.05
#: ... and below this, the threshold Vehtari et al. (2021) recommend, reported beside it.
RHAT_STRICT = 1.01
#: Per-job columns the aggregate may have (rows written before them have none): tail ESS and the Monte Carlo
#: standard error of each series (ArviZ ``ess(method="tail")``, ``mcse``). Tables show a dash where absent.
EXTRA_CONVERGENCE_COLUMNS = [f"{s}_{n}" for n in CONVERGENCE_SERIES for s in ("ess_tail", "mcse")]
#: Math labels of the per-sweep traces.
#: Math names in titles are set at 10 pt: their sub- and superscripts (0.7 of it) then print at 7 pt.
MATH_TITLE_PT = 10
TRACE_LABELS = {
    "log_likelihood": "log-likelihood",
    "g_xy": r"$\gamma_{xy}$ (noise precision)",
    "g_s": r"$\gamma_s$ (code precision)",
    "g_x": r"$\gamma_x$ (atom precision, $D^x$)",
    "g_y": r"$\gamma_y$ (atom precision, $D^y$)",
    "g_nx": r"$\gamma_{nx}$ (noise precision of $x$)",
    "g_ny": r"$\gamma_{ny}$ (noise precision of $y$)",
    "active_atoms": "active atoms",
    "acceptance": "logit acceptance",
}
_PRECISIONS = ("g_xy", "g_s", "g_x", "g_y", "g_nx", "g_ny")


def with_convergence_columns(df):
    """``df`` with every :data:`CONVERGENCE_COLUMNS` column (NaN where absent), placed after the others."""
    df = df.copy()
    for c in CONVERGENCE_COLUMNS:
        if c not in df.columns:
            df[c] = math.nan
    return df[[c for c in df.columns if c not in CONVERGENCE_COLUMNS] + CONVERGENCE_COLUMNS]


# ------------------------------------------------------------------------------------------------- summaries
def _with_extra_columns(df):
    """``df`` with every :data:`EXTRA_CONVERGENCE_COLUMNS` column, NaN where the rows have none."""
    missing = [c for c in EXTRA_CONVERGENCE_COLUMNS if c not in df.columns]
    return df.assign(**dict.fromkeys(missing, math.nan)) if missing else df


def converged(g, threshold=RHAT_OK):
    """Per row: whether the split R-hat of the log-likelihood and of g_xy are both below ``threshold``."""
    return (g["r_hat_log_likelihood"] < threshold) & (g["r_hat_g_xy"] < threshold)


def convergence_summary_table(df):
    """Per (protocol, source, activity, n_train, method) with several chains: splits, chains, the largest
    R-hat over splits and the smallest bulk and tail ESS over splits of each series, the largest Monte Carlo
    standard error of each series over splits (NaN for rows without tail ESS or MCSE), and the fraction of splits
    whose R-hat of the log-likelihood and of g_xy are both below :data:`RHAT_OK` (``converged``) and below
    :data:`RHAT_STRICT` (``converged_strict``)."""
    df = _with_extra_columns(with_convergence_columns(df))
    d = df[df["n_chains"].fillna(1) > 1]
    keys = ["protocol", "source", "activity", "n_train", "method"]
    if d.empty:
        return pd.DataFrame(columns=keys)
    rows = []
    for key, g in d.groupby(keys, sort=True):
        r = dict(zip(keys, key))
        r["splits"] = len(g)
        r["chains"] = int(g["n_chains"].max())
        for n in CONVERGENCE_SERIES:
            r[f"r_hat_{n}"] = (
                float(g[f"r_hat_{n}"].max()) if g[f"r_hat_{n}"].notna().any() else math.nan
            )
            for stat in ("ess_bulk", "ess_tail"):
                c = g[f"{stat}_{n}"]
                r[f"{stat}_{n}"] = float(c.min()) if c.notna().any() else math.nan
            c = g[f"mcse_{n}"]
            r[f"mcse_{n}"] = float(c.max()) if c.notna().any() else math.nan
        r["converged"] = float(converged(g, RHAT_OK).mean())
        r["converged_strict"] = float(converged(g, RHAT_STRICT).mean())
        rows.append(r)
    return pd.DataFrame(rows)


def _num(x, digits=2):
    return "--" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def convergence_latex(df, *, labels):
    """LaTeX tables of the convergence per method, over the activities, one table per (protocol, N)."""
    df = _with_extra_columns(with_convergence_columns(df))
    d = df[df["n_chains"].fillna(1) > 1]
    if d.empty:
        return (
            r"\noindent No method was run with several chains, so no R-hat was computed "
            r"(set \nolinkurl{methods.<M>.chains} $\geq 2$, e.g.\ \nolinkurl{config/ablation.yaml})."
        )
    out = []
    for (protocol, n_train), dp in d.groupby(["protocol", "n_train"], sort=True):
        acts = ", ".join(sorted(set(dp["activity"])))
        out += [
            r"\begin{table}[H]",
            r"\centering\footnotesize\setlength{\tabcolsep}{3pt}",
            rf"\caption{{Convergence, protocol ``{latex_escape(protocol)}'', $N={int(n_train)}$ (activities: "
            rf"{latex_escape(acts)}): "
            r"largest split $\hat R$ over splits, smallest bulk and tail ESS over splits (across the chains of each "
            r"split) and largest Monte Carlo standard error (MCSE, degrees) of the test error over splits; "
            r"$\ell$: log-likelihood, err: test error of each retained sample; the last two columns: share of splits "
            rf"with $\hat R < {RHAT_STRICT}$ (Vehtari et al.\ 2021) and $< {RHAT_OK}$ for both $\ell$ and "
            r"$\gamma_{xy}$; --: not recorded (results written before tail ESS and MCSE were).}",
            r"\begin{tabular}{@{}lrrrrrrrrrrrrrr@{}}",
            r"\toprule",
            r"& & & & \multicolumn{4}{c}{$\hat R$ (largest)} & \multicolumn{2}{c}{bulk ESS} & "
            r"\multicolumn{2}{c}{tail ESS} & MCSE & \multicolumn{2}{c}{$\hat R <$} \\",
            r"\cmidrule(lr){5-8}\cmidrule(lr){9-10}\cmidrule(lr){11-12}\cmidrule(lr){14-15}",
            r"Method & $N$ & splits & chains & $\ell$ & $\gamma_{xy}$ & $\gamma_s$ & "
            rf"err & $\ell$ & err & $\ell$ & err & err & {RHAT_STRICT} & {RHAT_OK} \\",
            r"\midrule",
        ]
        methods = list(dict.fromkeys(dp["method"]))
        for m in methods:
            for n, g in dp[dp["method"] == m].groupby("n_train", sort=True):

                def mx(c, g=g):
                    return float(g[c].max()) if g[c].notna().any() else math.nan

                def mn(c, g=g):
                    return float(g[c].min()) if g[c].notna().any() else math.nan

                out.append(
                    " & ".join(
                        [
                            latex_escape(labels.get(m, m)),
                            str(int(n)),
                            str(len(g)),
                            str(int(g["n_chains"].max())),
                            _num(mx("r_hat_log_likelihood")),
                            _num(mx("r_hat_g_xy")),
                            _num(mx("r_hat_g_s")),
                            _num(mx("r_hat_test_error")),
                            _num(mn("ess_bulk_log_likelihood"), 0),
                            _num(mn("ess_bulk_test_error"), 0),
                            _num(mn("ess_tail_log_likelihood"), 0),
                            _num(mn("ess_tail_test_error"), 0),
                            _num(mx("mcse_test_error"), 3),
                            f"{100 * converged(g, RHAT_STRICT).mean():.0f}\\%",
                            f"{100 * converged(g, RHAT_OK).mean():.0f}\\%",
                        ]
                    )
                    + r" \\"
                )
        out += [r"\bottomrule", r"\end{tabular}", r"\end{table}", ""]
    return "\n".join(out)


def _cell_stats(s, activity, n, method):
    c = s[(s["activity"] == activity) & (s["n_train"] == n) & (s["method"] == method)]
    if c.empty:
        return math.nan, math.nan
    return float(c["mean"].iloc[0]), float(c["std"].iloc[0])


def ablation_cells(df, *, variants, nn="NN1"):
    """Per (protocol, source, activity, n_train): the best variant's mean error, its name, 1-NN's mean, the best
    other method (baseline) and its mean. A DataFrame (empty if no variant ran)."""
    s = summarize(df)
    rows = []
    for key, g in s.groupby(
        ["protocol", "source", "activity", "paper_activity", "n_train"], sort=True
    ):
        g = g.set_index("method")["mean"]
        vs = g[[v for v in variants if v in g.index]].dropna()
        if vs.empty:
            continue
        others = g[[m for m in g.index if m not in variants and m != nn]].dropna()
        rows.append(
            {
                "protocol": key[0],
                "source": key[1],
                "activity": key[2],
                "paper_activity": key[3],
                "n_train": key[4],
                "best_variant": vs.idxmin(),
                "best_variant_error": float(vs.min()),
                "nn_error": float(g[nn]) if nn in g.index else math.nan,
                "best_baseline": others.idxmin() if len(others) else "",
                "best_baseline_error": float(others.min()) if len(others) else math.nan,
            }
        )
    return pd.DataFrame(rows)


#: Logit updates that leave the posterior invariant (Geweke-tested in tests/test_bsr_geweke.py); the two
#: "paper-*" updates of the ablation are the paper's printed acceptance ratios, which target another law.
EXACT_W_UPDATES = ("ess", "mh")


def _is_exact(params):
    """Whether a variant's params (dict or JSON string from the aggregate) select an exact logit update
    (``w_update`` absent means the default, elliptical slice)."""
    if isinstance(params, str):
        try:
            params = json.loads(params)
        except ValueError:
            params = {}
    return (params or {}).get("w_update", "ess") in EXACT_W_UPDATES


def goal_table(df, *, variants, nn="NN1"):
    """The issue's goal per (protocol, variant run with several chains): is it exact, in how many (source,
    activity, N) cells did every split converge (:data:`RHAT_OK` on the log-likelihood and g_xy), in how many is
    its mean error below 1-NN's, and in how many both. Sorted by protocol, then by cells with both (descending), then
    by the variant's mean rank of error among the variants over the cells. Empty DataFrame if no variant ran.

    Columns: protocol, method, exact, cells, converged, beats_nn, both, mean_rank, and converged_strict and
    both_strict: the same counts at :data:`RHAT_STRICT`.
    """
    df = with_convergence_columns(df)
    # only variants run with several chains: with one chain there is no R-hat, so convergence is not measured
    chained = set(df.loc[df["n_chains"].fillna(1) > 1, "method"])
    variants = [v for v in variants if v in chained]
    s = summarize(df)
    s = s[s["method"].isin(variants)]
    if s.empty:
        return pd.DataFrame(
            columns=[
                "protocol",
                "method",
                "exact",
                "cells",
                "converged",
                "beats_nn",
                "both",
                "mean_rank",
                "converged_strict",
                "both_strict",
            ]
        )
    keys = ["protocol", "source", "activity", "n_train"]
    nn_mean = (
        summarize(df[df["method"] == nn]).set_index(keys)["mean"]
        if (df["method"] == nn).any()
        else None
    )
    s = s.copy()
    s["rank"] = s.groupby(keys)["mean"].rank(method="average")
    conv = df[df["method"].isin(variants)].copy()
    conv["ok"] = converged(conv, RHAT_OK)
    conv["ok_strict"] = converged(conv, RHAT_STRICT)
    conv_cell = conv.groupby(keys + ["method"])["ok"].all()
    strict_cell = conv.groupby(keys + ["method"])["ok_strict"].all()
    exact = {
        m: _is_exact(g["params"].iloc[0]) if "params" in g else True
        for m, g in df[df["method"].isin(variants)].groupby("method")
    }
    rows = []
    for (protocol, m), g in s.groupby(["protocol", "method"], sort=True):
        conv_ok = beats = both = strict = both_strict = 0
        for _, r in g.iterrows():
            k = (r["protocol"], r["source"], r["activity"], r["n_train"])
            c = bool(conv_cell.get(k + (m,), False))
            cs = bool(strict_cell.get(k + (m,), False))
            b = nn_mean is not None and k in nn_mean.index and bool(r["mean"] < nn_mean[k])
            conv_ok += c
            beats += b
            both += c and b
            strict += cs
            both_strict += cs and b
        rows.append(
            {
                "protocol": protocol,
                "method": m,
                "exact": exact.get(m, True),
                "cells": len(g),
                "converged": conv_ok,
                "beats_nn": beats,
                "both": both,
                "mean_rank": float(g["rank"].mean()),
                "converged_strict": strict,
                "both_strict": both_strict,
            }
        )
    out = pd.DataFrame(rows)
    out["_exact_first"] = ~out["exact"]
    out = out.sort_values(
        ["protocol", "_exact_first", "both", "mean_rank"], ascending=[True, True, False, True]
    )
    return out.drop(columns="_exact_first").reset_index(drop=True)


def goal_sentence(df, *, variants, labels, nn="NN1"):
    """One paragraph (LaTeX) per protocol: the exact variant that best meets the goal (most cells converged and
    below 1-NN, then the best mean rank) and whether it meets it in at least three quarters of its cells."""
    t = goal_table(df, variants=variants, nn=nn)
    L = lambda m: latex_escape(labels.get(m, m))  # noqa: E731
    out = []
    for protocol, tp in t.groupby("protocol", sort=True):
        if not ((df["method"] == nn) & (df["protocol"] == protocol)).any():
            out.append(
                f"Protocol ``{latex_escape(protocol)}'': {L(nn)} was not run, so the goal is not judged."
            )
            continue
        ex = tp[tp["exact"]]
        if ex.empty:
            out.append(f"Protocol ``{latex_escape(protocol)}'': no exact variant was run.")
            continue
        top = ex.iloc[0]
        need = math.ceil(0.75 * int(top["cells"]))
        verdict = "meets" if int(top["both"]) >= need else "does not meet"
        out.append(
            f"Protocol ``{latex_escape(protocol)}'': the exact variant closest to the goal is {L(top['method'])}. "
            f"It has every split converged and a mean error below {L(nn)}'s in {int(top['both'])} of "
            f"{int(top['cells'])} cells (every split converged in {int(top['converged'])}, below {L(nn)} in "
            f"{int(top['beats_nn'])}), so it {verdict} the goal of at least {need} cells (three quarters). "
            f"At $\\hat R < {RHAT_STRICT}$ every split converged in {int(top['converged_strict'])} of its cells, "
            f"{int(top['both_strict'])} of them with a mean error below {L(nn)}'s."
        )
    return " ".join(out)


def goal_latex(df, *, variants, labels, nn="NN1"):
    """LaTeX table of :func:`goal_table`, one per protocol ('' if no variant ran)."""
    t = goal_table(df, variants=variants, nn=nn)
    if t.empty:
        return ""
    out = []
    for protocol, tp in t.groupby("protocol", sort=True):
        out += [
            r"\begin{table}[H]",
            r"\centering\footnotesize\setlength{\tabcolsep}{4pt}",
            rf"\caption{{The goal, protocol ``{latex_escape(protocol)}'': per PM variant, the (activity, $N$) cells "
            rf"in which every split converged ($\hat R < {RHAT_OK}$ on $\ell$ and $\gamma_{{xy}}$), those in which "
            rf"its mean error is below {latex_escape(labels.get(nn, nn))}'s, and both; rank: the variant's mean rank "
            r"of error among the variants over the cells (1 best); the last two columns: the same counts of converged "
            rf"cells and of both at $\hat R < {RHAT_STRICT}$ (Vehtari et al.\ 2021). Exact: its logit update leaves "
            r"the posterior invariant (Geweke test); the paper's printed ratios do not.}",
            r"\begin{tabular}{@{}lcrrrrrrr@{}}",
            r"\toprule",
            rf"& & & $\hat R < {RHAT_OK}$ & & $\hat R < {RHAT_OK}$ & & $\hat R < {RHAT_STRICT}$ & "
            rf"$\hat R < {RHAT_STRICT}$ \\",
            r"Variant & exact & cells & converged & beats "
            + latex_escape(labels.get(nn, nn))
            + r" & both & rank & converged & both \\",
            r"\midrule",
        ]
        for _, r in tp.iterrows():
            out.append(
                " & ".join(
                    [
                        latex_escape(labels.get(r["method"], r["method"])),
                        "yes" if r["exact"] else "no",
                        str(int(r["cells"])),
                        str(int(r["converged"])),
                        str(int(r["beats_nn"])),
                        str(int(r["both"])),
                        f"{r['mean_rank']:.1f}",
                        str(int(r["converged_strict"])),
                        str(int(r["both_strict"])),
                    ]
                )
                + r" \\"
            )
        out += [r"\bottomrule", r"\end{tabular}", r"\end{table}", ""]
    return "\n".join(out)


def ablation_latex(df, paper, *, variants, labels, nn="NN1", digits=2):
    """One table per (protocol, source, activity): variants x N, mean $\\pm$ std over splits, best in bold,
    1-NN, the best other method and (random protocol... and any protocol, for reference) the paper's PM."""
    s = summarize(df)
    out = []
    for (protocol, source, activity), sp in s.groupby(
        ["protocol", "source", "activity"], sort=True
    ):
        vs = [v for v in variants if v in set(sp["method"])]
        if not vs:
            continue
        sizes = sorted(int(n) for n in sp["n_train"].unique())
        pa = sp["paper_activity"].iloc[0]
        others = [m for m in dict.fromkeys(sp["method"]) if m not in variants and m != nn]
        rows = [(latex_escape(labels.get(v, v)), v) for v in vs]
        if nn in set(sp["method"]):
            rows.append((latex_escape(labels.get(nn, nn)), nn))
        grid = {m: [_cell_stats(sp, activity, n, m) for n in sizes] for _, m in rows}
        best_base = []
        for n in sizes:
            cand = [(m, _cell_stats(sp, activity, n, m)) for m in others]
            cand = [(m, st) for m, st in cand if np.isfinite(st[0])]
            best_base.append(
                min(cand, key=lambda t: t[1][0]) if cand else (None, (math.nan, math.nan))
            )
        bold = []
        for i in range(len(sizes)):
            col = [grid[m][i][0] for _, m in rows] + [best_base[i][1][0]]
            bold.append(best_mask(col, digits))
        out += [
            r"\begin{table}[H]",
            r"\centering\footnotesize\setlength{\tabcolsep}{4pt}",
            rf"\caption{{PM variants on {latex_escape(activity_label(activity, pa))} ({latex_escape(source)}), "
            rf"protocol ``{latex_escape(protocol)}'': mean error $\pm$ std (degrees) over splits; best of each "
            r"column in bold (variants, 1-NN and the best other method); italic: the paper's PM (random frames).}",
            r"\begin{tabular}{@{}l" + "c" * len(sizes) + "@{}}",
            r"\toprule",
            " & ".join(["Method"] + [f"$N={n}$" for n in sizes]) + r" \\",
            r"\midrule",
        ]
        for r, (lab, m) in enumerate(rows):
            if m == nn:
                out.append(r"\midrule")
            cells = [
                format_cell(*grid[m][i], bold=bold[i][r], digits=digits) for i in range(len(sizes))
            ]
            out.append(" & ".join([lab] + cells) + r" \\")
        cells = []
        for i in range(len(sizes)):
            m, st = best_base[i]
            cells.append(
                "--"
                if m is None
                else format_cell(*st, bold=bold[i][len(rows)], digits=digits)
                + rf" {{\scriptsize ({latex_escape(labels.get(m, m))})}}"
            )
        out.append(" & ".join(["best other method"] + cells) + r" \\")
        if paper is not None and paper_key(pa):
            pc = paper[(paper["key"] == paper_key(pa)) & (paper["method"] == "PM")].set_index(
                "n_train"
            )
            if any(n in pc.index for n in sizes):
                cells = [
                    r"\emph{"
                    + format_cell(
                        float(pc.at[n, "mean_deg"]), float(pc.at[n, "std_deg"]), digits=digits
                    )
                    + "}"
                    if n in pc.index
                    else ""
                    for n in sizes
                ]
                out.append(" & ".join([r"\emph{paper's PM}"] + cells) + r" \\")
        out += [r"\bottomrule", r"\end{tabular}", r"\end{table}", ""]
    return "\n".join(out)


def why_pm_sentences(df, paper, *, variants, labels, base="PM", nn="NN1"):
    """Plain sentences (LaTeX) drawn from the numbers: where the best variant beats 1-NN, which variants
    converge, and the base PM against the paper's."""
    L = lambda m: latex_escape(labels.get(m, m))  # noqa: E731
    out = []
    cells = ablation_cells(df, variants=variants, nn=nn)
    if cells.empty:
        return [f"No PM variant ({', '.join(L(v) for v in variants) or 'none'}) was run."]
    for protocol, c in cells.groupby("protocol", sort=True):
        have = c.dropna(subset=["nn_error"])
        wins = have[have["best_variant_error"] < have["nn_error"]]
        counts = c["best_variant"].value_counts()
        out.append(
            f"Protocol ``{latex_escape(protocol)}'': the best PM variant of each (activity, $N$) cell beats "
            f"{L(nn)} in {len(wins)} of {len(have)} cells; the best variant is "
            + ", ".join(f"{L(m)} in {k}" for m, k in counts.items())
            + " of them."
        )
        bb = c.dropna(subset=["best_baseline_error"])
        if len(bb):
            beat = int((bb["best_variant_error"] < bb["best_baseline_error"]).sum())
            out.append(
                f"Against the best other method of each cell ({', '.join(sorted({L(m) for m in bb['best_baseline']}))}), "
                f"the best PM variant is lower in {beat} of {len(bb)} cells."
            )
    conv = convergence_summary_table(df)
    conv = conv[conv["method"].isin(variants)] if not conv.empty else conv
    if conv.empty:
        out.append(
            "No PM variant was run with several chains, so convergence was not measured here."
        )
    else:
        per = conv.groupby("method", sort=False)["converged"].mean()
        strict = conv.groupby("method", sort=False)["converged_strict"].mean()
        good = [m for m, v in per.items() if v == 1.0]
        out.append(
            f"Convergence ($\\hat R < {RHAT_OK}$ on the log-likelihood and $\\gamma_{{xy}}$ in every split, "
            f"{int(conv['chains'].max())} chains): "
            + (", ".join(L(m) for m in good) if good else "no variant")
            + f" of {len(per)}; share of converged splits per variant: "
            + ", ".join(f"{L(m)} {100 * v:.0f}\\%" for m, v in per.items())
            + f"; at $\\hat R < {RHAT_STRICT}$ (Vehtari et al.\\ 2021): "
            + ", ".join(f"{L(m)} {100 * v:.0f}\\%" for m, v in strict.items())
            + "."
        )
        conv_good = conv[conv["method"].isin(good)]
        if len(conv_good) and conv_good["r_hat_g_s"].notna().any():
            out.append(
                f"For the converged variants the largest $\\hat R$ of $\\gamma_s$ is "
                f"{float(conv_good['r_hat_g_s'].max()):.2f} and the smallest bulk ESS of the log-likelihood "
                f"{float(conv_good['ess_bulk_log_likelihood'].min()):.0f}; for the others the largest "
                f"$\\hat R$ of the log-likelihood is "
                + (
                    f"{float(conv[~conv['method'].isin(good)]['r_hat_log_likelihood'].max()):.2f}."
                    if (~conv["method"].isin(good)).any()
                    else "not applicable (all converged)."
                )
            )
        # the goal as the goal table counts it: per protocol, cells with every split converged and a mean error
        # below 1-NN's, in at least three quarters of the variant's cells
        gt = goal_table(df, variants=variants, nn=nn)
        meet = gt[gt["exact"] & (gt["both"] >= np.ceil(0.75 * gt["cells"]))] if len(gt) else gt
        both = list(dict.fromkeys(meet["method"])) if len(meet) else []
        out.append(
            "Exact variants with every split converged and a mean error below "
            + L(nn)
            + "'s in at least three "
            "quarters of their cells (the goal): "
            + (", ".join(L(m) for m in both) if both else "none")
            + "."
        )
    if paper is not None and base in variants:
        # like with like: the paper's numbers are for random frames, so only this study's random protocol,
        # and per data source (the sources' features differ)
        s = summarize(df)
        sb = s[(s["method"] == base) & (s["protocol"] == "random")].copy()
        if sb.empty and (s["method"] == base).any():
            run = ", ".join(sorted(set(s.loc[s["method"] == base, "protocol"])))
            out.append(
                f"The paper's numbers are for random frames; this study ran only the {latex_escape(run)} "
                f"protocol, so {L(base)} is not compared with the paper's PM like for like."
            )
        else:
            pp = paper[paper["method"] == "PM"]
            m = sb.merge(pp, on=["key", "n_train"], suffixes=("", "_paper"))
            per_source = []
            for src, gs in m.groupby("source", sort=False):
                parts = [
                    f"$N={int(n)}$: {float(np.median(g['mean'])):.2f} against the paper's "
                    f"{float(np.median(g['mean_deg'])):.2f}"
                    for n, g in gs.groupby("n_train", sort=True)
                ]
                per_source.append(f"on the {latex_escape(src)} data, " + "; ".join(parts))
            if per_source:
                out.append(
                    f"{L(base)} here against the paper's PM (random protocol, as in the paper; median "
                    "over activities): " + "; ".join(per_source) + " degrees."
                )
    return out


def why_pm_section(df, paper, *, variants, labels, figures, base="PM", nn="NN1"):
    """The LaTeX section "Why PM trails the paper here" (input by reports/report.tex).

    ``figures``: list of (path relative to the study's report folder reports/{study}, caption).
    """
    lines = [
        "% generated from the study's aggregate table",
        r"\section{Why PM trails the paper here}",
        "",
    ]
    lines.append(
        r"The paper's PM is a Gibbs sampler; its numbers carry weight only if the chains have converged. Every PM "
        r"variant below is a method of its own (\texttt{config/ablation.yaml}); with several chains per split the "
        r"prediction pools the chains and the split R-hat and bulk ESS (ArviZ) are computed across them."
    )
    lines += (
        ["", r"\begin{itemize}"]
        + [
            r"\item " + t
            for t in why_pm_sentences(df, paper, variants=variants, labels=labels, base=base, nn=nn)
        ]
        + [r"\end{itemize}", ""]
    )
    lines += [r"\subsection*{Convergence}", convergence_latex(df, labels=labels), ""]
    goal = goal_latex(df, variants=variants, labels=labels, nn=nn)
    if goal:
        lines += [
            r"\subsection*{The goal: an exact PM that converges and beats "
            + latex_escape(labels.get(nn, nn))
            + "}",
            goal_sentence(df, variants=variants, labels=labels, nn=nn),
            "",
            goal,
            "",
        ]
    if len(variants) > 1 or nn in set(df["method"]):
        lines += [
            r"\subsection*{Ablation}",
            ablation_latex(df, paper, variants=variants, labels=labels, nn=nn),
            "",
        ]
    for f, caption in figures:
        lines += [
            r"\begin{figure}[H]",
            r"\centering",
            rf"\includegraphics[width=\linewidth,height=0.8\textheight,keepaspectratio]{{{f}}}",
            rf"\caption{{{caption}}}",
            r"\end{figure}",
        ]
    return "\n".join(lines) + "\n"


def write_why_pm(path, text):
    with atomic_path(path) as tmp:
        tmp.write_text(text)


# --------------------------------------------------------------------------------------------------- figures
def chain_traces(arrays):
    """``{name: (chains, sweeps)}`` of a saved fit (``chain_trace_<name>`` of a pooled split, or
    ``trace_<name>`` of a one-chain fit), plus ``draw_error`` (chains, retained samples) if saved."""
    out = {}
    for k, v in arrays.items():
        if k.startswith("chain_trace_"):
            out[k[len("chain_trace_") :]] = np.atleast_2d(np.asarray(v, dtype=float))
    if not out:
        for k, v in arrays.items():
            if k.startswith("trace_") and np.asarray(v).ndim == 1:
                out[k[len("trace_") :]] = np.asarray(v, dtype=float)[None, :]
    if "chain_draw_error" in arrays:
        out["draw_error"] = np.atleast_2d(np.asarray(arrays["chain_draw_error"], dtype=float))
    return out


def _log_axis(ax):
    """A log y axis with plain tick labels (no superscripts, which print below 7 pt) spread over the whole range
    shown (:func:`bsrbench.reporting.plots.label_log_axis`)."""
    from .plots import label_log_axis

    label_log_axis(ax)


def _informative(a):
    """A trace worth a panel: finite values that are not the same constant in every chain."""
    f = a[np.isfinite(a)]
    return f.size > 0 and np.ptp(f) > 0


def plot_chain_traces(arrays, *, title, n_burn_in=None):
    """Per-sweep traces of every chain of a split, overlaid (one colour per chain), burn-in shaded.

    Panels: log-likelihood, the precisions (log axis), active atoms, logit acceptance and the test error of
    each retained sample, each only if it was recorded and is not constant (e.g. elliptical slice sampling
    always moves, so its acceptance is 1 and gets no panel). Returns the figure.
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    tr = chain_traces(arrays)
    if n_burn_in is None and "n_burn_in" in arrays:
        n_burn_in = int(arrays["n_burn_in"])
    order = ["log_likelihood", *_PRECISIONS, "active_atoms", "acceptance", "draw_error"]
    names = [n for n in order if n in tr and _informative(tr[n])]
    names += sorted(n for n in tr if n not in order and _informative(tr[n]))
    n = max(1, len(names))
    ncols = 2 if n > 1 else 1
    nrows = math.ceil(n / ncols)
    from .plots import TEXT_WIDTH

    fig = plt.figure(figsize=(TEXT_WIDTH, 1.75 * nrows + 0.5))
    gs = fig.add_gridspec(nrows, ncols)
    n_chains = max((a.shape[0] for a in tr.values()), default=0)
    for i, name in enumerate(names):
        r, c = divmod(i, ncols)
        span = slice(c, ncols) if (i == n - 1 and n % ncols) else slice(c, c + 1)
        ax = fig.add_subplot(gs[r, span])
        a = tr[name]
        for k in range(a.shape[0]):
            ax.plot(np.arange(a.shape[1]), a[k], lw=0.6, color=f"C{k % 10}", label=f"chain {k}")
        if name == "draw_error":
            ax.set_xlabel("retained sample")
            ax.set_ylabel("degrees", fontsize=7)
            ax.set_title("test error of each retained sample")
        else:
            if n_burn_in:
                ax.axvspan(0, n_burn_in, color="0.9", zorder=0)
                ax.axvline(n_burn_in, color="0.3", ls="--", lw=0.8)
            if name in _PRECISIONS and np.all(a[np.isfinite(a)] > 0):
                _log_axis(ax)
            if name == "active_atoms":  # a count: whole-number ticks only (not 62.5)
                ax.yaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_xlabel("Gibbs sweep")
            label = TRACE_LABELS.get(name, name.replace("_", " "))
            ax.set_title(label, fontsize=MATH_TITLE_PT if "$" in label else None)
        ax.grid(alpha=0.3)
    if n_chains > 1 and names:
        fig.axes[0].legend(fontsize=7, ncol=min(n_chains, 4), loc="best")
    if not names:
        ax = fig.add_subplot(gs[0, 0])
        ax.text(0.5, 0.5, "the fit saved no trace", ha="center", va="center")
        ax.set_axis_off()
    suffix = f"; {n_chains} chains" if n_chains > 1 else ""
    suffix += "; shaded: burn-in" if n_burn_in else ""
    fig.suptitle(title + suffix)
    fig.tight_layout()
    return fig


def gxy_panel(params, n_train):
    """What one panel of the g_xy figure shows: ``(K, "≥" or "<", prior)`` from a fit's ``params`` (dict) at
    ``n_train`` training pairs; ``prior`` is ``(a_xy, b_xy)`` of a proper Gamma prior on g_xy, or None (the
    paper's improper one)."""
    k = params.get("n_atoms", "?")
    rel = "≥" if isinstance(k, int) and k >= int(n_train) else "<"
    prior = None
    if params.get("a_xy") is not None:
        prior = (float(params["a_xy"]), float(params.get("b_xy", params.get("b0", 1e-6))))
    return k, rel, prior


def gxy_caption(df, methods, *, protocol, n_train, labels):
    """LaTeX caption of the g_xy figure, describing the panels drawn: one per method of ``methods``
    (``report.gxy_methods``), with its K against ``n_train`` and its prior, read from the ``params`` of its rows in
    the aggregate table ``df`` (protocol ``protocol``, ``n_train`` training pairs)."""
    parts = []
    for m in methods:
        rows = df[
            (df["method"] == m) & (df["protocol"] == protocol) & (df["n_train"] == int(n_train))
        ]
        params = (
            json.loads(rows["params"].iloc[0])
            if len(rows) and isinstance(rows["params"].iloc[0], str)
            else {}
        )
        k, rel, prior = gxy_panel(params, n_train)
        text = f"{latex_escape(labels.get(m, m))}: "
        if k == "?":
            text += "$K$ unknown"
        else:
            op = "\\geq" if rel == "≥" else "<"
            text += f"$K = {k} {op} N = {int(n_train)}$"
            if rel == "≥":
                text += " (a code set can interpolate the training pairs)"
        if prior is not None:
            text += f", with a proper Gamma({prior[0]:g}, {prior[1]:g}) prior on $\\gamma_{{xy}}$"
        parts.append(text)
    what = f"the {len(parts)} methods" if len(parts) != 1 else "the method"
    return (
        "The noise precision $\\gamma_{xy}$ per chain (first activity, smallest $N$, first seed; log axis; "
        f"shaded: burn-in) of {what} of \\texttt{{report.gxy\\_methods}}: "
        + "; ".join(parts)
        + ". The panel titles repeat $K$ and $N$."
    )


def plot_gxy(items, *, n_burn_in=None):
    """The g_xy mechanism: g_xy traces (log axis, every chain) side by side, one panel per item.

    ``items``: list of (panel title, arrays of a saved fit). Returns the figure.
    """
    import matplotlib.pyplot as plt

    n = max(1, len(items))
    from .plots import TEXT_WIDTH

    fig, axes = plt.subplots(
        1, n, figsize=(min(TEXT_WIDTH, 2.5 * n + 0.8), 2.6), squeeze=False, sharey=True
    )
    for ax, (title, arrays) in zip(axes[0], items):
        tr = chain_traces(arrays).get("g_xy")
        burn = n_burn_in if n_burn_in is not None else int(arrays.get("n_burn_in", 0))
        if tr is None:
            ax.text(0.5, 0.5, "no g_xy trace", ha="center", va="center", transform=ax.transAxes)
            continue
        for k in range(tr.shape[0]):
            ax.plot(np.arange(tr.shape[1]), tr[k], lw=0.6, color=f"C{k % 10}")
        if burn:
            ax.axvspan(0, burn, color="0.9", zorder=0)
        _log_axis(ax)
        ax.set_title(title, fontsize=8)
        ax.set_xlabel("Gibbs sweep")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(r"$\gamma_{xy}$", fontsize=MATH_TITLE_PT)
    fig.suptitle(
        r"Noise precision $\gamma_{xy}$ per chain (log axis; shaded: burn-in)",
        fontsize=MATH_TITLE_PT,
    )
    fig.tight_layout()
    return fig
