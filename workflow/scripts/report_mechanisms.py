"""Snakemake adapter of rule report_mechanisms: the section "Do the paper's reasons hold?" (LaTeX) and its table
(CSV), from the aggregate and comparisons tables; the mechanism variants come from the configuration's methods."""

import sys

import pandas as pd

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.comparisons import read_comparisons
from bsrbench.reporting.mechanisms import (
    TABLE_COLUMNS,
    mechanism_table,
    section_latex,
    variants_from_config,
    write_section,
)
from bsrbench.reporting.tables import read_results, write_csv

sm = snakemake
base = sm.params.base
variants = variants_from_config(dict(sm.config["methods"]), list(sm.config["run"]), base=base)
df = read_results(sm.input.results)
comp = read_comparisons(sm.input.comparisons)
labels = dict(sm.params.labels)
write_section(
    sm.output.section, section_latex(df, comp, base=base, variants=variants, labels=labels)
)
table = (
    mechanism_table(df, comp, base=base, variants=variants)
    if variants
    else pd.DataFrame(columns=TABLE_COLUMNS)
)
write_csv(table, sm.output.table)
print(f"mechanism variants of {base}: {variants or 'none'}", file=sys.stderr)
