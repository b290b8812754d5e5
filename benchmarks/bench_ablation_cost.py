"""Cost of config/ablation.yaml from a measured slice: CPU seconds of one chain job per PM variant and N.

For each PM variant of the ablation whose parameters this BayesianSR accepts, one chain (fit + prediction of
the test frames, i.e. the body of a fit_chain job) is run on the golf features, contiguous split of seed 100,
at the smallest and the largest N of the ablation, and its process CPU time measured (time.process_time, one
thread; not wall time, which on a shared machine depends on the other processes). N between them is
interpolated linearly; variants this BayesianSR does not know yet are costed as the base variant PM (same K
and sweeps). The estimate is the sum over the ablation's chain jobs (chains x activities x seeds per variant
and N, the counts of ``snakemake -n``) of these CPU seconds, divided by the cores; scheduling, the pool jobs,
the baselines and their CV come on top (the script prints the baselines' measured fit and CV times when a
slice of the workflow has been run, from results/ablation/fit/.../seed100.json and results/ablation/cv/.../seed100.json).

    snakemake --cores 1 results/features/hsc/golf.npz     # the features, once
    .venv/bin/python benchmarks/bench_ablation_cost.py [--cores 2] [--activity golf]
"""

import argparse
import inspect
import json
import time
from pathlib import Path

import numpy as np
import yaml
from threadpoolctl import threadpool_limits

from bsrbench.errors import InputError
from bsrbench.io import load_features
from bsrbench.models.bsr import BayesianSR
from bsrbench.runs import run_chain
from bsrbench.splits import JobSpec

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--activity", default="golf")
    args = ap.parse_args()
    cfg = yaml.safe_load((ROOT / "config" / "ablation.yaml").read_text())
    feats = load_features(ROOT / "results" / "features" / "hsc" / f"{args.activity}.npz")
    sizes = sorted(cfg["n_train"])
    lo, hi = sizes[0], sizes[-1]
    accepted = set(inspect.signature(BayesianSR).parameters)
    est = "bsrbench.models.bsr:BayesianSR"
    variants = [m for m in cfg["run"] if cfg["methods"][m]["estimator"] == est]
    n_act, n_seeds = len(cfg["study_activities"]["hsc"]), cfg["n_seeds"]
    cpu = {}
    print(f"{'variant':<12} {'N':>4} {'CPU s':>7}  (one chain: fit + prediction)")
    for m in variants:
        params = cfg["methods"][m]["params"]
        if not set(params) <= accepted:
            continue
        for n in (lo, hi):
            spec = JobSpec(
                "hsc", args.activity, m, n, cfg["seed_start"], protocol=cfg["protocols"][0]
            )
            with threadpool_limits(1):
                t0 = time.process_time()
                try:
                    run_chain(spec, feats, estimator=est, params=params, chain=0)
                except InputError as exc:  # an option value this BayesianSR does not know yet
                    print(f"{m:<12} {n:>4} skipped ({exc}); costed as {cfg['run'][0]}")
                    break
                cpu[m, n] = time.process_time() - t0
            print(f"{m:<12} {n:>4} {cpu[m, n]:7.2f}", flush=True)
    total, jobs = 0.0, 0
    for m in variants:
        src = m if (m, lo) in cpu and (m, hi) in cpu else cfg["run"][0]
        chains = cfg["methods"][m].get("chains", 1)
        for n in sizes:
            t = np.interp(n, [lo, hi], [cpu[src, lo], cpu[src, hi]])
            total += chains * n_act * n_seeds * t
            jobs += chains * n_act * n_seeds
    print(
        f"\n{jobs} chain jobs, {total / 3600:.1f} CPU hours: {total / 3600 / args.cores:.1f} h wall on "
        f"{args.cores} cores (chain jobs only)"
    )
    res = ROOT / "results" / cfg.get("study", "ablation")
    for m in [m for m in cfg["run"] if m not in variants]:
        for n in sizes:
            f = (
                res
                / "fit"
                / cfg["protocols"][0]
                / "hsc"
                / args.activity
                / m
                / f"n{n}"
                / "seed100.json"
            )
            c = (
                res
                / "cv"
                / cfg["protocols"][0]
                / "hsc"
                / args.activity
                / m
                / f"n{n}"
                / "seed100.json"
            )
            if f.is_file():
                row = json.loads(f.read_text())
                cv = json.loads(c.read_text())["cv_seconds"] if c.is_file() else None
                print(
                    f"{m} N={n}: fit {row['fit_seconds']:.2f} s, predict {row['predict_seconds']:.2f} s, "
                    f"CV {cv if cv is None else round(cv, 1)} s (wall, measured in the workflow)"
                )


if __name__ == "__main__":
    main()
