"""Posterior averaging, separated: within one chain, and across chains, beside a point-estimate control.

The paper's second reason for PM's advantage is that averaging over posterior samples makes it robust to
overfitting. This script reads the chain files of the fair-budget PM on the paper protocol
(``config/paper-pmfair.yaml``: 4 chains per split, each averaging its last 25 retained samples with 100
prediction sweeps) and computes, on the same splits and from the same draws:

- **1 chain x 1 draw**: the test error of a prediction from one posterior draw (each chain's ``draw_error``; the
  mean over the 4 x 25 draws is the expected error of a one-draw prediction);
- **1 chain x 25 draws**: the error of one chain's predictive mean (mean over the 4 chains of each one's error);
- **4 chains x 25 draws**: the error of the pooled predictive mean (the published row's ``error``: checked);
- the **point-estimate control**: SR, the paper's non-Bayesian sparse representation (one coupled dictionary pair,
  codes by l1-penalised least squares), on the same splits from ``reports/published/paper.csv``.

Within-chain averaging is the step 1 draw -> 25 draws; cross-chain pooling the step 1 chain -> 4 chains. Each step
is tested on these frames (paired t-test and Wilcoxon over the splits of each N), on all splits and on the
converged ones (split R-hat of the test error across the 4 chains at most 1.01).

Run from the repository root after the fair-budget study (results/paper-pmfair/):
  .venv/bin/python benchmarks/pm_averaging.py [--write]
Seconds; writes benchmarks/tables/pm_averaging.md with --write.
"""

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from bsrbench.io import load_features, read_npz
from bsrbench.metrics import mean_angle_error
from bsrbench.poses import get_pose_transform
from bsrbench.reporting.tables import read_results

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "results" / "paper-pmfair"
PUBLISHED = ROOT / "reports" / "published"
OUT = ROOT / "benchmarks" / "tables" / "pm_averaging.md"
ROWS = ["1 chain x 1 draw", "1 chain x 25 draws", "4 chains x 25 draws", "SR (point estimate)"]


def split_errors(fair, paper):
    """One row per split: the three averaging levels, the control, and the split's R-hat."""
    out = []
    for r in fair.itertuples():
        d = STUDY / "fit" / r.protocol / r.source / r.activity / r.method / f"n{r.n_train}"
        chains = [read_npz(p) for p in sorted((d / f"seed{r.seed}").glob("chain*.npz"))]
        if len(chains) != int(r.n_chains):
            raise SystemExit(
                f"{d}/seed{r.seed}: {len(chains)} chain files, the row says {r.n_chains}"
            )
        feats = load_features(ROOT / "results" / "features" / r.source / f"{r.activity}.npz")
        transform = get_pose_transform(r.pose_transform, column=feats.get("heading_column", 2))
        Y = feats["Y"][chains[0]["test"]]
        means = [np.asarray(c["z_mean"], dtype=float) for c in chains]
        pooled = mean_angle_error(Y, transform.inverse(np.mean(means, axis=0)))
        if abs(pooled - r.error) > 1e-6 + 1e-4 * abs(r.error):
            raise SystemExit(f"{d}/seed{r.seed}: pooled error {pooled} is not the row's {r.error}")
        sr = paper[
            (paper["method"] == "SR")
            & (paper["activity"] == r.activity)
            & (paper["n_train"] == r.n_train)
            & (paper["seed"] == r.seed)
        ]["error"]
        out.append(
            {
                "activity": r.activity,
                "n_train": r.n_train,
                "seed": r.seed,
                ROWS[0]: float(np.mean([c["draw_error"] for c in chains])),
                ROWS[1]: float(np.mean([mean_angle_error(Y, transform.inverse(m)) for m in means])),
                ROWS[2]: pooled,
                ROWS[3]: float(sr.iloc[0]) if len(sr) else np.nan,
                "r_hat": r.r_hat_test_error,
            }
        )
    return pd.DataFrame(out)


def _test(a, b):
    """Mean of a - b, paired t-test p and Wilcoxon p over the splits."""
    d = np.asarray(a) - np.asarray(b)
    if len(d) < 2:
        return np.nan, np.nan, np.nan
    t = stats.ttest_rel(a, b).pvalue
    w = stats.wilcoxon(a, b).pvalue if np.any(d != 0) else 1.0
    return float(d.mean()), float(t), float(w)


def table(e, title):
    lines = [
        f"{title}",
        "",
        "| N | splits | "
        + " | ".join(ROWS)
        + " | 25 draws - 1 draw (t p, W p) | 4 chains - 1 chain (t p, W p) |",
        "|---:|---:|" + "---:|" * (len(ROWS) + 2),
    ]
    for n, g in e.groupby("n_train"):
        cols = [f"{g[c].mean():.2f}" for c in ROWS]
        steps = []
        for hi, lo in ((ROWS[1], ROWS[0]), (ROWS[2], ROWS[1])):
            m, t, w = _test(g[hi], g[lo])
            steps.append(f"{m:+.2f} ({t:.2g}, {w:.2g})" if np.isfinite(m) else "--")
        lines.append(f"| {n} | {len(g)} | " + " | ".join(cols) + " | " + " | ".join(steps) + " |")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", action="store_true", help=f"write {OUT.relative_to(ROOT)}")
    args = ap.parse_args(argv)
    fair = read_results(PUBLISHED / "paper-pmfair.csv")
    paper = read_results(PUBLISHED / "paper.csv")
    e = split_errors(fair, paper)
    conv = e[e["r_hat"] <= 1.01]
    lines = ["# Posterior averaging, within and across chains (benchmarks/pm_averaging.py)", ""]
    lines += table(
        e, "All splits: means over the 4 hsc activities x 10 seeds of the paper protocol (degrees)"
    )
    lines += [""]
    lines += table(
        conv,
        f"Converged splits only (split R-hat of the test error <= 1.01: {len(conv)} of {len(e)}); means (degrees)",
    )
    lines += [
        "",
        "PM with a fair budget (config/paper-pmfair.yaml), its chain files. 1 chain x 1 draw: the mean over the "
        "4 x 25 retained draws of the test error of a one-draw prediction; 1 chain x 25 draws: the mean over the "
        "4 chains of the error of one chain's predictive mean; 4 chains x 25 draws: the pooled predictive mean "
        "(the published row's error, checked to 1e-4). SR: the point-estimate control on the same splits "
        "(reports/published/paper.csv). Steps: mean difference in degrees (negative: averaging helps), paired "
        "t-test and Wilcoxon signed-rank p over the splits of the N, on these frames.",
    ]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        OUT.write_text(text)


if __name__ == "__main__":
    main()
