"""Generated text of the study report (setup and findings), and the PDF build with latexmk.

The findings check the paper's claims on the data at hand, computed from the aggregate table only:
"PM beats every baseline" (the paper's Tables I and II show PM best in every row), PM against the honest
references (1-NN, ridge), our errors against the paper's, the effect of the split protocol and the
calibration of the predictive intervals.
"""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io import atomic_path
from .tables import PAPER_METHODS, activity_label, latex_escape, summarize


def _pairs(s, protocol, n):
    d = s[(s["protocol"] == protocol) & (s["n_train"] == n)]
    return d.pivot_table(index=["source", "activity", "paper_activity"], columns="method", values="mean")


def _names(idx):
    return ", ".join(f"{latex_escape(activity_label(a, pa))} ({latex_escape(s)})" for s, a, pa in idx) or "none"


def findings(df, paper, *, labels, pm="PM", references=("NN1", "Ridge")):
    """Sentences (LaTeX) saying where the paper's claims hold on these data and where they do not."""
    out = []
    s = summarize(df)
    methods = list(dict.fromkeys(df["method"]))
    baselines = [m for m in methods if labels.get(m, m) in PAPER_METHODS and m != pm]
    refs = [m for m in references if m in methods]
    L = lambda m: latex_escape(labels.get(m, m))  # noqa: E731
    protocols = [p for p in ("random", "contiguous") if p in set(df["protocol"])]
    if pm not in methods:
        return [f"{latex_escape(pm)} was not run, so the paper's claims about it are not checked."]
    sizes = sorted(df["n_train"].unique())
    for protocol in protocols:
        tag = "" if protocol == "random" else " (contiguous protocol)"
        t = s[s["protocol"] == protocol].pivot_table(
            index=["source", "activity", "n_train"], columns="method", values="mean"
        )
        if pm in t.columns and baselines:
            bl = [b for b in baselines if b in t.columns]
            have = t.dropna(subset=[pm] + bl)
            ok = have[pm] < have[bl].min(axis=1)
            text = (
                f"Summary{tag}: the paper's Tables I--II show PM with the lowest error in every row; here PM is "
                f"lowest among the paper's methods in {int(ok.sum())} of {len(ok)} (activity, $N$) rows"
            )
            allm = [m for m in bl + refs if m in t.columns]
            if refs:
                ok2 = have[pm] < have[allm].min(axis=1)
                text += f", and lowest of all methods including the references in {int(ok2.sum())} of {len(ok2)}"
            out.append(text + ".")
    for protocol in protocols:
        tag = "" if protocol == "random" else " (contiguous protocol)"
        for n in sizes:
            t = _pairs(s, protocol, n)
            if pm not in t.columns:
                continue
            if baselines:
                have = t.dropna(subset=[pm] + [b for b in baselines if b in t.columns])
                bl = [b for b in baselines if b in t.columns]
                ok = have[pm] < have[bl].min(axis=1)
                verdict = "holds" if ok.all() else ("does not hold" if not ok.any() else "holds only partly")
                out.append(
                    f"``PM beats every baseline ({', '.join(L(b) for b in bl)}) at $N={n}$''{tag}: {verdict}, "
                    f"for {int(ok.sum())} of {len(ok)} activities"
                    + (f" (fails for {_names(ok.index[~ok])})." if (~ok).any() else ".")
                )
            for r in refs:
                if r not in t.columns:
                    continue
                have = t.dropna(subset=[pm, r])
                ok = have[pm] < have[r]
                diff = float(np.median(have[pm] - have[r])) if len(have) else float("nan")
                out.append(
                    f"PM vs {L(r)} at $N={n}${tag}: PM is lower for {int(ok.sum())} of {len(ok)} activities "
                    f"(median difference PM $-$ {L(r)} = {diff:+.2f} degrees)."
                )
    # paired per split: the same split for every method, so compare seed by seed
    r = df[df["protocol"] == "random"]
    if baselines and not r.empty:
        w = r.pivot_table(index=["source", "activity", "n_train", "seed"], columns="method", values="error")
        bl = [b for b in baselines if b in w.columns]
        if pm in w.columns and bl:
            w = w.dropna(subset=[pm] + bl)
            wins = int((w[pm] < w[bl].min(axis=1)).sum())
            out.append(
                f"Split by split (every method sees the same split): PM has the lowest error of PM and the "
                f"baselines on {wins} of {len(w)} random splits."
            )
    # ours vs the paper
    if paper is not None and not r.empty:
        sr = s[s["protocol"] == "random"].copy()
        sr["label"] = sr["method"].map(lambda m: labels.get(m, m))
        m = sr.merge(paper, left_on=["key", "n_train", "label"], right_on=["key", "n_train", "method"],
                     suffixes=("", "_paper"))
        if not m.empty:
            parts = []
            for lab, g in m.groupby("label", sort=False):
                ratio = float(np.median(g["mean"] / g["mean_deg"]))
                parts.append(f"{latex_escape(lab)} {ratio:.2f}")
            out.append(
                "Our error divided by the paper's, median over the matching (activity, $N$) cells: "
                + ", ".join(parts) + " (1 = same error; the paper's data are not identical to ours)."
            )
    # protocol effect
    if set(protocols) == {"random", "contiguous"}:
        w = s.pivot_table(index=["source", "activity", "method", "n_train"], columns="protocol", values="mean").dropna()
        if not w.empty:
            parts = [
                f"{L(mm)} {float(np.median(g['contiguous'] / g['random'])):.2f}"
                for mm, g in w.groupby(level="method", sort=False)
            ]
            out.append(
                "Contiguous against random frames (error ratio, median over activities and $N$): "
                + ", ".join(parts)
                + ". Random frames of one sequence put near-duplicates of test frames in the training set."
            )
    # calibration
    if "coverage_90" in df.columns:
        c = r.dropna(subset=["coverage_90"])
        if not c.empty:
            parts = [f"{L(mm)} {100 * float(g['coverage_90'].mean()):.0f}\\%" for mm, g in c.groupby("method", sort=False)]
            out.append("Coverage of the nominal 90\\% predictive interval (mean over random splits): " + ", ".join(parts) + ".")
    return out


