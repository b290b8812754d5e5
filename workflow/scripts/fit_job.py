"""Snakemake adapter of rule fit: one (protocol, source, activity, method, n_train, seed) job.

The body is bsrbench.jobs.fit; bsrbench.jobserver runs it in a fork of a warm job server (or in this process
with `job_server: false`). This script imports nothing heavy, so that a job costs milliseconds, not seconds.
"""

from bsrbench.jobserver import job_from_snakemake, run

# job_server is read from the config, not a rule param: where a job runs does not change its result, so
# switching it (the SLURM profile sets false) must not rerun finished jobs.
run("bsrbench.jobs:fit", job_from_snakemake(snakemake), use_server=snakemake.config["job_server"])  # noqa: F821
