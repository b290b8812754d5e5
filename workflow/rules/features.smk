# Features: codebook, rendered mocap features, checked .mat files.
# include: put this file's folder first on Python's path: off before anything is imported (bsrbench.pythonpath)
import os
import sys

if os.path.realpath(sys.path[0]) == os.path.realpath(
    workflow.current_basedir.get_path_or_uri(secret_free=False)
):
    del sys.path[0]


rule features_codebook:
    input:
        trials=codebook_files(),
    output:
        "results/features/codebook.npz",
    log:
        "logs/features/codebook.log",
    benchmark:
        "logs/features/codebook.benchmark.tsv"
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        render=render_params(),
        n_points=lookup(dpath="features/shape_context/n_points", within=config),
        frames_per_trial=lookup(dpath="features/codebook/frames_per_trial", within=config),
        n_centres=lookup(dpath="features/codebook/n_centres", within=config),
        skip_frames=lookup(dpath="features/codebook/skip_frames", within=config),
        checksums=lookup(dpath="features/codebook/checksums", within=config),
        seed=lookup(dpath="features/seed", within=config),
    script:
        "../scripts/features_codebook.py"


rule features_mocap:
    input:
        motion="results/mocap/{source}/{activity}.npz",
        codebook="results/features/codebook.npz",
    output:
        features="results/features/{source}/{activity}.npz",
        preview="results/features/{source}/{activity}.preview.png",
    log:
        "logs/features/{source}/{activity}.log",
    benchmark:
        "logs/features/{source}/{activity}.benchmark.tsv"
    wildcard_constraints:
        source=motion_source_regex(),
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        render=render_params(),
        n_points=lookup(dpath="features/shape_context/n_points", within=config),
        soft=lookup(dpath="features/histogram/soft", within=config),
        preview_frames=lookup(dpath="features/preview_frames", within=config),
        seed=lookup(dpath="features/seed", within=config),
        meta=features_meta,
    script:
        "../scripts/features_mocap.py"


rule features_mat:
    input:
        mat=mat_input,
    output:
        "results/features/{source}/{activity}.npz",
    log:
        "logs/features/{source}/{activity}.log",
    benchmark:
        "logs/features/{source}/{activity}.benchmark.tsv"
    wildcard_constraints:
        source=mat_source_regex(),
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        options=mat_params,
    script:
        "../scripts/features_mat.py"
