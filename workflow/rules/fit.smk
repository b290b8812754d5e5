# Fit jobs: one per (protocol, source, activity, method, n_train) and block of seeds (config key seeds_per_job), one
# per seed with seeds_per_job 1; CV jobs choose hyper-parameters. The files stay one per seed either way.
# Jobs run in bsrbench.jobs, through the job server; a block's seeds one after the other (bsrbench.jobserver).
# include: put this file's folder first on Python's path: off before anything is imported (bsrbench.pythonpath)
import os
import sys

if os.path.realpath(sys.path[0]) == os.path.realpath(
    workflow.current_basedir.get_path_or_uri(secret_free=False)
):
    del sys.path[0]

JOB = (
    "python -P -m bsrbench.jobserver job {target} --threads {{threads}} --log {{log:q}} {{params.job:q}} "
    "--settings {{params.settings:q}}"
)

CV_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    cv_params=lambda w: method_setting(w.method).get("cv_params") or {},
    grid=method_grid,
    folds=lambda w: STUDY.method_cv(w.method)["folds"],
    pose_transform=pose_transform,
    min_test=config["min_test"],
    gap=config["gap"],
)
FIT_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    cv_mode=lambda w: STUDY.method_cv(w.method)["mode"],
    paper_activity=lambda w: dataset(w.source, w.activity)["paper_activity"] or "",
    pose_transform=pose_transform,
    conformal=conformal,
    min_test=config["min_test"],
    gap=config["gap"],
)
CHAIN_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    pose_transform=pose_transform,
    conformal=conformal,
    min_test=config["min_test"],
    gap=config["gap"],
)


SPLIT = "{protocol}/{source}/{activity}/{method}/n{n_train}"
# {seeds: methods} of the cv jobs; a rule cv (of no method) even in a study without CV, as in every other study.
CV_BLOCKS = STUDY.cv_blocks() or {(STUDY.first_seed,): []}
PER_SEED = config.get("seeds_per_job") == 1


# seeds_per_job 1: one job per seed.
if PER_SEED:

    rule cv:
        input:
            features="results/features/{source}/{activity}.npz",
            code=estimator_sources,
        output:
            json=f"{RESULTS}/cv/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.json",
        log:
            f"{LOGS}/cv/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.log",
        benchmark:
            f"{RESULTS}/benchmarks/cv/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.tsv"
        conda:
            "../envs/bsrbench.yaml"
        threads: 1
        resources:
            mem_mb=2000,
            runtime=120,
        params:
            settings=jobserver.job_settings(CV_PARAMS),
            job=jobserver.job_params(),
        shell:
            JOB.format(target="bsrbench.jobs:cv")

    rule fit:
        input:
            features="results/features/{source}/{activity}.npz",
            cv=cv_input,
            code=estimator_sources,
        output:
            row=f"{RESULTS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.json",
            predictions=f"{RESULTS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.npz",
        log:
            f"{LOGS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.log",
        benchmark:
            f"{RESULTS}/benchmarks/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.tsv"
        wildcard_constraints:
            method=method_regex(chained=False),
        conda:
            "../envs/bsrbench.yaml"
        threads: 1
        resources:
            mem_mb=2000,
            runtime=30,
        params:
            settings=jobserver.job_settings(FIT_PARAMS),
            job=jobserver.job_params(),
        shell:
            JOB.format(target="bsrbench.jobs:fit")

