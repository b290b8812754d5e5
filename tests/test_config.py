"""`snakemake --config key=value`: list and mapping values read as YAML, like the configuration files, for every
list key of both configuration schemas; the cross-checks of bsrbench.config, without Snakemake."""

from pathlib import Path

import pytest
import yaml
from snakemake.cli import parse_config
from snakemake.utils import update_config

from bsrbench.config import (
    check_method_settings,
    load_schema,
    retype_cli_config,
    retype_yaml_numbers,
)
from bsrbench.errors import InputError
from bsrbench.estimators import estimator_defaults

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
    # null and ~ are YAML's null, as in a file
    args = ["conformal_level=null", "gap=~"]
    parsed = parse_config(args)
    config = dict(parsed)
    retype_cli_config(config, args, parsed)
    assert config == {"conformal_level": None, "gap": None} and parsed["conformal_level"] == "null"
    arg = "n_train=[30, 60"
    with pytest.raises(InputError, match=r"--config n_train='\[30, 60': not valid YAML"):
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


# ------------------------------------------------------------------ the study: checks without Snakemake
def _merged(**overrides):
    """config/datasets.yaml and config/config.yaml merged as the Snakefile's configfile lines do, then
    ``overrides`` (dotted keys) as --configfile would merge them."""
    config = {}
    for name in ("datasets.yaml", "config.yaml"):
        update_config(config, yaml.safe_load((ROOT / "config" / name).read_text()))
    for key, value in overrides.items():
        node = config
        *parents, last = key.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[last] = value
    return config


def _study(**overrides):
    from bsrbench.config import load_datasets, load_study

    return load_study(load_datasets(_merged(**overrides)), cwd="/here")


def test_quick_study_design_cells_and_skipped_cells():
    """The quick study: walk (167 frames of its BVH trial, fewer_frames: use_all) cannot give N = 100 with 100
    test frames left, so that cell is skipped with a note; every other cell runs, for every seed and method."""
    from bsrbench.config import Study

    study = _study()
    assert isinstance(study, Study)
    with pytest.raises(AttributeError):
        study.skipped = {}  # frozen
    assert (
        study.data.data_frames("mocap", "walk") == 167
    )  # 12_02.bvh: frames counted from the header
    assert dict(study.skipped) == {
        (
            "random",
            "mocap",
            "walk",
            100,
        ): "N = 100 skipped: the 167 frames leave at most 67 test frames, fewer than min_test = 100"
    }
    design = study.design
    assert design["pairs"] == [["hsc", "acrobatics"], ["mocap", "walk"]]
    assert design["seeds"] == [0, 1, 2] and design["n_train"] == [30, 100]
    assert design["skipped"] == [["random", "mocap", "walk", 100]]
    # 3 cells run (hsc 30, hsc 100, walk 30) x the methods of `run` x 3 seeds
    methods = design["methods"]
    assert {"PM", "NN1", "KNN", "GP"} <= set(methods)
    targets = study.fit_targets()
    assert len(targets) == 3 * len(methods) * 3 == len(set(targets))
    assert "results/quick/fit/random/mocap/walk/PM/n30/seed2.json" in targets
    assert not any("walk/PM/n100" in t for t in targets)
    assert study.largest_run_n("random", "mocap", "walk") == 30
    assert study.skipped_notes("mocap") == {
        "random": {"walk": [study.skipped[("random", "mocap", "walk", 100)]]}
    }
    assert study.results == "results/quick" and study.reports == "reports/quick"


def test_skipped_cells_against_the_split_limits():
    """A cell is skipped exactly when make_split refuses it (contiguous: the block and its gap)."""
    from bsrbench.config import skipped_cells
    from bsrbench.splits import make_split

    frames = {("s", "a"): 260}
    skipped = skipped_cells(
        frames, [("s", "a")], ["random", "contiguous"], [100, 130, 160, 170], 100, 30
    )
    for protocol in ("random", "contiguous"):
        for n in (100, 130, 160, 170):
            try:
                make_split(260, n, protocol=protocol, seed=0, min_test=100, gap=30)
                ok = True
            except InputError:
                ok = False
            assert ((protocol, "s", "a", n) not in skipped) == ok, (protocol, n)
    assert "(fewer after the gap of 30)" in skipped[("contiguous", "s", "a", 160)]


