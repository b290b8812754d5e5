"""Snakemake adapter of rule report_why_pm: the section "Why PM trails the paper here" (LaTeX) and the
convergence summary (CSV), from the aggregate table."""

import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.ablation import why_pm_section, write_why_pm
from bsrbench.reporting.captions import why_pm_captions
from bsrbench.reporting.convergence import convergence_summary_table
from bsrbench.reporting.tables import read_paper_tables, read_results, write_csv

sm = snakemake
df = read_results(sm.input.results)
labels = dict(sm.params.labels)
figures = why_pm_captions(
    df,
    sm.params.figures,
    gxy_methods=sm.config["report"].get("gxy_methods") or [],
    # the g_xy figure's panels (rule plot_gxy, gxy_inputs): first protocol, smallest N
    protocol=sm.config["protocols"][0],
    n_train=min(sm.config["n_train"]),
    labels=labels,
    root=Path(
        sm.output.section
    ).parent.parent,  # reports/{study}: the LaTeX paths are relative to it
)
text = why_pm_section(
    df,
    read_paper_tables(sm.input.paper),
    variants=list(sm.params.variants),
    labels=labels,
    figures=figures,
    base=sm.params.base,
    nn=sm.params.nn,
)
write_why_pm(sm.output.section, text)
write_csv(convergence_summary_table(df), sm.output.convergence)
