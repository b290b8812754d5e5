"""Bad input answered in one line before any job, without a traceback, on the real command lines: a missing or
unreadable --configfile (bin/study), a data file that is missing or fails its checksum, an unknown method name,
and the configuration check's own errors (snakemake -n in a copy of the workflow)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
ZEROS = "0" * 64


def _yaml(path):
    import yaml

    return yaml.safe_load((ROOT / path).read_text())


#: What the messages list: the configured methods, the hsc activities, the keys of the two schemas.
METHODS = sorted(_yaml("config/config.yaml")["methods"])
HSC = sorted(_yaml("config/datasets.yaml")["datasets"]["hsc"])
KEYS = sorted(
    {
        *_yaml("workflow/schemas/config.schema.yaml")["properties"],
        *_yaml("workflow/schemas/datasets.schema.yaml")["properties"],
    }
)
DATASET_KEYS = sorted(
    _yaml("workflow/schemas/datasets.schema.yaml")["$defs"]["dataset"]["properties"]
)


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """The workflow, profiles and configs in a fresh folder (resources linked), so that no result of the
    working tree counts."""
    work = tmp_path_factory.mktemp("workflow")
    for name in ("Snakefile", "workflow", "profiles", "config"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    (work / "resources").symlink_to(ROOT / "resources")
    return work


def run(args, cwd):
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    res = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=300, env=env)
    return res.returncode, res.stdout + res.stderr


def assert_one_line(out, message):
    """``message`` is a whole line of ``out``, and nothing of a traceback is there."""
    assert "Traceback" not in out, out[-3000:]
    assert 'File "' not in out, out[-3000:]
    assert message in out.splitlines(), out[-3000:]


@pytest.mark.parametrize(
    "config, message",
    [
        (
            "methods={PMx: {label: x}}",
            f"config key 'methods.PMx': unknown method 'PMx' (did you mean 'PM'?); known methods: {METHODS}; a "
            "new method needs an 'estimator' ('package.module:ClassName')",
        ),
        (
            "methods={Zebra: {params: {alpha: 1}}}",
            f"config key 'methods.Zebra': unknown method 'Zebra'; known methods: {METHODS}; a new method needs "
            "an 'estimator' ('package.module:ClassName')",
        ),
        (
            "datasets={mocap: {walk: {files: [resources/cmu-mocap/nope.bvh]}}}",
            "config datasets.mocap.walk (config/datasets.yaml): data file resources/cmu-mocap/nope.bvh does not "
            "exist; expected the file its `files` names (correct the path, or remove 'walk' from "
            "study_activities.mocap)",
        ),
        (
            f"datasets={{hsc: {{acrobatics: {{checksums: '{ZEROS}'}}}}}}",
            "config datasets.hsc.acrobatics (config/datasets.yaml): resources/paper-features/x4921.mat: checksum "
            f"mismatch: expected sha256 {ZEROS} (from the configuration), got "
            "5b6322db33aadbe313d61edab66a45e4a38baad5ccee48349a865c89cfb4bf1f",
        ),
        (
            "features={codebook: {files: [resources/cmu-mocap/codebook/nope.bvh]}}",
            "config features.codebook.files (config/datasets.yaml): codebook trial "
            "resources/cmu-mocap/codebook/nope.bvh does not exist; expected the BVH/AMC trials the "
            "shape-context codebook of the motion-capture features is built from",
        ),
        # the configuration check's own errors (before: followed by 3-4 lines of traceback)
        (
            "run=[PM, XGB]",
            f"config key 'run': unknown method 'XGB'; defined under 'methods': {METHODS}",
        ),
        (
            "study_activities={hsc: [juggling]}",
            f"config key 'study_activities.hsc': unknown activity 'juggling'; source 'hsc' has {HSC}",
        ),
        (
            "n_seed=3",
            "configuration: unknown key 'n_seed' (value 3): Additional properties are not allowed ('n_seed' was "
            f"unexpected); expected one of the keys {KEYS}",
        ),
        (
            "datasets={hsc: {golf: {fromat: mat}}}",
            "data sets (config/datasets.yaml): unknown key 'datasets.hsc.golf.fromat' (value 'mat'): Additional "
            f"properties are not allowed ('fromat' was unexpected); expected one of the keys {DATASET_KEYS}",
        ),
    ],
    ids=[
        "misspelt-method",
        "unknown-method",
        "missing-data-file",
        "checksum",
        "codebook",
        "run",
        "activity",
        "schema",
        "datasets-schema",
    ],
)
def test_configuration_error_is_one_line(work, config, message):
    rc, out = run([SNAKEMAKE, "-n", "--cores", "2", "--config", config], work)
    assert rc == 1, out[-3000:]
    assert_one_line(out, message)


def test_configuration_error_lines_name_only_the_problem(work):
    """Snakemake's own lines around ours are the profile and config-merge notes, nothing of a job."""
    rc, out = run([SNAKEMAKE, "-n", "--cores", "2", "--config", "run=[PM, XGB]"], work)
    assert rc == 1
    assert "Building DAG" not in out and "MissingInputException" not in out, out


