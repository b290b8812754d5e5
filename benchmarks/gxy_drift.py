"""Does the noise precision g_xy of BayesianSR drift upward when the codes can interpolate the training pairs?

docs/pm-convergence.md derives why it should with K >= rank(V) and the paper's Gamma(1e-6, 1e-6) priors, and why it
should not with K < rank(V) or with a proper prior on g_xy. This script measures it on the authors' golf features
(source hsc, resources/paper-features/x63.mat read with the package's reader, the first 600 frames, root translation
dropped, heading as sin/cos as in the study), N = 30 training frames from the paper protocol's random split of seed 0,
and prints g_xy (and g_s, the number of active atoms, the training log-likelihood per entry) at a few sweeps of
independent chains for four settings:

  K = 64 (>= N) and K = 16 (< N), each with a0 = b0 = 1e-6 on every precision (the paper) and with a proper
  Gamma(1, 1) prior on g_xy alone (a_xy = b_xy = 1; the other precisions as in the paper); and K = 64 with proper
  Gamma(1, 1) priors on g_s, g_x, g_y but the paper's on g_xy.

It also prints the log-slope of the marginal likelihood in g_xy, c(g) = d log p(V | g) / d log g, estimated from
the chain by Fisher's identity c(g) = E[(NM - g ||R||^2) / 2 | V, g] (R = the residual, NM = number of entries;
g ||R||^2 is recovered from the traced log-likelihood): c -> 0 if p(V | g) tends to a constant (the claim of
docs/pm-convergence.md, section 2), c > 0 if it still grows. At stationarity E[b g] = a + E[c] (the
stationarity of log g under g^(a-1) e^(-b g) p(V | g)).

Run from the repository root:  python benchmarks/gxy_drift.py [--sweeps 2000] [--chains 3]
One chain per setting at a time on one core; about two minutes at the defaults. Nothing is written.
"""

import os

for _var in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import time
from pathlib import Path

import numpy as np

from bsrbench.datasets import load_feature_mat
from bsrbench.models.bsr import BayesianSR
from bsrbench.poses import get_pose_transform
from bsrbench.seeds import derive_seed, split_seed
from bsrbench.splits import make_split

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = [
    ("K=64, a=b=1e-6", dict(n_atoms=64)),
    ("K=64, g_xy~Gamma(1,1)", dict(n_atoms=64, a_xy=1.0, b_xy=1.0)),
    ("K=16, a=b=1e-6", dict(n_atoms=16)),
    ("K=16, g_xy~Gamma(1,1)", dict(n_atoms=16, a_xy=1.0, b_xy=1.0)),
    # proper priors on g_s, g_x, g_y, the paper's on g_xy: is the growth of p(V | g_xy) due to the other priors?
    ("K=64, others Gamma(1,1)", dict(n_atoms=64, a0=1.0, b0=1.0, a_xy=1e-6, b_xy=1e-6)),
    # the rate b of the prior on g_xy sets where the chain stops: g_xy ~ c / b
    ("K=64, b_xy=1e-4", dict(n_atoms=64, b_xy=1e-4)),
    ("K=64, b_xy=1e-8", dict(n_atoms=64, b_xy=1e-8)),
    # a sparsity-inducing logit prior mean: fewer active atoms K_act, so by the power counting of the docs a
    # larger exponent c = (M - K_act) / 2, unless the codes stop interpolating
    ("K=64, w_prior_mean=-3", dict(n_atoms=64, w_prior_mean=-3.0)),
    # the training pairs standardized with the statistics of all 600 frames, so that they are not centred
    # (no exact linear dependency 1^T V = 0 among them): then c -> 0
    ("K=64, not centred", dict(n_atoms=64, standardize=False)),
]