else:
    # One rule per block of seeds (a rule's outputs are fixed by its wildcards), named cv/fit when a cell has
    # one block.
    for seeds, methods in CV_BLOCKS.items():

        rule:
            name:
                "cv" if len(CV_BLOCKS) == 1 else f"cv_{block_name(seeds)}"
            input:
                features="results/features/{source}/{activity}.npz",
                code=estimator_sources,
            output:
                json=seed_files(f"{RESULTS}/cv/{SPLIT}/seed{{seed}}.json", seeds),
            log:
                f"{LOGS}/cv/{SPLIT}/{block_name(seeds)}.log",
            benchmark:
                f"{RESULTS}/benchmarks/cv/{SPLIT}/{block_name(seeds)}.tsv"
            wildcard_constraints:
                method="|".join(methods) or "(?!x)x",
            conda:
                "../envs/bsrbench.yaml"
            threads: 1
            resources:
                mem_mb=2000,
                runtime=120 * len(seeds),
            params:
                settings=jobserver.job_settings(CV_PARAMS),
                job=jobserver.block_job_params(seeds),
            shell:
                JOB.format(target="bsrbench.jobs:cv")

    for seeds in STUDY.seed_blocks:

        rule:
            name:
                "fit" if len(STUDY.seed_blocks) == 1 else f"fit_{block_name(seeds)}"
            input:
                features="results/features/{source}/{activity}.npz",
                cv=block_cv_inputs(seeds),
                code=estimator_sources,
            output:
                row=seed_files(f"{RESULTS}/fit/{SPLIT}/seed{{seed}}.json", seeds),
                predictions=seed_files(f"{RESULTS}/fit/{SPLIT}/seed{{seed}}.npz", seeds),
            log:
                f"{LOGS}/fit/{SPLIT}/{block_name(seeds)}.log",
            benchmark:
                f"{RESULTS}/benchmarks/fit/{SPLIT}/{block_name(seeds)}.tsv"
            wildcard_constraints:
                method=method_regex(chained=False),
            conda:
                "../envs/bsrbench.yaml"
            threads: 1
            resources:
                mem_mb=2000,
                runtime=30 * len(seeds),
            params:
                settings=jobserver.job_settings(FIT_PARAMS),
                job=jobserver.block_job_params(seeds, {"cv": cv_input}),
            shell:
                JOB.format(target="bsrbench.jobs:fit")


# `chains: C` > 1: one job per split that runs its C chains (each the job of rule fit_chain), or, with seeds_per_job
# 1, one job per chain (rule fit_chain); either way rule pool_chains pools them. The pooling reads every chain file,
# so a changed chain count reruns it, and a missing chain file the chains' job.
SEED_DIR = f"{RESULTS}/fit/{SPLIT}/seed{{seed}}"
if PER_SEED:

    rule fit_chain:
        input:
            features="results/features/{source}/{activity}.npz",
            cv=cv_input,
            code=estimator_sources,
        output:
            chain=f"{SEED_DIR}/chain{{chain}}.npz",
        log:
            f"{LOGS}/fit/{SPLIT}/seed{{seed}}/chain{{chain}}.log",
        benchmark:
            f"{RESULTS}/benchmarks/fit/{SPLIT}/seed{{seed}}/chain{{chain}}.tsv"
        wildcard_constraints:
            method=method_regex(chained=True),
        conda:
            "../envs/bsrbench.yaml"
        threads: 1
        resources:
            mem_mb=2000,
            runtime=60,
        params:
            settings=jobserver.job_settings(CHAIN_PARAMS),
            job=jobserver.job_params(),
        shell:
            JOB.format(target="bsrbench.jobs:fit_chain")

else:
    CHAIN_GROUPS = STUDY.chain_groups()
    for n_chains, methods in CHAIN_GROUPS.items():

        rule:
            name:
                "fit_chains" if len(CHAIN_GROUPS) == 1 else f"fit_chains{n_chains}"
            input:
                features="results/features/{source}/{activity}.npz",
                cv=cv_input,
                code=estimator_sources,
            output:
                chains=[f"{SEED_DIR}/chain{c}.npz" for c in range(n_chains)],
            log:
                f"{LOGS}/fit/{SPLIT}/seed{{seed}}/chains.log",
            benchmark:
                f"{RESULTS}/benchmarks/fit/{SPLIT}/seed{{seed}}/chains.tsv"
            wildcard_constraints:
                method="|".join(methods),
            conda:
                "../envs/bsrbench.yaml"
            threads: 1
            resources:
                mem_mb=2000,
                runtime=30 * n_chains,
            params:
                settings=jobserver.job_settings(CHAIN_PARAMS),
                job=jobserver.chains_job_params(n_chains),
            shell:
                JOB.format(target="bsrbench.jobs:fit_chain")


rule pool_chains:
    input:
        features="results/features/{source}/{activity}.npz",
        cv=cv_input,
        chains=chain_inputs,
    output:
        row=f"{SEED_DIR}.json",
        predictions=f"{SEED_DIR}.npz",
    log:
        f"{LOGS}/fit/{SPLIT}/seed{{seed}}.log",
    wildcard_constraints:
        method=method_regex(chained=True),
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        settings=jobserver.job_settings(FIT_PARAMS),
        job=jobserver.job_params(),
    shell:
        JOB.format(target="bsrbench.jobs:pool")