@pytest.mark.parametrize(
    "make, message",
    [
        (
            None,
            "[study] --configfile config/nope.yaml: no such file; expected a YAML file such as config/paper.yaml",
        ),
        (
            lambda p: p.write_text("n_train: [30\n"),
            "[study] --configfile config/nope.yaml: not valid YAML at line 2 (while parsing a flow sequence); "
            "expected a YAML file such as config/paper.yaml",
        ),
        (
            lambda p: p.write_text("- 30\n"),
            "[study] --configfile config/nope.yaml: holds a list, not a mapping of configuration keys; expected "
            "a YAML file such as config/paper.yaml",
        ),
        (
            lambda p: p.mkdir(),
            "[study] --configfile config/nope.yaml: not a file; expected a YAML file such as config/paper.yaml",
        ),
    ],
    ids=["missing", "not-yaml", "not-a-mapping", "folder"],
)
def test_bin_study_checks_its_configfiles(work, make, message):
    """Snakemake loads --configfile before the Snakefile and answers a missing file with a traceback ending in
    FileNotFoundError; bin/study checks every file first (exit 2)."""
    bad = ROOT / "config" / "nope.yaml"
    assert not bad.exists()
    try:
        if make:
            make(bad)
        for args in (
            ["-n", "--configfile", "config/nope.yaml"],
            ["-n", "--configfiles", "config/ci.yaml", "config/nope.yaml", "--cores", "1"],
            ["-n", "--configfile=config/nope.yaml"],
        ):
            rc, out = run([str(ROOT / "bin" / "study"), *args], ROOT)
            assert rc == 2, out[-3000:]
            assert_one_line(out, message)
    finally:
        if bad.is_dir():
            bad.rmdir()
        else:
            bad.unlink(missing_ok=True)


