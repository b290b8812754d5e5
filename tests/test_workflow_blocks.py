"""Fit and CV jobs per block of seeds (config key seeds_per_job): the same per-seed jobs and results as one job per
seed, a failing seed named, the job counts of the paper protocol (docs/performance.md, "Job granularity")."""

import json
import re
import shlex
from pathlib import Path

import pytest
import yaml
from test_workflow import ROOT, copy_tree, smk

SPLIT = "results/ci/{kind}/random/hsc/golf/{method}/n30/seed{seed}.{ext}"


def seed_jobs(out):
    """{output file: (target, job spec, settings)} of the fit, chain, pooling and CV commands of a dry run with -p,
    one entry per step: a block job's command carries the spec of each of its steps (a seed, or a chain of a
    split). A step's spec is its one-step job's but the ``code`` inputs (:func:`bsrbench.jobserver._step_input`),
    which are left out here for both."""
    found = {}
    for line in out.splitlines():
        if "-m bsrbench.jobserver job" not in line:
            continue
        args = shlex.split(line[line.index("python -") :])
        target = args[args.index("bsrbench.jobserver") + 2]
        spec = json.loads(args[args.index("--log") + 2])
        settings = args[args.index("--settings") + 1]
        for one in spec.get("block", [spec]):
            one["input"].pop("code", None)
            out_file = (
                one["output"].get("row") or one["output"].get("json") or one["output"]["chain"]
            )
            found[out_file] = (target, json.dumps(one, sort_keys=True), settings)
    return found


def job_counts(out):
    return {k: int(v) for k, v in re.findall(r"^(\w+)\s+(\d+)$", out, re.M)}


def test_a_block_job_runs_each_seed_with_the_job_spec_of_its_one_seed_job(tmp_path):
    """The dry runs of config/ci.yaml with seeds_per_job 1 (one job per seed) and the default (one job per cell
    and method) plan the same per-seed jobs, spec for spec (input, output, wildcards, settings)."""
    work = copy_tree(tmp_path)
    runs = {}
    for k in ("1", "null"):
        res = smk("-n", "-p", "--cores", "2", "--configfile", "config/ci.yaml",
                  "--config", f"seeds_per_job={k}", cwd=work)  # fmt: skip
        out = res.stdout + res.stderr
        assert res.returncode == 0, out[-3000:]
        runs[k] = (seed_jobs(out), job_counts(out))
    (per_seed, n1), (blocks, n_default) = runs["1"], runs["null"]
    config = yaml.safe_load((ROOT / "config" / "ci.yaml").read_text())
    n_seeds, methods = config["n_seeds"], len(config["run"])
    assert n1["fit"] == n_seeds * methods and n_default["fit"] == methods
    assert n1["cv"] == n_default["cv"]  # per_size: one CV per cell and method either way
    assert len(per_seed) == n_seeds * methods + n1["cv"]
    assert per_seed == blocks


def test_a_chains_job_runs_each_chain_with_the_spec_of_its_one_chain_job(tmp_path):
    """The dry runs of the CI-scale ablation (2 chains per split) with seeds_per_job 1 (rule fit_chain: a job per
    chain) and the default (rule fit_chains: one job per split) plan the same chain steps, spec for spec (target,
    input, output, wildcards, settings), and the same pooling jobs; no block command carries the code paths."""
    work = copy_tree(tmp_path)
    runs = {}
    for k in ("1", "null"):
        res = smk("-n", "-p", "--cores", "2", "--configfile", "config/ablation.yaml", "config/ablation-ci.yaml",
                  "--config", f"seeds_per_job={k}", cwd=work)  # fmt: skip
        out = res.stdout + res.stderr
        assert res.returncode == 0, out[-3000:]
        runs[k] = (seed_jobs(out), job_counts(out), out)
    (per_step, n1, _), (blocks, n_default, out) = runs["1"], runs["null"]
    splits = n_default["fit_chains"]
    assert splits == n_default["pool_chains"] == n1["pool_chains"] and n1["fit_chain"] == 2 * splits
    assert "fit_chain" not in n_default
    chain_steps = [
        f for f, (target, _, _) in per_step.items() if target == "bsrbench.jobs:fit_chain"
    ]
    assert len(chain_steps) == 2 * splits
    assert per_step == blocks
    commands = [ln for ln in out.splitlines() if "bsrbench.jobs:fit_chain" in ln]
    assert len(commands) == splits and not any("bsrbench/runs.py" in ln for ln in commands)


