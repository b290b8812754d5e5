"""The report's sections "Tables" and "Figures" (tables/body.tex): the tables and figures of the study, in order,
with a note per data source on the paper's activities that have no data; and the writing of both generated
fragments of rule report_text (this one and findings.tex)."""

from pathlib import Path

from ..estimators import estimator_defaults
from ..io import atomic_path
from .captions import figure_captions
from .findings import write_generated
from .latex import escape, figure, listing, nobreak, tt
from .tables import PAPER_TABLES, tables_with_rows


def missing_data_note(source, status):
    """One short LaTeX paragraph on the paper's activities that have no row for ``source``; "" if none.

    ``status``: {paper activity: studied activity id, or {"kind", "activity", "command", "missing"}} (the
    workflow's data_status; kinds as in :data:`.tables.NO_ROW`). Commands are set in typewriter type, one per line
    and with ASCII hyphens, so that they can be copied. A table none of whose activities is studied on the
    source is not shown (:func:`bsrbench.reporting.tables.tables_with_rows`); the note's first line says so.
    """
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
        names = listing([nobreak(pa) for t in left_out for pa in PAPER_TABLES[t]])
        one = len(left_out) == 1
        lines.append(
            ("Table " if one else "Tables ")
            + listing(left_out)
            + f" ({names}) "
            + ("is" if one else "are")
            + f" not shown for the {escape(source)} data: this study has none of "
            + ("its" if one else "their")
            + " activities on that source, so every row would be empty."
        )
    for kind, items in by_kind.items():
        names = listing([nobreak(pa) for pa, _ in items])
        if kind == "none":
            lines.append(
                f"{names}: config/datasets.yaml has no {escape(source)} data set for "
                + ("it." if len(items) == 1 else "them.")
            )
        elif kind == "here":
            ids = listing([tt(st["activity"]) for _, st in items])
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
            lines.append(f"{names}: input files missing ({escape(', '.join(missing))}).")
    # one unbreakable box: the heading never stands alone at the foot of a page
    return (
        r"\par\medskip\noindent\begin{minipage}{\linewidth}"
        + "\n"
        + r"\paragraph{Activities of the paper without data ("
        + escape(source)
        + r").}"
        + "\n"
        + r"\begin{flushleft}\small"
        + "\n"
        + "\\\\\n".join(lines)
        + "\n"
        + r"\end{flushleft}"
        + "\n"
        + r"\end{minipage}"
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
        lines.append(figure(f.as_posix(), caption, command=r"\fitgraphics", label=f"fig:{f.stem}"))
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def write_report_text(
    findings_path,
    body_path,
    study,
    *,
    comparisons,
    name,
    results_folder,
    root,
    tables,
    figures,
    cd_figures,
    status,
):
    """The two fragments reports/report.tex inputs: ``findings_path`` (setup, parameters, findings:
    :func:`bsrbench.reporting.findings.write_generated`) and ``body_path`` (tables and figures, :func:`write_body`).

    ``study``: what the captions say about the study (:class:`bsrbench.reporting.captions.Study`, with the
    aggregate table and the paper's tables); ``comparisons``: the paired comparisons; ``name``,
    ``results_folder``: the study's name and results folder, named in the setup; ``root``: the study's report
    folder (reports/{study}), from which the paths of ``tables``, ``figures`` and ``cd_figures`` are given;
    ``status``: {source: the workflow's data_status}, for the notes on the paper's activities without data.
    """
    df = study.df
    # the estimators' defaults: the parameter table shows every value a method ran with
    estimators = df.drop_duplicates("method")[["method", "estimator"]].itertuples(index=False)
    write_generated(
        findings_path,
        df,
        study.paper,
        labels=study.labels,
        defaults={m: estimator_defaults(e) for m, e in estimators},
        study=(name, Path(results_folder).as_posix()),
        comparisons=comparisons,
    )
    write_body(
        body_path,
        tables=[Path(t).relative_to(root) for t in tables],
        figures=figure_captions(figures, cd_figures, study, root=root),
        notes={s: missing_data_note(s, dict(st)) for s, st in status.items()},
    )
