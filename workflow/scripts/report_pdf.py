"""Snakemake adapter of rule report_pdf: latexmk on reports/report.tex."""

import sys

sys.stderr = open(snakemake.log[0], "w")  # noqa: F821

from bsrbench.reporting.report import build_pdf  # noqa: E402

build_pdf(snakemake.input.template, snakemake.output[0], log=snakemake.log[0] + ".latexmk")  # noqa: F821
