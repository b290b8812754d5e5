"""The PM ablation and the report section on PM against the paper's ("Why PM trails the paper here" when it does
everywhere, :func:`why_pm_title`), computed from the aggregate table.

The ablation runs PM variants as methods of their own (``config/ablation.yaml``); the variants of a study are the
methods with the estimator of the trace method. Per (activity, N) cell it compares the best variant with 1-NN and
the best other method, and counts per variant the goal: an exact sampler whose chains converge
(:mod:`bsrbench.reporting.convergence`) and whose error is below 1-NN's.
"""

import json
import math

import numpy as np
import pandas as pd

from ..io import atomic_path
from .convergence import (
    RHAT_OK,
    RHAT_STRICT,
    converged,
    convergence_latex,
    convergence_summary_table,
    with_convergence_columns,
)
from .latex import best_mask, escape, figure, format_cell, percent, table
from .tables import activity_label, paper_key, summarize


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
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    out = []
    for protocol, tp in t.groupby("protocol", sort=True):
        if not ((df["method"] == nn) & (df["protocol"] == protocol)).any():
            out.append(
                f"Protocol ``{escape(protocol)}'': {L(nn)} was not run, so the goal is not judged."
            )
            continue
        ex = tp[tp["exact"]]
        if ex.empty:
            out.append(f"Protocol ``{escape(protocol)}'': no exact variant was run.")
            continue
        top = ex.iloc[0]
        need = math.ceil(0.75 * int(top["cells"]))
        verdict = "meets" if int(top["both"]) >= need else "does not meet"
        out.append(
            f"Protocol ``{escape(protocol)}'': the exact variant closest to the goal is {L(top['method'])}. "
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
        caption = (
            rf"The goal, protocol ``{escape(protocol)}'': per PM variant, the (activity, $N$) cells "
            rf"in which every split converged ($\hat R < {RHAT_OK}$ on $\ell$ and $\gamma_{{xy}}$), those in which "
            rf"its mean error is below {escape(labels.get(nn, nn))}'s, and both; rank: the variant's mean rank "
            r"of error among the variants over the cells (1 best); the last two columns: the same counts of converged "
            rf"cells and of both at $\hat R < {RHAT_STRICT}$ (Vehtari et al.\ 2021). Exact: its logit update leaves "
            r"the posterior invariant (Geweke test); the paper's printed ratios do not."
        )
        head = [
            rf"& & & $\hat R < {RHAT_OK}$ & & $\hat R < {RHAT_OK}$ & & $\hat R < {RHAT_STRICT}$ & "
            rf"$\hat R < {RHAT_STRICT}$ \\",
            r"Variant & exact & cells & converged & beats "
            + escape(labels.get(nn, nn))
            + r" & both & rank & converged & both \\",
        ]
        rows = [
            [
                escape(labels.get(r["method"], r["method"])),
                "yes" if r["exact"] else "no",
                str(int(r["cells"])),
                str(int(r["converged"])),
                str(int(r["beats_nn"])),
                str(int(r["both"])),
                f"{r['mean_rank']:.1f}",
                str(int(r["converged_strict"])),
                str(int(r["both_strict"])),
            ]
            for _, r in tp.iterrows()
        ]
        out += [
            table(rows, spec="@{}lcrrrrrrr@{}", head=head, caption=caption, tabcolsep="4pt"),
            "",
        ]
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
        rows = [(escape(labels.get(v, v)), v) for v in vs]
        if nn in set(sp["method"]):
            rows.append((escape(labels.get(nn, nn)), nn))
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
        caption = (
            rf"PM variants on {escape(activity_label(activity, pa))} ({escape(source)}), "
            rf"protocol ``{escape(protocol)}'': mean error $\pm$ std (degrees) over splits; best of each "
            r"column in bold (variants, 1-NN and the best other method); italic: the paper's PM (random frames)."
        )
        body = []
        for r, (lab, m) in enumerate(rows):
            if m == nn:
                body.append(r"\midrule")
            cells = [
                format_cell(*grid[m][i], bold=bold[i][r], digits=digits) for i in range(len(sizes))
            ]
            body.append([lab] + cells)
        cells = []
        for i in range(len(sizes)):
            m, st = best_base[i]
            cells.append(
                "--"
                if m is None
                else format_cell(*st, bold=bold[i][len(rows)], digits=digits)
                + rf" {{\scriptsize ({escape(labels.get(m, m))})}}"
            )
        body.append(["best other method"] + cells)
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
                body.append([r"\emph{paper's PM}"] + cells)
        out += [
            table(
                body,
                spec="@{}l" + "c" * len(sizes) + "@{}",
                head=[["Method"] + [f"$N={n}$" for n in sizes]],
                caption=caption,
                tabcolsep="4pt",
            ),
            "",
        ]
    return "\n".join(out)


def against_paper(df, paper, *, base="PM"):
    """``base``'s mean error here against the paper's PM per (source, activity, N), random protocol only (the
    paper's numbers are for random frames): a DataFrame with source, activity, paper_activity, n_train, mean (ours),
    mean_deg (the paper's); empty without such cells."""
    cols = ["source", "activity", "paper_activity", "n_train", "mean", "mean_deg"]
    if paper is None or paper.empty or df.empty:
        return pd.DataFrame(columns=cols)
    s = summarize(df)
    sb = s[(s["method"] == base) & (s["protocol"] == "random")]
    pp = paper[paper["method"] == "PM"][["key", "n_train", "mean_deg"]]
    m = sb.merge(pp, on=["key", "n_train"])
    return m[cols].sort_values(["source", "activity", "n_train"]).reset_index(drop=True)


def why_pm_title(df, paper, *, base="PM"):
    """The section's title, as the data show it: "Why PM trails the paper here" only if ``base``'s mean error is
    above the paper's PM in every cell compared (:func:`against_paper`), "Where PM trails the paper here" if in
    some, "PM against the paper's PM" if in none, and "PM's convergence and variants" without a comparison."""
    c = against_paper(df, paper, base=base)
    if c.empty:
        return "PM's convergence and variants"
    above = int((c["mean"] > c["mean_deg"]).sum())
    if above == len(c):
        return "Why PM trails the paper here"
    return "Where PM trails the paper here" if above else "PM against the paper's PM"


def _cells_text(c):
    return ", ".join(
        f"{escape(activity_label(r.activity, r.paper_activity))} ({escape(r.source)}) $N={int(r.n_train)}$"
        for r in c.itertuples(index=False)
    )


def trail_sentence(df, paper, *, labels, base="PM"):
    """Where ``base``'s mean error is above the paper's PM and where it is not (:func:`against_paper`), naming the
    cells, as one sentence (LaTeX); "" without a comparison."""
    c = against_paper(df, paper, base=base)
    if c.empty:
        return ""
    L = escape(labels.get(base, base))
    above, below = c[c["mean"] > c["mean_deg"]], c[c["mean"] <= c["mean_deg"]]
    text = (
        f"{L}'s mean error (random protocol, as in the paper) is above the paper's PM in {len(above)} of the "
        f"{len(c)} (activity, $N$) cells compared"
    )
    if len(above):
        text += f" ({_cells_text(above)})"
    if len(below):
        text += f", and at or below it in {_cells_text(below)}"
    return text + "."


def why_pm_sentences(df, paper, *, variants, labels, base="PM", nn="NN1"):
    """Plain sentences (LaTeX) drawn from the numbers: where the best variant beats 1-NN, which variants
    converge, and the base PM against the paper's."""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    out = []
    cells = ablation_cells(df, variants=variants, nn=nn)
    if cells.empty:
        return [f"No PM variant ({', '.join(L(v) for v in variants) or 'none'}) was run."]
    for protocol, c in cells.groupby("protocol", sort=True):
        have = c.dropna(subset=["nn_error"])
        wins = have[have["best_variant_error"] < have["nn_error"]]
        counts = c["best_variant"].value_counts()
        out.append(
            f"Protocol ``{escape(protocol)}'': the best PM variant of each (activity, $N$) cell beats "
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
            + ", ".join(f"{L(m)} {percent(v)}" for m, v in per.items())
            + f"; at $\\hat R < {RHAT_STRICT}$ (Vehtari et al.\\ 2021): "
            + ", ".join(f"{L(m)} {percent(v)}" for m, v in strict.items())
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
                f"The paper's numbers are for random frames; this study ran only the {escape(run)} "
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
                per_source.append(f"on the {escape(src)} data, " + "; ".join(parts))
            if per_source:
                out.append(
                    f"{L(base)} here against the paper's PM (random protocol, as in the paper; median "
                    "over activities): " + "; ".join(per_source) + " degrees."
                )
    return out


def why_pm_section(df, paper, *, variants, labels, figures, base="PM", nn="NN1"):
    """The LaTeX section on PM's convergence, variants and errors against the paper's (input by reports/report.tex),
    titled by what the data show (:func:`why_pm_title`; label ``sec:why-pm``).

    ``figures``: list of (path relative to the study's report folder reports/{study}, caption).
    """
    lines = [
        "% generated from the study's aggregate table",
        rf"\section{{{why_pm_title(df, paper, base=base)}}}\label{{sec:why-pm}}",
        "",
    ]
    lead = trail_sentence(df, paper, labels=labels, base=base)
    if lead:
        lines += [lead, ""]
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
            + escape(labels.get(nn, nn))
            + "}",
            goal_sentence(df, variants=variants, labels=labels, nn=nn),
            "",
            goal,
            "",
        ]
    # the ablation tables compare variants: none with PM alone (its errors are in Tables I-II)
    if len([v for v in variants if v in set(df["method"])]) > 1:
        lines += [
            r"\subsection*{Ablation}",
            ablation_latex(df, paper, variants=variants, labels=labels, nn=nn),
            "",
        ]
    lines += [
        figure(f, caption, options=r"width=\linewidth,height=0.8\textheight,keepaspectratio")
        for f, caption in figures
    ]
    return "\n".join(lines) + "\n"


def write_why_pm(path, text):
    with atomic_path(path) as tmp:
        tmp.write_text(text)
