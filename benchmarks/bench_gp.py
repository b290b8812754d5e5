"""The GP baseline's fit: the summed marginal-likelihood gradient against scikit-learn's per-output one.

``GaussianProcessARD`` fits ``_SharedKernelGPR`` (the gradient of the log marginal likelihood summed over the
outputs before its contraction with the kernel's gradient, in closed form for the baseline's kernel: "closed");
"summed" is the same with the general contraction of the n x n x (parameters) kernel gradient; "stock" is the
same estimator fitting scikit-learn's ``GaussianProcessRegressor`` (one contraction per output). Data: the
authors' golf features (resources/paper-features/x63.mat, first 600 frames), heading transform (58 outputs),
the study's random split of seed 0 at each N (``JobSpec("hsc", "golf", "GP", N, 0)``), the study's settings
(50 L-BFGS-B iterations, no restart).

Measured per N, the three variants interleaved in one process (their order rotating between repeats), one
BLAS thread: median wall and CPU seconds of ``fit``; median milliseconds of one log-marginal-likelihood
evaluation with its gradient at the fitted hyper-parameters; the test error of each fit (mean over the 57
angles of the per-angle RMS, degrees) and the largest difference of the fitted log hyper-parameters.

    .venv/bin/python benchmarks/bench_gp.py [--sizes 30 60 100 200] [--repeats 3]
"""

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from threadpoolctl import threadpool_limits

from bsrbench.datasets import load_feature_mat
from bsrbench.metrics import mean_angle_error
from bsrbench.models import sklearn_baselines
from bsrbench.models.sklearn_baselines import GaussianProcessARD, _SharedKernelGPR
from bsrbench.poses import HeadingTransform
from bsrbench.splits import JobSpec

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = {
    "stock": GaussianProcessRegressor,
    "summed": _SharedKernelGPR,
    "closed": _SharedKernelGPR,
}
CLOSED_FORM = sklearn_baselines._scaled_rbf_plus_noise


def _use(variant):
    """Make GaussianProcessARD fit ``variant``: scikit-learn's class, the summed gradient's general
    contraction (no closed form), or the closed form (the code as it is)."""
    sklearn_baselines._SharedKernelGPR = VARIANTS[variant]
    sklearn_baselines._scaled_rbf_plus_noise = (
        CLOSED_FORM if variant == "closed" else (lambda kernel: None)
    )


def fit(variant, X, Z):
    """GaussianProcessARD fitted as ``variant``; wall and CPU seconds."""
    _use(variant)
    w0, c0 = time.perf_counter(), time.process_time()
    est = GaussianProcessARD(random_state=0).fit(X, Z)
    return est, time.perf_counter() - w0, time.process_time() - c0


def eval_ms(gp, repeats=5):
    """Median milliseconds of one log marginal likelihood with its gradient at the fitted theta."""
    theta = gp.kernel_.theta
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        gp.log_marginal_likelihood(theta, eval_gradient=True)
        ts.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(ts))


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--sizes", type=int, nargs="+", default=[30, 60, 100, 200])
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    mat = ROOT / "resources" / "paper-features" / "x63.mat"
    fs = load_feature_mat(mat, n_frames=600, drop_y_columns=3, checksums=mat.parent / "SHA256SUMS")
    tf = HeadingTransform(column=2)
    splits = {n: JobSpec("hsc", "golf", "GP", n, 0).split(600) for n in a.sizes}
    res = {(n, v): {"wall": [], "cpu": [], "eval": []} for n in a.sizes for v in VARIANTS}
    last = {}
    warnings.simplefilter("ignore", ConvergenceWarning)
    with threadpool_limits(1):
        for r in range(a.repeats):
            for n in a.sizes:
                train, test = splits[n]
                order = list(VARIANTS)[r % len(VARIANTS) :] + list(VARIANTS)[: r % len(VARIANTS)]
                for v in order:
                    est, wall, cpu = fit(v, fs.X[train], tf.forward(fs.Y[train]))
                    res[n, v]["wall"].append(wall)
                    res[n, v]["cpu"].append(cpu)
                    res[n, v]["eval"].append(eval_ms(est.model_))  # still as variant v
                    err = mean_angle_error(fs.Y[test], tf.inverse(est.predict(fs.X[test])))
                    last[n, v] = (est.model_.kernel_.theta, err)
    print(
        f"GP (ARD) fit on golf, {fs.X.shape[1]}-D inputs, {tf.forward(fs.Y[:1]).shape[1]} outputs; "
        f"median of {a.repeats} interleaved repeats, 1 BLAS thread; load average "
        f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}\n"
    )
    _use("closed")
    print(
        "| N | variant | fit s wall | fit s CPU | CPU / stock | one evaluation ms | error deg | "
        "diff from stock deg | max abs diff log theta from stock |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for n in a.sizes:
        cpu0 = float(np.median(res[n, "stock"]["cpu"]))
        th0, err0 = last[n, "stock"]
        for v in VARIANTS:
            med = {k: float(np.median(x)) for k, x in res[n, v].items()}
            th, err = last[n, v]
            print(
                f"| {n} | {v} | {med['wall']:.2f} | {med['cpu']:.2f} | {med['cpu'] / cpu0:.2f} "
                f"| {med['eval']:.1f} | {err:.7f} | {abs(err - err0):.1e} | {np.abs(th - th0).max():.1e} |"
            )


if __name__ == "__main__":
    main()
