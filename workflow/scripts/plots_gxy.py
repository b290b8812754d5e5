"""Snakemake adapter of rule plot_gxy: g_xy traces, one panel per method of report.gxy_methods."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.convergence import gxy_figure
from bsrbench.reporting.plots import save
from bsrbench.reporting.tables import read_results

sm = snakemake
fig = gxy_figure(
    read_results(sm.input.results), list(sm.input.predictions), labels=dict(sm.params.labels)
)
save(fig, [sm.output.pdf, sm.output.png])
