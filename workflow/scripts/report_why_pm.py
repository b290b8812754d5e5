"""Snakemake adapter of rule report_why_pm: the section "Why PM trails the paper here" (LaTeX) and the
convergence summary (CSV), from the aggregate table."""

import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")  # noqa: F821

from bsrbench.reporting.convergence import convergence_summary_table, why_pm_section, write_why_pm  # noqa: E402
from bsrbench.reporting.tables import read_paper_tables, read_results, write_csv  # noqa: E402

sm = snakemake  # noqa: F821
CAPTIONS = {
    "trace": "MCMC traces of one PM split (first activity, largest $N$, first seed), every chain overlaid; "
    "precisions on a log axis; shaded: burn-in.",
    "gxy": "The noise precision $\\gamma_{xy}$ per chain (first activity, smallest $N$, first seed; log axis; "
    "shaded: burn-in) of the methods of \\texttt{report.gxy\\_methods}: $K \\geq N$ (a code set can "
    "interpolate the training pairs), $K < N$, and a proper Gamma prior on $\\gamma_{xy}$ alone. The panel "
    "titles give $K$, $N$ and the prior.",
}
df = read_results(sm.input.results)
paper = read_paper_tables(sm.input.paper)
root = Path(sm.output.section).parent.parent  # the study's report folder reports/{study}; LaTeX paths are from it
figures = [(Path(f).relative_to(root).as_posix(), CAPTIONS[Path(f).stem]) for f in sm.params.figures]
text = why_pm_section(df, paper, variants=list(sm.params.variants), labels=dict(sm.params.labels), figures=figures,
                      base=sm.params.base, nn=sm.params.nn)
write_why_pm(sm.output.section, text)
write_csv(convergence_summary_table(df), sm.output.convergence)
