"""The ablation workflow (config/ablation.yaml): dry-run job counts, and the CI-scale ablation
(config/ablation-ci.yaml: 2 chains per split) run end to end in a copy of the working tree: chain jobs, pooled
rows with R-hat and ESS in the aggregate, the convergence table, the trace and g_xy figures and the section
"Why PM trails the paper here" in the PDF; the published-table script on its aggregate."""

import json
import re
import shutil
import subprocess

import numpy as np
import pandas as pd
import pytest
from test_workflow import copy_tree, smk

from bsrbench.reporting.published import main as published_main
from bsrbench.runs import chain_seed

ABLATION = ("--configfile", "config/ablation.yaml", "config/ablation-ci.yaml")


@pytest.mark.slow  # a DAG of about 1,500 jobs
def test_ablation_dry_run_counts_one_job_per_split(tmp_path):
    res = smk("-n", "--cores", "2", "--configfile", "config/ablation.yaml", cwd=copy_tree(tmp_path))
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    counts = dict(re.findall(r"^(\w+)\s+(\d+)$", out, re.M))
    variants = 23  # PM variants in config/ablation.yaml
    cells = 4 * 3  # hsc activities x N
    splits = cells * 5  # x seeds
    assert int(counts["fit_chains"]) == variants * splits  # a job of its 4 chains per split
    assert int(counts["pool_chains"]) == variants * splits and "fit_chain" not in counts
    assert int(counts["fit"]) == 3 * cells  # 1-NN, TGP, SR: one job of the 5 seeds per cell
    assert (
        "seed100" in out and "seed0." not in out
    )  # splits disjoint from the paper protocol's seeds 0-9


@pytest.mark.slow  # a DAG of about 1,800 jobs
def test_goal_overlay_runs_the_chosen_variants_on_the_paper_protocols_splits(tmp_path):
    """config/paper-goal.yaml tests variants chosen on seeds 100-104 on the paper protocol's seeds 0-9."""
    res = smk(
        "-n",
        "--cores",
        "2",
        "--configfile",
        "config/ablation.yaml",
        "config/paper-goal.yaml",
        cwd=copy_tree(tmp_path),
    )
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    counts = dict(re.findall(r"^(\w+)\s+(\d+)$", out, re.M))
    cells = 4 * 4  # hsc activities x N
    splits = cells * 10  # x seeds
    assert int(counts["fit_chains"]) == int(counts["pool_chains"]) == 2 * splits
    assert int(counts["fit"]) == cells  # 1-NN: one job of the 10 seeds per cell
    assert "results/paper-goal/fit/random/hsc/" in out and "seed9" in out and "seed100" not in out


@pytest.mark.slow  # two runs of the CI-scale ablation
def test_a_job_per_chain_and_a_job_per_split_give_the_same_chains_and_rows(tmp_path):
    """seeds_per_job 1 (a job per chain, one that pools) and the default (one job per split) on the same machine:
    the chain files, the rows and the pooled predictions equal but for their timings."""
    runs = {}
    for k in ("1", "null"):
        (tmp_path / k).mkdir()
        work = copy_tree(tmp_path / k)
        res = smk("results/ablation-ci/aggregate/results.csv", "--cores", "2", *ABLATION,
                  "--config", f"seeds_per_job={k}", cwd=work, timeout=900)  # fmt: skip
        assert res.returncode == 0, (res.stdout + res.stderr)[-4000:]
        runs[k] = work / "results" / "ablation-ci" / "fit"
    a, b = runs["1"], runs["null"]
    chains = sorted(p.relative_to(a) for p in a.rglob("chain*.npz"))
    assert len(chains) == 3 * 2  # 3 PM variants x 2 chains
    timing = ("fit_seconds", "predict_seconds", "cv_seconds", "written_at")

    def untimed(path):
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files if k not in timing}

    for rel in chains:
        ca, cb = untimed(a / rel), untimed(b / rel)
        assert ca.keys() == cb.keys() and "trace_g_xy" in ca, rel
        for key in ca:
            np.testing.assert_array_equal(ca[key], cb[key], err_msg=f"{rel}: {key}")
    rows = sorted(p.relative_to(a) for p in a.rglob("seed*.json"))
    assert len(rows) == 5
    for rel in rows:
        ra, rb = (json.loads((d / rel).read_text()) for d in (a, b))
        assert {k: v for k, v in ra.items() if k not in timing} == {
            k: v for k, v in rb.items() if k not in timing
        }, rel
        pa, pb = untimed(a / rel.with_suffix(".npz")), untimed(b / rel.with_suffix(".npz"))
        assert pa.keys() == pb.keys() and "y_pred" in pa, rel
        for key in pa:
            np.testing.assert_array_equal(pa[key], pb[key], err_msg=f"{rel}: {key}")


