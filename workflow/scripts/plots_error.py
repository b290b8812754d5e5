"""Snakemake adapter of rule plot_error_vs_ntrain."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.plots import plot_error_vs_ntrain, save
from bsrbench.reporting.tables import read_paper_tables, read_results

sm = snakemake
fig = plot_error_vs_ntrain(
    read_results(sm.input.results, design=dict(sm.params.design)),
    read_paper_tables(sm.input.paper),
    source=sm.wildcards.source,
    methods=list(sm.params.methods),
    labels=dict(sm.params.labels),
    n_train=list(sm.params.n_train),
)
save(fig, [sm.output.pdf, sm.output.png])
