# bsrbench: Bayesian sparse-representation pose estimation, reproduced and benchmarked.
# Entry only: configuration, validation, rule modules, and the default target.
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/datasets.yaml"
configfile: "config/config.yaml"


# The configuration, read, retyped, validated and checked by bsrbench.config.
include: "workflow/rules/datasets.smk"
include: "workflow/rules/common.smk"


# The fit, CV and chain jobs are shell commands `python -m bsrbench.jobserver job ...` (workflow/rules/fit.smk):
# `python` is this interpreter (its directory first on PATH; a conda deployment puts its environment's first), and
# the config key job_server reaches them as an environment variable, so switching it reruns nothing.
import os

from bsrbench import jobserver

jobserver.configure_shell_jobs(use_server=config.get("job_server", True))


include: "workflow/rules/mocap.smk"
include: "workflow/rules/features.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/aggregate.smk"
include: "workflow/rules/report.smk"


# The job server (config key job_server) stops when this run ends and removes its files; its jobs carry this
# process's pid so that it also stops if the run is killed (bsrbench.jobserver). Job processes inherit the
# variable, so it names the main Snakemake process.
os.environ.setdefault(jobserver.OWNER_VAR, str(os.getpid()))


# Under the SLURM executor: a cluster whose status command cannot follow the jobs stops the run here, before any
# job is submitted, with what to set; a status query that keeps failing later ends the run (bsrbench.cluster).
from bsrbench import cluster


onstart:
    if workflow.executor_plugin.name == "slurm":
        cluster.guard_status_queries(workflow.executor_plugin.executor)
        jobs = [j for j in workflow.dag.needrun_jobs() if not j.is_local]
        if jobs:
            s = workflow.executor_settings
            cluster.check_cluster(
                s.status_command,
                s.init_seconds_before_status_checks,
                [j.resources.get("slurm_partition") for j in jobs],
            )


onsuccess:
    jobserver.shutdown()


onerror:
    jobserver.shutdown()


rule all:
    default_target: True
    input:
        feature_targets(),
        study_targets(),


# Under a cluster executor (profiles/slurm) these run on the submit host instead of as cluster jobs: they take
# seconds (the aggregate table, tables, plots, the poses of a few trials, the check of a .mat file), need TeX
# (report_pdf) or the network (downloads). The fit, CV and feature-rendering jobs are submitted.
localrules:
    all,
    aggregate,
    comparisons,
    table,
    report_text,
    plot_error_vs_ntrain,
    plot_calibration,
    plot_cd,
    plot_trace,
    plot_gxy,
    plot_subjective,
    report_why_pm,
    report_mechanisms,
    pool_chains,
    report_pdf,
    download_cmu_asf,
    download_cmu_amc,
    features_mat,
    mocap_poses,
