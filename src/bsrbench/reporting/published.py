"""Published result tables (``reports/published/*.csv``) and the README's results tables made from them.

``reports/published/paper.csv`` (the paper protocol, ``config/paper.yaml``) and ``reports/published/ablation.csv``
(``config/ablation.yaml``) are copies of the aggregate table of those runs: one row per fit job, the columns of
``results/{study}/aggregate/results.csv`` including the convergence columns (NaN where not computed). They are committed,
so that anyone can regenerate and check the README's tables without rerunning the study::

    python -m bsrbench.reporting.published publish results/paper/aggregate/results.csv reports/published/paper.csv
    python -m bsrbench.reporting.published readme reports/published/paper.csv --update README.md
    python -m bsrbench.reporting.published readme reports/published/paper.csv --update docs/results.md

``publish`` checks the table (key columns, no duplicate job, every convergence column) before writing it, and that
it is the table of the study the destination is named after: the study is the folder ``<study>`` of
``results/<study>/aggregate/results.csv`` and the destination must be ``<study>.csv``
(``reports/published/<study>.csv``), so that another study's results (e.g. the quick default study's) cannot
silently replace ``paper.csv``. For a source outside ``results/`` name the study with ``--study NAME``::

    python -m bsrbench.reporting.published publish --study paper /elsewhere/results.csv reports/published/paper.csv

``comparisons`` writes the paired comparisons of a published table (:mod:`bsrbench.reporting.comparisons`; no
refit), with exactly the columns of :data:`bsrbench.reporting.comparisons.PUBLISHED_COLUMNS`, to
``reports/published/<study>-comparisons.csv``::

    python -m bsrbench.reporting.published comparisons reports/published/paper.csv \\
        reports/published/paper-comparisons.csv

``readme`` prints the markdown tables (one per data source, random protocol: mean +- std over seeds, the paper's
number in brackets, the lowest mean of each row in bold, a dagger on the means statistically indistinguishable from
it) and the count of PM's significant differences, or, with ``--update``, replaces the text between the markers
``<!-- results-table:<source> -->`` and ``<!-- /results-table:<source> -->`` (docs/results.md), between
``<!-- results-summary -->`` and ``<!-- /results-summary -->`` (the README: per method, the means over the cells,
:func:`readme_summary`) and between ``<!-- results-counts -->`` and ``<!-- /results-counts -->``, where the file has
these markers.

``mechanisms`` prints the README's paragraph on the paper's two reasons (:mod:`bsrbench.reporting.mechanisms`:
each mechanism variant of PM against PM on the same splits), or, with ``--update``, writes it between
``<!-- mechanisms -->`` and ``<!-- /mechanisms -->``::

    python -m bsrbench.reporting.published mechanisms reports/published/ablation-mechanisms.csv --update README.md
"""

import argparse
import math
import re
import sys
from pathlib import Path

import numpy as np

from ..errors import DataFileError, InputError
from ..methods import configured
from . import comparisons as cmp
from . import freshness, headline
from .convergence import with_convergence_columns
from .tables import KEY_COLUMNS, TIE_TEXT, best_mask, read_paper_tables, read_results, summarize
from .verdict import verdict

#: The study whose published table the README shows (``reports/published/paper.csv``, ``config/paper.yaml``).
_DEFAULT_PAPER = Path(__file__).resolve().parents[3] / "resources" / "paper-tables.csv"


def study_of(src):
    """The study of an aggregate table: ``<study>`` of a path ending in ``results/<study>/aggregate/results.csv``,
    else None."""
    parts = Path(src).parts
    if len(parts) >= 4 and parts[-4] == "results" and parts[-2:] == ("aggregate", "results.csv"):
        return parts[-3]
    return None