@pytest.mark.parametrize(
    "overrides, match",
    [
        (
            {"run": ["RVM", "Nope"]},
            r"config key 'run': unknown method 'Nope'; defined under 'methods'",
        ),
        (
            {"report.trace_method": "Nope"},
            r"config key 'report.trace_method': unknown method 'Nope'; defined under 'methods'",
        ),
        (
            {"report.gxy_methods": ["TGP"], "run": ["RVM"]},
            r"config key 'report.gxy_methods': method 'TGP' is not run; 'run' lists \['RVM'\]",
        ),
        (
            {"report.subjective_methods": ["Nope"]},
            r"config key 'report.subjective_methods': unknown method 'Nope'",
        ),
        (
            {"study_activities": {"hsc": [], "mocap": []}},
            r"config key 'study_activities': no activity to study",
        ),
        (
            {"study_activities": {"nosuch": ["golf"]}},
            r"config key 'study_activities': unknown data source 'nosuch'; config/datasets.yaml defines",
        ),
        (
            {"study_activities": {"hsc": ["golff"]}},
            r"config key 'study_activities.hsc': unknown activity 'golff'; source 'hsc' has \[",
        ),
        (
            {"protocols": ["cross_trial"], "study_activities": {"hsc": ["golf"]}},
            r"config key 'protocols': cross_trial needs a motion-capture data set of several trials; "
            r"hsc/golf is format 'mat' with 1 file\(s\)",
        ),
        (
            {"study_activities": {"hsc": ["golf"], "mocap": ["walk"]}, "n_train": [100]},
            r"config key 'study_activities.mocap': walk has 167 frames, and every n_train \[100\] leaves "
            r"fewer than min_test=100",
        ),
        (
            {"study_activities": {"hsc": ["golf"]}, "n_train": [30, 550]},
            r"config key 'n_train': 550 is too large for hsc/golf \(600 frames\) with protocol 'random'",
        ),
        (
            {"methods.Ridge.params": {"alpha": -1.0}},
            r"config key 'methods.Ridge.params' \(method Ridge, bsrbench.models.reference:RidgeRegressor\)",
        ),
        ({"n_seeds": 0}, r"configuration: key 'n_seeds', value 0: "),
        (
            {"conformal_level": 0.97},
            r"config key 'conformal_level': 0.97 needs at least 34 training frames .* but n_train has 30; "
            r"lower conformal_level \(at most 0.9667\) or set it to null",
        ),
        ({"nosuchkey": 1}, r"configuration: unknown key 'nosuchkey' \(value 1\)"),
    ],
)
def test_study_checks_name_the_key_the_value_and_what_was_expected(overrides, match):
    with pytest.raises(ValueError, match=match):
        _study(**overrides)


def test_an_empty_datasets_key_names_the_working_directory():
    from bsrbench.config import DataSets, load_study

    config = _merged()
    config["datasets"] = {}
    data = DataSets(config=config, entries={})
    with pytest.raises(
        ValueError, match=r"config key 'datasets': empty, .* working directory /here"
    ):
        load_study(data, cwd="/here")


@pytest.mark.parametrize(
    "entry, match",
    [
        (
            {"format": "bvh", "files": []},
            r"datasets.mocap.x: give `files` \(a list of paths\) or `cmu_trials`",
        ),
        (
            {"format": "bvh", "cmu_trials": ["01_01"]},
            r"datasets.mocap.x: cmu_trials are downloaded as .amc; expected format: amc, got 'bvh'",
        ),
        (
            {"format": "bvh", "files": ["a.amc"]},
            r"file 'a.amc' does not end in .bvh \(format: bvh\)",
        ),
        (
            {
                "format": "bvh",
                "files": ["a.bvh"],
                "fewer_frames": "use_all",
                "frame_selection": "spread",
            },
            r"fewer_frames: use_all needs frame_selection: first; got 'spread'",
        ),
        ({"format": "bvh", "files": ["a.bvh"], "joint_map": []}, r"joint_map is an empty list"),
        (
            {"format": "mat", "files": ["a.mat", "b.mat"]},
            r"format mat takes exactly one file; got 2",
        ),
        (
            {"format": "mat", "files": ["a.mat"]},
            r"config datasets: source\(s\) \['mocap'\] mix format mat with bvh/amc entries",
        ),
        (
            {"format": "bvh", "files": ["a.bvh"], "frame_step": 2, "extra": 1},
            r"data sets \(config/datasets.yaml\): unknown key 'datasets.mocap.x.extra'",
        ),
    ],
)
def test_dataset_checks_name_the_entry(entry, match):
    from bsrbench.config import load_datasets

    config = _merged()
    config["datasets"]["mocap"]["x"] = entry
    with pytest.raises(InputError, match=match):
        load_datasets(config)


