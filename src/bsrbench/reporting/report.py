"""Generated text of the study report (setup and findings), and the PDF build with latexmk.

The findings check the paper's claims on the data at hand, computed from the aggregate table only:
"PM beats every baseline" (counted in the paper's Tables I and II and here), PM against the honest
references (1-NN, ridge), our errors against the paper's, the effect of the split protocol and the
calibration of the predictive intervals.
"""

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io import atomic_path
from .tables import PAPER_METHODS, activity_label, latex_escape, summarize


def _pairs(s, protocol, n):
    d = s[(s["protocol"] == protocol) & (s["n_train"] == n)]
    return d.pivot_table(
        index=["source", "activity", "paper_activity"], columns="method", values="mean"
    )


def nobreak(text):
    """LaTeX for ``text`` (escaped) that is never hyphenated or broken across lines (activity names)."""
    return r"\mbox{" + latex_escape(text) + "}"


def _names(idx):
    return ", ".join(nobreak(f"{activity_label(a, pa)} ({s})") for s, a, pa in idx)


def _listing(items):
    """``a``, ``a and b``, ``a, b and c``."""
    items = list(items)
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def _each(names):
    """ "X" for one name, "each of X, Y and Z" for several."""
    names = list(names)
    return names[0] if len(names) == 1 else "each of " + _listing(names)


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


def _methods(df, labels):
    """The methods of ``df`` in the order of ``labels`` (the configuration's ``run``), then any others."""
    have = list(dict.fromkeys(df["method"]))
    return [m for m in labels if m in have] + [m for m in have if m not in labels]


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
    from .comparisons import pm_counts

    if comp is None or comp.empty:
        return []
    t = pm_counts(comp, pm=pm, nn=nn)
    L = lambda m: latex_escape(labels.get(m, m))  # noqa: E731
    out = []
    for (protocol, source), g in t.groupby(["protocol", "source"], sort=True):
        g = g.set_index("versus")
        parts, wilcoxon = [], []
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
            wilcoxon.append(f"than {name} in {int(r['worse_wilcoxon'])}")
        if not parts:
            continue
        out.append(
            f"{latex_escape(protocol.replace('_', '-').capitalize())} protocol, {latex_escape(source)} data, "
            f"paired by split (corrected resampled $t$-test, Holm-adjusted over each cell's comparisons, "
            f"significant at $p < 0.05$): {L(pm)} is significantly worse, tied or better "
            + "; ".join(parts)
            + ". By the Wilcoxon signed-rank test alone (no allowance for the overlap of the splits or for the "
            f"number of comparisons) {L(pm)} is worse "
            + " and ".join(wilcoxon)
            + " (Table~\\ref{tab:pm-counts})."
        )
    return out


