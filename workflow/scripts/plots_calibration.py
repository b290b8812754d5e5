"""Snakemake adapter of rule plot_calibration."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.plots import plot_calibration, save
from bsrbench.reporting.tables import read_results

sm = snakemake
fig = plot_calibration(
    read_results(sm.input.results, design=dict(sm.params.design)),
    methods=list(sm.params.methods),
    labels=dict(sm.params.labels),
    source=sm.wildcards.source,
)
save(fig, [sm.output.pdf, sm.output.png])
