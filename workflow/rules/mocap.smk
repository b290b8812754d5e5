# Motion capture: CMU downloads and pose extraction.
# include: put this file's folder first on Python's path: off before anything is imported (bsrbench.pythonpath)
import os
import sys

if os.path.realpath(sys.path[0]) == os.path.realpath(
    workflow.current_basedir.get_path_or_uri(secret_free=False)
):
    del sys.path[0]


rule download_cmu_asf:
    output:
        asf=f"{download_dir()}/{{subject}}/{{subject}}.asf",
        sha256=f"{download_dir()}/{{subject}}/{{subject}}.asf.sha256",
    log:
        "logs/download/{subject}.asf.log",
    wildcard_constraints:
        subject=r"\d+",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        base_url=lookup(dpath="download/base_url", within=config),
        expected=lambda wildcards: download_checksum(f"{wildcards.subject}.asf"),
    script:
        "../scripts/download_cmu_asf.py"


rule download_cmu_amc:
    input:
        asf=f"{download_dir()}/{{subject}}/{{subject}}.asf",
    output:
        amc=f"{download_dir()}/{{subject}}/{{subject}}_{{trial}}.amc",
        sha256=f"{download_dir()}/{{subject}}/{{subject}}_{{trial}}.amc.sha256",
    log:
        "logs/download/{subject}_{trial}.amc.log",
    wildcard_constraints:
        subject=r"\d+",
        trial=r"\d+",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        base_url=lookup(dpath="download/base_url", within=config),
        expected=lambda wildcards: download_checksum(f"{wildcards.subject}_{wildcards.trial}.amc"),
    script:
        "../scripts/download_cmu_amc.py"


rule mocap_poses:
    input:
        unpack(motion_inputs),
    output:
        "results/mocap/{source}/{activity}.npz",
    log:
        "logs/mocap/{source}/{activity}.log",
    benchmark:
        "logs/mocap/{source}/{activity}.benchmark.tsv"
    wildcard_constraints:
        source=motion_source_regex(),
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        options=motion_params,
    script:
        "../scripts/mocap_poses.py"
