"""Snakemake adapter of rule report_today: the section "Today's metrics and baselines" (LaTeX) and its
uncertainty table (CSV), from the aggregate and comparisons tables."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.comparisons import read_comparisons
from bsrbench.reporting.tables import read_results, write_csv, write_text
from bsrbench.reporting.today import scores_summary, section_latex

sm = snakemake
df = read_results(sm.input.results, design=dict(sm.params.design))
methods = list(sm.params.methods)
write_text(
    sm.output.section,
    section_latex(
        df,
        read_comparisons(sm.input.comparisons),
        methods=methods,
        groups=dict(sm.params.groups),
        labels=dict(sm.params.labels),
        pit_figure=sm.params.pit_figure,
    ),
)
write_csv(scores_summary(df, methods=methods), sm.output.table)