def test_bin_study_reports_an_unreadable_configfile(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root reads any file")
    bad = tmp_path / "secret.yaml"
    bad.write_text("n_seeds: 1\n")
    bad.chmod(0)
    rc, out = run([str(ROOT / "bin" / "study"), "-n", "--configfile", str(bad)], ROOT)
    assert rc == 2
    assert_one_line(
        out,
        f"[study] --configfile {bad}: cannot be read (Permission denied); expected a YAML file such as "
        "config/paper.yaml",
    )


def test_configfile_args_reads_snakemakes_forms():
    from bsrbench.config import configfile_args

    argv = [
        "-n",
        "--configfile",
        "a.yaml",
        "b.yaml",
        "--cores",
        "2",
        "--configfiles=c.yaml",
        "target",
    ]
    assert configfile_args(argv) == ["a.yaml", "b.yaml", "c.yaml"]
    assert configfile_args(["--config", "study=x", "all"]) == []


@pytest.mark.parametrize("entry", ["foo", "=1", "study", "1x=2", "x y=1", "a=1", "ab-=1"])
def test_study_names_a_config_entry_that_is_not_key_value(entry):
    """Keys as Snakemake's command line takes them: one character, or one ending in -, is refused there too."""
    rc, out = run([str(ROOT / "bin" / "study"), "-n", "--config", "n_seeds=1", entry], ROOT)
    assert rc == 2
    assert_one_line(
        out,
        f"[study] --config {entry!r}: expected KEY=VALUE (KEY: at least two characters, letters, digits, _ or -, "
        "from a letter or _, ending in a letter, digit or _), for example --config study=mine "
        "'study_activities={hsc: [golf], mocap: []}' (config/README.md lists the keys)",
    )


def test_argv_problems_reads_config_entries_in_snakemakes_forms():
    from bsrbench.config import argv_problems

    assert argv_problems(["--config", "study=x", "n_seeds=2", "-n", "all"]) == []
    assert argv_problems(["-C", "ab=1", "--config=bc=2", "-Ccd=3"]) == []
    assert argv_problems(["-Cfoo"])[0].startswith("--config 'foo': expected KEY=VALUE")
    bad = argv_problems(["--config", "study=x", "oops", "--cores", "2", "target"])
    assert len(bad) == 1 and bad[0].startswith("--config 'oops': expected KEY=VALUE")


@pytest.mark.parametrize(
    "argv",
    [
        ["--config"],
        ["-C"],
        ["-n", "--config"],
        ["--config", "-n", "all"],
        ["-C", "ab=1", "-C", "--cores", "2"],
    ],
)
def test_argv_problems_names_a_config_option_without_an_entry(argv):
    """Snakemake takes ``--config`` with no entry and would run the whole study with the defaults."""
    from bsrbench.config import argv_problems

    assert argv_problems(argv) == ["--config: no KEY=VALUE given"]


def test_study_refuses_a_config_option_without_an_entry():
    rc, out = run([str(ROOT / "bin" / "study"), "-n", "--config"], ROOT)
    assert rc == 2
    assert_one_line(out, "[study] --config: no KEY=VALUE given")


# --------------------------------------------------------------------- a configuration never runs code
def _marker_config(tmp_path, estimator, params):
    marker = tmp_path / "marker"
    config = tmp_path / "evil.yaml"
    config.write_text(
        f"run: [EVIL]\nmethods:\n  EVIL:\n    estimator: {estimator!r}\n    params: {params}\n    grid: null\n"
    )
    return config, marker


@pytest.mark.parametrize(
    "estimator, params, words",
    [
        (
            "os:system",
            "{{command: 'touch {marker}'}}",
            "estimator 'os:system': module 'os' is of Python's standard library, which has no estimator",
        ),
        (
            "subprocess:Popen",
            "{{args: [touch, '{marker}']}}",
            "estimator 'subprocess:Popen': module 'subprocess' is of Python's standard library",
        ),
        (
            "fractions:Fraction",
            "{{numerator: 1}}",
            "estimator 'fractions:Fraction': module 'fractions' is of Python's standard library",
        ),
        (
            "sklearn.linear_model:ridge_regression",
            "{{}}",
            "estimator 'sklearn.linear_model:ridge_regression': 'ridge_regression' is a function, not a class",
        ),
        (
            "numpy:ndarray",
            "{{shape: [1]}}",
            "estimator 'numpy:ndarray': class 'ndarray' has no fit, predict, get_params",
        ),
    ],
    ids=[
        "function-of-os",
        "class-of-subprocess",
        "stdlib-class",
        "library-function",
        "class-not-estimator",
    ],
)
def test_a_dry_run_refuses_an_estimator_that_is_not_an_estimator_class_and_calls_nothing(
    work, tmp_path, estimator, params, words
):
    """Planning a study imports only the estimators' own modules and builds nothing before the class is known to
    be a regressor: a configuration naming a function or another class gets one line, and its payload never
    runs."""
    config, marker = _marker_config(tmp_path, estimator, params.format(marker=tmp_path / "marker"))
    rc, out = run([SNAKEMAKE, "-n", "--cores", "2", "--configfile", str(config)], work)
    assert rc == 1, out[-3000:]
    assert "Traceback" not in out and 'File "' not in out, out[-3000:]
    lines = [x for x in out.splitlines() if x.startswith("config key 'methods.EVIL.estimator'")]
    assert len(lines) == 1 and lines[0].startswith(
        f"config key 'methods.EVIL.estimator': {words}"
    ), out
    assert not marker.exists()


def test_a_dry_run_refuses_a_module_planted_in_the_working_directory(work, tmp_path):
    """Snakemake puts the project folder (its working directory) on Python's path, and the Snakefile takes it off:
    a ``.py`` file planted there and named by a configuration is not found, refused in one line, and its
    top-level code never runs."""
    marker = tmp_path / "marker"
    planted = work / "planted_estimator.py"
    planted.write_text(
        f"open({str(marker)!r}, 'w').close()\n"
        "class Planted:\n    def fit(self, X, Y):\n        return self\n"
        "    def predict(self, X):\n        return X\n    def get_params(self, deep=True):\n        return {}\n"
    )
    config = tmp_path / "planted.yaml"
    config.write_text(
        "run: [EVIL]\nmethods:\n  EVIL:\n    estimator: 'planted_estimator:Planted'\n    params: {}\n    grid: null\n"
    )
    try:
        rc, out = run([SNAKEMAKE, "-n", "--cores", "2", "--configfile", str(config)], work)
    finally:
        planted.unlink()
    assert rc == 1, out[-3000:]
    assert "Traceback" not in out and 'File "' not in out, out[-3000:]
    lines = [x for x in out.splitlines() if x.startswith("config key 'methods.EVIL.estimator'")]
    assert len(lines) == 1 and lines[0].startswith(
        "config key 'methods.EVIL.estimator': estimator 'planted_estimator:Planted': cannot find module "
        "'planted_estimator'; expected 'package.module:ClassName'"
    ), out
    assert not marker.exists()


def test_bin_study_refuses_a_configfile_that_asks_snakemake_to_evaluate_python(tmp_path):
    """Snakemake reads --configfile files with YTE, which evaluates the expressions of a file that sets
    __use_yte__: bin/study refuses such a file before Snakemake reads it."""
    marker = tmp_path / "marker"
    bad = tmp_path / "yte.yaml"
    bad.write_text(f"__use_yte__: true\nstudy: ?__import__('os').system('touch {marker}')\n")
    rc, out = run([str(ROOT / "bin" / "study"), "-n", "--configfile", str(bad)], ROOT)
    assert rc == 2, out[-3000:]
    assert_one_line(
        out,
        f"[study] --configfile {bad}: key '__use_yte__' asks Snakemake to evaluate the file's Python expressions "
        "(YTE templates); expected a plain YAML configuration",
    )
    assert not marker.exists()


def _alias_bomb(levels=7):
    """A YAML document of a few hundred bytes whose aliases expand to 10**levels strings."""
    lines = ['a0: &a0 ["x","x","x","x","x","x","x","x","x","x"]']
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ",".join([f"*a{k - 1}"] * 10) + "]")
    return "\n".join(lines) + f"\nn_train: *a{levels - 1}\n"


