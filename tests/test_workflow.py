"""The Snakemake workflow: lint, dry runs (default, paper, SLURM profile), config errors before any job,
lists overridden from the command line, and a real end-to-end run of config/ci.yaml in a temporary copy of the
working tree (studies kept apart, the job server gone after the run, the report rules local under SLURM)."""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bsrbench.paper import PAPER_TABLES as PAPER_TABLE_ROWS

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
STUDY_RULES = {
    "cv",
    "fit",
    "aggregate",
    "table",
    "report_text",
    "plot_error_vs_ntrain",
    "plot_calibration",
    "plot_trace",
    "plot_subjective",
    "report_pdf",
    "all",
}


def smk(*args, cwd=ROOT, timeout=600):
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    return subprocess.run(
        [SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env
    )


def test_lint_is_clean():
    res = smk("--lint")
    out = res.stdout + res.stderr
    flagged = set(re.findall(r"Lints for rule (\w+)", out))
    assert not flagged & STUDY_RULES, out
    assert "Lints for" not in out, out
    assert res.returncode == 0, out


@pytest.mark.parametrize(
    "args",
    [
        (),
        ("--configfile", "config/paper.yaml"),
        ("--workflow-profile", "profiles/slurm", "--configfile", "config/paper.yaml"),
    ],
    ids=["default", "paper", "slurm-profile"],
)
def test_dry_run(args):
    res = smk("-n", "--cores", "2", *args) if "--workflow-profile" not in args else smk("-n", *args)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    out = res.stdout + res.stderr
    # a plan (fits from scratch; only report jobs in a working tree with results) or nothing to do
    assert re.search(r"^(fit|total)\s+\d+", out, re.M) or "Nothing to be done" in out, out[-3000:]


@pytest.mark.parametrize(
    "override, message",
    [
        (
            "study_activities: {hsc: [juggling]}",
            r"study_activities\.hsc.*unknown activity 'juggling'",
        ),
        (
            "study_activities: {nosource: [golf]}",
            r"study_activities.*unknown data source 'nosource'",
        ),
        ("run: [PM, XGB]", r"'run': unknown method 'XGB'"),
        ("n_train: [30, 550]", r"'n_train': 550 is too large for hsc/acrobatics"),
        (
            "n_train: [200]",
            r"study_activities\.mocap': walk has 167 frames, and every n_train \[200\] leaves",
        ),
        ("n_seeds: 0", r"n_seeds"),
        ("n_seed: 10", r"Additional properties are not allowed \('n_seed' was unexpected\)"),
        ("protocols: [blocks]", r"blocks"),
        ("cv: {mode: sometimes}", r"sometimes"),
        (
            "methods: {GPR: {estimator: 'bsrbench.models.gpr:GPR'}}\nrun: [PM, GPR]",
            r"'methods\.GPR\.estimator': estimator 'bsrbench\.models\.gpr:GPR': cannot find module",
        ),
        (
            "methods: {PM: {params: {n_atom: 8}}}",
            r"'methods\.PM\.params': n_atom: 8 is not a parameter of "
            r"bsrbench\.models\.bsr:BayesianSR; expected one of \[",
        ),
        (
            "methods: {Ridge: {grid: {lam: [1.0]}}}",
            r"'methods\.Ridge\.grid': lam: \[1\.0\] is not a parameter",
        ),
        # parameter values, checked by each estimator's own validation (before: only when a job ran)
        (
            "methods: {PM: {params: {n_atoms: -3}}}",
            r"'methods\.PM\.params' \(method PM, bsrbench\.models\.bsr:BayesianSR\): .*The 'n_atoms' parameter of BayesianSR must be an int in the range \[1, inf\)\. Got -3",
        ),
        (
            "methods: {PM: {params: {w_update: foo}}}",
            r"'methods\.PM\.params' .*'w_update' parameter of BayesianSR must be a str among .*Got 'foo'",
        ),
        (
            "methods: {PM: {params: {n_neighbors: 40}}}",
            r"'methods\.PM\.params' .*smallest n_train N = 30: BayesianSR needs at least max\(2, n_neighbors=40\)",
        ),
        (
            "methods: {PM: {params: {thin: 200}}}",
            r"thin=200 retains no sweep of the n_iter - n_burn_in = 100",
        ),
        (
            "cv: {mode: per_size, folds: 40}",
            r"'cv\.folds': 40 folds of the smallest n_train N = 30 .*empty folds",
        ),
        # reports/published holds the committed tables; reports/{study} is a study's report folder
        (
            "study: published",
            r"configuration: key 'study', value 'published': not allowed here; .*Not the name of a "
            r"shared folder or file \(features, mocap, benchmarks, published, report\.tex\)",
        ),
    ],
)
def test_bad_configuration_is_rejected_before_any_job(override, message, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(override + "\n")
    res = smk("-n", "--cores", "1", "--configfile", str(bad))
    out = res.stdout + res.stderr
    assert res.returncode == 1
    assert re.search(message, out), out[-4000:]
    # one line: no traceback after it (before: 3-4 lines of `File ".../common.smk", line 15, in <module>`)
    assert "Traceback" not in out and 'File "' not in out, out[-4000:]


@pytest.mark.parametrize(
    "override, message",
    [
        (
            "n_trian=[30]",
            r"^configuration: unknown key 'n_trian' \(value \[30\]\): Additional properties are not "
            r"allowed \('n_trian' was unexpected\); expected one of the keys \[.*'n_train'",
        ),
        (
            "protocols=[random, blocks]",
            r"^configuration: key 'protocols\[1\]', value 'blocks': not one of the allowed "
            r"values; expected one of \['random', 'contiguous', 'blocked', 'cross_trial'\]$",
        ),
        (
            "methods={PM: {parms: {n_atoms: 8}}}",
            r"^configuration: unknown key 'methods\.PM\.parms' \(value "
            r"\{'n_atoms': 8\}\): .*expected one of the keys \[.*'params'",
        ),
        (
            "n_seeds=0",
            r"^configuration: key 'n_seeds', value 0: 0 is less than the minimum of 1; expected minimum: 1 "
            r"\(Repetitions",
        ),
        (
            "seeds_per_job=0",
            r"^configuration: key 'seeds_per_job', value 0: 0 is less than the minimum of 1; expected "
            r"minimum: 1 \(Seeds of a",
        ),
        (
            "datasets={hsc: {golf: {fromat: mat}}}",
            r"^data sets \(config/datasets\.yaml\): unknown key "
            r"'datasets\.hsc\.golf\.fromat' \(value 'mat'\): .*'format'",
        ),
        (
            "datasets={hsc: {Golf2: {format: mat, files: [x]}}}",
            r"^data sets \(config/datasets\.yaml\): a name under key 'datasets\.hsc', value 'Golf2': 'Golf2' does not "
            r"match '\^\[a-z0-9_\]\+\$'",
        ),
    ],
    ids=[
        "typo",
        "enum",
        "nested-typo",
        "minimum",
        "seeds-per-job",
        "datasets-typo",
        "datasets-name",
    ],
)
def test_schema_error_is_one_line_naming_the_key(override, message):
    """`snakemake -n --config n_trian='[30]'` printed 966 lines (Snakemake's validation error dumps the schema and
    the configuration) around the one useful line. Now one line names the key path, the value and what was
    expected, and the whole output is a few lines."""
    res = smk("-n", "--cores", "1", "--config", override)
    out = res.stdout + res.stderr
    assert res.returncode != 0
    assert len(out.splitlines()) < 30, out[-3000:]
    assert any(re.search(message, line) for line in out.splitlines()), out[-3000:]
    assert "Traceback" not in out and 'File "' not in out, out[-3000:]


def _readme_override_examples():
    """The `--config` examples of docs/running.md (the README links there)."""
    text = (ROOT / "docs" / "running.md").read_text()
    lines = [line for line in text.splitlines() if line.startswith("snakemake --cores 2 --config ")]
    assert lines, "docs/running.md has no `snakemake --cores 2 --config` examples"
    return lines


@pytest.mark.parametrize("line", _readme_override_examples())
def test_readme_override_examples_run_in_a_study_of_their_own(line):
    """The README's `--config` examples wrote into the default study's results/quick and reports/quick, and the
    `methods='{Ridge: {grid: ...}}'` one changed nothing (the default study has cv.mode none, which ignores grids).
    Each example now names its study, its dry run passes and writes only there, and a grid example runs CV jobs of
    that method."""
    args = shlex.split(line)[1:]
    studies = [a.split("=", 1)[1] for a in args if a.startswith("study=")]
    assert studies and studies[0] != "quick", (
        f"the example does not name a study of its own: {line}"
    )
    study = studies[0]
    res = smk("-n", *args)
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    assert "results/quick/" not in out and "reports/quick/" not in out
    assert f"results/{study}/aggregate/results.csv" in out
    for method in re.findall(r"methods='\{(\w+): \{grid:", line):
        assert re.search(
            rf"output: results/{re.escape(study)}/cv/\S+/{method}/n\d+/seed\d+\.json", out
        ), out[-3000:]


@pytest.mark.parametrize("how", ["configfile", "config"])
def test_exponent_numbers_are_numbers_in_config_files_and_on_the_command_line(how, tmp_path):
    """YAML 1.1 reads 1e-3 as a string: before, `gap: 3e1` failed the schema ("'3e1' is not of type 'integer'")
    and `alpha: 1e-3` reached the estimator as '1e-3'; now both are numbers (bsrbench.config), and the
    load-time value check (which rejects a string alpha) passes."""
    if how == "configfile":
        over = tmp_path / "over.yaml"
        over.write_text(
            "gap: 3e1\nprotocols: [contiguous]\nmethods: {Ridge: {params: {alpha: 1e-3}}}\n"
        )
        res = smk("-n", "--cores", "1", "--configfile", str(over))
    else:
        res = smk(
            "-n",
            "--cores",
            "1",
            "--config",
            "methods={Ridge: {params: {alpha: 1e-3}}}",
            "n_train=[3e1, 1e2]",
            "n_seeds=2e0",
        )
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]


def test_run_outside_the_repository_and_capital_activity_names_are_named(tmp_path):
    """Fresh-user findings: with --directory elsewhere, config/datasets.yaml is not found and Snakemake skips it
    silently (the error used to be "unknown data source 'hsc'; config/datasets.yaml defines []"); an activity
    name with capitals passed the schema but no rule can build it (wildcards are lower case)."""
    res = smk(
        "-n", "--cores", "1", "-d", str(tmp_path), "--configfile", str(ROOT / "config" / "ci.yaml")
    )
    assert res.returncode != 0
    assert (
        "config/datasets.yaml was not loaded from the working directory" in res.stdout + res.stderr
    )
    over = tmp_path / "upper.yaml"
    over.write_text(
        "datasets: {hsc: {Golf2: {kind: mat, file: resources/paper-features/x4921.mat}}}\n"
    )
    res = smk("-n", "--cores", "1", "--configfile", str(over))
    assert res.returncode != 0
    assert re.search(r"Golf2.*does not match.*\^\[a-z0-9_\]\+\$", res.stdout + res.stderr, re.S), (
        res.stderr[-3000:]
    )


def test_boolean_on_the_command_line(tmp_path):
    """`--config job_server=false` (YAML's spelling, as config/README.md documents it) used to fail the schema
    ("'false' is not of type 'boolean'")."""
    res = smk("-n", "--cores", "1", "--config", "job_server=false")
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]


