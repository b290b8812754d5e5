"""The LaTeX tables in the layout of the paper's Tables I and II, and the summary (mean and std over seeds) they show.

Every table, plot and finding is computed from the aggregate table (``results/{study}/aggregate/results.csv``, one
row per fit job, built by :func:`bsrbench.results.aggregate_rows`). Tables contain no timings, so two runs of the same
configuration give identical tables.
"""

import math
import re

import numpy as np
import pandas as pd

from ..errors import DataFileError, InputError
from ..io import atomic_path, read_csv
from ..paper import PAPER_METHODS, PAPER_TABLES  # noqa: F401 (PAPER_METHODS: report.py's name)
from ..results import (  # noqa: F401 (the aggregate table's functions, under the names the scripts use)
    KEY_COLUMNS,
    aggregate_files,
    aggregate_rows,
    check_rows,
    read_results,
    write_csv,
)

#: Why a paper activity has no row (the ``kind`` of the workflow's data_status), as a table cell says it.
NO_ROW = {
    "none": "no data set of this source",
    "here": "data here, not in this study",
    "download": "data not on this machine",
    "missing": "input files missing",
}
#: The mark of a mean statistically indistinguishable from the best of its row (LaTeX; the README's is TIE_TEXT).
TIE_MARK = r"$^{\dagger}$"
TIE_TEXT = "†"


def tables_with_rows(status):
    """The paper's tables (``"I"``, ``"II"``, in order) that have a row of results on a data source: those with at
    least one studied activity. A table none of whose activities is studied on a source would be a block of
    "no data" rows; the report leaves it out and says so (:func:`bsrbench.reporting.report.missing_data_note`).

    ``status``: {paper activity: studied activity id, or a dict saying why it has no row} (the workflow's
    ``data_status``; a paper activity missing from it has no row).
    """
    return [
        t
        for t, names in PAPER_TABLES.items()
        if any(isinstance(status.get(pa), str) for pa in names)
    ]


def other_activities(status, studied):
    """{activity: its name in a table} of the ``studied`` activities (ids, in order) of a data source that are no
    row of the paper's Tables I-II (``paper_activity: null``, or a second data set of a paper activity): they get
    a table of their own (:func:`activities_table`). ``status``: the workflow's data_status of the source."""
    rows = {v for v in status.values() if isinstance(v, str)}
    return {a: activity_label(a) for a in studied if a not in rows}


def error_tables(folder, sources):
    """The error tables of the report, per data source in order: Tables I-II with a row
    (:func:`tables_with_rows`), ``<folder>/tables/table<T>_<source>.tex``, and the table of
    :func:`other_activities`, ``<folder>/tables/activities_<source>.tex``. ``sources``: {source: (status,
    studied activities)}."""
    out = []
    for s, (status, studied) in sources.items():
        out += [f"{folder}/tables/table{t}_{s}.tex" for t in tables_with_rows(status)]
        if other_activities(status, studied):
            out.append(f"{folder}/tables/activities_{s}.tex")
    return out


def paper_key(name):
    """Case-insensitive key of a paper activity name (the paper writes "kick soccer ball" and "Run")."""
    return " ".join(str(name).lower().split()) if isinstance(name, str) and name.strip() else ""


def activity_label(activity, paper_activity=None):
    """The paper's name of an activity if it has one, else the identifier, capitalised."""
    if isinstance(paper_activity, str) and paper_activity.strip():
        return paper_activity
    return str(activity).replace("_", " ").capitalize()


def paper_names(df):
    """{method: the paper's name of its estimator (a column of Tables I-II: "RVM", ..., "PM") or None}, from the
    rows' ``estimator`` column (:func:`bsrbench.methods.paper_name`); {} for rows without one."""
    from ..methods import paper_name

    if "estimator" not in df.columns:
        return {}
    first = df.dropna(subset=["estimator"]).groupby("method", sort=False)["estimator"].first()
    return {m: paper_name(str(est)) for m, est in first.items()}


