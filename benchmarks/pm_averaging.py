"""Posterior averaging, separated: within one chain, and across chains, beside a point-estimate control.

The paper's second reason for PM's advantage is that averaging over posterior samples makes it robust to
overfitting. On the splits of the fair-budget PM on the paper protocol (``config/paper-pmfair.yaml``) this
script computes, from the same draws:

- **1 chain x 1 draw**: the test error of a prediction from one posterior draw (each chain's ``draw_error``; the
  mean over all retained draws is the expected error of a one-draw prediction);
- **1 chain x D draws**: the error of one chain's predictive mean (mean over the chains of each one's error);
- **4 chains x D draws**: the error of the pooled predictive mean;
- the **point-estimate control**: SR, the paper's non-Bayesian sparse representation (one coupled dictionary pair,
  codes by l1-penalised least squares), on the same splits from ``reports/published/paper.csv``.

Within-chain averaging is the step 1 draw -> D draws; cross-chain pooling the step 1 chain -> 4 chains. Each step
is tested on these frames (paired t-test and Wilcoxon over the splits of each N), on all splits and on the
converged ones (split R-hat of the test error across the 4 chains at most 1.01).

Two regimes:

- the study's chains (default): the chain files of results/paper-pmfair/ (D = 25: each chain's last 25 retained
  samples, 1200 sweeps); the pooled error is checked against each published row;
- ``--long``: chains ten times longer (:data:`LONG`: 12000 sweeps, 7000 burn-in, every 100th kept, D = 50), fitted
  here by the study's own :func:`bsrbench.runs.run_chain` with each split's published settings (K, j and b_xy as
  CV chose them on training data), one chain per process on 2 processes, for the N and seeds asked for. Chain
  files go to results/pm-averaging-long/ and are reused: an interrupted run resumes.

Run from the repository root after the fair-budget study (results/paper-pmfair/, results/features/):
  .venv/bin/python benchmarks/pm_averaging.py [--write]
  .venv/bin/python benchmarks/pm_averaging.py --long --n 30 200 --seeds 5 [--write]
Seconds for the study's chains; the long chains of 2 x 20 splits take about 20 minutes. Writes
benchmarks/tables/pm_averaging.md (pm_averaging_long.md with --long) with --write.
"""

import argparse
import json
import os
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
from scipy import stats

from bsrbench.io import load_features, read_npz, write_arrays
from bsrbench.metrics import mean_angle_error
from bsrbench.poses import get_pose_transform
from bsrbench.reporting.tables import read_results

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "results" / "paper-pmfair"
LONG_DIR = ROOT / "results" / "pm-averaging-long"
PUBLISHED = ROOT / "reports" / "published"
TABLES = ROOT / "benchmarks" / "tables"
# The long regime: 10 times the study's sweeps; the 50 retained samples all averaged.
LONG = {"n_iter": 12000, "n_burn_in": 7000, "thin": 100, "n_predict_samples": 50}


def rows_for(draws, chains=4):
    return [
        "1 chain x 1 draw",
        f"1 chain x {draws} draws",
        f"{chains} chains x {draws} draws",
        "SR (point estimate)",
    ]


def _features(source, activity):
    return load_features(ROOT / "results" / "features" / source / f"{activity}.npz")


def _spec(r):
    from bsrbench.splits import JobSpec

    return JobSpec(
        r.source, r.activity, r.method, int(r.n_train), int(r.seed), r.protocol, r.pose_transform
    )


def _chain_dir(r, long):
    if long:
        return LONG_DIR / r.source / r.activity / f"n{r.n_train}" / f"seed{r.seed}"
    return (
        STUDY
        / "fit"
        / r.protocol
        / r.source
        / r.activity
        / r.method
        / f"n{r.n_train}"
        / f"seed{r.seed}"
    )


def _fit_long(r, chain):
    """Fit chain ``chain`` of row ``r``'s split with the long budget; write its chain file (once)."""
    from bsrbench.runs import run_chain

    r = SimpleNamespace(**r)
    path = _chain_dir(r, True) / f"chain{chain}.npz"
    params = {**json.loads(r.params), **LONG}
    made_with = json.dumps({"estimator": r.estimator, "params": params}, sort_keys=True)
    if path.exists() and str(read_npz(path).get("made_with", "")) == made_with:
        return path  # fitted before with these settings: reused (a changed setting refits)
    out = run_chain(
        _spec(r), _features(r.source, r.activity), estimator=r.estimator, params=params, chain=chain
    )
    out["made_with"] = np.array(made_with)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_arrays(path, out)
    return path