#: Files that every study shares: the features and poses (and their inputs and logs), built once for all.
SHARED_PREFIXES = (
    "results/features/",
    "results/mocap/",
    "resources/",
    "logs/features/",
    "logs/mocap/",
    "logs/download/",
)


def _planned_files(res):
    """The output and log files of the jobs of a dry run (Snakemake's job listing)."""
    return [
        f.strip()
        for ln in res.stdout.splitlines()
        if ln.strip().startswith(("output:", "log:"))
        for f in ln.split(":", 1)[1].split(",")
    ]


def test_the_quick_study_builds_only_the_tables_with_a_studied_activity():
    """The quick study has acrobatics (Table I) on hsc and walk (Table II) on mocap: before, all four tables were
    built, two of them blocks of "no data" rows (mocap Table I: "data not on this machine" three times)."""
    res = smk("-n", "--forceall", "--cores", "1")
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    tables = sorted(
        f for f in _planned_files(res) if re.fullmatch(r"reports/quick/tables/table\w+\.tex", f)
    )
    assert tables == [
        "reports/quick/tables/tableII_mocap.tex",
        "reports/quick/tables/tableI_hsc.tex",
    ]


def test_two_studies_share_no_report_result_or_log_file():
    """Each study's report is in reports/{study}/ (before: reports/tables, reports/figures and reports/report.pdf
    for every study, so that the PDF and `snakemake --report` showed whichever study wrote last). Only the shared
    features and poses are in both studies' jobs: once they are built, Snakemake's directory lock (which refuses a
    run whose jobs would write a file that a running one reads or writes) lets the two studies run at once."""
    planned = {}
    for study, args in (
        ("ci", ("--configfile", "config/ci.yaml")),
        ("ablation-ci", ("--configfile", "config/ablation.yaml", "config/ablation-ci.yaml")),
    ):
        res = smk("-n", "--forceall", "--cores", "1", *args)
        assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
        planned[study] = set(_planned_files(res))
        reports = sorted(f for f in planned[study] if f.startswith("reports/"))
        assert {f"reports/{study}/report.pdf", f"reports/{study}/tables/why_pm.tex"} <= set(reports)
        assert all(f.startswith(f"reports/{study}/") for f in reports), reports
        assert any(f.startswith(f"logs/{study}/report/") for f in planned[study])
    both = planned["ci"] & planned["ablation-ci"]
    assert "results/features/hsc/golf.npz" in both  # the check below sees the jobs of both studies
    assert all(f.startswith(SHARED_PREFIXES) for f in both), sorted(both)