@pytest.mark.slow  # two runs of config/ci.yaml
def test_one_job_per_seed_and_the_default_blocks_give_the_same_rows_and_tables(tmp_path):
    import pandas as pd

    outputs = {}
    for k in ("1", "null"):
        (tmp_path / k).mkdir()
        work = copy_tree(tmp_path / k)
        res = smk("reports/ci/report.pdf", "--cores", "2", "--configfile", "config/ci.yaml",
                  "--config", f"seeds_per_job={k}", cwd=work, timeout=900)  # fmt: skip
        assert res.returncode == 0, (res.stdout + res.stderr)[-4000:]
        outputs[k] = work
    a, b = outputs["1"], outputs["null"]
    rows = sorted(p.relative_to(a) for p in (a / "results" / "ci" / "fit").rglob("seed*.json"))
    assert len(rows) == 18  # 9 methods x 2 seeds
    timing = ("fit_seconds", "predict_seconds", "cv_seconds", "written_at")
    for path in rows:
        ra, rb = (json.loads((w / path).read_text()) for w in (a, b))
        assert {k: v for k, v in ra.items() if k not in timing} == {
            k: v for k, v in rb.items() if k not in timing
        }, path
        npz = path.with_suffix(".npz")
        assert (a / npz).read_bytes() == (b / npz).read_bytes(), npz
    agg = [pd.read_csv(w / "results" / "ci" / "aggregate" / "results.csv") for w in (a, b)]
    cols = [c for c in agg[0].columns if c not in timing]
    pd.testing.assert_frame_equal(agg[0][cols], agg[1][cols])
    tables = [sorted((w / "reports" / "ci" / "tables").iterdir()) for w in (a, b)]
    assert [p.name for p in tables[0]] == [p.name for p in tables[1]]
    for pa, pb in zip(*tables):
        assert pa.read_bytes() == pb.read_bytes(), pa.name


def test_a_block_with_a_failing_seed_fails_naming_it_and_keeps_none_of_its_outputs(tmp_path):
    """Ridge with a CV per seed (cv.mode per_job): seed 1's CV result is made unreadable, so that the fit job of
    seeds 0-1 fails at seed 1 after seed 0 wrote its files; Snakemake then removes the block's outputs."""
    work = copy_tree(tmp_path)
    (work / "overlay.yaml").write_text("run: [Ridge]\ncv: {mode: per_job, folds: 2}\n")
    study = ("--cores", "1", "--configfile", "config/ci.yaml", "overlay.yaml")
    cv = [SPLIT.format(kind="cv", method="Ridge", seed=s, ext="json") for s in (0, 1)]
    res = smk(*cv, *study, cwd=work)
    assert res.returncode == 0, (res.stdout + res.stderr)[-3000:]
    out = res.stdout + res.stderr
    assert (
        re.search(r"^(local)?rule cv:", out, re.M) and job_counts(out)["cv"] == 1
    )  # one job, two seeds
    (work / cv[1]).write_text("not JSON")
    fits = [
        SPLIT.format(kind="fit", method="Ridge", seed=s, ext=e)
        for s in (0, 1)
        for e in ("json", "npz")
    ]
    res = smk(*fits[:1], *study, cwd=work)
    out = res.stdout + res.stderr
    assert res.returncode != 0
    assert "bsrbench.jobs:fit: seed 1 of the block of seeds 0-1 failed" in out, out[-3000:]
    assert "JSONDecodeError" in out, out[-3000:]
    assert [f for f in fits if (work / f).exists()] == []
    log = (
        work / "logs" / "ci" / "fit" / "random" / "hsc" / "golf" / "Ridge" / "n30" / "seeds0to1.log"
    )
    text = log.read_text()
    assert (
        text.index("--- seed 0 ---") < text.index("--- seed 1 ---") < text.index("JSONDecodeError")
    )


def test_the_paper_protocol_has_one_fit_job_per_cell_and_method(tmp_path):
    """config/paper.yaml's dry run: one fit job per (cell, method), each of its n_seeds seeds; one CV job per cell
    and method with a grid (cv.mode per_size). The cells and methods come from the aggregate's inputs (every
    per-seed result of the protocol), n_seeds from the config file."""
    res = smk("-n", "--cores", "2", "--configfile", "config/paper.yaml", cwd=copy_tree(tmp_path))
    out = res.stdout + res.stderr
    assert res.returncode == 0, out[-3000:]
    config = yaml.safe_load((ROOT / "config" / "paper.yaml").read_text())
    agg = re.search(r"^rule aggregate:\n\s+input: (.*)$", out, re.M).group(1).split(", ")
    rows = [Path(p) for p in agg]
    cell_methods = {p.parent for p in rows}
    cells = {(p.parts[-6], p.parts[-5], p.parts[-4], p.parts[-2]) for p in rows}
    assert len(rows) == len(cell_methods) * config["n_seeds"]
    assert len(cell_methods) == len(cells) * len(config["run"])
    cv_files = set(re.findall(r"output: (results/paper/cv/\S+\.json)", out))
    assert {Path(f).name for f in cv_files} == {"seed0.json"}  # per_size: the first seed's split
    counts = job_counts(out)
    assert counts["fit"] == len(cell_methods)
    assert counts["cv"] == len(cv_files)
    assert "fit_chain" not in counts  # chains: 1
    print(f"paper protocol: {counts['fit']} fit and {counts['cv']} CV jobs, {len(rows)} fits")