def test_first_frame_on_motion_capture_and_an_empty_codebook_are_refused():
    from bsrbench.config import load_datasets

    config = _merged()
    config["datasets"]["mocap"]["walk"]["first_frame"] = 2
    with pytest.raises(
        InputError,
        match=r"datasets.mocap.walk: first_frame applies to format mat; got 2 for format bvh",
    ):
        load_datasets(config)
    config = _merged()
    config["features"]["codebook"]["files"] = []
    with pytest.raises(InputError, match=r"config features.codebook.files is empty"):
        load_datasets(config)


def test_cmu_trials_resolve_to_the_download_folder_and_defaults_are_filled_in():
    from bsrbench.config import load_datasets

    config = _merged()
    config["download"]["dir"] = "dl/"
    config["datasets"]["mocap"]["kick_x"] = {"format": "amc", "cmu_trials": ["10_1", "10_02"]}
    data = load_datasets(config)
    d = data.dataset("mocap", "kick_x")
    assert d["files"] == ["dl/10/10_01.amc", "dl/10/10_02.amc"] and d["asf"] == "dl/10/10.asf"
    assert d["enabled"] is True and d["frame_step"] == 1  # the schema's defaults
    with pytest.raises(
        InputError, match=r"config datasets: no data set mocap/nope; configured: \["
    ):
        data.dataset("mocap", "nope")


def test_cv_seed_grid_table_methods_and_data_status():
    import bsrbench
    from bsrbench.models import reference

    study = _study(**{"cv.mode": "per_size", "methods.RVM.grid": None})
    assert study.grid("Ridge") == reference.DEFAULT_GRID["RidgeRegressor"]  # grid: default
    assert study.grid("RVM") == {}
    assert study.cv_seed("RVM", "2") is None  # grid: null
    assert study.cv_seed("Ridge", "2") == 0  # per_size: seed 0's CV for every seed
    assert _study(**{"cv.mode": "per_job"}).cv_seed("Ridge", "2") == "2"
    assert _study().cv_seed("Ridge", "2") is None  # cv.mode none
    assert study.table_methods() == study.run  # one PM variant
    status = study.data_status("hsc")
    assert status["Acrobatics"] == "acrobatics"  # studied
    assert status["Golf"]["kind"] == "here"  # data here, not studied
    assert status["Navigate"]["kind"] == "none"  # no data set of hsc for it
    # the estimator's module, the sampler kernels it imports and the job logic with its imports; no other model
    code = [
        Path(p).relative_to(Path(bsrbench.__file__).parent).as_posix()
        for p in study.estimator_sources("PM")
    ]
    for f in (
        "models/bsr.py",
        "models/_bsr_kernels.py",
        "jobs.py",
        "runs.py",
        "splits.py",
        "metrics.py",
    ):
        assert f in code
    assert "models/rvm.py" not in code and "config.py" not in code and len(code) == len(set(code))


def test_report_arg_reads_snakemakes_report_option():
    from bsrbench.results import report_arg

    assert report_arg(["snakemake", "--cores", "2"]) is None
    assert report_arg(["snakemake", "--report", "r/x.html"]) == "r/x.html"
    assert report_arg(["snakemake", "--report=r/y.html"]) == "r/y.html"
    assert report_arg(["snakemake", "--report"]) == "report.html"
    assert report_arg(["snakemake", "--report", "--cores", "1"]) == "report.html"


