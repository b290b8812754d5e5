"""Snakemake adapter of rule report_mechanisms: the section "Do the paper's reasons hold?" (LaTeX) and its table
(CSV), from the aggregate and comparisons tables; the mechanism variants come from the configuration's methods."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.comparisons import read_comparisons
from bsrbench.reporting.mechanisms import section_and_table, write_section
from bsrbench.reporting.tables import read_results, write_csv

sm = snakemake
text, table, variants = section_and_table(
    read_results(sm.input.results),
    read_comparisons(sm.input.comparisons),
    methods=dict(sm.config["methods"]),
    run=list(sm.config["run"]),
    base=sm.params.base,
    labels=dict(sm.params.labels),
)
write_section(sm.output.section, text)
write_csv(table, sm.output.table)
print(f"mechanism variants of {sm.params.base}: {variants or 'none'}", file=sys.stderr)