def fit_long(fair):
    """The long chains of every row of ``fair``, one chain per process, 2 processes (single-threaded each)."""
    os.environ["NUMBA_NUM_THREADS"] = "1"
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"
    missing = sorted(
        {
            str(ROOT / "results" / "features" / r.source / f"{r.activity}.npz")
            for r in fair.itertuples()
        }
        - {str(p) for p in (ROOT / "results" / "features").glob("*/*.npz")}
    )
    if missing:
        raise SystemExit(
            f"{missing[0]}: features file does not exist ({len(missing)} missing); expected the features of the "
            "fair-budget study: run it first (config/paper-pmfair.yaml's header)"
        )
    tasks = [(r, c) for r in fair.to_dict("records") for c in range(int(r["n_chains"]))]
    with ProcessPoolExecutor(max_workers=2, mp_context=get_context("spawn")) as pool:
        for k, path in enumerate(pool.map(_fit_long, *zip(*tasks)), 1):
            print(f"{k}/{len(tasks)} {path.relative_to(ROOT)}", flush=True)


def split_errors(fair, paper, long=False):
    """One row per split: the three averaging levels, the control, and the split's R-hat of the test error."""
    from bsrbench.convergence import convergence_summary

    out = []
    for r in fair.itertuples():
        d = _chain_dir(r, long)
        chains = [read_npz(p) for p in sorted(d.glob("chain*.npz"))]
        if len(chains) != int(r.n_chains):
            raise SystemExit(
                f"{d}: {len(chains)} chain files, the published row says {r.n_chains}; expected the chain files "
                f"of {'this script --long' if long else 'the fair-budget study (config/paper-pmfair.yaml)'}: "
                "run it first"
            )
        feats = _features(r.source, r.activity)
        transform = get_pose_transform(r.pose_transform, column=feats.get("heading_column", 2))
        Y = feats["Y"][chains[0]["test"]]
        means = [np.asarray(c["z_mean"], dtype=float) for c in chains]
        pooled = mean_angle_error(Y, transform.inverse(np.mean(means, axis=0)))
        if not long and abs(pooled - r.error) > 1e-6 + 1e-4 * abs(r.error):
            raise SystemExit(f"{d}: pooled error {pooled} is not the row's {r.error}")
        sr = paper[
            (paper["method"] == "SR")
            & (paper["protocol"] == r.protocol)
            & (paper["source"] == r.source)
            & (paper["activity"] == r.activity)
            & (paper["n_train"] == r.n_train)
            & (paper["seed"] == r.seed)
        ]["error"]
        out.append(
            {
                "activity": r.activity,
                "n_train": r.n_train,
                "seed": r.seed,
                "draws": np.size(chains[0]["draw_error"]),
                "chains": len(chains),
                "1 chain x 1 draw": float(np.mean([c["draw_error"] for c in chains])),
                "1 chain x D draws": float(
                    np.mean([mean_angle_error(Y, transform.inverse(m)) for m in means])
                ),
                "chains x D draws": pooled,
                "SR (point estimate)": float(sr.iloc[0]) if len(sr) else np.nan,
                "r_hat": convergence_summary(chains)["r_hat_test_error"]
                if long
                else r.r_hat_test_error,
                "study_error": r.error,
                "study_r_hat": r.r_hat_test_error,
            }
        )
    return pd.DataFrame(out)


COLUMNS = ["1 chain x 1 draw", "1 chain x D draws", "chains x D draws", "SR (point estimate)"]


def _test(a, b):
    """Mean of a - b, paired t-test p and Wilcoxon p over the splits."""
    d = np.asarray(a) - np.asarray(b)
    if len(d) < 2:
        return np.nan, np.nan, np.nan
    t = stats.ttest_rel(a, b).pvalue
    w = stats.wilcoxon(a, b).pvalue if np.any(d != 0) else 1.0
    return float(d.mean()), float(t), float(w)


def table(e, title):
    draws, chains = int(e["draws"].iloc[0]), int(e["chains"].iloc[0])
    labels = rows_for(draws, chains)
    lines = [
        f"{title}",
        "",
        "| N | splits | "
        + " | ".join(labels)
        + f" | {draws} draws - 1 draw (t p, W p) | {chains} chains - 1 chain (t p, W p) |",
        "|---:|---:|" + "---:|" * (len(labels) + 2),
    ]
    for n, g in e.groupby("n_train"):
        cols = [f"{g[c].mean():.2f}" for c in COLUMNS]
        steps = []
        for hi, lo in ((COLUMNS[1], COLUMNS[0]), (COLUMNS[2], COLUMNS[1])):
            m, t, w = _test(g[hi], g[lo])
            steps.append(f"{m:+.2f} ({t:.2g}, {w:.2g})" if np.isfinite(m) else "--")
        lines.append(f"| {n} | {len(g)} | " + " | ".join(cols) + " | " + " | ".join(steps) + " |")
    return lines