@pytest.fixture(scope="module")
def ablation_run(tmp_path_factory):
    work = copy_tree(tmp_path_factory.mktemp("ablation"))
    res = smk("reports/ablation-ci/report.pdf", "--cores", "2", *ABLATION, cwd=work, timeout=900)
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return work


def test_chains_are_pooled_into_one_row_with_rhat_and_ess(ablation_run):
    df = pd.read_csv(ablation_run / "results" / "ablation-ci" / "aggregate" / "results.csv")
    assert len(df) == 5 and set(df["seed"]) == {100}
    pm = df[df["method"].isin(["PM", "PMK16", "PMj3"])]
    assert (pm["n_chains"] == 2).all()
    for col in (
        "r_hat_log_likelihood",
        "r_hat_g_xy",
        "r_hat_g_s",
        "ess_bulk_log_likelihood",
        "ess_bulk_g_xy",
    ):
        assert pm[col].notna().all() and (pm[col] > 0).all(), col
    assert df.loc[df["method"].isin(["NN1", "Ridge"]), "r_hat_g_xy"].isna().all()
    row = pm[pm["method"] == "PM"].iloc[0]
    seeds = json.loads(row["chain_seeds"])
    assert seeds == [chain_seed(int(row["method_seed"]), c) for c in range(2)]
    d = (
        ablation_run
        / "results"
        / "ablation-ci"
        / "fit"
        / "contiguous"
        / "hsc"
        / "golf"
        / "PM"
        / "n30"
    )
    chains = [np.load(d / "seed100" / f"chain{c}.npz") for c in range(2)]
    pooled = np.load(d / "seed100.npz")
    np.testing.assert_array_equal(pooled["chain_trace_g_xy"][1], chains[1]["trace_g_xy"])
    assert pooled["chain_trace_log_likelihood"].shape == (2, 40)


def test_a_changed_chain_count_reruns_the_splits_chains_and_pooling(ablation_run):
    """PM from 2 to 3 chains after a finished run: its chain job (the new chain file is missing, and the pooling
    reads it) and its pooling rerun; the other variants and methods do not. The dry run writes nothing."""
    overlay = ablation_run / "three_chains.yaml"
    overlay.write_text("methods: {PM: {chains: 3}}\n")
    res = smk("results/ablation-ci/aggregate/results.csv", "-n", "--cores", "2", *ABLATION, str(overlay),
              cwd=ablation_run)  # fmt: skip
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    counts = dict(re.findall(r"^(\w+)\s+(\d+)$", out, re.M))
    assert counts == {"fit_chains3": "1", "pool_chains": "1", "aggregate": "1", "total": "3"}, (
        counts
    )
    assert (
        "wildcards: protocol=contiguous, source=hsc, activity=golf, method=PM, n_train=30, seed=100"
        in out
    )
    overlay.unlink()