def counts_latex(comp, *, labels, pm="PM", nn="NN1"):
    """LaTeX table of :func:`bsrbench.reporting.comparisons.pm_counts` ('' without comparisons)."""
    from .comparisons import pm_counts

    if comp is None or comp.empty:
        return ""
    t = pm_counts(comp, pm=pm, nn=nn)
    if t.empty:
        return ""
    L = lambda m: latex_escape(labels.get(m, m))  # noqa: E731
    rows = []
    for r in t.itertuples(index=False):
        versus = "best method" if r.versus == "best" else L(r.versus)
        rows.append(
            " & ".join(
                [
                    latex_escape(r.protocol.replace("_", "-")),
                    latex_escape(r.source),
                    versus,
                    str(r.cells),
                    str(r.worse),
                    str(r.tied),
                    str(r.better),
                    str(r.pm_best) if r.versus == "best" else "",
                    str(r.untested),
                    str(r.worse_wilcoxon),
                ]
            )
            + r" \\"
        )
    return "\n".join(
        [
            r"\begin{table}[H]",
            r"\centering\footnotesize",
            rf"\caption{{In how many (activity, $N$) cells {L(pm)} is significantly worse than, tied with or better "
            rf"than the cell's best method and {L(nn)}: paired by split, corrected resampled $t$-test (Nadeau and "
            r"Bengio 2003), Holm-adjusted over each cell's comparisons, $p < 0.05$. PM best: cells where PM has the "
            r"lowest mean; no test: fewer than 2 common splits; last column: the cells where PM is worse by the "
            r"Wilcoxon signed-rank test alone ($p < 0.05$, no allowance for overlapping splits, no correction).}",
            r"\label{tab:pm-counts}",
            r"\begin{tabular}{@{}lllrrrrrrr@{}}",
            r"\toprule",
            rf"Protocol & Source & {L(pm)} against & cells & worse & tied & better & PM best & no test & "
            r"worse (W.) \\",
            r"\midrule",
            *rows,
            r"\bottomrule",
            r"\end{tabular}",
            r"\end{table}",
        ]
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
    methods = _methods(df, labels)
    baselines = [m for m in methods if labels.get(m, m) in PAPER_METHODS and m != pm]
    refs = [m for m in references if m in methods]
    L = lambda m: latex_escape(labels.get(m, m))  # noqa: E731
    order = ("random", "contiguous", "cross_trial")
    protocols = [p for p in order if p in set(df["protocol"])] + sorted(
        set(df["protocol"]) - set(order)
    )
    sources = list(dict.fromkeys(df["source"]))
    if pm not in methods:
        variants = [m for m in methods if m.startswith(pm)]
        return [
            f"No method named {latex_escape(pm)} was run, so the paper's claims about it are not checked here"
            + (
                f"; the PM variants run ({', '.join(L(m) for m in variants)}) are compared in the section "
                "``Why PM trails the paper here''."
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
        tag = latex_escape(protocol.replace("_", "-").capitalize()) + " protocol"
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
                    f"{_listing([L(r) for r in refs])} included) in {int(ok2.sum())} of the {len(ok2)} rows"
                )
            out.append(text + ".")
    for protocol in protocols:
        tag = (
            ""
            if protocol == "random"
            else f" ({latex_escape(protocol.replace('_', '-'))} protocol)"
        )
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
                f"{latex_escape(lab)} {float(np.median(g['mean'] / g['mean_deg'])):.2f}"
                for lab, g in sorted(
                    groups.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else 99
                )
            ]
            per_source.append(f"on the {latex_escape(src)} data, " + ", ".join(parts))
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
            per_source.append(f"on the {latex_escape(src)} data, " + ", ".join(parts))
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
                f"{L(mm)} {100 * float(cs.loc[cs['method'] == mm, 'coverage_90'].mean()):.0f}\\%"
                for mm in methods
                if mm in set(cs["method"])
            ]
            per_source.append(f"on the {latex_escape(src)} data, " + ", ".join(parts))
        if per_source:
            out.append(
                "Share of the test angles inside the central 90\\% predictive interval (mean over random splits; "
                "90\\% for a calibrated method): " + "; ".join(per_source) + "."
            )
    return out


def _fmt_value(v):
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def parameters_used(df, *, defaults, labels=None):
    """Per method, the parameters its fits actually used: ``{method: (set, default)}``.

    ``set``: ``{name: [values]}`` of the parameters given by the configuration or chosen by CV (the aggregate
    table's ``params``, one list entry per distinct value over jobs); ``default``: ``{name: value}`` of the
    estimator's other constructor parameters (``defaults[method]``, e.g. from
    :func:`bsrbench.estimators.estimator_defaults`), i.e. the values it ran with. ``random_state`` is set per job.
    """
    out = {}
    for m in _methods(df, labels or {}):
        seen = {}
        for text in df.loc[df["method"] == m, "params"].astype(str):
            try:
                params = json.loads(text) if text not in ("", "nan") else {}
            except json.JSONDecodeError:
                params = {}
            for k, v in params.items():
                vals = seen.setdefault(k, [])
                if v not in vals:
                    vals.append(v)
        for k in seen:
            try:
                seen[k] = sorted(seen[k])
            except TypeError:
                pass
        default = {k: v for k, v in (defaults.get(m) or {}).items() if k not in seen}
        if "random_state" in default:
            default["random_state"] = "per job"
        out[m] = (seen, default)
    return out