def _r_hat_lines(e):
    lines = [
        "Split R-hat of the test error across the chains, per N: median, largest, and the splits at most 1.01",
        "",
        "| N | splits | median | max | <= 1.01 |",
        "|---:|---:|---:|---:|---:|",
    ]
    for n, g in e.groupby("n_train"):
        lines.append(
            f"| {n} | {len(g)} | {g['r_hat'].median():.3f} | {g['r_hat'].max():.3f} | "
            f"{int((g['r_hat'] <= 1.01).sum())} |"
        )
    return lines


def _against_study_lines(e):
    """The long chains against the study's (the published rows of the same splits): pooled error and R-hat."""
    lines = [
        "Against the study's chains of the same splits (1200 sweeps, 4 chains x 25 draws; the published rows)",
        "",
        "| N | splits | pooled error, study | pooled error, long | long - study (t p, W p) | R-hat median, study "
        "| R-hat median, long | <= 1.01, study | <= 1.01, long |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for n, g in e.groupby("n_train"):
        m, t, w = _test(g["chains x D draws"], g["study_error"])
        lines.append(
            f"| {n} | {len(g)} | {g['study_error'].mean():.2f} | {g['chains x D draws'].mean():.2f} "
            f"| {m:+.2f} ({t:.2g}, {w:.2g}) | {g['study_r_hat'].median():.3f} | {g['r_hat'].median():.3f} "
            f"| {int((g['study_r_hat'] <= 1.01).sum())} | {int((g['r_hat'] <= 1.01).sum())} |"
        )
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--long", action="store_true", help="fit and use chains 10 times longer (LONG)")
    ap.add_argument("--n", type=int, nargs="+", help="--long: training sizes (default: 30 200)")
    ap.add_argument("--seeds", type=int, help="--long: seeds 0..SEEDS-1 (default 5)")
    ap.add_argument("--write", action="store_true", help="write the table to benchmarks/tables/")
    args = ap.parse_args(argv)
    fair = read_results(PUBLISHED / "paper-pmfair.csv")
    fair = fair[fair["source"] == "hsc"]
    paper = read_results(PUBLISHED / "paper.csv")
    if not args.long and (args.n is not None or args.seeds is not None):
        ap.error(
            "--n and --seeds choose the splits of --long; the study's chains are read for every split"
        )
    if args.long:
        sizes, seeds = args.n or [30, 200], 5 if args.seeds is None else args.seeds
        fair = fair[fair["n_train"].isin(sizes) & (fair["seed"] < seeds)]
        if fair.empty:
            ap.error(
                f"--n {' '.join(map(str, sizes))} --seeds {seeds} selects no split of the fair-budget table; "
                f"expected N among {sorted(set(read_results(PUBLISHED / 'paper-pmfair.csv')['n_train']))} and "
                "--seeds of at least 1"
            )
        fit_long(fair)
    e = split_errors(fair, paper, long=args.long)
    conv = e[e["r_hat"] <= 1.01]
    name = "pm_averaging_long" if args.long else "pm_averaging"
    lines = [
        f"# Posterior averaging, within and across chains (benchmarks/pm_averaging.py{' --long' * args.long})",
        "",
    ]
    n_seeds = e["seed"].nunique()
    lines += table(
        e,
        f"All splits: means over the 4 hsc activities x {n_seeds} seeds of the paper protocol (degrees)",
    )
    lines += [""]
    if len(conv):
        lines += table(
            conv,
            f"Converged splits only (split R-hat of the test error <= 1.01: {len(conv)} of {len(e)}); means "
            "(degrees)",
        )
    else:
        lines += [f"No split converged (split R-hat of the test error <= 1.01: 0 of {len(e)})."]
    lines += [""] + _r_hat_lines(e) + [""]
    if args.long:
        lines += _against_study_lines(e) + [""]
    budget = (
        f"chains of {LONG['n_iter']} sweeps ({LONG['n_burn_in']} burn-in, every {LONG['thin']}th kept), fitted by "
        "this script with each split's published settings (K, j and b_xy as CV chose them), "
        "the study's splits and chain seeds"
        if args.long
        else "its chain files (1200 sweeps, 700 burn-in); the pooled predictive mean is the published row's "
        "error, checked to 1e-4"
    )
    lines += [
        f"PM with a fair budget (config/paper-pmfair.yaml), {budget}. 1 chain x 1 draw: the mean over the "
        "retained draws of the test error of a one-draw prediction; 1 chain x D draws: the mean over the "
        "chains of the error of one chain's predictive mean; 4 chains x D draws: the pooled predictive mean. "
        "SR: the point-estimate control on the same splits (reports/published/paper.csv). Steps: mean "
        "difference in degrees (negative: averaging helps), paired t-test and Wilcoxon signed-rank p over the "
        "splits of the N, on these frames.",
    ]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        (TABLES / f"{name}.md").write_text(text)


if __name__ == "__main__":
    main()