def check_study(src, dest, study=None):
    """The study being published (see the module docstring); InputError naming ``src``, ``dest``, both studies and
    the right command if the destination is not ``<study>.csv``, or if the study of ``src`` cannot be told from its
    path and ``study`` is not given, or if ``study`` contradicts the path."""
    cmd = "python -m bsrbench.reporting.published publish"
    found = study_of(src)
    if study is not None and found is not None and study != found:
        raise InputError(
            f"--study {study!r} contradicts the source {str(src)!r}, which is study {found!r} "
            f"(results/<study>/aggregate/results.csv); drop --study: {cmd} {src} reports/published/{found}.csv"
        )
    study = study if study is not None else found
    if study is None:
        raise InputError(
            f"cannot tell the study of the source {str(src)!r}: expected results/<study>/aggregate/results.csv, or "
            f"name the study with --study NAME (the destination is then reports/published/NAME.csv)"
        )
    dest_study = Path(dest).name[:-4] if Path(dest).name.endswith(".csv") else Path(dest).name
    if dest_study != study:
        right = Path(dest).with_name(f"{study}.csv")
        flag = "" if found is not None else f"--study {study} "
        raise InputError(
            f"the source {str(src)!r} is study {study!r} but the destination {str(dest)!r} is study "
            f"{dest_study!r} (reports/published/<study>.csv); not publishing. The right command: "
            f"{cmd} {flag}{src} {right}"
        )
    return study


def publish(src, dest, study=None, configfiles=None):
    """Copy the aggregate table ``src`` to ``dest`` with every convergence column; check it first
    (:func:`.tables.read_results`: one row per job, valid values, every cell with all its seeds).

    ``dest``'s folder must exist (a mistyped destination is an error, not a new folder): DataFileError naming
    ``dest`` otherwise, before anything is read or written. ``dest`` must be named after the study of ``src``
    (:func:`check_study`; ``study`` for a source outside ``results/``): InputError otherwise, before anything is
    read or written. ``configfiles``: the study's configuration files, recorded in the provenance (default:
    ``config/<study>.yaml``; a part of a study run with ``--config study=...`` names its study's files)."""
    parent = Path(dest).parent
    if not parent.is_dir():
        what = "is not a folder" if parent.exists() else "does not exist"
        raise DataFileError(
            dest,
            f"cannot write the published table: its folder {str(parent)!r} {what}; expected the path of a "
            f"table in an existing folder, e.g. reports/published/paper.csv",
        )
    check_study(src, dest, study)
    # the files must be readable and run the table's methods, or the check and verify could not read their code
    config = freshness.study_config(configfiles) if configfiles else None
    df = read_results(src)
    if configfiles:
        registry = freshness.study_registry(config, " + ".join(configfiles))
        unknown = sorted(set(df["method"]) - set(registry))
        if unknown:
            raise InputError(
                f"--configfiles {' '.join(configfiles)}: do not run the methods {unknown} of {src}; expected "
                "the configuration files the study was run with"
            )
    df = with_convergence_columns(df).sort_values(KEY_COLUMNS, kind="mergesort")
    # the provenance beside it: per method the fingerprint and digests the staleness check compares; made (and
    # the destination's old one read) before anything is written, and written together with the table
    prov = freshness.table_provenance(dest, df, configfiles)
    freshness.write_table(df, dest, "the published table", prov)
    return df


def publish_comparisons(src, dest):
    """Write the paired comparisons of the published table ``src`` (checked as :func:`.tables.read_results`
    checks it) to ``dest`` with exactly :data:`.comparisons.PUBLISHED_COLUMNS`, and the verdict across cells and
    activities (:func:`.verdict.verdict`) to ``<study>-verdict.csv`` beside it. ``dest`` must be
    ``<study>-comparisons.csv`` next to ``<study>.csv`` naming: InputError otherwise, before anything is read."""
    want = Path(src).stem + "-comparisons.csv"
    if Path(dest).name != want:
        raise InputError(
            f"the comparisons of {str(src)!r} go to {want!r} (reports/published/<study>-comparisons.csv); got "
            f"{str(dest)!r}. The right command: python -m bsrbench.reporting.published comparisons {src} "
            f"{Path(dest).with_name(want)}"
        )
    if not Path(dest).parent.is_dir():
        raise DataFileError(
            dest, f"cannot write the comparisons: folder {str(Path(dest).parent)!r} does not exist"
        )
    df = read_results(src)
    out = cmp.published(cmp.comparisons(df))
    verdict_dest = Path(dest).with_name(Path(src).stem + "-verdict.csv")
    verdict_table = verdict(df, motions=published_motions(src))
    freshness.write_table(out, dest, "the comparisons")
    freshness.write_table(verdict_table, verdict_dest, "the verdict")
    return out


