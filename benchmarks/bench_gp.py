"""The GP baseline's fit: the summed marginal-likelihood gradient against scikit-learn's per-output one.

``GaussianProcessARD`` fits ``_SharedKernelGPR`` (the gradient of the log marginal likelihood summed over the
outputs before its contraction with the kernel's gradient); "stock" is the same estimator fitting scikit-learn's
``GaussianProcessRegressor`` (one contraction per output). Data: the authors' golf features
(resources/paper-features/x63.mat, first 600 frames), heading transform (58 outputs), the study's random split
of seed 0 at each N (``JobSpec("hsc", "golf", "GP", N, 0)``), the study's settings (50 L-BFGS-B iterations,
no restart).

Measured per N, the two variants interleaved in one process (their order alternating between repeats), one
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
VARIANTS = {"stock": GaussianProcessRegressor, "summed": _SharedKernelGPR}


def fit(variant, X, Z):
    """GaussianProcessARD fitted with the regressor class of ``variant``; wall and CPU seconds."""
    sklearn_baselines._SharedKernelGPR = VARIANTS[variant]
    try:
        w0, c0 = time.perf_counter(), time.process_time()
        est = GaussianProcessARD(random_state=0).fit(X, Z)
        return est, time.perf_counter() - w0, time.process_time() - c0
    finally:
        sklearn_baselines._SharedKernelGPR = _SharedKernelGPR


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
                order = list(VARIANTS) if r % 2 == 0 else list(VARIANTS)[::-1]
                for v in order:
                    est, wall, cpu = fit(v, fs.X[train], tf.forward(fs.Y[train]))
                    res[n, v]["wall"].append(wall)
                    res[n, v]["cpu"].append(cpu)
                    res[n, v]["eval"].append(eval_ms(est.model_))
                    err = mean_angle_error(fs.Y[test], tf.inverse(est.predict(fs.X[test])))
                    last[n, v] = (est.model_.kernel_.theta, err)
    print(
        f"GP (ARD) fit on golf, {fs.X.shape[1]}-D inputs, {tf.forward(fs.Y[:1]).shape[1]} outputs; "
        f"median of {a.repeats} interleaved repeats, 1 BLAS thread; load average "
        f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}\n"
    )
    print(
        "| N | stock fit s (CPU) | summed fit s (CPU) | ratio wall (CPU) | one evaluation ms stock / "
        "summed | error deg stock / summed | max abs diff log theta |"
    )
    print("|---|---|---|---|---|---|---|")
    for n in a.sizes:
        s, m = res[n, "stock"], res[n, "summed"]
        med = {k: (float(np.median(s[k])), float(np.median(m[k]))) for k in s}
        (th_s, err_s), (th_m, err_m) = last[n, "stock"], last[n, "summed"]
        print(
            f"| {n} | {med['wall'][0]:.2f} ({med['cpu'][0]:.2f}) | {med['wall'][1]:.2f} ({med['cpu'][1]:.2f}) "
            f"| {med['wall'][1] / med['wall'][0]:.2f} ({med['cpu'][1] / med['cpu'][0]:.2f}) "
            f"| {med['eval'][0]:.1f} / {med['eval'][1]:.1f} | {err_s:.7f} / {err_m:.7f} "
            f"(diff {abs(err_s - err_m):.1e}) | {np.abs(th_s - th_m).max():.1e} |"
        )


if __name__ == "__main__":
    main()