@pytest.mark.parametrize(
    "args",
    [("--report", "reports/report.html"), ("--report=reports/paper/report.html",)],
    ids=["shared-folder", "other-study"],
)
def test_the_html_report_goes_to_the_study_folder(args, tmp_path):
    """The HTML report of study ci is refused in reports/ itself or in another study's folder, where it would
    pass for that study's (the report's location is the one place Snakemake leaves to the command line)."""
    res = smk("--configfile", "config/ci.yaml", *args, cwd=copy_tree(tmp_path))
    out = res.stdout + res.stderr
    assert res.returncode != 0, out[-3000:]
    assert "the HTML report of study 'ci' goes to its report folder reports/ci/" in out, out[-3000:]
    assert "Traceback" not in out and 'File "' not in out, out[-3000:]  # one line
    assert not list((tmp_path / "reports").rglob("*.html"))


def copy_tree(work):
    """The workflow, profiles and configs in ``work`` (resources linked, not copied), so that no result of the
    working tree counts."""
    for name in ("Snakefile", "workflow", "profiles", "config"):
        src = ROOT / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    (work / "reports").mkdir()
    shutil.copy(ROOT / "reports" / "report.tex", work / "reports" / "report.tex")
    (work / "resources").symlink_to(ROOT / "resources")
    return work