def test_report_checks_and_the_design_change_message(tmp_path, monkeypatch):
    """--report refuses another study's report folder and a table of another design; the design-change
    message names what changed; a table of the configured design passes both."""
    import pandas as pd

    from bsrbench.errors import DataFileError
    from bsrbench.results import KEY_COLUMNS, check_report_is_current, design_change_message

    monkeypatch.chdir(tmp_path)
    # the data files are checked when the study is loaded
    (tmp_path / "resources").symlink_to(Path(__file__).resolve().parents[1] / "resources")
    study = _study(
        **{"study_activities": {"hsc": ["golf"], "mocap": []}, "n_seeds": 1, "n_train": [30]}
    )
    with pytest.raises(
        ValueError, match=r"--report reports/other/r.html: the HTML report of study 'quick'"
    ):
        check_report_is_current(study, ["snakemake", "--report", "reports/other/r.html"])
    check_report_is_current(
        study, ["snakemake", "--report", "reports/quick/report.html"]
    )  # no table yet
    assert design_change_message(study) is None
    rows = [
        {
            "protocol": "random",
            "source": "hsc",
            "activity": "golf",
            "method": m,
            "n_train": 30,
            "seed": 0,
            "error": 1.0,
        }
        for m in study.run
    ]
    table = tmp_path / "results/quick/aggregate/results.csv"
    table.parent.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(table, index=False)
    check_report_is_current(study, ["snakemake", "--report", "reports/quick/report.html"])
    assert design_change_message(study) is None
    pd.DataFrame(rows[:-1]).to_csv(table, index=False)  # one method fewer than configured
    message = design_change_message(study)
    assert message.startswith(
        "study 'quick': the configuration differs from the design of its results"
    )
    assert (
        "method: the table has" in message and "1 job(s) to add, 0 no longer configured" in message
    )
    with pytest.raises(
        DataFileError, match=r"does not match the configuration: 1 configured job\(s\) without"
    ):
        check_report_is_current(study, ["snakemake", "--report", "reports/quick/report.html"])
    table.write_text("not,a\n\x00")
    assert design_change_message(study) is None  # unreadable: the aggregate and report rules say so
    assert KEY_COLUMNS[-1] == "seed"


# ------------------------------------------------------------------------- methods and their values
REF = "bsrbench.models.reference"


@pytest.mark.parametrize(
    "setting, message",
    [
        (
            {"estimator": "bsrbench.models.gpr:GPR"},
            r"'methods\.M\.estimator': estimator 'bsrbench\.models\.gpr:GPR': cannot find module",
        ),
        ({"estimator": f"{REF}:Nope"}, r"'methods\.M\.estimator'.*no attribute 'Nope'"),
        (
            {"estimator": f"{REF}:RidgeRegressor", "params": {"alpah": 1.0}},
            r"'methods\.M\.params': alpah: 1\.0 is not a parameter of .*RidgeRegressor; expected one of \['alpha'",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "cv_params": {"folds": 3}},
            r"'methods\.M\.cv_params': folds: 3",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "grid": {"lambda": [1.0]}},
            r"'methods\.M\.grid': lambda: \[1\.0\]",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "grid": {"alpha": 1.0}},
            r"'methods\.M\.grid': alpha: 1\.0; expected a non-empty list",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "params": [1.0]},
            r"'methods\.M\.params': expected a mapping",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "chains": 2},
            r"'methods\.M\.chains': 2, but bsrbench\.models\.reference:RidgeRegressor takes no random_state, "
            r"so its chains would be identical; expected chains: 1, or an estimator that samples",
        ),
    ],
)
def test_method_settings_are_checked_before_any_job(setting, message):
    with pytest.raises(InputError, match=message):
        check_method_settings(
            {"M": setting, "Ok": {"estimator": f"{REF}:RidgeRegressor"}}, ["Ok", "M"]
        )
    check_method_settings(
        {"M": setting, "Ok": {"estimator": f"{REF}:RidgeRegressor"}}, ["Ok"]
    )  # M not run
    with pytest.raises(InputError, match=r"'run': unknown method 'X'"):
        check_method_settings({"M": setting}, ["X"])


PM_PATH = "bsrbench.models.bsr:BayesianSR"
PM_OK = {"n_atoms": 16, "n_neighbors": 5, "n_iter": 40, "n_burn_in": 20}