def test_an_alias_bomb_is_refused_before_anything_walks_it(work, tmp_path):
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(_alias_bomb())
    assert len(bomb.read_bytes()) < 1000
    message = (
        "configuration: expands to more than 100000 values (YAML anchors and aliases counted at each use); "
        "expected a configuration of ordinary size"
    )
    rc, out = run([SNAKEMAKE, "-n", "--cores", "2", "--configfile", str(bomb)], work)
    assert rc == 1, out[-3000:]
    assert_one_line(out, message)
    rc, out = run([str(ROOT / "bin" / "study"), "-n", "--configfile", str(bomb)], ROOT)
    assert rc == 2, out[-3000:]
    assert_one_line(out, f"[study] --configfile {bomb}: {message.removeprefix('configuration: ')}")


def test_seed_start_beyond_32_bit_seeds_is_refused(work):
    """The schema's maximum leaves room for n_seeds (at most 1000) below 2**31."""
    rc, out = run([SNAKEMAKE, "-n", "--cores", "2", "--config", "seed_start=2147483640"], work)
    assert rc == 1, out[-3000:]
    assert (
        "configuration: key 'seed_start', value 2147483640: 2147483640 is greater than the maximum"
        in out
    )
    assert "Traceback" not in out


def test_a_mat_data_set_asking_for_rows_its_file_lacks_is_refused_by_the_dry_run(work):
    """x4921.mat (acrobatics) has 600 rows: from first_frame 1, 600 frames need row 600. This passed the dry run
    and failed only in the features job."""
    config = "datasets={hsc: {acrobatics: {first_frame: 1}}}"
    rc, out = run([SNAKEMAKE, "-n", "--cores", "2", "--config", config], work)
    assert rc == 1, out[-3000:]
    assert_one_line(
        out,
        "config datasets.hsc.acrobatics (config/datasets.yaml): first_frame 1, frame_step 1 and n_frames 600 "
        "need row 600, but resources/paper-features/x4921.mat has 600 rows (X), 599 of them from first_frame "
        "every frame_step; expected first_frame + (n_frames - 1) x frame_step below 600 (lower n_frames, "
        "first_frame or frame_step, or set fewer_frames: use_all with frame_selection: first)",
    )
