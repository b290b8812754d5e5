# Fit jobs: one per (protocol, source, activity, method, n_train, seed); CV jobs choose hyper-parameters.


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
    params:
        estimator=lambda w: method_setting(w.method)["estimator"],
        fixed=lambda w: method_setting(w.method).get("params", {}),
        cv_params=lambda w: method_setting(w.method).get("cv_params") or {},
        grid=method_grid,
        folds=config["cv"]["folds"],
        pose_transform=config["pose_transform"],
        min_test=config["min_test"],
        gap=config["gap"],
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    resources:
        mem_mb=2000,
        runtime=120,
    script:
        "../scripts/cv_job.py"


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
    params:
        estimator=lambda w: method_setting(w.method)["estimator"],
        fixed=lambda w: method_setting(w.method).get("params", {}),
        cv_mode=config["cv"]["mode"],
        paper_activity=lambda w: dataset(w.source, w.activity)["paper_activity"] or "",
        pose_transform=config["pose_transform"],
        min_test=config["min_test"],
        gap=config["gap"],
    wildcard_constraints:
        method=method_regex(chained=False),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    resources:
        mem_mb=2000,
        runtime=30,
    script:
        "../scripts/fit_job.py"


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
    params:
        estimator=lambda w: method_setting(w.method)["estimator"],
        fixed=lambda w: method_setting(w.method).get("params", {}),
        pose_transform=config["pose_transform"],
        min_test=config["min_test"],
        gap=config["gap"],
    wildcard_constraints:
        method=method_regex(chained=True),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    resources:
        mem_mb=2000,
        runtime=60,
    script:
        "../scripts/fit_chain.py"


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
    params:
        estimator=lambda w: method_setting(w.method)["estimator"],
        fixed=lambda w: method_setting(w.method).get("params", {}),
        cv_mode=config["cv"]["mode"],
        paper_activity=lambda w: dataset(w.source, w.activity)["paper_activity"] or "",
        pose_transform=config["pose_transform"],
        min_test=config["min_test"],
        gap=config["gap"],
    wildcard_constraints:
        method=method_regex(chained=True),
    threads: 1
    conda:
        "../envs/bsrbench.yaml"
    resources:
        mem_mb=2000,
        runtime=10,
    script:
        "../scripts/pool_chains.py"
