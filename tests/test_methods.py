"""The method registry (bsrbench.methods): one configuration entry plus one class make a method of every table."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from bsrbench import methods, sources
from bsrbench.methods import Method, configured, registry

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))


def test_registry_reads_label_group_and_order_with_their_defaults():
    conf = {
        "A": {"estimator": "bsrbench.models.reference:RidgeRegressor", "label": "Ridge A"},
        "B": {"estimator": "bsrbench.models.reference:RidgeRegressor", "group": "today"},
    }
    reg = registry(conf, ["B", "A"])
    assert list(reg) == ["B", "A"]
    assert reg["A"] == Method(
        "A", "Ridge A", "paper", 1, "bsrbench.models.reference:RidgeRegressor"
    )
    assert (reg["B"].label, reg["B"].group, reg["B"].order) == ("B", "today", 0)


def test_a_methods_modules_are_its_estimators_imports_and_the_job_logic():
    pm = Method("PM", "PM", "paper", 0, "bsrbench.models.bsr:BayesianSR")
    mods = pm.modules()
    # the sampler kernels come from bsr.py's import, the job logic from bsrbench.jobs' imports
    for m in (
        "bsrbench.models.bsr",
        "bsrbench.models._bsr_kernels",
        "bsrbench.jobs",
        "bsrbench.runs",
    ):
        assert m in mods
    assert "bsrbench.models.rvm" not in mods and "bsrbench.reporting.tables" not in mods
    assert mods == sources.closure(["bsrbench.models.bsr", "bsrbench.jobs"])
    files = pm.source_files()
    assert str(ROOT / "src" / "bsrbench" / "models" / "_bsr_kernels.py") in files
    with pytest.raises(
        ValueError,
        match=r"methods.X.estimator': estimator 'no_such_module_x:Y': cannot find module",
    ):
        Method("X", "X", "paper", 0, "no_such_module_x:Y").source_files()


def test_paper_names_come_from_the_classes_and_the_class_map_from_all():
    import bsrbench.models as models

    assert methods.paper_name("bsrbench.models.bsr:BayesianSR") == "PM"
    assert methods.paper_name("bsrbench.models.rvm:RVM") == "RVM"
    assert methods.paper_name("bsrbench.models.reference:RidgeRegressor") is None
    for name, module in methods.model_classes().items():
        assert getattr(models, name).__module__ == module
        # read from the source without importing: the same as the imported class's attribute
        assert getattr(getattr(models, name), "paper_name", None) == methods.paper_name(
            f"{module}:{name}"
        )
    preload = methods.job_preload()
    assert set(methods.model_classes().values()) <= set(preload)


def test_every_column_of_the_paper_has_one_class():
    from bsrbench.paper import PAPER_METHODS

    names = [methods.paper_name(f"{m}:{c}") for c, m in methods.model_classes().items()]
    assert sorted(n for n in names if n) == sorted(PAPER_METHODS)


def test_the_published_studys_registry_is_its_configuration_over_the_default():
    reg = configured("paper")
    assert list(reg)[:5] == ["RVM", "TGP", "SR", "DDL", "PM"]
    assert reg["NN1"].label == "1-NN" and reg["KNN"].group == "today"
    assert reg["PM"].paper_name == "PM"


# -------------------------------------------------------------------------------------------- a toy method
TOY_CLASS = '''
import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin


class MeanPose(RegressorMixin, BaseEstimator):
    """Predicts the mean training pose for every frame."""

    def __init__(self, shrink=0.0):
        self.shrink = shrink

    def fit(self, X, Y):
        self.mean_ = (1.0 - self.shrink) * np.asarray(Y, dtype=float).mean(axis=0)
        return self

    def predict(self, X):
        return np.tile(self.mean_, (np.asarray(X).shape[0], 1))
'''

TOY_CONFIG = """
study: toy
study_activities:
  hsc: [golf]
  mocap: []
