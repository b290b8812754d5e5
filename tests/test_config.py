"""`snakemake --config key=value`: list and mapping values read as YAML, like the configuration files, for every
list key of both configuration schemas; the cross-checks of bsrbench.config, without Snakemake."""

from pathlib import Path

import pytest
import yaml
from snakemake.cli import parse_config
from snakemake.utils import update_config

from bsrbench.config import load_schema, retype_cli_config, retype_yaml_numbers
from bsrbench.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
SCHEMAS = [
    ROOT / "workflow" / "schemas" / "config.schema.yaml",
    ROOT / "workflow" / "schemas" / "datasets.schema.yaml",
]

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
    config = (
        {"keep": 1, name: {"other": "kept"}}
        if isinstance(yaml.safe_load(text), dict)
        else {"keep": 1}
    )
    update_config(config, parsed)
    retype_cli_config(config, [arg], parsed)
    expected = {"keep": 1}
    if isinstance(yaml.safe_load(text), dict):
        expected[name] = {"other": "kept"}
    update_config(
        expected, {name: yaml.safe_load(text)}
    )  # what a --configfile with this value gives
    assert config == expected


def test_scalars_keep_snakemakes_reading_and_bad_yaml_names_the_key():
    assert parse_config(["n_train=[100]"]) == {
        "n_train": ["100"]
    }  # Snakemake alone: the failure
    parsed = parse_config(["n_seeds=4", "job_server=False", "study=1e3"])
    config = dict(parsed)
    retype_cli_config(config, ["n_seeds=4", "job_server=False", "study=1e3"], parsed)
    assert config == {"n_seeds": 4, "job_server": False, "study": 1000.0}
    arg = "n_train=[30, 60"
    with pytest.raises(InputError, match=r"--config n_train: '\[30, 60' is not valid YAML"):
        retype_cli_config({}, [arg], {"n_train": ["fake"]})


# ------------------------------------------------------------------------------ 1e-3: a string in YAML 1.1
def test_exponent_numbers_read_as_numbers_where_the_schema_allows_one():
    """YAML 1.1 (PyYAML, Snakemake's loader) reads 1e-3, 1E3 and 1.0e3 as strings. Before, `alpha: 1e-3` reached
    the estimator as the string '1e-3' and `gap: 3e1` failed the schema; now both are numbers, and keys the schema
    types as strings keep the text."""
    config = yaml.safe_load(
        """
        study: 1e3
        gap: 3e1
        n_seeds: 10.0
        min_test: 1.5e0
        n_train: [3e1, 1E2, 60]
        methods:
          Ridge: {estimator: x, label: 1e3, params: {alpha: 1e-3, input_scaling: pooled},
                  grid: {alpha: [1e-3, 1.0e3, -2E2, 10]}, cv_params: {alpha: 1e-1}}
          PM: {grid: default}
        datasets: {mocap: {walk: {n_frames: 2e2, files: [1e3]}}}
        features: {render: {view_azimuth_deg: 1e1, image_size: [1.28e2, 128]}}
        """
    )
    assert (
        config["gap"] == "3e1" and config["methods"]["Ridge"]["params"]["alpha"] == "1e-3"
    )  # YAML 1.1
    changed = retype_yaml_numbers(config, load_schema(*SCHEMAS))
    assert config["gap"] == 30 and isinstance(
        config["gap"], int
    )  # integer keys: whole numbers as int
    assert config["n_seeds"] == 10 and isinstance(
        config["n_seeds"], int
    )  # `--config n_seeds=1e1` gives 10.0
    assert config["min_test"] == "1.5e0"  # not whole: left for the schema to reject, naming the key
    assert config["n_train"] == [30, 100, 60] and all(isinstance(n, int) for n in config["n_train"])
    ridge = config["methods"]["Ridge"]
    assert ridge["params"] == {"alpha": 0.001, "input_scaling": "pooled"}
    assert ridge["grid"] == {"alpha": [0.001, 1000.0, -200.0, 10]} and ridge["cv_params"] == {
        "alpha": 0.1
    }
    assert config["methods"]["PM"]["grid"] == "default"
    assert config["study"] == "1e3" and ridge["label"] == "1e3"  # string keys untouched
    assert config["datasets"]["mocap"]["walk"] == {"n_frames": 200, "files": ["1e3"]}
    assert config["features"]["render"] == {"view_azimuth_deg": 10.0, "image_size": [128, 128]}
    assert isinstance(
        config["features"]["render"]["view_azimuth_deg"], float
    )  # a number key stays a float
    assert "methods.Ridge.params.alpha" in changed and "study" not in changed


def test_every_shipped_configuration_is_unchanged_by_the_number_reading():
    schema = load_schema(*SCHEMAS)
    for path in sorted((ROOT / "config").glob("*.yaml")):
        config = yaml.safe_load(path.read_text())
        assert retype_yaml_numbers(config, schema) == [], path


def test_true_false_strings_read_as_booleans_where_the_schema_wants_one():
    """`--config job_server=false` reaches the config as the string 'false' (Snakemake parses only Python's
    True/False) and failed the schema; it is a boolean now. Strings elsewhere keep their text."""
    config = {
        "job_server": "false",
        "study": "true",
        "methods": {"Ridge": {"params": {"flag": "false"}}},
    }
    changed = retype_yaml_numbers(config, load_schema(*SCHEMAS))
    assert config["job_server"] is False and changed == ["job_server"]
    assert config["study"] == "true" and config["methods"]["Ridge"]["params"]["flag"] == "false"
    config = {"job_server": "True"}
    retype_yaml_numbers(config, load_schema(*SCHEMAS))
    assert config["job_server"] is True
