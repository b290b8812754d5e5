"""Snakemake adapter of rule fit_chain: one MCMC chain of one split (body: bsrbench.jobs.fit_chain)."""

from bsrbench.jobserver import job_from_snakemake, run

run("bsrbench.jobs:fit_chain", job_from_snakemake(snakemake), use_server=snakemake.config["job_server"])  # noqa: F821