def read_paper_tables(path):
    """The paper's Tables I and II as rows (table, activity, n_train, method, mean_deg, std_deg), keyed by our ids."""
    df = read_csv(path, "the paper's tables")
    need = {"table", "activity", "n_train", "method", "mean_deg", "std_deg"}
    if not need <= set(df.columns):
        raise DataFileError(path, f"needs columns {sorted(need)}; has {list(df.columns)}")
    for col, expected in (
        ("n_train", "a whole number"),
        ("mean_deg", "a finite number >= 0 (degrees)"),
        ("std_deg", "a finite number >= 0 (degrees)"),
    ):
        v = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(v) | (v < 0) | ((v != np.round(v)) if col == "n_train" else False)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DataFileError(
                path, f"row {i + 2}, column {col!r}: {df[col].iloc[i]!r}; expected {expected}"
            )
    df = df.astype({"n_train": int, "mean_deg": float, "std_deg": float})
    known = {paper_key(a) for t in PAPER_TABLES.values() for a in t}
    unknown = sorted(set(df["activity"]) - {a for a in df["activity"] if paper_key(a) in known})
    if unknown:
        raise DataFileError(
            path, f"unknown activities {unknown}; expected the paper's {sorted(known)}"
        )
    df = df.copy()
    df["key"] = df["activity"].map(paper_key)
    return df


def summarize(df):
    """Mean and sample std (ddof=1) of the error over seeds per (protocol, source, activity, method, n_train).

    Carries ``paper_activity`` along and adds ``key`` (:func:`paper_key` of it) to match the paper's rows.
    """
    df = df.copy()
    if "paper_activity" not in df.columns:
        df["paper_activity"] = ""
    df["paper_activity"] = df["paper_activity"].fillna("").astype(str)
    g = df.groupby(
        ["protocol", "source", "activity", "paper_activity", "method", "n_train"], sort=True
    )["error"]
    out = g.agg(
        mean="mean", std=lambda e: float(np.std(e, ddof=1)) if len(e) > 1 else math.nan, n="count"
    )
    out = out.reset_index()
    out["key"] = out["paper_activity"].map(paper_key)
    return out


# --------------------------------------------------------------------------------------------------- LaTeX
def latex_escape(text):
    repl = {
        "\\": r"\textbackslash{}",
        "&": r"\&",
        "%": r"\%",
        "$": r"\$",
        "#": r"\#",
        "_": r"\_",
        "{": r"\{",
        "}": r"\}",
        "~": r"\textasciitilde{}",
        "^": r"\textasciicircum{}",
    }
    return "".join(repl.get(c, c) for c in str(text))


STD_SIZE = "scriptsize"  # LaTeX size of the std in a table cell; the tables are \footnotesize


def format_cell(mean, std, *, bold=False, tie=False, digits=2):
    """``mean $\\pm$ {\\scriptsize std}`` with the mean in bold if ``bold``, marked with :data:`TIE_MARK` if
    ``tie`` (and not bold); ``--`` for a missing mean.

    The std is set one size below the tables' ``\\footnotesize``, so it prints smaller than the mean."""
    if mean is None or not np.isfinite(mean):
        return "--"
    m = f"{mean:.{digits}f}"
    if bold:
        m = rf"\textbf{{{m}}}"
    elif tie:
        m += TIE_MARK
    if std is None or not np.isfinite(std):
        return m
    return rf"{m} $\pm$ {{\{STD_SIZE} {std:.{digits}f}}}"


def best_mask(values, digits=2):
    """True where a value is the smallest (after rounding to ``digits``, so that printed ties are both bold)."""
    v = np.array(
        [np.round(x, digits) if x is not None and np.isfinite(x) else np.inf for x in values]
    )
    if not np.isfinite(v).any():
        return [False] * len(v)
    return list(v == v.min())


