"""Snakemake adapter of rule table_activities: the error table of the studied activities of one data source that are
no row of the paper's Tables I-II, as LaTeX."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.comparisons import read_comparisons, tied_with_best
from bsrbench.reporting.tables import activities_tables, read_results, summarize, write_text

sm = snakemake
text = activities_tables(
    summarize(read_results(sm.input.results, design=dict(sm.params.design))),
    source=sm.wildcards.source,
    activities=dict(sm.params.activities),
    methods=list(sm.params.methods),
    groups=dict(sm.params.groups),
    labels=dict(sm.params.labels),
    n_train=list(sm.params.n_train),
    protocols=list(sm.params.protocols),
    skipped={p: {a: list(v) for a, v in d.items()} for p, d in dict(sm.params.skipped).items()},
    frames=dict(sm.params.frames),
    ties=tied_with_best(read_comparisons(sm.input.comparisons)),
)
write_text(sm.output[0], text)