def setup_text(df, *, labels):
    """A paragraph describing what was run (computed from the aggregate table)."""
    sources = {}
    pa_col = df["paper_activity"] if "paper_activity" in df.columns else [""] * len(df)
    d = df.assign(paper_activity=pa_col)[["source", "activity", "paper_activity"]].drop_duplicates()
    for src, act, pa in d.itertuples(index=False):
        sources.setdefault(src, []).append(f"{activity_label(act, pa)} ({act})")
    seeds = sorted(df["seed"].unique())
    sizes = sorted(df["n_train"].unique())
    cv = sorted(df["cv"].dropna().unique()) if "cv" in df.columns else []
    lines = [
        "Data: " + "; ".join(f"{latex_escape(s)}: {latex_escape(', '.join(a))}" for s, a in sources.items()) + ".",
        f"Training sizes $N \\in \\{{{', '.join(str(n) for n in sizes)}\\}}$, {len(seeds)} splits (seeds) per size, "
        f"protocols: {latex_escape(', '.join(sorted(df['protocol'].unique())))}; "
        f"pose transform: {latex_escape(', '.join(sorted(df['pose_transform'].unique())))}.",
        "Hyper-parameters: " + latex_escape(", ".join(cv) or "n/a") + " (per\\_size: one 5-fold CV per activity, "
        "method and $N$ on the training frames of seed 0, used for every seed; per\\_job: one CV per split; "
        "none: fixed parameters).",
    ]
    params = []
    for m in dict.fromkeys(df["method"]):
        ps = sorted(set(df.loc[df["method"] == m, "params"].astype(str)))
        shown = latex_escape("; ".join(ps[:3])) + (f"; \\ldots\\ ({len(ps)} settings)" if len(ps) > 3 else "")
        params.append(f"{latex_escape(labels.get(m, m))}: \\texttt{{{shown}}}")
    # One item per method, typeset sloppily: long typewriter runs must break at their spaces, not overflow.
    lines.append(r"Parameters used:\begin{sloppypar}\begin{itemize}" + " ".join(r"\item " + p for p in params)
                 + r"\end{itemize}\end{sloppypar}")
    return lines


def write_generated(path, df, paper, *, labels, study=None):
    """The LaTeX fragment with the setup and the findings (input by reports/report.tex).

    ``study``: (name, results folder) of the study shown, named first in the setup; None leaves it out.
    """
    body = ["% generated from the study's aggregate table", r"\section{Setup}", ""]
    lines = setup_text(df, labels=labels)
    if study is not None:
        name, folder = study
        lines.insert(0, f"Study: \\textbf{{{latex_escape(name)}}} (configuration key \\texttt{{study}}; results in "
                        f"\\texttt{{{latex_escape(folder)}/}}, aggregate table "
                        f"\\texttt{{{latex_escape(folder)}/aggregate/results.csv}}).")
    body += [" ".join(lines), "", r"\section{Findings}", r"\begin{itemize}"]
    body += [r"\item " + f for f in findings(df, paper, labels=labels)]
    body += [r"\end{itemize}", ""]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(body))


def write_body(path, *, tables, figures):
    """The fragment listing the tables and figures (paths relative to reports/)."""
    lines = [r"\section{Tables}"]
    lines += [rf"\input{{{Path(t).with_suffix('').as_posix()}}}" for t in tables]
    lines += [r"\clearpage", r"\section{Figures}"]
    for f, caption in figures:
        lines += [
            r"\begin{figure}[H]",
            r"\centering",
            rf"\includegraphics[width=\linewidth,height=0.8\textheight,keepaspectratio]{{{Path(f).as_posix()}}}",
            rf"\caption{{{caption}}}",
            r"\end{figure}",
        ]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def build_pdf(tex, pdf, *, log=None):
    """Run latexmk (pdflatex) on ``tex`` in its folder, output in ``<folder>/build``; copy the PDF to ``pdf``."""
    tex = Path(tex).resolve()
    if shutil.which("latexmk") is None:
        raise InputError("latexmk is not installed (bin/setup installs TeX Live); cannot build the PDF")
    build = tex.parent / "build"
    cmd = ["latexmk", "-pdf", "-interaction=nonstopmode", "-halt-on-error", f"-outdir={build}", tex.name]
    res = subprocess.run(cmd, cwd=tex.parent, capture_output=True, text=True)
    if log is not None:
        Path(log).write_text(res.stdout + res.stderr)
    if res.returncode != 0:
        raise RuntimeError(f"latexmk failed on {tex} (exit {res.returncode}); see {build / tex.with_suffix('.log').name}")
    with atomic_path(pdf) as tmp:
        shutil.copyfile(build / tex.with_suffix(".pdf").name, tmp)


def labels_from_json(text):
    d = json.loads(text)
    if not isinstance(d, dict):
        raise InputError("labels must be a JSON object {method: label}")
    return d
