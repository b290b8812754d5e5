# One aggregate table of every fit job: the only input of every table, plot and finding.
# include: put this file's folder first on Python's path: off before anything is imported (bsrbench.pythonpath)
import os
import sys

if os.path.realpath(sys.path[0]) == os.path.realpath(
    workflow.current_basedir.get_path_or_uri(secret_free=False)
):
    del sys.path[0]


rule aggregate:
    input:
        fit_targets("json"),
    output:
        report(
            f"{RESULTS}/aggregate/results.csv",
            category="Results",
            caption="../report/results.rst",
        ),
    log:
        f"{LOGS}/aggregate/aggregate.log",
    benchmark:
        f"{RESULTS}/benchmarks/aggregate/aggregate.tsv"
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    script:
        "../scripts/aggregate.py"


# Paired comparisons per (protocol, source, activity, N): every method against PM and the cell's best.
rule comparisons:
    input:
        f"{RESULTS}/aggregate/results.csv",
    output:
        report(
            f"{RESULTS}/aggregate/comparisons.csv",
            category="Results",
            caption="../report/comparisons.rst",
        ),
    log:
        f"{LOGS}/aggregate/comparisons.log",
    benchmark:
        f"{RESULTS}/benchmarks/aggregate/comparisons.tsv"
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    script:
        "../scripts/comparisons.py"


# The verdict across cells and motions: Friedman, mean ranks, PM against each method across the blocks.
rule verdict:
    input:
        f"{RESULTS}/aggregate/results.csv",
    output:
        report(
            f"{RESULTS}/aggregate/verdict.csv",
            category="Results",
            caption="../report/verdict.rst",
        ),
    log:
        f"{LOGS}/aggregate/verdict.log",
    benchmark:
        f"{RESULTS}/benchmarks/aggregate/verdict.tsv"
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        motions=STUDY.data.motions(),
    script:
        "../scripts/verdict.py"
