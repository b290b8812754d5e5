# One fit job per split and method; CV jobs choose hyper-parameters.
# Jobs run in bsrbench.jobs, through the job server.

JOB = (
    "python -m bsrbench.jobserver job {target} --threads {{threads}} --log {{log:q}} {{params.job:q}} "
    "--settings {{params.settings:q}}"
)

CV_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    cv_params=lambda w: method_setting(w.method).get("cv_params") or {},
    grid=method_grid,
    folds=lambda w: STUDY.method_cv(w.method)["folds"],
    pose_transform=config["pose_transform"],
    min_test=config["min_test"],
    gap=config["gap"],
)
FIT_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    cv_mode=lambda w: STUDY.method_cv(w.method)["mode"],
    paper_activity=lambda w: dataset(w.source, w.activity)["paper_activity"] or "",
    pose_transform=config["pose_transform"],
    conformal=conformal,
    min_test=config["min_test"],
    gap=config["gap"],
)
CHAIN_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    pose_transform=config["pose_transform"],
    conformal=conformal,
    min_test=config["min_test"],
    gap=config["gap"],
)


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


# `chains: C` > 1: one job per chain, pooled per split.
rule fit_chain:
    input:
        features="results/features/{source}/{activity}.npz",
        cv=cv_input,
        code=estimator_sources,
    output:
        chain=f"{RESULTS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}/chain{{chain}}.npz",
    log:
        f"{LOGS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}/chain{{chain}}.log",
    benchmark:
        f"{RESULTS}/benchmarks/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}/chain{{chain}}.tsv"
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


rule pool_chains:
    input:
        features="results/features/{source}/{activity}.npz",
        cv=cv_input,
        chains=chain_inputs,
    output:
        row=f"{RESULTS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.json",
        predictions=f"{RESULTS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.npz",
    log:
        f"{LOGS}/fit/{{protocol}}/{{source}}/{{activity}}/{{method}}/n{{n_train}}/seed{{seed}}.log",
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
