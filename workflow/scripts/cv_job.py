"""Snakemake adapter of rule cv: K-fold grid search on the training frames of one split.

The body is bsrbench.jobs.cv, run by bsrbench.jobserver (see fit_job.py).
"""

from bsrbench.jobserver import job_from_snakemake, run

# job_server is read from the config, not a rule param: where a job runs does not change its result, so
# switching it (the SLURM profile sets false) must not rerun finished jobs.
run("bsrbench.jobs:cv", job_from_snakemake(snakemake), use_server=snakemake.config["job_server"])  # noqa: F821
