# bsrbench: Bayesian sparse-representation pose estimation, reproduced and benchmarked.
# Entry only: configuration, validation, rule modules, and the default target.
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/datasets.yaml"
configfile: "config/config.yaml"


include: "workflow/rules/datasets.smk"
include: "workflow/rules/common.smk"
include: "workflow/rules/mocap.smk"
include: "workflow/rules/features.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/aggregate.smk"
include: "workflow/rules/report.smk"


rule all:
    input:
        feature_targets(),
        study_targets(),
    default_target: True