def tie_caption(ties, *, protocol, source):
    """The caption's sentence on the marks of :func:`latex_table` for one protocol and source."""
    if ties is None:
        return "No paired comparisons were made, so no mean is marked as tied with the best."
    tested = any(k[0] == protocol and k[1] == source for k in ties)
    text = (
        TIE_MARK
        + ": not distinguishable from the best of its row on these frames (paired $t$-test over the splits, "
        r"Holm-adjusted over the row's comparisons, $p \geq 0.05$; the corrected resampled $t$-test, which asks "
        r"about a new data set of independent frames, is in the comparisons table)."
    )
    if not tested:
        text += r" No row has 2 common splits, so no row was tested and none is marked."
    return text


def _row(cells):
    return " & ".join(cells) + r" \\"


def no_row_line(table, status):
    """The one line under a table (LaTeX) naming the paper's activities of ``table`` that have no row on its data
    source and why (:data:`NO_ROW`), or "" if every one has a row. The tables show rows of results only."""
    why = {}
    for paper_name in PAPER_TABLES[table]:
        st = status.get(paper_name, {"kind": "none"})
        if isinstance(st, dict):
            why.setdefault(NO_ROW.get(st.get("kind"), "no data"), []).append(paper_name)
    if not why:
        return ""
    parts = [
        f"{', '.join(latex_escape(n) for n in names)} ({reason})" for reason, names in why.items()
    ]
    return (
        r"\par\smallskip{\scriptsize Not shown (no results here): "
        + "; ".join(parts)
        + "; see the note below the tables.}"
    )


def latex_table(
    summary,
    paper,
    *,
    source,
    table,
    methods,
    labels,
    n_train,
    status,
    protocols,
    digits=2,
    skipped=None,
    frames=None,
    ties=None,
    best_of=None,
    block=None,
):
    """LaTeX (booktabs) for one of the paper's tables on one data source, one tabular per protocol.

    Parameters
    ----------
    summary : DataFrame from :func:`summarize`.
    paper : DataFrame from :func:`read_paper_tables`.
    methods : method keys in column order; labels : {method: column label}.
    n_train : training sizes of the study (rows per activity).
    status : {paper activity name: studied activity id, or {"kind": why there is no row, ...}} (see
        :data:`NO_ROW`); the activities without a row are named in one line under the table
        (:func:`no_row_line`), which points to the note under the tables
        (:func:`bsrbench.reporting.body.missing_data_note`); a paper activity missing from ``status`` has no data.
    protocols : protocols of the study; the paper's numbers are shown (in an italic row under ours) for
        the random protocol, the paper's.
    skipped : {protocol: {activity id: [note, ...]}}: training sizes not run because too few test frames
        would remain; each note starts with ``"N = <n> skipped"`` and takes that size's row.
    frames : {activity id: sentence}: how each studied activity's frames were chosen, stated under the table.
    ties : {(protocol, source, activity, n_train): {method, ...}}: the best method of each cell and those
        statistically indistinguishable from it (:func:`bsrbench.reporting.comparisons.tied_with_best`); their
        means get :data:`TIE_MARK` unless bold. None: no comparisons, no marks (the caption says so); a cell
        missing from it had no test (fewer than 2 common splits).
    best_of : the methods among which a row's best is bolded (default ``methods``): all the study's table
        methods when ``methods`` is one block of them.
    block : None for the paper's methods, or the caption's name of another block (e.g. "today's baselines"),
        whose table gets no rows of the paper's numbers and a label ending in ``-today``.
    """
    if table not in PAPER_TABLES:
        raise InputError(f"table must be one of {sorted(PAPER_TABLES)}; got {table!r}")
    rows = [
        (paper_name, status[paper_name], paper_name)
        for paper_name in PAPER_TABLES[table]
        if isinstance(status.get(paper_name), str)
    ]
    return error_table(
        summary,
        paper,
        rows=rows,
        title=f"Table {table}",
        label=f"tab:{table}-{source}",
        source=source,
        methods=methods,
        labels=labels,
        n_train=n_train,
        protocols=protocols,
        digits=digits,
        skipped=skipped,
        frames=frames,
        ties=ties,
        best_of=best_of,
        block=block,
        under=no_row_line(table, status),
    )