def parameters_table(df, *, labels, defaults):
    """LaTeX table: per method, the estimator, the parameters set by the configuration or CV, and the estimator
    defaults it ran with (see :func:`parameters_used`)."""
    used = parameters_used(df, defaults=defaults, labels=labels)
    est = {}
    if "estimator" in df.columns:
        est = df.drop_duplicates("method").set_index("method")["estimator"].to_dict()

    def cell(pairs):
        # a line may break after each "|" of a CV list (tt text has no other break points)
        items = [
            latex_escape(f"{k}={v}").replace("-", "-{}").replace("|", r"|\allowbreak{}")
            for k, v in pairs
        ]
        return ", ".join(items) if items else r"\textrm{none}"

    rows = []
    for m, (seen, default) in used.items():
        set_pairs = [
            (k, "|".join(_fmt_value(x) for x in vals) + (" (CV)" if len(vals) > 1 else ""))
            for k, vals in seen.items()
        ]
        dflt_pairs = [(k, _fmt_value(v)) for k, v in default.items()]
        name = latex_escape(labels.get(m, m))
        cls = latex_escape(str(est.get(m, "")).split(":")[-1])
        rows.append(rf"{name} & \texttt{{{cls}}} & {cell(set_pairs)} & {cell(dflt_pairs)} \\")
    return "\n".join(
        [
            r"\begin{table}[H]",
            r"\centering\footnotesize",
            r"\caption{Parameters each method ran with: those set by the configuration or chosen by cross-validation "
            r"(several values separated by $|$: chosen per activity and $N$), and the estimator's defaults for the "
            r"others.}",
            r"\label{tab:parameters}",
            r"\begin{tabularx}{\linewidth}{@{}ll>{\hsize=0.75\hsize\raggedright\arraybackslash\ttfamily}X"
            r">{\hsize=1.25\hsize\raggedright\arraybackslash\ttfamily}X@{}}",
            r"\toprule",
            r"Method & Class & \textrm{Set by the configuration or CV} & \textrm{Estimator defaults} \\",
            r"\midrule",
            *rows,
            r"\bottomrule",
            r"\end{tabularx}",
            r"\end{table}",
        ]
    )


def setup_text(df, *, labels):
    """Sentences describing what was run (computed from the aggregate table)."""
    sources = {}
    pa_col = df["paper_activity"] if "paper_activity" in df.columns else [""] * len(df)
    d = df.assign(paper_activity=pa_col)[["source", "activity", "paper_activity"]].drop_duplicates()
    for src, act, pa in d.itertuples(index=False):
        sources.setdefault(src, []).append(nobreak(activity_label(act, pa)))
    seeds = sorted(df["seed"].unique())
    sizes = sorted(df["n_train"].unique())
    cv = sorted(df["cv"].dropna().unique()) if "cv" in df.columns else []
    splits = "split (seed)" if len(seeds) == 1 else "splits (seeds)"
    methods = [latex_escape(labels.get(m, m)) for m in _methods(df, labels)]
    how = {
        "per_size": "chosen by cross-validation once per activity, method and $N$, on the training frames of "
        f"seed {int(min(seeds))} (the study's first), and used for every seed",
        "per_job": "chosen by cross-validation on the training frames of each split",
        "none": "as configured (no cross-validation)",
    }
    return [
        "Data: "
        + "; ".join(f"{latex_escape(s)}: {', '.join(a)}" for s, a in sources.items())
        + ".",
        f"Methods: {', '.join(methods)}.",
        f"Training sizes $N \\in \\{{{', '.join(str(n) for n in sizes)}\\}}$, {len(seeds)} {splits} per size; "
        f"protocol: {latex_escape(', '.join(sorted(df['protocol'].unique())))}; "
        f"pose transform: {latex_escape(', '.join(sorted(df['pose_transform'].unique())))}.",
        "Hyper-parameters: "
        + "; ".join(how.get(c, latex_escape(c)) for c in cv or ["none"])
        + " (configuration key \\texttt{cv.mode}: "
        + latex_escape(", ".join(cv) or "none")
        + "). "
        "Table~\\ref{tab:parameters} lists the parameters each method ran with.",
    ]


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
            f"Study: \\textbf{{{latex_escape(name)}}} (configuration key \\texttt{{study}}; results in "
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


def tt(text):
    """``text`` in typewriter type, exactly as typed: "--" stays two ASCII hyphens (no en-dash ligature), so a
    command copied from the PDF runs."""
    return r"\texttt{" + latex_escape(text).replace("-", "-{}") + "}"


