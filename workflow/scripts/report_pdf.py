"""Snakemake adapter of rule report_pdf: the page-1 header, then latexmk on reports/report.tex."""

import sys

sys.stderr = open(snakemake.log[0], "w")  # noqa: F821

from bsrbench.reporting.report import build_header, build_pdf  # noqa: E402

sm = snakemake  # noqa: F821
build_pdf(
    sm.input.template,
    sm.output[0],
    log=sm.log[0] + ".latexmk",
    header=build_header(configfiles=list(sm.params.configfiles)),
)
