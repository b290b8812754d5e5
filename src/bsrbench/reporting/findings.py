"""The report's section "Findings" and the fragment it closes (tables/findings.tex: Setup, then Findings).

The findings check the paper's claims on the data at hand, computed from the aggregate table only:
"PM beats every baseline" (counted in the paper's Tables I and II and here), PM against the honest
references (1-NN, ridge), our errors against the paper's, the effect of the split protocol and the
calibration of the predictive intervals.
"""

import numpy as np

from ..io import atomic_path
from ..splits import PROTOCOLS
from .comparisons import pm_counts
from .latex import escape, listing, nobreak, percent, table
from .study_setup import method_order, parameters_table, setup_text
from .tables import PAPER_METHODS, activity_label, paper_names, summarize


def _pairs(s, protocol, n):
    d = s[(s["protocol"] == protocol) & (s["n_train"] == n)]
    return d.pivot_table(
        index=["source", "activity", "paper_activity"], columns="method", values="mean"
    )


def _names(idx):
    return ", ".join(nobreak(f"{activity_label(a, pa)} ({s})") for s, a, pa in idx)


def _each(names):
    """ "X" for one name, "each of X, Y and Z" for several."""
    names = list(names)
    return names[0] if len(names) == 1 else "each of " + listing(names)


def _for_how_many(ok):
    """How many activities a boolean Series (indexed by source, activity, paper activity) is true for, in words,
    naming them: "for both activities (A, B)", "for all 3 activities (A, B, C)", "for none of the 2 activities (A, B)",
    "for 1 of the 2 activities (A); not for B", and with one activity "for the activity studied (A)" or
    "for no activity: not for A, the only activity studied"."""
    n, k = len(ok), int(ok.sum())
    word = "activity" if n == 1 else "activities"
    if k == n:
        every = {1: "the", 2: "both"}.get(n, f"all {n}")
        return f"for {every} {word} studied ({_names(ok.index)})"
    if k == 0 and n == 1:
        return f"for no activity: not for {_names(ok.index)}, the only activity studied"
    if k == 0:
        return f"for none of the {n} {word} studied ({_names(ok.index)})"
    return f"for {k} of the {n} {word} studied ({_names(ok.index[ok])}), but not for {_names(ok.index[~ok])}"


def paper_pm_count(paper, pm="PM"):
    """In how many of the paper's rows (table, activity, $N$) with PM and at least one other method PM has a lower
    error than every other method: ``(k, n)``; ``(0, 0)`` without a paper table."""
    if paper is None or paper.empty:
        return 0, 0
    w = paper.pivot_table(
        index=["table", "activity", "n_train"], columns="method", values="mean_deg"
    )
    if pm not in w.columns:
        return 0, 0
    others = [c for c in w.columns if c != pm]
    w = w[w[pm].notna() & w[others].notna().any(axis=1)] if others else w.iloc[:0]
    ok = w[pm] < w[others].min(axis=1)
    return int(ok.sum()), len(ok)


def comparison_sentences(comp, *, labels, pm="PM", nn="NN1"):
    """Per protocol and source, in how many (activity, $N$) cells PM is significantly worse than, tied with or
    better than the cell's best method and 1-NN (:func:`bsrbench.reporting.comparisons.pm_counts`), as sentences
    (LaTeX); [] without comparisons."""
    if comp is None or comp.empty:
        return []
    t = pm_counts(comp, pm=pm, nn=nn)
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    out = []
    for (protocol, source), g in t.groupby(["protocol", "source"], sort=True):
        g = g.set_index("versus")
        parts, corrected = [], []
        for what, name in (("best", "the best method of the cell"), (nn, L(nn))):
            if what not in g.index:
                continue
            r = g.loc[what]
            text = f"than {name}: worse in {int(r['worse'])}, tied in {int(r['tied'])}, better in {int(r['better'])}"
            if what == "best" and int(r["pm_best"]):
                text += f", and PM is itself the best in {int(r['pm_best'])}"
            if int(r["untested"]):
                text += f" (no test in {int(r['untested'])}: fewer than 2 common splits)"
            text += f" of the {int(r['cells'])} cells"
            parts.append(text)
            corrected.append(f"than {name} in {int(r['worse_corrected'])}")
        if not parts:
            continue
        out.append(
            f"{escape(protocol.replace('_', '-').capitalize())} protocol, {escape(source)} data, "
            f"on these frames (paired $t$-test over the splits, Holm-adjusted over each cell's comparisons, "
            f"significant at $p < 0.05$): {L(pm)} is significantly worse, tied or better "
            + "; ".join(parts)
            + ". By the corrected resampled $t$-test (Nadeau and Bengio 2003), which asks about a new data set "
            f"of independent frames, {L(pm)} is worse "
            + " and ".join(corrected)
            + " (Table~\\ref{tab:pm-counts})."
        )
    return out


