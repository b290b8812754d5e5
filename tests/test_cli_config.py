"""`snakemake --config key=value`: list and mapping values read as YAML, like the configuration files, for every
list key of both configuration schemas (bsrbench.cli_config)."""

from pathlib import Path

import pytest
import yaml
from snakemake.cli import parse_config
from snakemake.utils import update_config

from bsrbench.cli_config import retype_cli_config
from bsrbench.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
SCHEMAS = [ROOT / "workflow" / "schemas" / "config.schema.yaml", ROOT / "workflow" / "schemas" / "datasets.schema.yaml"]

#: One command-line override per list key of the schemas (the README's syntax: key='YAML flow value').
OVERRIDES = {
    "study_activities.*": "study_activities={hsc: [golf, run], mocap: []}",
    "n_train": "n_train=[30, 60]",
    "protocols": "protocols=[random,contiguous]",
    "run": "run=[PM, Ridge]",
    "methods.*.grid.*": "methods={Ridge: {grid: {alpha: [0.5, 2.0, 1e-1, 10]}}, PM: {params: {n_atoms: 16}}}",
    "report.subjective_methods": "report={subjective_methods: [PM, SR], trace_method: null}",
    "report.gxy_methods": "report={gxy_methods: [PM]}",
    "datasets.*.*.files": "datasets={hsc: {golf: {files: [resources/paper-features/golf.mat]}}}",
    "datasets.*.*.cmu_trials": "datasets={mocap_cmu: {kick: {cmu_trials: ['10_01', '10_02'], format: amc}}}",
    "datasets.*.*.joint_map": "datasets={mocap: {walk: {joint_map: [Hips, LeftUpLeg, 3]}}}",
    "features.render.image_size": "features={render: {image_size: [64, 96]}}",
    "features.codebook.files": "features={codebook: {files: [a.bvh, b.bvh]}}",
}


def _list_keys(node, path=()):
    """Dotted paths of the array-typed keys of a JSON schema ('*' for additionalProperties)."""
    out = set()
    if isinstance(node, dict):
        t = node.get("type")
        if path and (t == "array" or (isinstance(t, list) and "array" in t)):
            out.add(".".join(path))
        for k, v in node.items():
            if k == "properties":
                for name, sub in v.items():
                    out |= _list_keys(sub, path + (name,))
            elif k == "additionalProperties":
                out |= _list_keys(v, path + ("*",))
            elif k in ("oneOf", "anyOf"):
                for sub in v:
                    out |= _list_keys(sub, path)
            elif k == "$defs" and "dataset" in v:
                out |= _list_keys(v["dataset"], ("datasets", "*", "*"))
    return out


def test_every_list_key_of_the_schemas_has_an_override_case():
    keys = set().union(*(_list_keys(yaml.safe_load(p.read_text())) for p in SCHEMAS))
    assert keys == set(OVERRIDES)


@pytest.mark.parametrize("key", sorted(OVERRIDES))
def test_list_override_reads_like_a_config_file(key):
    arg = OVERRIDES[key]
    name, _, text = arg.partition("=")
    parsed = parse_config([arg])  # Snakemake's own reading: scalars inside lists stay strings
    config = {"keep": 1, name: {"other": "kept"}} if isinstance(yaml.safe_load(text), dict) else {"keep": 1}
    update_config(config, parsed)
    retype_cli_config(config, [arg], parsed)
    expected = {"keep": 1}
    if isinstance(yaml.safe_load(text), dict):
        expected[name] = {"other": "kept"}
    update_config(expected, {name: yaml.safe_load(text)})  # what a --configfile with this value gives
    assert config == expected


def test_scalars_keep_snakemakes_reading_and_bad_yaml_names_the_key():
    assert parse_config(["n_train=[100]"]) == {"n_train": ["100"]}  # Snakemake alone: the failure
    parsed = parse_config(["n_seeds=4", "job_server=False", "study=1e3"])
    config = dict(parsed)
    retype_cli_config(config, ["n_seeds=4", "job_server=False", "study=1e3"], parsed)
    assert config == {"n_seeds": 4, "job_server": False, "study": 1000.0}
    arg = "n_train=[30, 60"
    with pytest.raises(InputError, match=r"--config n_train: '\[30, 60' is not valid YAML"):
        retype_cli_config({}, [arg], {"n_train": ["fake"]})
