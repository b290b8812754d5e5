"""Snakemake adapter of rule plot_cd: the critical-difference diagrams of one source, one per protocol."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.comparisons import cd_diagram
from bsrbench.reporting.plots import save
from bsrbench.reporting.tables import read_results

sm = snakemake
fig = cd_diagram(
    read_results(sm.input.results, design=dict(sm.params.design)),
    source=sm.wildcards.source,
    protocols=list(sm.params.protocols),
    labels=dict(sm.params.labels),
)
save(fig, [sm.output.pdf, sm.output.png])