def golf_training_set(n_train=30, seed=0, centred=True):
    """Training pairs of the paper protocol's split; ``centred=False``: standardized with all 600 frames' mean and
    std (the estimator then runs with standardize=False), so the training pairs are not centred."""
    fs = load_feature_mat(
        ROOT / "resources/paper-features/x63.mat",
        n_frames=600,
        frame_selection="first",
        drop_y_columns=3,
        checksums=ROOT / "resources/paper-features/SHA256SUMS",
    )
    train, _ = make_split(
        fs.X.shape[0], n_train, protocol="random", seed=split_seed("hsc", "golf", n_train, seed)
    )
    Y_all = get_pose_transform("heading", column=2).forward(fs.Y)
    X, Y = fs.X[train], Y_all[train]
    if not centred:
        sx, sy = fs.X.std(axis=0), Y_all.std(axis=0)
        sx[sx == 0], sy[sy == 0] = 1.0, 1.0
        X, Y = (X - fs.X.mean(axis=0)) / sx, (Y - Y_all.mean(axis=0)) / sy
    return X, Y


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sweeps", type=int, default=3000)
    ap.add_argument("--chains", type=int, default=3)
    ap.add_argument("--n-train", type=int, default=30)
    args = ap.parse_args(argv)
    X, Y = golf_training_set(args.n_train)
    data = {True: (X, Y), False: golf_training_set(args.n_train, centred=False)}
    for centred, (Xc, Yc) in data.items():
        V = (
            np.hstack([Xc, Yc])
            if not centred
            else np.hstack(
                [
                    (X - X.mean(0)) / X.std(0).clip(1e-300),
                    (Y - Y.mean(0)) / np.where(Y.std(0) > 0, Y.std(0), 1),
                ]
            )
        )
        sv = np.linalg.svd(V, compute_uv=False)
        print(
            f"golf (hsc), N = {X.shape[0]}, Mx = {X.shape[1]}, My = {Y.shape[1]}; standardized training pairs "
            f"{'centred on the training set' if centred else 'with the 600 frames statistics'}: smallest singular "
            f"value / largest = {sv[-1] / sv[0]:.2g}"
        )
    at = [s for s in (10, 50, 100, 200, 300, 500, 1000, 1500, 2000, 3000, 5000) if s <= args.sweeps]
    nm = X.shape[0] * (X.shape[1] + Y.shape[1])
    print(
        "g_xy at sweep "
        + ", ".join(map(str, at))
        + "; then, over the last 20% of sweeps: median g_s, active"
        " atoms, log-lik per entry, mean c(g) (see the docstring)"
    )
    for name, params in SETTINGS:
        for chain in range(args.chains):
            t0 = time.perf_counter()
            Xc, Yc = data[params.get("standardize", True)]
            m = BayesianSR(
                n_iter=args.sweeps,
                n_burn_in=args.sweeps - 1,
                thin=1,
                random_state=derive_seed("gxy_drift", name, chain),
                **params,
            ).fit(Xc, Yc)
            tr = m.trace_
            g = " ".join(f"{tr['g_xy'][s - 1]:9.3g}" for s in at)
            tail = slice(-max(args.sweeps // 5, 1), None)
            # the trace holds g_xy after the sweep and the log-likelihood at it: g ||R||^2 = NM log(g / 2 pi) - 2 ll
            g_rr = nm * np.log(tr["g_xy"] / (2 * np.pi)) - 2 * tr["log_likelihood"]
            c = 0.5 * (nm - g_rr)
            print(
                f"{name:24s} chain {chain}: {g} | g_s {np.median(tr['g_s'][tail]):7.3g}, "
                f"active {np.median(tr['active_atoms'][tail]):4.0f}, "
                f"ll/entry {np.median(tr['log_likelihood'][tail]) / nm:6.2f}, c {np.mean(c[tail]):7.1f}, "
                f"b_xy g_xy {float(m.b0 if m.b_xy is None else m.b_xy) * np.mean(tr['g_xy'][tail]):7.1f}"
                f"  ({time.perf_counter() - t0:.1f} s)",
                flush=True,
            )


if __name__ == "__main__":
    main()
