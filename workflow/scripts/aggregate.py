"""Snakemake adapter of rule aggregate: result rows (JSON) -> results/{study}/aggregate/results.csv.

The convergence columns (n_chains, r_hat_*, ess_bulk_*) are always present, NaN where not computed.
"""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.convergence import with_convergence_columns
from bsrbench.reporting.tables import aggregate_files, write_csv

df = with_convergence_columns(aggregate_files(snakemake.input))
write_csv(df, snakemake.output[0])
print(f"{len(df)} rows", file=sys.stderr)