# Modules planted in the project's folders, each writing a marker file if imported (test_planted_packages_never_run):
# packages shadowing the project's and its dependencies, and standard-library names Snakemake and the jobs import.
PLANTED = (
    "bsrbench/__init__.py",
    "numpy/__init__.py",
    "sklearn/__init__.py",
    "workflow/rules/bsrbench/__init__.py",
    "workflow/rules/sklearn/__init__.py",
    "workflow/rules/difflib.py",
    "workflow/scripts/yaml/__init__.py",
    ".snakemake/scripts/pickle.py",
)


@pytest.fixture(scope="module")
def ci_run(tmp_path_factory):
    """config/ci.yaml run end to end in a copy of the working tree (resources linked, not copied), into whose
    folder packages named like the project's and its dependencies were planted (:data:`PLANTED`)."""
    work = copy_tree(tmp_path_factory.mktemp("study"))
    markers = work.parent / "markers"
    markers.mkdir()
    for name in PLANTED:
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        marker = markers / name.replace("/", "_")
        (work / name).write_text(f"open({str(marker)!r}, 'w').close()\n")
    res = smk(
        "reports/ci/report.pdf",
        "--cores",
        "2",
        "--configfile",
        "config/ci.yaml",
        cwd=work,
        timeout=900,
    )
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return work


def test_planted_packages_never_run(ci_run):
    """Snakemake puts the Snakefile's folder and each included file's first on Python's path, ``python -m`` the
    working directory and ``python script.py`` the script's: the Snakefile and every rule file take the project's
    folders off and jobs run with PYTHONSAFEPATH, so a module planted there neither shadows the installed one nor
    runs, in the Snakefile, the job server, a fit job or a ``script:`` job."""
    assert sorted(p.name for p in (ci_run.parent / "markers").iterdir()) == []
    assert all((ci_run / name).is_file() for name in PLANTED)


def test_rule_files_included_by_a_snakefile_of_ones_own_run_no_planted_module(tmp_path):
    """Each rule file takes its own folder off Python's path before it imports anything, so a Snakefile elsewhere
    that includes them (a researcher's own) does not import modules planted beside them."""
    (tmp_path / "project").mkdir()
    work = copy_tree(tmp_path / "project")
    markers = tmp_path / "markers"
    markers.mkdir()
    for name in ("bsrbench/__init__.py", "sklearn/__init__.py", "difflib.py"):
        planted = work / "workflow" / "rules" / name
        planted.parent.mkdir(parents=True, exist_ok=True)
        planted.write_text(f"open({str(markers / name.replace('/', '_'))!r}, 'w').close()\n")
    own = tmp_path / "own"
    shutil.copytree(work / "config", own / "config")
    (own / "resources").symlink_to(ROOT / "resources")
    rules = work / "workflow" / "rules"
    (own / "Snakefile").write_text(
        'configfile: "config/datasets.yaml"\nconfigfile: "config/config.yaml"\n\n\n'
        f'include: "{rules / "datasets.smk"}"\ninclude: "{rules / "common.smk"}"\n\n\n'
        'rule mine:\n    output:\n        "mine.txt",\n    shell:\n        "touch {output}"\n'
    )
    res = smk("-n", "--cores", "1", "mine", cwd=own)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert sorted(p.name for p in markers.iterdir()) == []


def test_ci_run_writes_every_result_and_a_tidy_aggregate(ci_run):
    import pandas as pd

    df = pd.read_csv(ci_run / "results" / "ci" / "aggregate" / "results.csv")
    assert len(df) == 9 * 2  # 9 methods x 1 activity x 1 size x 2 seeds
    assert set(df["method"]) == {"RVM", "TGP", "SR", "DDL", "PM", "NN1", "Ridge", "KNN", "GP"}
    # the new columns: joint-position errors for all, proper scores only with a predictive distribution
    assert (df["pa_mpjpe_mm"] <= df["mpjpe_mm"]).all() and df["mpjpe_mm"].between(1, 500).all()
    scored = df.set_index("method")["scores_from"].dropna().groupby(level=0).first().to_dict()
    assert scored == {"RVM": "gaussian", "GP": "gaussian", "PM": "samples"}
    assert df.loc[df["scores_from"].isna(), ["nlpd", "crps"]].isna().all().all()
    assert df["error"].between(0, 180).all()
    assert df.loc[df["method"] == "PM", "coverage_90"].between(0, 1).all()
    assert (
        ci_run / "results" / "ci" / "cv" / "random" / "hsc" / "golf" / "PM" / "n30" / "seed0.json"
    ).is_file()
    assert not (ci_run / "results" / "fit").exists()  # every fit of the study is under results/ci/


