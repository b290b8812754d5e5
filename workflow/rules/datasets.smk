# Data sets of config/datasets.yaml (bsrbench.config).
# include: put this file's folder first on Python's path: off before anything is imported (bsrbench.pythonpath)
import os
import sys

if os.path.realpath(sys.path[0]) == os.path.realpath(
    workflow.current_basedir.get_path_or_uri(secret_free=False)
):
    del sys.path[0]
from pathlib import Path

from bsrbench.config import load_datasets, or_exit

# A bad data-set configuration stops here with its one-line message.
DATA = or_exit(
    load_datasets,
    config,
    schema_dir=Path(str(workflow.current_basedir)).parent / "schemas",
    config_args=workflow.config_settings.config_args,
    parsed_args=workflow.config_settings.config,
    validate=not workflow.modifier.skip_validation,
)

dataset = DATA.dataset
is_motion = DATA.is_motion
download_dir = DATA.download_dir
download_checksum = DATA.download_checksum
codebook_files = DATA.codebook_files
render_params = DATA.render_params
feature_targets = DATA.feature_targets
preview_targets = DATA.preview_targets
data_availability = DATA.data_availability
frame_protocol_text = DATA.frame_protocol_text
stick_kind = DATA.stick_kind


def motion_source_regex():
    return DATA.source_regex(motion=True)


def mat_source_regex():
    return DATA.source_regex(motion=False)


def motion_inputs(wildcards):
    """The trial files (and the ASF skeleton of amc trials)."""
    d = dataset(wildcards.source, wildcards.activity)
    return {"trials": d["files"], **({"asf": d["asf"]} if d["format"] == "amc" else {})}


def motion_params(wildcards):
    return DATA.motion_params(wildcards.source, wildcards.activity)


def mat_input(wildcards):
    return dataset(wildcards.source, wildcards.activity)["files"][0]


def mat_params(wildcards):
    return DATA.mat_params(wildcards.source, wildcards.activity)


def features_meta(wildcards):
    return DATA.features_meta(wildcards.source, wildcards.activity)