def published_motions(table):
    """{(source, activity): motion} of the data sets of a published table's study (its provenance's
    configfiles over config/datasets.yaml)."""
    from ..datasets import motion_map
    from ..methods import study_datasets

    return motion_map(study_datasets(freshness.configfiles(table)))


TIE_LEGEND = (
    f"Bold: the lowest mean of the row; {TIE_TEXT}: not distinguishable from it on these frames (paired t-test "
    "over the splits, Holm-adjusted over the row's comparisons, p >= 0.05; the corrected resampled t-test is in "
    "reports/published/paper-comparisons.csv)."
)


def readme_tables(
    df, paper, *, protocol="random", methods=None, labels=None, digits=2, comparisons=None
):
    """{source: markdown table} of the README: one row per (activity, N), one column per method, the means
    tied with the row's best marked (:data:`.tables.TIE_TEXT`, from ``comparisons``, computed from ``df`` if None),
    and the legend under the table. ``methods`` (the first columns, in order; the others follow by name) default to
    the paper's block of the README's study, and ``labels`` to its labels (:func:`bsrbench.methods.configured`)."""
    registry = configured(README_STUDY)
    if methods is None:
        methods = [m for m, r in registry.items() if r.group != "today"]
    labels = {**{m: r.label for m, r in registry.items()}, **(labels or {})}
    if comparisons is None:
        comparisons = cmp.comparisons(df[df["protocol"] == protocol])
    ties = cmp.tied_with_best(comparisons)
    s = summarize(df[df["protocol"] == protocol])
    if s.empty:
        raise InputError(f"no rows of protocol {protocol!r} to tabulate")
    shown = [m for m in methods if m in set(s["method"])] + sorted(set(s["method"]) - set(methods))
    out = {}
    for source, ss in s.groupby("source", sort=False):
        lines = [
            "| activity | N | " + " | ".join(labels.get(m, m) for m in shown) + " |",
            "|" + "---|" * (2 + len(shown)),
        ]
        for (activity, n), g in ss.groupby(["activity", "n_train"], sort=True):
            g = g.set_index("method")
            means = [float(g.at[m, "mean"]) if m in g.index else math.nan for m in shown]
            bold = best_mask(means, digits)
            tied = ties.get((protocol, source, activity, n), set())
            cells = []
            for m, mean, b in zip(shown, means, bold):
                if not np.isfinite(mean):
                    cells.append("--")
                    continue
                txt = f"**{mean:.{digits}f}**" if b else f"{mean:.{digits}f}"
                if m in tied and not b:
                    txt += TIE_TEXT
                std = float(g.at[m, "std"])
                if np.isfinite(std):
                    txt += f"±{std:.{digits}f}"
                key = g["key"].iloc[0]
                p = paper[
                    (paper["key"] == key)
                    & (paper["n_train"] == n)
                    & (paper["method"] == labels.get(m, m))
                ]
                if key and len(p):
                    txt += f" ({float(p['mean_deg'].iloc[0]):.{digits}f})"
                cells.append(txt)
            lines.append(f"| {activity} | {int(n)} | " + " | ".join(cells) + " |")
        lines += ["", TIE_LEGEND]
        out[source] = "\n".join(lines)
    return out