def counts_latex(comp, *, labels, pm="PM", nn="NN1"):
    """LaTeX table of :func:`bsrbench.reporting.comparisons.pm_counts` ('' without comparisons)."""
    if comp is None or comp.empty:
        return ""
    t = pm_counts(comp, pm=pm, nn=nn)
    if t.empty:
        return ""
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    rows = [
        [
            escape(r.protocol.replace("_", "-")),
            escape(r.source),
            "best method" if r.versus == "best" else L(r.versus),
            str(r.cells),
            str(r.worse),
            str(r.tied),
            str(r.better),
            str(r.pm_best) if r.versus == "best" else "",
            str(r.untested),
            str(r.worse_corrected),
        ]
        for r in t.itertuples(index=False)
    ]
    return table(
        rows,
        spec="@{}lllrrrrrrr@{}",
        caption=rf"In how many (activity, $N$) cells {L(pm)} is significantly worse than, tied with or better "
        rf"than the cell's best method and {L(nn)} on these frames: paired $t$-test over the splits, "
        r"Holm-adjusted over each cell's comparisons, $p < 0.05$. PM best: cells where PM has the "
        r"lowest mean; no test: fewer than 2 common splits; last column: the cells where PM is worse by the "
        r"corrected resampled $t$-test (Nadeau and Bengio 2003), the sensitivity to the assumption of a new data "
        r"set of independent frames.",
        label="tab:pm-counts",
        head=[
            rf"Protocol & Source & {L(pm)} against & cells & worse & tied & better & PM best & no test & "
            r"worse (corr.) \\"
        ],
    )


