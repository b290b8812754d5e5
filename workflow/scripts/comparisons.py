"""Snakemake adapter of rule comparisons: results/{study}/aggregate/results.csv -> comparisons.csv."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.comparisons import comparisons
from bsrbench.reporting.tables import read_results, write_csv

df = comparisons(read_results(snakemake.input[0]))
write_csv(df, snakemake.output[0])
print(f"{len(df)} comparisons", file=sys.stderr)