n_train: [30]
n_seeds: 2
protocols: [random]
cv: {mode: none, folds: 2}
run: [NN1, Toy]
methods:
  Toy:
    estimator: toy_pose:MeanPose
    label: Mean pose
    group: today
    params: {shrink: 0.0}
    grid: null
"""


@pytest.fixture(scope="module")
def toy_run(tmp_path_factory):
    """A toy method added as one class (toy_pose.py on PYTHONPATH) and one configuration entry, run by the real
    workflow at the size of config/ci.yaml (one activity, N = 30, two seeds) beside 1-NN."""
    work = tmp_path_factory.mktemp("toy")
    for name in ("Snakefile", "workflow", "profiles", "config"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    (work / "resources").symlink_to(ROOT / "resources")
    (work / "toy_pose.py").write_text(TOY_CLASS)
    (work / "config" / "toy.yaml").write_text(TOY_CONFIG)
    env = dict(
        os.environ,
        PYTHONPATH=f"{work}:{os.environ.get('PYTHONPATH', '')}",
        PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}",
    )
    targets = [
        "results/toy/aggregate/results.csv",
        "reports/toy/tables/tableI_hsc.tex",
        "reports/toy/tables/today.tex",
        "reports/toy/tables/uncertainty.csv",
        "reports/toy/figures/error_vs_ntrain_hsc.pdf",
    ]
    res = subprocess.run(
        [SNAKEMAKE, *targets, "--cores", "2", "--configfile", "config/toy.yaml"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return work


def test_a_toy_method_is_in_the_aggregate_the_tables_and_the_figures(toy_run):
    df = pd.read_csv(toy_run / "results/toy/aggregate/results.csv")
    toy = df[df["method"] == "Toy"]
    assert len(toy) == 2 and set(toy["estimator"]) == {"toy_pose:MeanPose"}
    assert (
        toy["error"] > df[df["method"] == "NN1"]["error"].min()
    ).all()  # the mean pose is a poor guess
    table = (toy_run / "reports/toy/tables/tableI_hsc.tex").read_text()
    assert "Mean pose" in table and "today's baselines" in table  # its group's block of Table I
    assert "Mean pose" in (toy_run / "reports/toy/tables/today.tex").read_text()
    # the paired comparisons behind the tables' marks; the uncertainty table lists only methods with intervals
    comparisons = pd.read_csv(toy_run / "results/toy/aggregate/comparisons.csv")
    assert ("Toy", "NN1") in set(zip(comparisons["method"], comparisons["versus"]))
    assert "Toy" not in set(pd.read_csv(toy_run / "reports/toy/tables/uncertainty.csv")["method"])
    text = subprocess.run(
        ["pdftotext", str(toy_run / "reports/toy/figures/error_vs_ntrain_hsc.pdf"), "-"],
        capture_output=True,
        text=True,
    ).stdout
    assert "Mean pose" in text


def test_a_toy_methods_jobs_rerun_when_its_module_changes(toy_run):
    """Its code inputs are its class's file and the job logic: an edit of the class reruns its fits only."""
    env = dict(os.environ, PYTHONPATH=f"{toy_run}:{os.environ.get('PYTHONPATH', '')}")
    (toy_run / "toy_pose.py").write_text(TOY_CLASS + "\n# edited\n")
    res = subprocess.run(
        [SNAKEMAKE, "-n", "results/toy/aggregate/results.csv", "--cores", "1"]
        + ["--configfile", "config/toy.yaml", "--quiet", "rules"],
        cwd=toy_run,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    assert "fit" in out and "aggregate" in out, out[-3000:]
    dry = subprocess.run(
        [SNAKEMAKE, "-n", "results/toy/aggregate/results.csv", "--cores", "1"]
        + ["--configfile", "config/toy.yaml"],
        cwd=toy_run,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    ).stdout
    assert "method=Toy" in dry and "method=NN1" not in dry