def activities_table(summary, *, source, activities, **kwargs):
    """The mean angle error table (layout, bold and tie marks of :func:`latex_table`) of studied activities with no
    row in the paper's Tables I-II (``paper_activity: null``, or a second data set of a paper activity) on
    ``source``: ``activities`` is {activity id: its name in the table}; no rows of the paper's numbers.
    Other arguments as :func:`latex_table` (``best_of``, ``block``, ``ties``, ...; no ``status`` or ``table``)."""
    rows = [(name, a, None) for a, name in activities.items()]
    return error_table(
        summary,
        None,
        rows=rows,
        title="Activities not in the paper's tables",
        label=f"tab:activities-{source}",
        source=source,
        **kwargs,
    )


def error_table(
    summary,
    paper,
    *,
    rows,
    title,
    label,
    source,
    methods,
    labels,
    n_train,
    protocols,
    digits=2,
    skipped=None,
    frames=None,
    ties=None,
    best_of=None,
    block=None,
    under="",
):
    """LaTeX (booktabs) of the mean angle error per (activity, N) on one data source, one tabular per protocol.

    ``rows``: [(row name, studied activity id, the paper's activity name or None)]: a row per training size of
    each activity, under it (random protocol, paper's block) the paper's numbers if it has a paper name.
    ``title``: the caption's first words ("Table I"); ``label``: the LaTeX label's stem (protocol and block are
    appended); ``under``: a line of LaTeX set under the tabular. Other arguments as :func:`latex_table`.
    """
    skipped = skipped or {}
    best_of = list(best_of or methods)
    frames = frames or {}
    ncol = 2 + len(methods)
    # fixed-width method columns that fill the 17.8 cm text width (activity 3.1 cm, N 0.8 cm, 3.5 pt gaps)
    box = min(1.8, (17.8 - 3.1 - 0.8 - 0.25 * (len(methods) + 1)) / max(1, len(methods)))
    sizes = sorted(int(n) for n in n_train)
    s = summary[summary["source"] == source]
    out = [f"% {title} on data source {source!r}; generated from the study's aggregate table"]
    for protocol in protocols:
        sp = s[s["protocol"] == protocol]
        which = f" ({latex_escape(block)})" if block else ""
        best = (
            "best of each row (of both tables)" if best_of != list(methods) else "best of each row"
        )
        caption = (
            f"{title}{which} on the {latex_escape(source)} data, protocol "
            f"``{latex_escape(protocol)}'': "
            rf"mean error $\pm$ std (degrees) over seeds; {best} in bold. "
            + tie_caption(ties, protocol=protocol, source=source)
        )
        with_paper = protocol == "random" and not block and paper is not None
        if with_paper and any(pn for _, _, pn in rows):
            caption += " Italic rows: the paper's numbers."
        out += [
            r"\begin{table}[H]",
            r"\centering\footnotesize\setlength{\tabcolsep}{3.5pt}",
            rf"\caption{{{caption}}}",
            rf"\label{{{label}-{protocol}{'-today' if block else ''}}}",
            # activity names wrap at spaces only (never hyphenated): the paper's names, as printed there
            r"\begin{tabular}{@{}>{\raggedright\arraybackslash\hyphenpenalty=10000\exhyphenpenalty=10000}p{3.1cm}r"
            + "c" * len(methods)
            + "@{}}",
            r"\toprule",
            # fixed-width headers keep the columns apart in tables whose rows are all notes
            _row(
                ["Activity", r"Tr.\ \#"]
                + [rf"\makebox[{box:.2f}cm]{{{latex_escape(labels.get(m, m))}}}" for m in methods]
            ),
        ]
        for row_name, activity, paper_name in rows:
            out.append(r"\midrule")
            name = latex_escape(row_name)
            if activity not in set(sp["activity"]):
                note = rf"\multicolumn{{{ncol - 1}}}{{@{{}}l@{{}}}}{{\emph{{no results of this protocol}}}}"
                out.append(_row([name, note]))
                continue
            notes = {}
            for note in skipped.get(protocol, {}).get(activity, []):
                m = re.match(r"N = (\d+) skipped", note)
                if m:
                    notes[int(m.group(1))] = note
            for n in sizes:
                if n in notes:
                    note = rf"\multicolumn{{{ncol - 2}}}{{@{{}}l@{{}}}}{{\emph{{{latex_escape(notes[n])}}}}}"
                    out.append(_row([name, str(n), note]))
                    continue
                cell = sp[(sp["activity"] == activity) & (sp["n_train"] == n)].set_index("method")
                means = [
                    float(cell.at[m, "mean"]) if m in cell.index else math.nan for m in methods
                ]
                stds = [float(cell.at[m, "std"]) if m in cell.index else math.nan for m in methods]
                others = [
                    float(cell.at[m, "mean"])
                    for m in best_of
                    if m not in methods and m in cell.index
                ]
                bold = best_mask(means + others, digits)[: len(means)]
                tied = (ties or {}).get((protocol, source, activity, n), set())
                out.append(
                    _row(
                        [name, str(n)]
                        + [
                            format_cell(a, b, bold=c, tie=m in tied, digits=digits)
                            for a, b, c, m in zip(means, stds, bold, methods)
                        ]
                    )
                )
                if not (with_paper and paper_name):
                    continue
                pc = paper[
                    (paper["key"] == paper_key(paper_name)) & (paper["n_train"] == n)
                ].set_index("method")
                if not any(labels.get(m, m) in pc.index for m in methods):
                    continue
                pl = [labels.get(m, m) for m in methods]
                pm = [float(pc.at[lab, "mean_deg"]) if lab in pc.index else math.nan for lab in pl]
                ps = [float(pc.at[lab, "std_deg"]) if lab in pc.index else math.nan for lab in pl]
                pb = best_mask(pm, digits)
                cells = [
                    r"\emph{" + format_cell(a, b, bold=c, digits=digits) + "}"
                    if np.isfinite(a)
                    else ""
                    for a, b, c in zip(pm, ps, pb)
                ]
                out.append(_row([r"\emph{\quad paper}", ""] + cells))
        out += [r"\bottomrule", r"\end{tabular}"]
        studied = set(sp["activity"])
        shown = list(dict.fromkeys(a for _, a, _ in rows if a in frames and a in studied))
        if shown:
            text = "; ".join(f"{a}: {frames[a]}" for a in shown)
            out.append(r"\par\smallskip{\scriptsize Frames. " + latex_escape(text) + ".}")
        if under:
            out.append(under)
        out += [r"\end{table}", ""]
    return "\n".join(out)