def test_chains_are_allowed_for_an_estimator_with_a_random_state():
    check_method_settings(
        {"M": {"estimator": PM_PATH, "params": PM_OK, "chains": 4, "grid": None}}, ["M"]
    )


@pytest.mark.parametrize(
    "setting, cv, message",
    [
        (
            {"params": {**PM_OK, "n_atoms": -3}},
            None,
            r"'methods\.M\.params' \(method M, bsrbench\.models\.bsr:BayesianSR\): params \{.*n_atoms: -3.*\}: "
            r"The 'n_atoms' parameter of BayesianSR must be an int in the range \[1, inf\)\. Got -3",
        ),
        (
            {"params": {**PM_OK, "w_update": "foo"}},
            None,
            r"'methods\.M\.params' .*'w_update' parameter of BayesianSR must be a str among \['ess', 'mh', .*\]\. Got 'foo'",
        ),
        (
            {"params": {**PM_OK, "n_burn_in": 40}},
            None,
            r"'methods\.M\.params' .*n_burn_in must be smaller than n_iter=40 .*got n_burn_in=40",
        ),
        (
            {"params": {**PM_OK, "thin": 25}},
            None,
            r"'methods\.M\.params' .*thin=25 retains no sweep of the n_iter - n_burn_in = 20 after burn-in; "
            r"expected thin <= 20",
        ),
        (
            {"params": {**PM_OK, "n_neighbors": 31}},
            None,
            r"'methods\.M\.params' .*fitted on the smallest n_train N = 30: BayesianSR needs at least "
            r"max\(2, n_neighbors=31\) training rows; got n_samples = 30",
        ),
        (
            {"params": PM_OK, "grid": {"n_neighbors": [3, 40]}},
            {"mode": "per_size", "folds": 5},
            r"'methods\.M\.grid' .*grid point \{n_neighbors: 40\} .*smallest n_train N = 30: .*n_neighbors=40",
        ),
        (
            {"params": PM_OK, "grid": {"n_neighbors": [3, 27]}},
            {"mode": "per_job", "folds": 5},
            r"'methods\.M\.grid' .*CV fits of grid point \{n_neighbors: 27\} .*training folds of 24 frames "
            r"\(N = 30, cv\.folds = 5\): .*n_neighbors=27\) training rows; got n_samples = 24",
        ),
        (
            {"params": PM_OK, "grid": {"n_atoms": [8, -1]}},
            {"mode": "per_size", "folds": 5},
            r"'methods\.M\.grid' .*grid point \{n_atoms: -1\}.*The 'n_atoms' parameter of BayesianSR must be an int in the range \[1, inf\)\. Got -1",
        ),
        (
            {"params": PM_OK, "cv_params": {"n_iter": 10}, "grid": {"n_atoms": [8]}},
            {"mode": "per_size", "folds": 5},
            r"'methods\.M\.cv_params' .*cv_params \{n_iter: 10\} over params .*n_burn_in must be smaller than n_iter=10",
        ),
        (
            {"params": PM_OK, "grid": {"n_atoms": [8]}},
            {"mode": "per_size", "folds": 31},
            r"'cv\.folds': 31 folds of the smallest n_train N = 30 .*would leave empty folds; expected folds <= 30",
        ),
        (
            {"estimator": f"{REF}:NearestNeighbourRegressor", "params": {"n_neighbors": 31}},
            None,
            r"'methods\.M\.params' .*NearestNeighbourRegressor\).*N = 30: n_neighbors=31 exceeds .* n_samples = 30",
        ),
        (
            {"estimator": f"{REF}:NearestNeighbourRegressor", "params": {"weights": ["uniform"]}},
            None,
            r"The 'weights' parameter of NearestNeighbourRegressor must be a str among .*Got \['uniform'\] instead",
        ),
        (
            {"estimator": f"{REF}:RidgeRegressor", "params": {"alpha": "1e-3"}},
            None,
            r"'methods\.M\.params' .*The 'alpha' parameter of RidgeRegressor must be a float in the range \[0\.0, inf\)\. Got '1e-3'",
        ),
        (
            {"estimator": "bsrbench.models.tgp:TGP", "params": {"lambda_x": 0}},
            None,
            r"The 'lambda_x' parameter of TGP must be a float in the range \(0\.0, inf\)\. Got 0 instead",
        ),
        (
            {"estimator": "sklearn.linear_model:Ridge", "params": {"alpha": -1.0}},
            None,
            r"'methods\.M\.params' \(method M, sklearn\.linear_model:Ridge\).*The 'alpha' parameter of Ridge must be",
        ),
    ],
    ids=[
        "n_atoms",
        "w_update",
        "burn-in",
        "thin",
        "n_neighbors>N",
        "grid-n_neighbors>N",
        "grid-n_neighbors>fold",
        "grid-value",
        "cv_params",
        "folds>N",
        "1-NN-k>N",
        "unhashable-choice",
        "string-number",
        "TGP",
        "sklearn",
    ],
)
def test_method_values_are_checked_before_any_job(setting, cv, message):
    """Before: every one of these passed the configuration check and failed (or, thin, silently kept one sweep)
    only when a fit or CV job ran; now the error names the key, the method, the value and what was expected."""
    setting = {"estimator": PM_PATH, "grid": None, **setting}
    with pytest.raises(InputError, match=message):
        check_method_settings(
            {"M": setting}, ["M"], n_train=[100, 30], cv=cv or {"mode": "none", "folds": 5}
        )


