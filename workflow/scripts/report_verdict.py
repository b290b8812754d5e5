"""Snakemake adapter of rule report_verdict: the section "The verdict across cells and motions" (LaTeX)."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.tables import write_text
from bsrbench.reporting.verdict import read_verdict, section_latex

write_text(
    snakemake.output[0],
    section_latex(read_verdict(snakemake.input[0]), labels=dict(snakemake.params.labels)),
)