def findings(df, paper, *, labels, pm="PM", references=("NN1", "Ridge"), comparisons=None):
    """Plain sentences (LaTeX) saying where the paper's claims hold on these data and where they do not.

    Every sentence states what was compared, on which rows, and the count in words; ratios to the paper's
    errors and coverages are given per data source (their data differ). ``comparisons``: the paired comparisons
    (:func:`bsrbench.reporting.comparisons.comparisons`); with them the findings say in how many cells PM is
    significantly worse than, tied with or better than the best method and 1-NN.
    """
    out = []
    s = summarize(df)
    methods = method_order(df, labels)
    names = paper_names(df)
    baselines = [m for m in methods if names.get(m) in PAPER_METHODS and names.get(m) != "PM"]
    refs = [m for m in references if m in methods]
    L = lambda m: escape(labels.get(m, m))  # noqa: E731
    protocols = [p for p in PROTOCOLS if p in set(df["protocol"])] + sorted(
        set(df["protocol"]) - set(PROTOCOLS)
    )
    sources = list(dict.fromkeys(df["source"]))
    if pm not in methods:
        variants = [m for m in methods if names.get(m) == "PM"]
        return [
            f"No method named {escape(pm)} was run, so the paper's claims about it are not checked here"
            + (
                f"; the PM variants run ({', '.join(L(m) for m in variants)}) are compared in "
                r"Section~\ref{sec:why-pm}."
                if variants
                else "."
            )
        ]
    sizes = sorted(df["n_train"].unique())
    k_paper, n_paper = paper_pm_count(paper, pm)
    in_paper = (
        f"in the paper's Tables I and II, PM has a lower error than every other method in {k_paper} of the "
        f"{n_paper} (activity, $N$) rows. "
        if n_paper
        else ""
    )
    for protocol in protocols:
        tag = escape(protocol.replace("_", "-").capitalize()) + " protocol"
        t = s[s["protocol"] == protocol].pivot_table(
            index=["source", "activity", "n_train"], columns="method", values="mean"
        )
        if pm in t.columns and baselines:
            bl = [b for b in baselines if b in t.columns]
            have = t.dropna(subset=[pm] + bl)
            ok = have[pm] < have[bl].min(axis=1)
            text = (
                f"{tag}, summary: {in_paper}Here PM has "
                f"a lower mean error than {_each(L(b) for b in baselines)} in {int(ok.sum())} of the {len(ok)} "
                f"(activity, $N$) rows"
            )
            allm = [m for m in bl + refs if m in t.columns]
            if refs:
                ok2 = have[pm] < have[allm].min(axis=1)
                text += (
                    f", and a lower mean error than every other method run (the references "
                    f"{listing([L(r) for r in refs])} included) in {int(ok2.sum())} of the {len(ok2)} rows"
                )
            out.append(text + ".")
    for protocol in protocols:
        tag = "" if protocol == "random" else f" ({escape(protocol.replace('_', '-'))} protocol)"
        for n in sizes:
            t = _pairs(s, protocol, n)
            if pm not in t.columns:
                continue
            bl = [b for b in baselines if b in t.columns]
            if bl:
                have = t.dropna(subset=[pm] + bl)
                ok = have[pm] < have[bl].min(axis=1)
                out.append(
                    f"At $N={n}${tag}, PM has a lower mean error than {_each(L(b) for b in bl)} "
                    f"{_for_how_many(ok)}."
                )
            for r in refs:
                if r not in t.columns:
                    continue
                have = t.dropna(subset=[pm, r])
                ok = have[pm] < have[r]
                diff = float(np.median(have[pm] - have[r])) if len(have) else float("nan")
                side = "PM's error is higher" if diff > 0 else "PM's error is lower"
                over = ", median over these activities," if len(have) > 1 else ""
                out.append(
                    f"At $N={n}${tag}, PM has a lower mean error than {L(r)} {_for_how_many(ok)}; "
                    f"PM's mean error minus {L(r)}'s{over} is {diff:+.2f} degrees ({side})."
                )
    out += comparison_sentences(
        comparisons, labels=labels, pm=pm, nn=references[0] if references else "NN1"
    )
    # paired per split: the same split for every method, so compare seed by seed
    r = df[df["protocol"] == "random"]
    if baselines and not r.empty:
        w = r.pivot_table(
            index=["source", "activity", "n_train", "seed"], columns="method", values="error"
        )
        bl = [b for b in baselines if b in w.columns]
        if pm in w.columns and bl:
            w = w.dropna(subset=[pm] + bl)
            wins = int((w[pm] < w[bl].min(axis=1)).sum())
            out.append(
                f"Split by split (every method sees the same random split), PM has a lower error than "
                f"{_each(L(b) for b in bl)} on {wins} of the {len(w)} splits."
            )
    # ours vs the paper, per source (the sources' features differ, and so do their ratios)
    if paper is not None and not r.empty:
        sr = s[s["protocol"] == "random"].copy()
        sr["label"] = sr["method"].map(lambda m: labels.get(m, m))
        m = sr.merge(
            paper,
            left_on=["key", "n_train", "label"],
            right_on=["key", "n_train", "method"],
            suffixes=("", "_paper"),
        )
        per_source = []
        order = [labels.get(mm, mm) for mm in methods]
        for src in sources:
            g_src = m[m["source"] == src]
            if g_src.empty:
                continue
            groups = dict(list(g_src.groupby("label", sort=False)))
            parts = [
                f"{escape(lab)} {float(np.median(g['mean'] / g['mean_deg'])):.2f}"
                for lab, g in sorted(
                    groups.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else 99
                )
            ]
            per_source.append(f"on the {escape(src)} data, " + ", ".join(parts))
        if per_source:
            out.append(
                "Our mean error divided by the paper's for the same method, activity and $N$ (median over the "
                "matching cells; below 1: a lower error here than in the paper): "
                + "; ".join(per_source)
                + ". The paper's features are not the ones used here, so these ratios compare data sets as much "
                "as implementations."
            )
    # protocol effect
    if set(protocols) == {"random", "contiguous"}:
        w = s.pivot_table(
            index=["source", "activity", "method", "n_train"], columns="protocol", values="mean"
        ).dropna()
        per_source = []
        for src in sources:
            if src not in w.index.get_level_values("source"):
                continue
            ws = w.xs(src, level="source")
            parts = [
                f"{L(mm)} {float(np.median(g['contiguous'] / g['random'])):.2f}"
                for mm, g in ws.groupby(level="method", sort=False)
            ]
            per_source.append(f"on the {escape(src)} data, " + ", ".join(parts))
        if per_source:
            out.append(
                "Mean error under the contiguous protocol divided by that under the random protocol (median "
                "over activities and $N$; above 1: the contiguous protocol is harder): "
                + "; ".join(per_source)
                + ". Random frames of one sequence put near-duplicates of test frames in the training set."
            )
    # calibration
    if "coverage_90" in df.columns:
        c = r.dropna(subset=["coverage_90"])
        per_source = []
        for src in sources:
            cs = c[c["source"] == src]
            if cs.empty:
                continue
            parts = [
                f"{L(mm)} {percent(float(cs.loc[cs['method'] == mm, 'coverage_90'].mean()))}"
                for mm in methods
                if mm in set(cs["method"])
            ]
            per_source.append(f"on the {escape(src)} data, " + ", ".join(parts))
        if per_source:
            out.append(
                "Share of the test angles inside the central 90\\% predictive interval (mean over random splits; "
                "90\\% for a calibrated method): " + "; ".join(per_source) + "."
            )
    return out