def missing_data_note(source, status):
    """One short LaTeX paragraph on the paper's activities that have no row for ``source``; "" if none.

    ``status``: {paper activity: studied activity id, or {"kind", "activity", "command", "missing"}} (the
    workflow's data_status; kinds as in :data:`.tables.NO_ROW`). Commands are set in typewriter type, one per line
    and with ASCII hyphens, so that they can be copied. A table none of whose activities is studied on the
    source is not shown (:func:`bsrbench.reporting.tables.tables_with_rows`); the note's first line says so.
    """
    from .tables import PAPER_TABLES, tables_with_rows

    shown = tables_with_rows(status)
    left_out = [t for t in PAPER_TABLES if t not in shown]
    by_kind = {}
    for names in PAPER_TABLES.values():
        for pa in names:
            st = status.get(pa, {"kind": "none"})
            if isinstance(st, dict):
                by_kind.setdefault(st.get("kind", "none"), []).append((pa, st))
    if not by_kind:
        return ""
    lines = []
    if left_out:
        names = _listing([nobreak(pa) for t in left_out for pa in PAPER_TABLES[t]])
        one = len(left_out) == 1
        lines.append(
            ("Table " if one else "Tables ")
            + _listing(left_out)
            + f" ({names}) "
            + ("is" if one else "are")
            + f" not shown for the {latex_escape(source)} data: this study has none of "
            + ("its" if one else "their")
            + " activities on that source, so every row would be empty."
        )
    for kind, items in by_kind.items():
        names = _listing([nobreak(pa) for pa, _ in items])
        if kind == "none":
            lines.append(
                f"{names}: config/datasets.yaml has no {latex_escape(source)} data set for "
                + ("it." if len(items) == 1 else "them.")
            )
        elif kind == "here":
            ids = _listing([tt(st["activity"]) for _, st in items])
            lines.append(
                f"{names}: the data are here; add {ids} to the configuration key "
                f"{tt('study_activities.' + source)} to study "
                + ("it." if len(items) == 1 else "them.")
            )
        elif kind == "download":
            lines.append(
                f"{names}: the data are not on this machine; these commands download and build them:"
            )
            lines += [r"\hspace*{1.5em}" + tt(st["command"]) for _, st in items]
        else:
            missing = sorted({f for _, st in items for f in st.get("missing", [])})
            lines.append(f"{names}: input files missing ({latex_escape(', '.join(missing))}).")
    return (
        r"\paragraph{Activities of the paper without data ("
        + latex_escape(source)
        + r").}"
        + "\n"
        + r"\begin{flushleft}\small"
        + "\n"
        + "\\\\\n".join(lines)
        + "\n"
        + r"\end{flushleft}"
    )


def write_body(path, *, tables, figures, notes=None):
    """The fragment with the tables and figures (paths relative to the study's report folder, reports/{study}).

    ``tables``: paths of the table fragments (``table<T>_<source>.tex``); after the last table of a source
    comes ``notes[source]`` (see :func:`missing_data_note`; after the last table for a source with none).
    ``figures``: (path, caption) pairs. Figures are
    included at their natural size (``\fitgraphics`` of reports/report.tex): they are drawn at the size they
    are printed, with no font below 7 pt; one wider than the text is scaled down to it.
    """
    notes = notes or {}
    tables = [Path(t) for t in tables]
    sources = [t.stem.split("_", 1)[1] if "_" in t.stem else "" for t in tables]
    lines = [r"\section{Tables}"]
    for k, (t, src) in enumerate(zip(tables, sources)):
        lines.append(rf"\input{{{t.with_suffix('').as_posix()}}}")
        last = k + 1 == len(tables) or sources[k + 1] != src
        if last and notes.get(src):
            lines.append(notes[src])
    # the note of a source without any table (none of the paper's activities studied on it)
    lines += [note for src, note in notes.items() if note and src not in sources]
    lines += [r"\clearpage", r"\section{Figures}"]
    for f, caption in figures:
        f = Path(f)
        lines += [
            r"\begin{figure}[H]",
            r"\centering",
            rf"\fitgraphics{{{f.as_posix()}}}",
            rf"\caption{{{caption}}}",
            rf"\label{{fig:{f.stem}}}",
            r"\end{figure}",
        ]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def config_provenance(configfiles, overrides=()):
    """LaTeX of the configuration a study ran with: the configuration files in the order they apply, then the
    ``--config KEY=VALUE`` overrides of the command line (or of the profile), which apply last, as a shell would
    take them (quoted where needed, in typewriter type with upright quotes and ASCII hyphens, so that the
    command copied from the PDF runs).

    ``configfiles``: paths; ``overrides``: the raw ``KEY=VALUE`` strings (Snakemake's
    ``workflow.config_settings.config_args``).
    """
    import shlex

    files = ", ".join(latex_escape(str(f)) for f in configfiles)
    text = (files + " (in the order they apply)") if configfiles else "none"
    overrides = [str(o) for o in overrides or ()]
    if overrides:
        command = shlex.join(["--config", *overrides])
        typed = latex_escape(command).replace("-", "-{}").replace("'", r"\textquotesingle{}")
        text += r", then \texttt{\frenchspacing " + typed + "}"  # no wider space after a colon
    return text