def test_ci_tables_have_the_paper_rows(ci_run):
    """Table I has the rows of the studied activity and names the others in one line; Table II, none of whose
    activities the ci study has, is left out, and the note under the hsc tables says so (before: a table of
    "no data" rows)."""
    assert not (ci_run / "reports" / "ci" / "tables" / "tableII_hsc.tex").exists()
    body = (ci_run / "reports" / "ci" / "tables" / "body.tex").read_text()
    assert r"\input{tables/tableI_hsc}" in body and "tableII" not in body
    assert re.search(
        r"Table II \(.*\) is not shown for the hsc data: this study has none of its activities",
        body,
    )
    for table, names in list(PAPER_TABLE_ROWS.items())[:1]:
        text = (ci_run / "reports" / "ci" / "tables" / f"table{table}_hsc.tex").read_text()
        assert r"\toprule" in text and r"\bottomrule" in text
        # the paper's methods' block; the second one has today's baselines beside PM
        text, today = text.split(r"\end{table}")[:2]
        assert "(today's baselines)" in today and "k-NN" in today
        rows = [
            ln.split(" & ")[0]
            for ln in text.splitlines()
            if ln.endswith(r"\\") and not ln.startswith(r"\emph")
        ]
        assert rows[0] == "Activity"
        # rows of results only (golf); one line under the table names the other activities of the paper's table
        assert list(dict.fromkeys(rows[1:])) == ["Golf"]
        under = next(ln for ln in text.splitlines() if "Not shown (no results here)" in ln)
        assert all(n in under for n in names if n != "Golf"), under
    table_i = (ci_run / "reports/ci/tables/tableI_hsc.tex").read_text()
    golf = [ln for ln in table_i.splitlines() if ln.startswith("Golf & 30")]
    # a row per block: the paper's 7 methods, then PM, k-NN and the GP; one bold mean over both
    assert [ln.count(r"$\pm$") for ln in golf] == [7, 3]
    assert sum(ln.count(r"\textbf") for ln in golf) >= 1


def test_ci_pdf_and_html_report(ci_run):
    pdf = ci_run / "reports" / "ci" / "report.pdf"
    assert pdf.read_bytes()[:5] == b"%PDF-"
    if shutil.which("pdfinfo"):
        info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True).stdout
        assert int(re.search(r"Pages:\s+(\d+)", info).group(1)) >= 3
    res = smk("--configfile", "config/ci.yaml", "--report", "reports/ci/report.html", cwd=ci_run)
    assert res.returncode == 0, res.stderr[-3000:]
    # snakemake issue #4280: the default `disk` resource's size coroutine is never awaited (see the profile)
    assert "never awaited" not in res.stderr, res.stderr[-3000:]
    html = (ci_run / "reports" / "ci" / "report.html").read_text()
    assert len(html) > 10_000
    assert "study <strong>ci</strong>" in html  # the report names it
    # and embeds this study's report files only (before, reports/tables etc. of whichever study wrote last)
    assert set(re.findall(r"reports/[A-Za-z0-9_.-]+/", html)) == {"reports/ci/"}


def test_job_server_stopped_with_the_run_and_left_no_files(ci_run):
    from bsrbench import jobserver

    sock = jobserver.socket_path(cwd=ci_run)
    left = sorted(str(p) for p in sock.parent.glob(sock.name + "*"))
    assert left == [], left


def _planned_outputs(res):
    return [
        f.strip()
        for ln in res.stdout.splitlines()
        if ln.strip().startswith("output:")
        for f in ln.split(":", 1)[1].split(",")
    ]


@pytest.mark.parametrize(
    "args",
    [("--config", "study=other"), ("--configfile", "config/paper.yaml")],
    ids=["other-study", "paper"],
)
def test_another_study_touches_nothing_of_this_one(ci_run, args):
    res = smk("-n", "--cores", "2", *args, cwd=ci_run)
    assert res.returncode == 0, res.stderr[-3000:]
    planned = _planned_outputs(res)
    study = "other" if "study=other" in args else "paper"
    fits = [f for f in planned if "/fit/" in f]
    assert fits and all(f.startswith(f"results/{study}/fit/") for f in fits)
    assert not [f for f in planned if f.startswith(("results/ci/", "reports/ci/", "logs/ci/"))]
    # its report goes to its own folder, and shared features and poses stay up to date too: nothing planned exists
    reports = [f for f in planned if f.startswith("reports/")]
    assert f"reports/{study}/report.pdf" in reports and all(
        f.startswith(f"reports/{study}/") for f in reports
    )
    assert not [f for f in planned if (ci_run / f).exists()]
    assert (
        r"Study: \textbf{ci}" in (ci_run / "reports" / "ci" / "tables" / "findings.tex").read_text()
    )


#: Rules submitted as cluster jobs under profiles/slurm; every other rule is in the Snakefile's `localrules`.
CLUSTER_RULES = {"fit", "cv", "features_codebook", "features_mocap"}
LOCAL_RULES = {
    "all",
    "report_today",
    "plot_pit",
    "aggregate",
    "comparisons",
    "verdict",
    "report_verdict",
    "plot_cd",
    "table",
    "table_activities",
    "report_text",
    "plot_error_vs_ntrain",
    "plot_calibration",
    "plot_trace",
    "plot_gxy",
    "report_why_pm",
    "report_mechanisms",
    "pool_chains",
    "plot_subjective",
    "report_pdf",
    "features_mat",
    "mocap_poses",
    "download_cmu_asf",
    "download_cmu_amc",
}


def test_every_rule_is_local_or_a_cluster_job():
    res = smk("--list-rules")
    assert res.returncode == 0, res.stderr[-2000:]
    assert set(res.stdout.split()) == CLUSTER_RULES | LOCAL_RULES


