"""Snakemake adapter of rule table: the paper's Table I or II on one data source, as LaTeX."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.comparisons import read_comparisons, tied_with_best
from bsrbench.reporting.tables import (
    latex_tables,
    read_paper_tables,
    read_results,
    summarize,
    write_text,
)

sm = snakemake
text = latex_tables(
    summarize(read_results(sm.input.results, design=dict(sm.params.design))),
    read_paper_tables(sm.input.paper),
    source=sm.wildcards.source,
    table=sm.wildcards.table,
    methods=list(sm.params.methods),
    groups=dict(sm.params.groups),
    labels=dict(sm.params.labels),
    n_train=list(sm.params.n_train),
    status=dict(sm.params.status),
    protocols=list(sm.params.protocols),
    skipped={p: {a: list(v) for a, v in d.items()} for p, d in dict(sm.params.skipped).items()},
    frames=dict(sm.params.frames),
    ties=tied_with_best(read_comparisons(sm.input.comparisons)),
)
write_text(sm.output[0], text)
