"""Snakemake adapter of rule verdict: results/{study}/aggregate/results.csv -> verdict.csv."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.tables import read_results, write_csv
from bsrbench.reporting.verdict import verdict

motions = {tuple(k.split("/")): v for k, v in snakemake.params.motions.items()}
df = verdict(read_results(snakemake.input[0]), motions=motions)
write_csv(df, snakemake.output[0])
print(f"{len(df)} rows", file=sys.stderr)