@pytest.mark.parametrize(
    "seeds_per_job, chain_rules",
    [("null", {"fit_chains2", "fit_chains4"}), ("1", {"fit_chain"})],
)
def test_chained_methods_run_in_one_job_per_split_or_per_chain(seeds_per_job, chain_rules):
    """Chained methods (here with 2 and 4 chains): one job of the chains per split, a rule per chain count, or a job
    per chain with seeds_per_job 1 (cluster jobs); the pooling (pool_chains, local) and every other rule as ever."""
    res = smk("--list-rules", "--configfile", "config/ablation.yaml", "config/ablation-ci.yaml",
              "--config", f"seeds_per_job={seeds_per_job}", "run=[PM,PMK16,PMj3,PMK8s5000text]")  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    assert "not present" not in res.stderr, res.stderr
    assert set(res.stdout.split()) - CLUSTER_RULES - LOCAL_RULES == chain_rules


def test_slurm_profile_runs_the_quick_rules_locally(ci_run):
    """Under the SLURM executor the report, tables, plots, aggregate, poses and .mat checks run on this host.

    Snakemake's dry run does not mark local rules (it leaves the decision to execution), so this is a real run
    of the SLURM profile; no SLURM is installed here, so a rule that was submitted would fail."""
    for d in ("results/ci/aggregate", "reports/ci/tables", "reports/ci/figures"):
        shutil.rmtree(ci_run / d)
    (ci_run / "reports" / "ci" / "report.pdf").unlink()
    targets = [
        "reports/ci/report.pdf",
        "results/features/hsc/run.npz",
        "results/mocap/mocap/walk.npz",
    ]
    res = smk(
        *targets,
        "--workflow-profile",
        "profiles/slurm",
        "--configfile",
        "config/ci.yaml",
        cwd=ci_run,
    )
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-4000:]
    assert "workflow specific profile profiles/slurm" in out
    ran_local = set(re.findall(r"^localrule (\w+):", out, re.M))
    submitted = set(re.findall(r"^rule (\w+):", out, re.M))
    assert ran_local == {
        "aggregate",
        "comparisons",
        "verdict",
        "report_verdict",
        "plot_cd",
        "table",
        "report_text",
        "plot_error_vs_ntrain",
        "plot_calibration",
        "plot_trace",
        "report_why_pm",
        "report_mechanisms",
        "report_today",
        "plot_pit",
        "plot_subjective",
        "report_pdf",
        "features_mat",
        "mocap_poses",
    }
    assert (
        submitted == set()
    )  # and the fits and CV of the local run were not rerun: where they ran is no param
    assert (ci_run / "reports" / "ci" / "report.pdf").read_bytes()[:5] == b"%PDF-"


@pytest.mark.skipif(
    shutil.which("sbatch") is not None, reason="a real SLURM: this would submit jobs"
)
def test_slurm_profile_submits_fit_and_cv_jobs(ci_run):
    """New fit and CV jobs go to SLURM (here, without SLURM, their submission fails); nothing else is touched."""
    targets = [
        "results/ci/fit/random/hsc/golf/NN1/n40/seed0.json",
        "results/ci/cv/random/hsc/golf/Ridge/n40/seed0.json",
    ]
    res = smk(
        *targets,
        "--workflow-profile",
        "profiles/slurm",
        "--configfile",
        "config/ci.yaml",
        cwd=ci_run,
    )
    out = res.stdout + res.stderr
    assert res.returncode != 0
    assert not any((ci_run / t).exists() for t in targets)
    if shutil.which("scontrol") is None:
        # without the SLURM client commands the cluster check at the start refuses, before any submission
        assert "`scontrol` is not installed on this host" in out, out[-3000:]
        assert not re.search(r"^(local)?rule (fit|cv):", out, re.M)
        return
    assert set(re.findall(r"^rule (\w+):", out, re.M)) == {"fit", "cv"}, out[-3000:]
    assert not re.search(r"^localrule (fit|cv):", out, re.M)
    assert "Job submission failed" in out, out[-3000:]
    assert not any((ci_run / t).exists() for t in targets)


def _snapshot(work):
    """Bytes of every report output (tables, figures, PDF, HTML) and of the aggregate table."""
    paths = [
        *sorted((work / "reports").rglob("*")),
        work / "results" / "ci" / "aggregate" / "results.csv",
    ]
    return {p.relative_to(work): p.read_bytes() for p in paths if p.is_file()}


def test_a_method_that_cannot_be_built_fails_the_run_before_anything_is_written(ci_run):
    """The stale-results case: a configuration naming an estimator module that does not exist must fail the
    run (the study and the HTML report) and leave the existing tables, figures and reports untouched."""
    before = _snapshot(ci_run)
    bad = ci_run / "gpr.yaml"
    bad.write_text(
        "methods: {GPR: {estimator: 'bsrbench.models.gpr:GPR', label: GPR, params: {}, grid: null}}\n"
        "run: [RVM, TGP, SR, DDL, PM, NN1, Ridge, GPR]\n"
    )
    args = ("--configfile", "config/ci.yaml", str(bad))
    for cmd in (
        ("--cores", "2", *args),
        ("reports/ci/report.pdf", "--cores", "2", *args),
        ("--report", "reports/ci/report.html", *args),
    ):
        res = smk(*cmd, cwd=ci_run)
        out = res.stdout + res.stderr
        assert res.returncode != 0, out[-3000:]
        assert re.search(
            r"methods\.GPR\.estimator': estimator 'bsrbench\.models\.gpr:GPR': cannot find module",
            out,
        ), out[-3000:]
    assert _snapshot(ci_run) == before