def test_method_values_checked_only_where_they_apply():
    """A grid is fitted only when CV runs; the smallest N and fold bound only the settings that are fitted."""
    grid = {"n_neighbors": [3, 27]}  # 27 > the 24 rows of a training fold of N = 30, <= N
    setting = {"estimator": PM_PATH, "params": PM_OK, "grid": grid}
    check_method_settings(
        {"M": setting}, ["M"], n_train=[30], cv={"mode": "none", "folds": 5}
    )  # no CV: no grid
    check_method_settings(
        {"M": setting}, ["M"], n_train=[40], cv={"mode": "per_size", "folds": 5}
    )  # folds of 32
    check_method_settings({"M": setting}, ["M"])  # no sizes given: values alone
    with pytest.raises(InputError, match="training folds of 24 frames"):
        check_method_settings(
            {"M": setting}, ["M"], n_train=[30, 40], cv={"mode": "per_size", "folds": 5}
        )
    # cv_params act in CV fits only
    bad_cv = {**setting, "cv_params": {"n_iter": 10}}  # n_burn_in 20 >= 10 in the CV fits
    check_method_settings({"M": bad_cv}, ["M"], n_train=[40], cv={"mode": "none", "folds": 5})
    with pytest.raises(InputError, match=r"'methods\.M\.cv_params'"):
        check_method_settings(
            {"M": bad_cv}, ["M"], n_train=[40], cv={"mode": "per_size", "folds": 5}
        )
    # cv.folds > N matters only when a method is tuned
    check_method_settings(
        {"M": {**setting, "grid": None}}, ["M"], n_train=[30], cv={"mode": "per_size", "folds": 31}
    )


def test_method_settings_accept_the_shipped_configurations_and_report_defaults():
    from pathlib import Path

    import yaml

    root = Path(__file__).resolve().parents[1]
    base = yaml.safe_load((root / "config" / "config.yaml").read_text())
    check_method_settings(
        base["methods"], base["run"], n_train=base["n_train"], cv=base["cv"]
    )  # default grids
    for name in ("paper.yaml", "ci.yaml", "ablation.yaml"):
        over = yaml.safe_load((root / "config" / name).read_text())
        methods = {m: {**base["methods"].get(m, {}), **s} for m, s in over["methods"].items()}
        check_method_settings(
            {**base["methods"], **methods},
            over.get("run", base["run"]),
            n_train=over.get("n_train", base["n_train"]),
            cv={**base["cv"], **over.get("cv", {})},
        )
    d = estimator_defaults(f"{REF}:RidgeRegressor")
    assert d == {"alpha": 1.0, "standardize": True, "input_scaling": "pooled"}


def test_conformal_settings_per_method():
    study = _study()
    pm = study.method("PM")
    assert study.conformal("PM") == {"level": 0.9, "params": dict(pm.get("cv_params") or {})}
    assert _study(conformal_level=None).conformal("PM") is None
    assert _study(**{"methods.PM.conformal": False}).conformal("PM") is None
    assert _study(conformal_level=0.8).conformal("RVM")["level"] == 0.8


