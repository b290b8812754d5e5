"""A method's own CV (`methods.<M>.cv`) in the workflow: in a study with `cv: none` only that method gets CV
jobs, and its fits use the CV's choice (a dry run's plan and a tiny real run in a copy of the workflow)."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
STUDY = """\
study: ownCV
study_activities: {hsc: [golf], mocap: []}
n_train: [30]
n_seeds: 2
cv: {mode: none, folds: 5}
conformal_level: null
run: [NN1, Ridge]
methods:
  Ridge:
    grid: {alpha: [0.001, 1000.0]}
    cv: {mode: per_size, folds: 3}
report: {trace_method: null, subjective_methods: []}
"""
FIT = "results/ownCV/fit/random/hsc/golf/{m}/n30/seed{s}.json"
CV = "results/ownCV/cv/random/hsc/golf/{m}/n30/seed{s}.json"


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    work = tmp_path_factory.mktemp("owncv")
    for name in ("Snakefile", "workflow", "profiles", "config"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    (work / "resources").symlink_to(ROOT / "resources")
    (work / "config" / "owncv.yaml").write_text(STUDY)
    return work


def smk(work, *args):
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    res = subprocess.run(
        [SNAKEMAKE, "--configfile", "config/owncv.yaml", *args],
        cwd=work,
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    return res.returncode, res.stdout + res.stderr


def test_only_the_method_with_its_own_cv_gets_cv_jobs(work):
    targets = [FIT.format(m=m, s=s) for m in ("NN1", "Ridge") for s in (0, 1)]
    rc, out = smk(work, "-n", "--cores", "2", *targets)
    assert rc == 0, out[-3000:]
    # per_size: one CV job for Ridge, none for NN1
    assert re.search(r"^cv\s+1$", out, re.M), out[-3000:]
    planned = set(re.findall(r"results/ownCV/cv/\S+?\.json", out))
    assert planned == {CV.format(m="Ridge", s=0)}, planned


def test_the_fits_use_their_methods_cv(work):
    targets = [FIT.format(m=m, s=s) for m in ("NN1", "Ridge") for s in (0, 1)]
    rc, out = smk(work, "--cores", "2", *targets)
    assert rc == 0, out[-4000:]
    choice = json.loads((work / CV.format(m="Ridge", s=0)).read_text())["best_params"]
    assert set(choice) == {"alpha"} and choice["alpha"] in (0.001, 1000.0)
    for seed in (0, 1):  # per_size: both seeds use seed 0's choice
        ridge = json.loads((work / FIT.format(m="Ridge", s=seed)).read_text())
        assert ridge["cv"] == "per_size" and ridge["params"] == choice, ridge
        nn1 = json.loads((work / FIT.format(m="NN1", s=seed)).read_text())
        assert nn1["cv"] == "none", nn1
    assert not (work / "results" / "ownCV" / "cv" / "random" / "hsc" / "golf" / "NN1").exists()


def test_the_report_says_which_methods_were_tuned():
    import pandas as pd

    from bsrbench.reporting.study_setup import setup_text

    row = dict(source="hsc", activity="golf", paper_activity="Golf", seed=0, n_train=30)
    row.update(protocol="random", pose_transform="heading")
    df = pd.DataFrame(
        [{**row, "method": "NN1", "cv": "none"}, {**row, "method": "Ridge", "cv": "per_size"}]
    )
    text = setup_text(df, labels={"NN1": "1-NN", "Ridge": "Ridge"})[-1]
    assert text.startswith(
        "Hyper-parameters: 1-NN: as configured (no cross-validation); Ridge: chosen by cross-validation once "
        "per activity, method and $N$"
    ), text
    assert "\\texttt{methods.*.cv}" in text
    one = setup_text(df.assign(cv="none"), labels={"NN1": "1-NN", "Ridge": "Ridge"})[-1]
    assert one.startswith(
        "Hyper-parameters: as configured (no cross-validation) (configuration key \\texttt{cv.mode}: none). "
    ), one