def test_the_html_report_refuses_an_aggregate_of_another_configuration(ci_run):
    """`snakemake --report` does not check that outputs are current: the workflow refuses a stale aggregate."""
    before = _snapshot(ci_run)
    more = ci_run / "seeds.yaml"
    more.write_text("n_seeds: 3\n")
    res = smk(
        "--configfile",
        "config/ci.yaml",
        str(more),
        "--report",
        "reports/ci/report.html",
        cwd=ci_run,
    )
    out = res.stdout + res.stderr
    assert res.returncode != 0, out[-3000:]
    assert re.search(
        r"results\.csv: does not match the configuration.*seed: the table has \[0, 1\], "
        r"the configuration \[0, 1, 2\]",
        out,
    ), out[-3000:]
    assert _snapshot(ci_run) == before


@pytest.mark.parametrize(
    "override, changed",
    [
        (
            "n_seeds=3",
            r"seed: the table has \[0, 1\], the configuration \[0, 1, 2\]; 9 job\(s\) to add, 0 no longer",
        ),
        (
            "run=[RVM,PM]",
            r"method: the table has \['DDL', 'GP', 'KNN', 'NN1', 'PM', 'RVM', 'Ridge', 'SR', 'TGP'\], the "
            r"configuration \['PM', 'RVM'\]; 0 job\(s\) to add, 14 no longer configured",
        ),
    ],
)
def test_a_design_changed_under_the_same_study_name_is_named_at_the_start(
    ci_run, override, changed
):
    """Before: nothing said that the ci study's results were of another design until the aggregate check of a
    report rule failed. Now the dry run says it before any job: what changed, that the aggregate and report
    will be rebuilt, and how to keep the old study (a study name of its own) or start afresh."""
    before = _snapshot(ci_run)
    res = smk(
        "-n", "--cores", "1", "--configfile", "config/ci.yaml", "--config", override, cwd=ci_run
    )
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    warning = re.search(
        r"Warning: study 'ci': the configuration differs from the design of its results in "
        r"results/ci/ \(results/ci/aggregate/results\.csv: (.*)",
        out,
    )
    assert warning, out[-3000:]
    assert re.match(changed, warning.group(1)), warning.group(1)
    assert "run this design under a study name of its own (--config study=NAME" in out
    assert "delete results/ci/ and reports/ci/" in out
    assert out.index("Warning: study 'ci'") < out.index("Job stats")  # before the jobs
    assert _snapshot(ci_run) == before
    same = smk(
        "-n",
        "--cores",
        "1",
        "--configfile",
        "config/ci.yaml",
        "--config",
        "n_train=[30]",
        cwd=ci_run,
    )
    assert same.returncode == 0 and "the configuration differs" not in same.stdout + same.stderr


def test_a_changed_method_setting_reruns_its_fits_and_cv(ci_run):
    """Before: the fit rules passed their settings only inside params.job, which depends on input and output, and
    Snakemake's params trigger ignores such params: --config methods='{PM: {params: {n_iter: 60}}}' reran no fit,
    left the results of n_iter = 40, and page 1 of the rebuilt report named the override."""
    before = _snapshot(ci_run)
    res = smk(
        "-n",
        "--cores",
        "1",
        "--configfile",
        "config/ci.yaml",
        "--config",
        "methods={PM: {params: {n_iter: 60}}}",
        cwd=ci_run,
    )
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    counts = dict(re.findall(r"^(\w+)\s+(\d+)$", out, re.M))
    pm_jobs = set(
        re.findall(r"output: results/ci/(?:fit|cv)/\S+/(\w+)/n\d+/seed\d+\.(?:npz|json)", out)
    )
    assert int(counts.get("fit", 0)) >= 1 and pm_jobs == {"PM"}, out[-3000:]  # PM's jobs only
    assert "Params have changed since last execution" in out and '"n_iter": 60' in out
    assert (
        _snapshot(ci_run) == before
    )  # (test_ci_rerun_is_a_no_op: the unchanged configuration reruns nothing)


def test_ci_report_has_no_overfull_box_undefined_reference_or_small_figure_font(ci_run):
    from pdftext import figure_text_sizes

    from bsrbench.reporting.build import latex_log_problems

    log = (ci_run / "reports" / "ci" / "build" / "report.log").read_text(errors="replace")
    assert latex_log_problems(log, max_overfull_pt=1.0) == []
    sizes = figure_text_sizes(ci_run / "reports" / "ci" / "report.pdf")
    n_figures = len(list((ci_run / "reports" / "ci" / "figures").glob("*.pdf")))
    assert len(sizes) >= n_figures - 1  # every figure with text (a trace may have none of ours)
    small = {k: min(v) for k, v in sizes.items() if min(v) < 7.0 - 1e-6}
    assert not small, f"figure text below 7 pt (page, figure): {small}"


