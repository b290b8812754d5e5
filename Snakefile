# bsrbench: entry point (configuration, rule modules, default target).
import os
import sys

from snakemake.utils import min_version

# Snakemake put this folder first on Python's path (unless PYTHONPATH has it): off before the project is imported
# (a package planted here would shadow it), then the project's other folders (bsrbench.pythonpath).
if sys.path and os.path.realpath(sys.path[0]) == os.path.realpath(workflow.basedir):
    del sys.path[0]
from bsrbench.pythonpath import keep_project_off_path

keep_project_off_path(workflow.basedir)

min_version("9.0")


configfile: "config/datasets.yaml"
configfile: "config/config.yaml"


# Configuration: checked by bsrbench.config.
include: "workflow/rules/datasets.smk"
include: "workflow/rules/common.smk"


# Fit jobs run this interpreter's `python` (docs/performance.md).
# job_server is an environment variable: switching it reruns nothing.
from bsrbench import jobserver

jobserver.configure_shell_jobs(use_server=config.get("job_server", True))


include: "workflow/rules/mocap.smk"
include: "workflow/rules/features.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/aggregate.smk"
include: "workflow/rules/report.smk"


# The job server stops with this run (bsrbench.jobserver).
os.environ.setdefault(jobserver.OWNER_VAR, str(os.getpid()))


# SLURM: refuse a cluster whose status query cannot work (bsrbench.cluster).
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


# Quick, TeX or network rules run on the submit host under SLURM.
localrules:
    all,
    aggregate,
    comparisons,
    verdict,
    report_verdict,
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
    report_today,
    plot_pit,
    pool_chains,
    report_pdf,
    download_cmu_asf,
    download_cmu_amc,
    features_mat,
    mocap_poses,
