"""Snakemake adapter of rule plot_trace: the MCMC traces of one split, every chain overlaid."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.convergence import trace_figure
from bsrbench.reporting.plots import save
from bsrbench.reporting.tables import read_results

sm = snakemake
fig = trace_figure(
    read_results(sm.input.results), sm.input.predictions, labels=dict(sm.params.labels)
)
save(fig, [sm.output.pdf, sm.output.png])