def build_header(*, configfiles, overrides=(), when=None, root="."):
    """LaTeX for the page-1 header: build date, git commit (and whether the tree has uncommitted changes),
    configuration (files and ``--config`` overrides, :func:`config_provenance`) and machine."""
    import datetime
    import os
    import platform

    when = when or datetime.datetime.now(datetime.UTC)
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=normal"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        code = f"git commit {commit}" + (
            " with uncommitted changes" if dirty else ", no uncommitted changes"
        )
    except (OSError, subprocess.CalledProcessError):
        code = "not a git checkout (commit unknown)"
    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = " ".join(line.split(":", 1)[1].split())
                break
    except OSError:
        pass
    machine = f"{platform.node()}: {platform.system()} {platform.machine()}, {os.cpu_count()} logical CPUs"
    if cpu:
        machine += f" ({cpu})"
    machine += f", Python {platform.python_version()}"
    rows = [
        ("Built", when.strftime("%Y-%m-%d %H:%M UTC")),
        ("Code", code),
        ("Machine", machine),
    ]
    rows = [(k, latex_escape(v)) for k, v in rows]
    rows.insert(2, ("Configuration", config_provenance(configfiles, overrides)))
    body = "\n".join(rf"{k} & {v} \\" for k, v in rows)
    return (
        "\\begin{center}\\small\n\\begin{tabularx}{0.9\\linewidth}{@{}l>{\\raggedright\\arraybackslash}X@{}}\n"
        + body
        + "\n\\end{tabularx}\n\\end{center}\n"
    )


def build_pdf(tex, pdf, *, root=None, log=None, header=None):
    """Run latexmk (pdflatex) on the template ``tex`` in the folder ``root`` (default: the template's folder),
    output in ``<root>/build``; copy the PDF to ``pdf``.

    TeX looks for the files the template inputs (``tables/*.tex``, ``figures/*.pdf``, ``build/header.tex``) in the
    folder it runs in, so one template serves every study's report folder (``reports/{study}``).
    ``header``: LaTeX written to ``<root>/build/header.tex`` first (the template inputs it; see
    :func:`build_header`). Raises InputError without latexmk, RuntimeError if LaTeX fails (naming its log).
    """
    tex = Path(tex).resolve()
    root = Path(root).resolve() if root is not None else tex.parent
    if shutil.which("latexmk") is None:
        raise InputError(
            "latexmk is not installed (bin/setup installs TeX Live); cannot build the PDF"
        )
    build = root / "build"
    build.mkdir(parents=True, exist_ok=True)
    (build / "header.tex").write_text(header if header is not None else "")
    cmd = [
        "latexmk",
        "-pdf",
        "-interaction=nonstopmode",
        "-halt-on-error",
        f"-outdir={build}",
        str(tex),
    ]
    res = subprocess.run(cmd, cwd=root, capture_output=True, text=True)
    if log is not None:
        Path(log).write_text(res.stdout + res.stderr)
    if res.returncode != 0:
        raise RuntimeError(
            f"latexmk failed on {tex} (exit {res.returncode}); see {build / tex.with_suffix('.log').name}"
        )
    with atomic_path(pdf) as tmp:
        shutil.copyfile(build / tex.with_suffix(".pdf").name, tmp)


def latex_log_problems(text, *, max_overfull_pt=1.0):
    """Problems in a LaTeX log: overfull boxes wider than ``max_overfull_pt``, undefined references and
    citations, and the request to rerun. Returns a list of the offending log lines (empty if none)."""
    out = []
    for line in text.splitlines():
        m = re.match(r"Overfull \\[hv]box \(([\d.]+)pt too (wide|high)\)", line)
        if m and float(m.group(1)) > max_overfull_pt:
            out.append(line)
        elif (
            re.search(r"LaTeX Warning: (Reference|Citation) .* undefined", line)
            or "There were undefined references" in line
            or "Rerun to get cross-references right" in line
        ):
            out.append(line)
    return out


def labels_from_json(text):
    d = json.loads(text)
    if not isinstance(d, dict):
        raise InputError("labels must be a JSON object {method: label}")
    return d