def test_a_method_can_ask_for_its_own_cv():
    """methods.<M>.cv replaces the study's cv for that method alone: with cv.mode none, Ridge is tuned (its fits
    read the first seed's CV with per_size, their own seed's with per_job) and NN1 is not."""
    study = _study(
        **{
            "cv": {"mode": "none", "folds": 5},
            "methods.Ridge.cv": {"mode": "per_size", "folds": 3},
            "methods.Ridge.grid": {"alpha": [0.1, 10.0]},
        }
    )
    assert study.method_cv("Ridge") == {"mode": "per_size", "folds": 3}
    assert study.method_cv("NN1") == {"mode": "none", "folds": 5}
    assert [study.cv_seed("Ridge", s) for s in (0, 2)] == [0, 0]
    assert study.cv_seed("NN1", 2) is None
    # folds default to the study's; per_job reads each seed's own CV
    study = _study(**{"methods.Ridge.cv": {"mode": "per_job"}})
    assert study.method_cv("Ridge") == {"mode": "per_job", "folds": 5}
    assert study.cv_seed("Ridge", 2) == 2
    # and a method can opt out of the study's CV
    study = _study(**{"cv": {"mode": "per_size", "folds": 2}, "methods.Ridge.cv": {"mode": "none"}})
    assert study.cv_seed("Ridge", 1) is None and study.cv_seed("PM", 1) == 0


@pytest.mark.parametrize(
    "cv, grid, message",
    [
        (
            {"mode": "sometimes"},
            "default",
            r"^configuration: key 'methods\.Ridge\.cv\.mode', value 'sometimes': not one of the allowed values; "
            r"expected one of \['per_size', 'per_job', 'none'\]$",
        ),
        (
            {"mode": "per_size", "folds": 1},
            "default",
            r"^configuration: key 'methods\.Ridge\.cv\.folds', value 1: 1 is less than the minimum of 2; "
            r"expected minimum: 2 \(Number of CV folds\.\)$",
        ),
        (
            {"folds": 3},
            "default",
            r"^configuration: key 'methods\.Ridge\.cv', value \{'folds': 3\}: 'mode' is a required property",
        ),
        (
            {"mode": "per_size", "foldz": 3},
            "default",
            r"^configuration: unknown key 'methods\.Ridge\.cv\.foldz'",
        ),
        (
            {"mode": "per_size"},
            None,
            r"^config key 'methods\.Ridge\.cv': \{'mode': 'per_size'\} asks for CV, but the method has no grid "
            r"\(methods\.Ridge\.grid is None\); expected a grid \{parameter: \[values\]\} or 'default' with a "
            r"DEFAULT_GRID, or no cv$",
        ),
        (
            {"mode": "per_size", "folds": 31},
            "default",
            r"^config key 'methods\.Ridge\.cv\.folds': 31 folds of the smallest n_train N = 30 \(method Ridge is "
            r"tuned by CV, mode 'per_size'\) would leave empty folds; expected folds <= 30$",
        ),
    ],
    ids=["mode", "folds<2", "no-mode", "typo", "no-grid", "folds>N"],
)
def test_a_methods_cv_is_validated(cv, grid, message):
    from bsrbench.errors import InputError

    with pytest.raises(InputError, match=message):
        _study(**{"methods.Ridge.cv": cv, "methods.Ridge.grid": grid, "n_train": [30, 100]})


def test_amc_trials_get_stick_figures_and_their_frame_rate():
    """An AMC data set (navigate, CMU 09_12) is drawn with silhouette and stick figures like a BVH one, and its
    frame protocol reads the AMC's 120 fps (before: BVH headers only, so no stick figures and no rate)."""
    data = _study().data
    assert data.stick_kind("mocap", "navigate") == data.stick_kind("mocap", "walk") == "bvh"
    assert data.stick_kind("hsc", "golf") == "authors"
    assert data.frame_protocol_text("mocap", "navigate").startswith(
        "one frame in 4 of the 120 fps trials (30 fps)"
    )
