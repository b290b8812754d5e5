"""Snakemake adapter of rule cv: K-fold grid search on the training frames of one split.

The body is bsrbench.jobs.cv, run by bsrbench.jobserver (see fit_job.py).
"""

from bsrbench.jobserver import job_from_snakemake, run

run("bsrbench.jobs:cv", job_from_snakemake(snakemake), use_server=snakemake.params.job_server)  # noqa: F821
