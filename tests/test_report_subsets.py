"""Every report rule works for a study of any subset of methods and activities: the real workflow runs tiny studies
(config/ci.yaml-sized: one activity, N = 30, two seeds, no CV, cheap methods) to the PDF report, which must have
pages, and a section with nothing to show says so in one line. Between them the studies have no method with a
predictive distribution, no PM, one method, one activity (of the paper's, or of one's own) and one N.

Before: a study without a method with a predictive distribution (``run: [NN1, Ridge]``) failed in rule plot_pit
("Number of rows must be a positive integer, not 0"), and an activity without a row in the paper's tables
(``paper_activity: null``) had no error table."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))

#: A CMU trial already in resources/ added as an activity of its own, with no row in the paper's tables.
OWN_TRIAL = """
datasets:
  mocap:
    walk_trial:
      paper_activity: null
      format: bvh
      files: [resources/cmu-mocap/12_02.bvh]
      checksums: resources/cmu-mocap/SHA256SUMS
      skip_frames: 6
      n_frames: 600
      frame_step: 4
      frame_selection: first
      fewer_frames: use_all
"""

#: name: (study_activities, run, extra configuration)
STUDIES = {
    # no method with a predictive distribution, no PM, one activity of one's own (no paper row)
    "own-deterministic": ("{hsc: [], mocap: [walk_trial]}", "[NN1, Ridge]", OWN_TRIAL),
    # one method, PM alone: no reference to compare it with, no baseline, no variant
    "pm-only": ("{hsc: [golf], mocap: []}", "[PM]", ""),
}


def study_config(name, activities, run, extra):
    return f"""study: subset-{name}
study_activities: {activities}
n_train: [30]
n_seeds: 2
protocols: [random]
cv: {{mode: none, folds: 2}}
run: {run}
methods:
  PM:
    params: {{n_atoms: 16, n_neighbors: 3, n_iter: 40, n_burn_in: 20}}
{extra}"""


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """The workflow in a temporary folder (resources linked), with the working tree's shared features and
    poses when it has them (the codebook takes minutes to learn)."""
    work = tmp_path_factory.mktemp("subsets")
    for name in ("Snakefile", "workflow", "profiles", "config"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    (work / "reports").mkdir()
    shutil.copy(ROOT / "reports" / "report.tex", work / "reports" / "report.tex")
    (work / "resources").symlink_to(ROOT / "resources")
    for shared in ("results/features/codebook.npz", "results/features/hsc/golf.npz"):
        if (ROOT / shared).is_file():
            (work / shared).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / shared, work / shared)
    return work


def pdf_text(pdf):
    return subprocess.run(
        ["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True
    ).stdout


@pytest.mark.parametrize("name", list(STUDIES))
def test_a_study_of_a_subset_has_a_report(work, name):
    activities, run, extra = STUDIES[name]
    config = work / "config" / f"subset-{name}.yaml"
    config.write_text(study_config(name, activities, run, extra))
    study = f"subset-{name}"
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    res = subprocess.run(
        [SNAKEMAKE, f"reports/{study}/report.pdf", "--cores", "2", "--configfile", str(config)]
        + ["--config", "job_server=false"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    pdf = work / "reports" / study / "report.pdf"
    assert pdf.read_bytes()[:5] == b"%PDF-"
    if shutil.which("pdfinfo"):
        info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True).stdout
        assert int(re.search(r"Pages:\s+(\d+)", info).group(1)) >= 2
    tables = work / "reports" / study / "tables"
    today = (tables / "today.tex").read_text()
    if name == "own-deterministic":
        # the activity's own error table, in its file and in the report, with its rows for both methods
        table = (tables / "activities_mocap.tex").read_text()
        rows = [ln for ln in table.splitlines() if ln.startswith("Walk trial & 30 & ")]
        assert len(rows) == 1 and rows[0].count(r"$\pm$") == 2, table
        assert "paper}" not in table  # no paper numbers
        assert r"\input{tables/activities_mocap}" in (tables / "body.tex").read_text()
        # no predictive distribution: one line, and the PIT figure says so instead of failing
        assert "No method of this study gives a predictive distribution." in today
        if shutil.which("pdftotext"):
            text = pdf_text(pdf)
            assert re.search(r"Activities not in the paper.s tables on the mocap data", text), text
            assert re.search(r"Walk trial\s+30\s+\d+\.\d\d", text), text
    if name == "pm-only":
        why = (tables / "why_pm.tex").read_text()
        assert r"\label{sec:why-pm}" in why and "PM variants on" not in why
