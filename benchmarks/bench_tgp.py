"""Speed of TGP prediction: precomputed/vectorized implementation against a naive per-point reference.

Golf features of the authors (resources/paper-features/x63.mat, first 600 frames). The model is fit on
N = 200 frames (split of bsrbench.seeds.split_seed("hsc", "golf", 200, 0)) and queried at the 570 frames
outside a N = 30 split (split_seed("hsc", "golf", 30, 0)): 570 queries on the N = 200 model, the most
expensive combination of the protocol (some queries are training frames of the model). Heading transform
on; 100-D features, 58-D outputs.

Measured: wall time of ``TGP.predict`` (full and kNN-restricted) and of a naive per-point reference that
recomputes the input-kernel solve and the output-kernel inverse for every test point (what the
precomputation removes); median over ``--repeats`` runs, one BLAS thread. Also checks that both give the
same predictions.

    .venv/bin/python benchmarks/bench_tgp.py [--repeats 3] [--n-neighbors 50]
"""

import argparse
import time
from pathlib import Path

import numpy as np
import scipy.io as sio
from scipy.optimize import minimize
from threadpoolctl import threadpool_limits

from bsrbench.metrics import mean_angle_error
from bsrbench.models.tgp import TGP, _kld_objective
from bsrbench.poses import HeadingTransform
from bsrbench.seeds import split_seed

ROOT = Path(__file__).resolve().parents[1]


def naive_predict(model, Xt, n_neighbors=None):
    """Per-point TGP without precomputation: kernel matrices built, factorised and inverted per test point."""
    Xtr, Ytr = model.X_train_, model.Y_train_
    wx, wy = model.width_x_, model.width_y_
    out = np.empty((Xt.shape[0], Ytr.shape[1]))
    for i, x in enumerate(Xt):
        d2 = ((Xtr - x) ** 2).sum(1)
        idx = (
            np.arange(len(Xtr))
            if n_neighbors is None
            else np.argsort(d2, kind="stable")[:n_neighbors]
        )
        Xi, Yi = Xtr[idx], Ytr[idx]
        Kx = np.exp(
            -((Xi[:, None] - Xi[None]) ** 2).sum(-1) / (2 * wx**2)
        ) + model.lambda_x * np.eye(len(idx))
        Ky = np.exp(
            -((Yi[:, None] - Yi[None]) ** 2).sum(-1) / (2 * wy**2)
        ) + model.lambda_y * np.eye(len(idx))
        kx = np.exp(-d2[idx] / (2 * wx**2))
        u = np.linalg.solve(Kx, kx)
        eta = max(1.0 + model.lambda_x - kx @ u, 0.0)
        Ainv = np.linalg.inv(Ky)
        y0 = Ytr[np.argmin(d2)] / wy
        res = minimize(
            _kld_objective,
            y0,
            args=(Yi / wy, Ainv, u, eta, 1.0 + model.lambda_y, 1.0),
            jac=True,
            method="L-BFGS-B",
            options={"maxiter": model.max_iter, "ftol": model.tol, "gtol": model.tol},
        )
        out[i] = res.x * wy
    return out


def timed(fn, repeats):
    ts, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts)), out


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--n-neighbors", type=int, default=50)
    a = ap.parse_args()
    d = sio.loadmat(ROOT / "resources" / "paper-features" / "x63.mat")
    X, Y = d["X"][:600].astype(float), d["Y"][:600, 3:].astype(float)
    H = HeadingTransform()
    perm = np.random.default_rng(split_seed("hsc", "golf", 200, 0)).permutation(600)
    tr = perm[:200]
    test = np.random.default_rng(split_seed("hsc", "golf", 30, 0)).permutation(600)[
        30:
    ]  # 570 queries
    with threadpool_limits(1):
        model = TGP(width_scale_x=2.0, width_scale_y=0.5).fit(X[tr], H.forward(Y[tr]))
        print(
            f"TGP on golf: N = {len(tr)} training frames, {len(test)} test points, X {X.shape[1]}-D, "
            f"Y {H.forward(Y[:1]).shape[1]}-D; median of {a.repeats} repeats, 1 BLAS thread"
        )
        for k in (None, a.n_neighbors):
            t_fast, P = timed(lambda k=k: model.predict(X[test], n_neighbors=k), a.repeats)
            t_naive, Pn = timed(lambda k=k: naive_predict(model, X[test], n_neighbors=k), a.repeats)
            err = mean_angle_error(Y[test], H.inverse(P))
            diff = float(np.max(np.abs(P - Pn)))
            label = "full" if k is None else f"kNN k={k}"
            print(
                f"{label:10s} vectorized {t_fast:6.2f} s   naive per-point {t_naive:6.2f} s   "
                f"ratio {t_naive / t_fast:5.2f}x   error {err:5.2f} deg   max |fast - naive| {diff:.2e}"
            )


if __name__ == "__main__":
    main()