def test_ci_report_metadata_and_page_one_header(ci_run):
    pdf = str(ci_run / "reports" / "ci" / "report.pdf")
    info = subprocess.run(["pdfinfo", pdf], capture_output=True, text=True).stdout
    assert re.search(r"^Title:\s+bsrbench study report: reproducing", info, re.M), info
    assert re.search(r"^Author:\s+bsrbench workflow", info, re.M), info
    page1 = subprocess.run(
        ["pdftotext", "-f", "1", "-l", "1", "-layout", pdf, "-"], capture_output=True, text=True
    ).stdout
    for field in ("Built", "Code", "Configuration", "Machine"):
        assert re.search(rf"^\s*{field}\s", page1, re.M), page1[:2000]
    assert "config/ci.yaml" in page1 and "UTC" in page1
    # typewriter text copies as typed (underscores are glyphs, not rules)
    text = subprocess.run(["pdftotext", pdf, "-"], capture_output=True, text=True).stdout
    assert "study_activities.hsc" in text


def test_ci_report_names_the_config_overrides_it_ran_with(ci_run, tmp_path):
    """Before: page 1 named the configuration files but not the `--config` overrides. In a copy of the ci run (so
    that the other tests see its report as built), an override that changes no job's result rebuilds the PDF
    only, and page 1 lists it after the files, copyable as typed; job_server, an execution setting (the SLURM
    profile's), is not part of the study's configuration: switching it reruns nothing."""
    work = tmp_path / "work"
    shutil.copytree(ci_run, work, symlinks=True)
    res = smk(
        "reports/ci/report.pdf",
        "-n",
        "--cores",
        "1",
        "--configfile",
        "config/ci.yaml",
        "--config",
        "job_server=false",
        cwd=work,
    )
    assert res.returncode == 0 and "Nothing to be done" in res.stdout, res.stdout[-3000:]
    res = smk(
        "reports/ci/report.pdf",
        "--cores",
        "1",
        "--configfile",
        "config/ci.yaml",
        "--config",
        "job_server=false",
        "n_train=[30]",
        cwd=work,
    )
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    assert set(re.findall(r"^localrule (\w+):", out, re.M)) == {"report_pdf"}, out[-3000:]
    page1 = subprocess.run(
        ["pdftotext", "-f", "1", "-l", "1", str(work / "reports" / "ci" / "report.pdf"), "-"],
        capture_output=True,
        text=True,
    ).stdout
    flat = " ".join(page1.split())
    assert "config/ci.yaml (in the order they apply), then --config 'n_train=[30]'" in flat, flat
    assert "job_server" not in flat


def test_ci_rerun_is_a_no_op(ci_run):
    res = smk(
        "reports/ci/report.pdf", "-n", "--cores", "2", "--configfile", "config/ci.yaml", cwd=ci_run
    )
    assert res.returncode == 0 and "Nothing to be done" in res.stdout, res.stdout[-3000:]


@pytest.mark.slow
def test_two_studies_run_at_once_in_one_working_tree(ci_run):
    """With the shared features built (the ci run built those of hsc/golf), the CI-scale ablation runs while the
    ci study redoes its aggregate and report: Snakemake's directory lock admits both runs (before, both wrote
    reports/tables, reports/figures and reports/report.pdf, and the second stopped with LockException), both
    finish, each report is its own, and the ci tables come out unchanged."""
    tables = {p.name: p.read_text() for p in (ci_run / "reports" / "ci" / "tables").glob("*.tex")}
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    runs = {
        "ablation-ci": ["--configfile", "config/ablation.yaml", "config/ablation-ci.yaml"],
        "ci": ["--configfile", "config/ci.yaml", "--forcerun", "aggregate"],
    }
    procs = {
        study: subprocess.Popen(
            [SNAKEMAKE, f"reports/{study}/report.pdf", "--cores", "1", *args],
            cwd=ci_run,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
        )
        for study, args in runs.items()
    }
    outs = {study: p.communicate(timeout=900)[0] for study, p in procs.items()}
    for study, p in procs.items():
        assert p.returncode == 0, f"{study}:\n" + outs[study][-4000:]
        assert "LockException" not in outs[study]
    assert re.search(r"^localrule aggregate:", outs["ci"], re.M)  # the ci run did redo its report
    pdfs = [(ci_run / "reports" / study / "report.pdf").read_bytes() for study in runs]
    assert all(pdf[:5] == b"%PDF-" for pdf in pdfs) and pdfs[0] != pdfs[1]
    assert {
        p.name: p.read_text() for p in (ci_run / "reports" / "ci" / "tables").glob("*.tex")
    } == tables


@pytest.mark.slow
def test_ci_tables_are_identical_when_everything_is_recomputed(ci_run):
    before = {p.name: p.read_text() for p in (ci_run / "reports" / "ci" / "tables").glob("*.tex")}
    for d in (
        "results/ci/fit",
        "results/ci/cv",
        "results/ci/aggregate",
        "reports/ci/tables",
        "reports/ci/figures",
    ):
        shutil.rmtree(ci_run / d)
    (ci_run / "reports" / "ci" / "report.pdf").unlink()
    res = smk(
        "reports/ci/report.pdf",
        "--cores",
        "2",
        "--configfile",
        "config/ci.yaml",
        cwd=ci_run,
        timeout=900,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    after = {p.name: p.read_text() for p in (ci_run / "reports" / "ci" / "tables").glob("*.tex")}
    assert after == before
