"""Snakemake adapter of rule report_why_pm: the section "Why PM trails the paper here" (LaTeX) and the
convergence summary (CSV), from the aggregate table."""

import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.ablation import why_pm_section, write_why_pm
from bsrbench.reporting.convergence import convergence_summary_table, gxy_caption
from bsrbench.reporting.tables import read_paper_tables, read_results, write_csv

sm = snakemake
CAPTIONS = {
    "trace": "MCMC traces of one PM split (first activity, largest $N$, first seed), every chain overlaid; "
    "precisions on a log axis; shaded: burn-in.",
}
df = read_results(sm.input.results)
# the g_xy figure's panels (rule plot_gxy, gxy_inputs): first protocol, smallest N, one per report.gxy_methods
CAPTIONS["gxy"] = gxy_caption(
    df,
    sm.config["report"].get("gxy_methods") or [],
    protocol=sm.config["protocols"][0],
    n_train=min(sm.config["n_train"]),
    labels=dict(sm.params.labels),
)
paper = read_paper_tables(sm.input.paper)
root = Path(
    sm.output.section
).parent.parent  # the study's report folder reports/{study}; LaTeX paths are from it
figures = [
    (Path(f).relative_to(root).as_posix(), CAPTIONS[Path(f).stem]) for f in sm.params.figures
]
text = why_pm_section(
    df,
    paper,
    variants=list(sm.params.variants),
    labels=dict(sm.params.labels),
    figures=figures,
    base=sm.params.base,
    nn=sm.params.nn,
)
write_why_pm(sm.output.section, text)
write_csv(convergence_summary_table(df), sm.output.convergence)
