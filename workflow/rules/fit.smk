# Fit jobs: one per (protocol, source, activity, method, n_train, seed); CV jobs choose hyper-parameters.
#
# The bodies are in bsrbench.jobs; each rule's shell command hands its job (params.job: JSON of the named input, output,
# wildcards and the *_PARAMS below, evaluated) to bsrbench.jobserver, which runs it in a fork of a warm Python process
# (config key job_server) or in the command's own process. Shell rather than script: a script job would spend ~0.25 s
# importing Snakemake.
#
# The *_PARAMS are also given as plain params, which the job does not read: Snakemake's params trigger records only
# params that do not depend on input or output ("non-derived"), and params.job does, so without them a changed method
# setting (e.g. --config methods='{PM: {params: {n_iter: 60}}}') would rerun no fit and leave stale results.

JOB = "python -m bsrbench.jobserver job {target} --threads {{threads}} --log {{log:q}} {{params.job:q}}"

CV_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    cv_params=lambda w: method_setting(w.method).get("cv_params") or {},
    grid=method_grid,
    folds=config["cv"]["folds"],
    pose_transform=config["pose_transform"],
    min_test=config["min_test"],
    gap=config["gap"],
)
FIT_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    cv_mode=config["cv"]["mode"],
    paper_activity=lambda w: dataset(w.source, w.activity)["paper_activity"] or "",
    pose_transform=config["pose_transform"],
    min_test=config["min_test"],
    gap=config["gap"],
)
CHAIN_PARAMS = dict(
    estimator=lambda w: method_setting(w.method)["estimator"],
    fixed=lambda w: method_setting(w.method).get("params", {}),
    pose_transform=config["pose_transform"],
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
        **CV_PARAMS,  # not read by the job: recorded for Snakemake's params trigger (see above)
        job=jobserver.job_params(CV_PARAMS),
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
        **FIT_PARAMS,  # not read by the job: recorded for Snakemake's params trigger (see above)
        job=jobserver.job_params(FIT_PARAMS),
    shell:
        JOB.format(target="bsrbench.jobs:fit")


# Methods with `chains: C` > 1: C chain jobs per split (one MCMC chain per process, sampler seed
# method_seed + chain), pooled into the split's result row and predictions by pool_chains.
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
        **CHAIN_PARAMS,  # not read by the job: recorded for Snakemake's params trigger (see above)
        job=jobserver.job_params(CHAIN_PARAMS),
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
        **FIT_PARAMS,  # not read by the job: recorded for Snakemake's params trigger (see above)
        job=jobserver.job_params(FIT_PARAMS),
    shell:
        JOB.format(target="bsrbench.jobs:pool")
