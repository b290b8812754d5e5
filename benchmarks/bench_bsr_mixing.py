"""Mixing per second of the two dictionary updates of BayesianSR: block (all atoms jointly) against single
(one atom at a time), on the authors' acrobatics features.

For each K and seed: one chain of n_iter sweeps (elliptical slice sampling for the logits) on N training
frames; wall time of the fit; effective sample size (ArviZ, bulk) of the post-burn-in traces of the
log-likelihood and of g_xy; ESS per second; and the test error (mean over angles of the per-angle RMS, in
degrees) on the other frames. Results: benchmarks/results/bsr_mixing.csv (git-ignored).

Run from the repository root:  python benchmarks/bench_bsr_mixing.py [--quick]
"""

import os

for _var in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import time
from pathlib import Path

import arviz as az
import numpy as np
import pandas as pd
from scipy.io import loadmat

from bsrbench.io import atomic_path
from bsrbench.metrics import mean_angle_error
from bsrbench.models.bsr import BayesianSR

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one seed, fewer sweeps")
    ap.add_argument("--n-train", type=int, default=200)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bsr_mixing.csv"))
    args = ap.parse_args(argv)
    d = loadmat(ROOT / "resources" / "paper-features" / "x4921.mat")
    X, Y = d["X"][:600].astype(float), d["Y"][:600, 3:].astype(float)
    n_iter, n_burn = (600, 300) if args.quick else (1200, 700)
    seeds = (0,) if args.quick else (0, 1, 2)
    rows = []
    for K in (64, 256):
        for seed in seeds:
            perm = np.random.default_rng(100 + seed).permutation(len(X))
            tr, te = perm[: args.n_train], perm[args.n_train :]
            for au in ("block", "single"):
                m = BayesianSR(
                    n_atoms=K, n_iter=n_iter, n_burn_in=n_burn, atom_update=au, random_state=seed
                )
                t = time.perf_counter()
                m.fit(X[tr], Y[tr])
                fit_s = time.perf_counter() - t
                row = dict(K=K, seed=seed, atom_update=au, fit_seconds=fit_s)
                for name in ("log_likelihood", "g_xy"):
                    ess = float(az.ess(m.trace_[name][n_burn:][None, :]))
                    row[f"ess_{name}"] = ess
                    row[f"ess_per_s_{name}"] = ess / fit_s
                row["error_deg"] = float(mean_angle_error(Y[te], m.predict(X[te])))
                rows.append(row)
                print(
                    ", ".join(
                        f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in row.items()
                    ),
                    flush=True,
                )
    df = pd.DataFrame(rows)
    print(
        df.groupby(["K", "atom_update"])
        .median(numeric_only=True)
        .drop(columns="seed")
        .round(3)
        .to_string()
    )
    out = Path(args.out)
    with atomic_path(out) as tmp:
        df.to_csv(tmp, index=False)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
