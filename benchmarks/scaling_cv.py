"""Choice of the input scaling (issue 14) by cross-validation on TRAINING frames only.

For each hsc activity, training size N and seed, the training frames of the study's contiguous split
(:meth:`bsrbench.splits.JobSpec.split`, the frames the contiguous protocol trains on; its test frames are never
used) are cut into 5 folds: blocked (``KFold(shuffle=False)``: each validation fold is a run of consecutive
frames, so validation poses lie off the range of the fold's training frames, as in the protocol) and shuffled
(``KFold(shuffle=True)``, the study's tuning CV). Every estimator that scales its inputs (Ridge, PM, and
TGP started from ridge) is fitted with each ``input_scaling`` of :mod:`bsrbench.models.scaling` and with
the old unfloored per-bin standardization (``"bin-nofloor"``, for reference), with the study's fixed
parameters, heading transform on; the score is the mean angle error (deg) on the validation fold, averaged
over folds. Writes ``benchmarks/results/scaling_cv.csv`` and prints the mean per (method, activity, scaling).
Output clipping is switched off here so that only the scaling is compared.

    .venv/bin/python benchmarks/scaling_cv.py [--sizes 30 100] [--seeds 3] [--pm-sweeps 150 100]
"""

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from contiguous_offrange import ACTIVITIES, load
from sklearn.model_selection import KFold
from threadpoolctl import threadpool_limits

from bsrbench.estimators import make_estimator
from bsrbench.io import atomic_path
from bsrbench.metrics import mean_angle_error
from bsrbench.models import scaling
from bsrbench.poses import HeadingTransform
from bsrbench.splits import JobSpec

ROOT = Path(__file__).resolve().parents[1]
SCALINGS = ("pooled", "bin", "none", "bin-nofloor")


def fit_predict(method, cfg, kind, Xtr, Ztr, Xva, seed, pm_sweeps):
    m = cfg["methods"][method]
    params = dict(m.get("params") or {})
    if method == "PM":
        params.update(n_iter=pm_sweeps[0], n_burn_in=pm_sweeps[1])
    if method == "TGP":
        params.update(init="ridge")
    est = make_estimator(m["estimator"], params, random_state=seed)
    old_floor, old_margin = scaling.BIN_FLOOR, scaling.OUTPUT_MARGIN
    try:
        scaling.OUTPUT_MARGIN = np.inf  # no clipping: compare the scalings alone
        if kind == "bin-nofloor":
            scaling.BIN_FLOOR = 0.0
            kind = "bin"
        est.set_params(input_scaling=kind)
        est.fit(Xtr, Ztr)
        return est.predict(Xva)
    finally:
        scaling.BIN_FLOOR, scaling.OUTPUT_MARGIN = old_floor, old_margin


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--activities", nargs="+", default=list(ACTIVITIES), choices=list(ACTIVITIES))
    ap.add_argument("--sizes", nargs="+", type=int, default=[30, 100])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--methods", nargs="+", default=["Ridge", "PM", "TGP"])
    ap.add_argument(
        "--pm-sweeps", nargs=2, type=int, default=[150, 100], metavar=("N_ITER", "N_BURN_IN")
    )
    ap.add_argument("--folds", type=int, default=5)
    args = ap.parse_args(argv)
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    tf = HeadingTransform(column=2)
    rows = []
    with threadpool_limits(1):
        for activity in args.activities:
            f = load(activity)
            for n in args.sizes:
                for seed in range(args.seeds):
                    spec = JobSpec(
                        source="hsc",
                        activity=activity,
                        method="-",
                        n_train=n,
                        seed=seed,
                        protocol="contiguous",
                        min_test=cfg["min_test"],
                        gap=cfg["gap"],
                    )
                    train, _ = spec.split(f["X"].shape[0])  # the test frames are not touched
                    X, Y = f["X"][train], f["Y"][train]
                    for cv_kind, shuffle in (("blocked", False), ("shuffled", True)):
                        folds = KFold(
                            args.folds, shuffle=shuffle, random_state=seed if shuffle else None
                        )
                        for method in args.methods:
                            if method != "Ridge" and cv_kind == "shuffled":
                                continue  # the shuffled CV only for the cheap method
                            for kind in SCALINGS:
                                t0 = time.perf_counter()
                                errs = []
                                for k, (tr, va) in enumerate(folds.split(X)):
                                    P = fit_predict(
                                        method,
                                        cfg,
                                        kind,
                                        X[tr],
                                        tf.forward(Y[tr]),
                                        X[va],
                                        1000 * seed + k,
                                        args.pm_sweeps,
                                    )
                                    errs.append(mean_angle_error(Y[va], tf.inverse(P)))
                                rows.append(
                                    {
                                        "activity": activity,
                                        "n_train": n,
                                        "seed": seed,
                                        "cv": cv_kind,
                                        "method": method,
                                        "scaling": kind,
                                        "error": float(np.mean(errs)),
                                        "seconds": time.perf_counter() - t0,
                                    }
                                )
                                print(
                                    f"{activity} N={n} seed={seed} {cv_kind} {method} {kind}: "
                                    f"{rows[-1]['error']:.2f} ({rows[-1]['seconds']:.1f} s)",
                                    flush=True,
                                )
    df = pd.DataFrame(rows)
    out = ROOT / "benchmarks" / "results" / "scaling_cv.csv"
    with atomic_path(out) as tmp:
        df.to_csv(tmp, index=False)
    table = df.pivot_table(
        index=["cv", "method", "n_train", "activity"],
        columns="scaling",
        values="error",
        aggfunc="mean",
    )
    print(table.to_string(float_format=lambda v: f"{v:.2f}"))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