def table_blocks(methods, groups, reference="PM"):
    """``[(block, methods), ...]`` of the tables: the paper's methods (block None), then, if any, today's
    baselines (``groups[m] == "today"``) beside ``reference`` (the paper's PM, when it is a table method)."""
    paper = [m for m in methods if groups.get(m, "paper") != "today"]
    today = [m for m in methods if groups.get(m, "paper") == "today"]
    out = [(None, paper)] if paper else []
    if today:
        out.append(("today's baselines", ([reference] if reference in paper else []) + today))
    return out


def latex_tables(summary, paper, *, methods, groups, reference="PM", **kwargs):
    """:func:`latex_table` for each block of :func:`table_blocks`, bolding the best over all ``methods``."""
    return "\n".join(
        latex_table(summary, paper, methods=ms, best_of=methods, block=block, **kwargs)
        for block, ms in table_blocks(methods, groups, reference)
    )


def activities_tables(summary, *, methods, groups, reference="PM", **kwargs):
    """:func:`activities_table` for each block of :func:`table_blocks`, bolding the best over all ``methods``."""
    return "\n".join(
        activities_table(summary, methods=ms, best_of=methods, block=block, **kwargs)
        for block, ms in table_blocks(methods, groups, reference)
    )


def write_text(path, text):
    with atomic_path(path) as tmp:
        tmp.write_text(text)