def readme_summary(df, paper=None, *, protocol="random", labels=None, comparisons=None, digits=2):
    """Markdown table: per method (the paper's, then today's baselines in italics) and data source, the mean over
    the (activity, N) cells of the mean angle error (degrees), of the MPJPE (mm, where recorded) and of the
    method's rank in the cell (1: lowest mean error), and in how many cells the method is the best or
    statistically indistinguishable from it; and its legend. With ``paper`` (:func:`.tables.read_paper_tables`),
    the paper's mean over the same cells follows a paper method's error in brackets. The methods' order, labels
    and groups come from the registry of the README's study (:func:`bsrbench.methods.configured`)."""
    registry = configured(README_STUDY)
    labels = {**{m: r.label for m, r in registry.items()}, **(labels or {})}
    today = {m for m, r in registry.items() if r.group == "today"}
    d = df[df["protocol"] == protocol]
    if d.empty:
        raise InputError(f"no rows of protocol {protocol!r} to summarise")
    if comparisons is None:
        comparisons = cmp.comparisons(d)
    ties = cmp.tied_with_best(comparisons)
    sources = list(dict.fromkeys(d["source"]))
    present = set(d["method"])
    order = [
        m for m in sorted(registry, key=lambda m: (m in today, registry[m].order)) if m in present
    ]
    order += sorted(present - set(order))
    cells = d.groupby(["source", "activity", "n_train", "method"])
    err = cells["error"].mean()
    keys = summarize(d).drop_duplicates(["source", "activity", "n_train"])
    keys = keys.set_index(["source", "activity", "n_train"])["key"]
    rank = err.groupby(level=["source", "activity", "n_train"]).rank(method="average")
    mpjpe = cells["mpjpe_mm"].mean() if "mpjpe_mm" in d.columns else None
    # an MPJPE column per source with recorded MPJPE (tables from before it have none)
    has_mpjpe = {
        src: mpjpe is not None and bool(mpjpe.xs(src, level="source").notna().any())
        for src in sources
    }
    head = ["method"]
    for src in sources:
        head += [f"{src} error (°)"] + ([f"{src} MPJPE (mm)"] if has_mpjpe[src] else [])
        head += [f"{src} rank", f"{src} best or tied"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for m in order:
        name = labels.get(m, m)
        row = [f"*{name}*" if m in today else name]
        for src in sources:
            e = err.xs((src, m), level=("source", "method"))
            txt = f"{e.mean():.{digits}f}"
            if paper is not None:
                theirs = []
                for a, n in e.index.to_list():
                    key = keys.get((src, a, n), "")
                    hit = paper[
                        (paper["key"] == key) & (paper["n_train"] == n) & (paper["method"] == name)
                    ]
                    if key and len(hit):
                        theirs.append(float(hit["mean_deg"].iloc[0]))
                if theirs and len(theirs) == len(e):
                    txt += f" ({np.mean(theirs):.{digits}f})"
            row.append(txt)
            if has_mpjpe[src]:
                p = mpjpe.xs((src, m), level=("source", "method")).dropna()
                row.append(f"{p.mean():.1f}" if len(p) else "")
            row.append(f"{rank.xs((src, m), level=('source', 'method')).mean():.1f}")
            n_cells = len(e)
            good = sum(m in ties.get((protocol, src, a, n), set()) for a, n in e.index.to_list())
            row.append(f"{good}/{n_cells}")
        lines.append("| " + " | ".join(row) + " |")
    lines += [
        "",
        "Means over the (activity, N) cells of the random protocol, the paper's mean over the same cells in "
        "brackets (rank 1: the lowest mean error of a cell); "
        "best or tied: the cells where the method has "
        "the lowest mean or is not distinguishable from it on these frames (paired t-test over the splits, "
        "Holm-adjusted, p >= 0.05). Italic: today's baselines. Every cell, with the paper's numbers: "
        "[docs/results.md](docs/results.md).",
    ]
    return "\n".join(lines)


def readme_counts(comparisons, *, labels=None, pm="PM", nn="NN1"):
    """Markdown table: per protocol and source, in how many (activity, N) cells PM is significantly worse than,
    tied with or better than the cell's best method and 1-NN on these frames (paired t-test over the splits), and
    worse, tied or better by the corrected resampled t-test (:func:`.comparisons.pm_counts`), and its legend."""
    labels = {**{m: r.label for m, r in configured(README_STUDY).items()}, **(labels or {})}
    t = cmp.pm_counts(comparisons, pm=pm, nn=nn)
    lines = [
        f"| protocol | source | {pm} against | cells | worse | tied | better | PM best | no test "
        "| worse (corrected) | tied (corrected) | better (corrected) |",
        "|" + "---|" * 12,
    ]
    for r in t.itertuples(index=False):
        versus = "best method" if r.versus == "best" else labels.get(r.versus, r.versus)
        best = str(r.pm_best) if r.versus == "best" else ""
        lines.append(
            f"| {r.protocol} | {r.source} | {versus} | {r.cells} | {r.worse} | {r.tied} | {r.better} | {best} "
            f"| {r.untested} | {r.worse_corrected} | {r.tied_corrected} | {r.better_corrected} |"
        )
    lines += [
        "",
        "Worse, tied, better: on these frames, by the paired t-test over the splits (Holm-adjusted over each "
        "cell's comparisons, p < 0.05); (corrected): by the corrected resampled t-test of Nadeau and Bengio 2003, "
        "which asks about a new data set of independent frames; PM best: cells where PM has the lowest mean; no "
        "test: fewer than 2 common splits.",
    ]
    return "\n".join(lines)


def update_readme(path, tables, counts=None, summary=None):
    """Replace the text between ``<!-- results-table:<source> -->`` and ``<!-- /results-table:<source> -->``,
    ``counts`` (markdown, :func:`readme_counts`) between ``<!-- results-counts -->`` and
    ``<!-- /results-counts -->``, and ``summary`` (:func:`readme_summary`) between ``<!-- results-summary -->`` and
    ``<!-- /results-summary -->``, where the file has these markers: the README has the summary and the counts,
    docs/results.md the tables per source. Returns whether the counts were written.

    Raises DataFileError naming ``path`` if it is refused (:func:`.headline.check_update_target`), missing, not
    UTF-8 text, has neither a source's table markers nor the summary markers, or cannot be written (the file is
    then unchanged)."""
    path = Path(path)
    headline.check_update_target(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise DataFileError(
            path,
            f"cannot read the file to update ({why}); expected an existing UTF-8 text file (the README) with "
            f"the markers '<!-- results-table:<source> -->' ... '<!-- /results-table:<source> -->'",
        ) from exc
    summary_pat = re.compile(r"(<!-- results-summary -->\n).*?(\n<!-- /results-summary -->)", re.S)
    has_summary = summary is not None and summary_pat.search(text) is not None
    if has_summary:
        text = summary_pat.sub(lambda m: m.group(1) + summary + m.group(2), text)
    for source, table in tables.items():
        pat = re.compile(
            rf"(<!-- results-table:{re.escape(source)} -->\n).*?(\n<!-- /results-table:{re.escape(source)} -->)",
            re.S,
        )
        if not pat.search(text):
            if has_summary:
                continue
            raise DataFileError(
                path,
                f"no markers '<!-- results-table:{source} -->' ... '<!-- /results-table:{source} -->' (nor "
                f"'<!-- results-summary -->' ... '<!-- /results-summary -->')",
            )
        text = pat.sub(lambda m, table=table: m.group(1) + table + m.group(2), text)
    wrote_counts = False
    if counts is not None:
        pat = re.compile(r"(<!-- results-counts -->\n).*?(\n<!-- /results-counts -->)", re.S)
        if pat.search(text):
            text = pat.sub(lambda m: m.group(1) + counts + m.group(2), text)
            wrote_counts = True
    headline.write_update(path, text)
    return wrote_counts


MECHANISMS_MARKERS = ("<!-- mechanisms -->", "<!-- /mechanisms -->")


def update_mechanisms(path, paragraph):
    """Replace the text between :data:`MECHANISMS_MARKERS` of ``path`` with ``paragraph`` (markdown,
    :func:`.mechanisms.readme_paragraph`). DataFileError naming ``path`` if it cannot be read or written or lacks
    the markers (the file is then unchanged)."""
    headline.update_blocks(
        path, {"mechanisms": paragraph}, required={"mechanisms": "the mechanisms paragraph"}
    )


def reconcile_markdown(table, paper=_DEFAULT_PAPER):
    """The reconciliation table (:func:`.reconcile.markdown`) of a published table, its study's methods and data
    sets read from the configuration files its provenance names, and PM's table under the nearest variant
    (:func:`.reconcile.pm_markdown`) when the table holds PM."""
    from . import reconcile

    df, config, datasets, paper = reconcile.published_inputs(table, paper)
    c = reconcile.cells(df, config, datasets, paper)
    text = reconcile.markdown(c, study=freshness.study_name(table))
    variant, _ = reconcile.nearest(reconcile.summary(c))
    rows, pm = reconcile.pm_rows(df, config, datasets, variant)
    if len(rows):
        metric = reconcile.METRICS[variant["metric"]]
        summaries = reconcile.pm_summary(rows, pm, paper, metric=metric)
        text += "\n\n" + reconcile.pm_markdown(summaries, variant)
    return text


def _block_table_arguments(parser, studies):
    """The arguments of a command that turns a published table into a marked block of a document: the table,
    the paper's tables and ``--update FILE`` (the block named after the table's study, e.g. ``studies``)."""
    parser.add_argument("table")
    parser.add_argument("--paper", default=str(_DEFAULT_PAPER), help="the paper's tables")
    parser.add_argument(
        "--update",
        metavar="FILE",
        help="replace the text between <!-- STUDY --> and <!-- /STUDY --> instead of printing (STUDY: the "
        f"table's study, {studies})",
    )


#: The study whose published table the README's results tables show (``readme --update`` refuses any other).
README_STUDY = "paper"


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m bsrbench.reporting.published", description=__doc__.split("\n")[0]
    )
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser(
        "publish", help="copy an aggregate table to reports/published/<study>.csv (checked)"
    )
    p.add_argument("src", help="results/<study>/aggregate/results.csv")
    p.add_argument("dest", help="reports/published/<study>.csv (named after the study of src)")
    p.add_argument(
        "--study",
        help="the study of a src outside results/ (default: <study> of "
        "results/<study>/aggregate/results.csv)",
    )
    p.add_argument(
        "--configfiles",
        nargs="+",
        metavar="FILE",
        help="the study's configuration files, as given to snakemake --configfile (default: "
        "config/<study>.yaml); a part run with --config study=<part> names its study's files",
    )
    c = sub.add_parser(
        "comparisons",
        help="the paired comparisons of a published table (reports/published/<study>-comparisons.csv)",
    )
    c.add_argument("table", help="reports/published/<study>.csv")
    c.add_argument("dest", help="reports/published/<study>-comparisons.csv")
    r = sub.add_parser("readme", help="the README's results tables from a published table")
    r.add_argument("table")
    r.add_argument(
        "--paper",
        default=str(_DEFAULT_PAPER),
        help="the paper's tables (resources/paper-tables.csv)",
    )
    r.add_argument("--protocol", default="random")
    r.add_argument(
        "--update",
        metavar="README",
        help="replace the marked tables in this file instead of printing",
    )
    mp = sub.add_parser(
        "mechanisms",
        help="the README's paragraph on the paper's reasons from a published table "
        "(reports/published/ablation-mechanisms.csv)",
    )
    mp.add_argument("table")
    mp.add_argument(
        "--update",
        metavar="README",
        help="replace the text between <!-- mechanisms --> and <!-- /mechanisms --> instead of printing",
    )
    rc = sub.add_parser(
        "reconcile",
        help="the protocol reconciliation table from a published table (reports/published/reconcile.csv)",
    )
    _block_table_arguments(rc, "reconcile or reconcile-pm")
    bu = sub.add_parser(
        "budget",
        help="PM with a fair budget beside the headline PM on the same splits, from a published table "
        "(reports/published/paper-pmfair.csv) and the headline table",
    )
    _block_table_arguments(bu, "paper-pmfair")
    bu.add_argument(
        "--beside",
        default=str(_DEFAULT_PAPER.parents[1] / "reports" / "published" / "paper.csv"),
        help="the headline table (its PM and baselines)",
    )
    pr = sub.add_parser(
        "prose",
        help="the numbers of the README, docs/ and config comments marked <!-- n:CLAIM -->: list those that "
        "differ from the published tables (exit 1), or --update them",
    )
    pr.add_argument(
        "--update", action="store_true", help="rewrite every marked number from the tables"
    )
    freshness.add_commands(sub)
    args = ap.parse_args(argv)
    if args.cmd in freshness.COMMANDS:
        return freshness.run_command(args)
    try:
        if isinstance(getattr(args, "update", None), str):  # refused before the tables are computed
            headline.check_update_target(args.update)
        if args.cmd == "prose":
            from . import prose

            return prose.run_command(args)
        if args.cmd in ("reconcile", "budget"):
            if args.cmd == "budget":
                from .budget import published_markdown

                text = published_markdown(args.table, args.beside, args.paper)
            else:
                text = reconcile_markdown(args.table, args.paper)
            if args.update:
                block = freshness.study_name(args.table)
                headline.update_blocks(
                    args.update,
                    {block: text},
                    required={block: f"the {args.cmd} table of {args.table}"},
                )
            else:
                print(text)
            return 0
        if args.cmd == "mechanisms":
            from .mechanisms import readme_paragraph

            df = read_results(args.table)
            try:
                paragraph = readme_paragraph(df, cmp.comparisons(df))
            except DataFileError:
                raise
            except InputError as e:  # about the table's contents: name the table
                raise DataFileError(args.table, str(e)) from None
            if args.update:
                update_mechanisms(args.update, paragraph)
            else:
                print(paragraph)
            return 0
        if args.cmd == "publish":
            df = publish(args.src, args.dest, study=args.study, configfiles=args.configfiles)
            print(f"{args.dest}: {len(df)} rows", file=sys.stderr)
            return 0
        if args.cmd == "comparisons":
            out = publish_comparisons(args.table, args.dest)
            print(f"{args.dest}: {len(out)} comparisons", file=sys.stderr)
            return 0
        if args.update and (Path(args.table).stem != README_STUDY or args.protocol != "random"):
            # the README's tables are those of the paper protocol: another study's table would replace them
            raise InputError(
                f"{args.table} --protocol {args.protocol}: --update writes the README's results tables, which are "
                f"the paper protocol's (reports/published/{README_STUDY}.csv, --protocol random); print this "
                "table's tables without --update"
            )
        df = read_results(args.table)
        comp = cmp.comparisons(df[df["protocol"] == args.protocol])
        tables = readme_tables(
            df, read_paper_tables(args.paper), protocol=args.protocol, comparisons=comp
        )
        counts = readme_counts(comp)
        summary = readme_summary(
            df, read_paper_tables(args.paper), protocol=args.protocol, comparisons=comp
        )
        labels = {m: r.label for m, r in configured(README_STUDY).items()}
        generated = headline.blocks(
            df,
            comp,
            verdict(df, motions=published_motions(args.table)),
            labels=labels,
            protocol=args.protocol,
        )
        if args.update:
            if not update_readme(args.update, tables, counts, summary):
                print(
                    f"{args.update}: no markers '<!-- results-counts -->' ... '<!-- /results-counts -->'; the "
                    "count of PM's significant differences was not written",
                    file=sys.stderr,
                )
            headline.update_blocks(args.update, generated)
        else:
            for name, text in generated.items():
                print(f"\n**{name}**\n\n{text}")
            print("\n\n".join(f"**{s}**\n\n{t}" for s, t in tables.items()))
            print("\n**PM against the best method and 1-NN**\n\n" + counts)
            print("\n**Summary**\n\n" + summary)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