def write_generated(path, df, paper, *, labels, defaults=None, study=None, comparisons=None):
    """The LaTeX fragment with the setup (and parameter table) and the findings (input by reports/report.tex).

    ``study``: (name, results folder) of the study shown, named first in the setup; None leaves it out.
    ``comparisons``: the paired comparisons; with them the findings count PM's significant differences and a
    table gives the counts (:func:`counts_latex`).
    """
    body = ["% generated from the study's aggregate table", r"\section{Setup}", ""]
    lines = setup_text(df, labels=labels)
    if study is not None:
        name, folder = study
        # \nolinkurl (hyperref's url) breaks paths at slashes, which \texttt cannot
        lines.insert(
            0,
            f"Study: \\textbf{{{escape(name)}}} (configuration key \\texttt{{study}}; results in "
            f"\\nolinkurl{{{folder}/}}, aggregate table "
            f"\\nolinkurl{{{folder}/aggregate/results.csv}}).",
        )
    body += [" ".join(lines), ""]
    body += [parameters_table(df, labels=labels, defaults=defaults or {}), ""]
    items = findings(df, paper, labels=labels, comparisons=comparisons) or [
        "No sentence applies to what was run (the findings compare PM with the paper's baselines and references)."
    ]
    # ragged right: the activity names are unbreakable boxes, and a justified line of them can overflow
    body += [r"\section{Findings}", r"\begin{itemize}\raggedright"]
    body += [r"\item " + f for f in items]
    body += [r"\end{itemize}", ""]
    counts = counts_latex(comparisons, labels=labels)
    if counts and comparison_sentences(comparisons, labels=labels):
        body += [counts, ""]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(body))
