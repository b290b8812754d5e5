"""Snakemake adapter of rule report_pdf: the page-1 header, then latexmk on reports/report.tex in the study's
report folder reports/{study} (the PDF's folder), where its tables and figures are."""

import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.build import build_header, build_pdf

sm = snakemake
build_pdf(
    sm.input.template,
    sm.output[0],
    root=Path(sm.output[0]).parent,
    log=sm.log[0] + ".latexmk",
    header=build_header(
        configfiles=list(sm.params.configfiles), overrides=list(sm.params.overrides)
    ),
)
