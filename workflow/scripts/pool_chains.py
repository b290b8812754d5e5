"""Snakemake adapter of rule pool_chains: a split's result from its chains (body: bsrbench.jobs.pool)."""

from bsrbench.jobserver import job_from_snakemake, run

run("bsrbench.jobs:pool", job_from_snakemake(snakemake), use_server=snakemake.config["job_server"])  # noqa: F821