def test_report_has_the_convergence_table_and_the_section(ablation_run):
    tex = (ablation_run / "reports" / "ablation-ci" / "tables" / "why_pm.tex").read_text()
    # the contiguous protocol only: no comparison with the paper's random-frame PM, so no claim that PM trails it
    assert r"\section{PM's convergence and variants}\label{sec:why-pm}" in tex
    assert re.search(r"^PM & 30 & 1 & 2 & \d\.\d\d & \d\.\d\d", tex, re.M), tex
    assert "beats 1-NN in" in tex and "figures/trace.pdf" in tex and "figures/gxy.pdf" in tex
    conv = pd.read_csv(ablation_run / "reports" / "ablation-ci" / "tables" / "convergence.csv")
    assert set(conv["method"]) == {"PM", "PMK16", "PMj3"} and (conv["chains"] == 2).all()
    # Tables I-II keep the reference variant PM and the other methods; the variants are in the ablation table.
    # (Table I: golf is its only activity; Table II, without a studied activity, is not built.)
    assert not (ablation_run / "reports" / "ablation-ci" / "tables" / "tableII_hsc.tex").exists()
    table1 = (ablation_run / "reports" / "ablation-ci" / "tables" / "tableI_hsc.tex").read_text()
    header = next(ln for ln in table1.splitlines() if ln.startswith("Activity"))
    assert "PM" in header and "1-NN" in header and "Ridge" in header, header
    assert "K=16" not in header and "j=3" not in header, header
    assert "K=16" in tex and "j=3" in tex
    # captions and sentences say what this study drew and ran: two g_xy panels (PM, PMK16), the contiguous
    # protocol only (no comparison with the paper's random-frame PM; calibration on the contiguous protocol)
    assert "the 2 methods of" in tex and "proper Gamma" not in tex, tex
    assert "this study ran only the contiguous protocol" in tex and "against the paper's" not in tex
    body = (ablation_run / "reports" / "ablation-ci" / "tables" / "body.tex").read_text()
    assert (
        "(contiguous protocol, as named in the panel titles; this study did not run the random one)"
        in body
    )
    assert (
        "Filled markers: this study (dashed lines: contiguous protocol)" in body
        and "solid lines" not in body
    )
    # no variant differs from PM in a mechanism option only: no section "Do the paper's reasons hold?"
    mech = (ablation_run / "reports" / "ablation-ci" / "tables" / "mechanisms.tex").read_text()
    assert r"\section" not in mech
    pdf = ablation_run / "reports" / "ablation-ci" / "report.pdf"
    if shutil.which("pdftotext"):
        text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True).stdout
        assert "convergence and variants" in text and "Convergence" in text
        assert "reasons hold" not in text


def test_published_table_and_readme_tables_from_the_aggregate(ablation_run, tmp_path):
    agg = ablation_run / "results" / "ablation-ci" / "aggregate" / "results.csv"
    dest = tmp_path / "published" / "ablation-ci.csv"  # named after the study (publish checks)
    dest.parent.mkdir()  # publish writes into an existing folder only
    assert published_main(["publish", str(agg), str(dest)]) == 0
    pub = pd.read_csv(dest)
    assert len(pub) == 5 and "r_hat_test_error" in pub.columns
    readme = tmp_path / "README.md"
    readme.write_text(
        "intro\n<!-- results-table:hsc -->\nSTALE TABLE\n<!-- /results-table:hsc -->\nend\n"
    )
    # the README shows the paper protocol's tables: another study's table does not replace them (it did, silently)
    assert (
        published_main(["readme", str(dest), "--protocol", "contiguous", "--update", str(readme)])
        == 2
    )
    assert "STALE TABLE" in readme.read_text()
    as_paper = (
        tmp_path / "published" / "paper.csv"
    )  # the mechanics, on this table as if it were the paper's
    pub.assign(protocol="random").to_csv(as_paper, index=False)
    assert (
        published_main(
            ["readme", str(as_paper), "--protocol", "contiguous", "--update", str(readme)]
        )
        == 2
    )
    assert published_main(["readme", str(as_paper), "--update", str(readme)]) == 0
    text = readme.read_text()
    assert "STALE TABLE" not in text and text.startswith("intro\n") and text.endswith("end\n")
    row = next(ln for ln in text.splitlines() if ln.startswith("| golf | 30 |"))
    errors = pub.set_index("method")["error"]
    best = errors.idxmin()
    assert f"**{errors[best]:.2f}**" in row and row.count("**") == 2
    assert (
        published_main(["readme", str(dest), "--protocol", "random"]) == 2
    )  # no such rows: a clear error
