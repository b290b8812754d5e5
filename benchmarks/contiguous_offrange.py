"""The contiguous protocol on the authors' (hsc) features: error and largest predicted angle per method.

Reproduces issue 14 (predictions far outside the training range) and measures its fix. For each activity,
training size N and seed, the study's own job function (:func:`bsrbench.runs.run_job`) fits every method of
``config/config.yaml`` with its fixed ``params`` (``cv.mode: none``, as a new user's first run) on the
contiguous split of :func:`bsrbench.splits.make_split` (gap 30, min_test 100, heading transform), and records
the mean angle error (deg) and the largest absolute predicted angle (deg, before wrapping). Writes one row
per (activity, N, seed, method) to ``benchmarks/results/<protocol>_<tag>.csv`` and prints the table of
means over seeds.

    .venv/bin/python benchmarks/contiguous_offrange.py --tag after [--activities acrobatics] [--sizes 30]
        [--seeds 3] [--pm-sweeps 300 200]
    .venv/bin/python benchmarks/contiguous_offrange.py --compare before after

``--pm-sweeps N_ITER N_BURN_IN`` overrides PM's sweeps (the quick study's 300/200 by default).
Issue 14's "before" run used the code before the shared input scaling (commit 183491a) with this script:
``git archive 183491a | tar -x -C /tmp/before``, copy this file into /tmp/before/benchmarks, run it there with
``PYTHONPATH=/tmp/before/src``, and copy its CSV into benchmarks/results.
``--compare before after`` runs nothing and prints the before/after table of two earlier runs (means over
seeds: error, its change, largest predicted angle).
"""

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from threadpoolctl import threadpool_limits

from bsrbench.datasets import load_feature_mat
from bsrbench.io import atomic_path
from bsrbench.runs import run_job
from bsrbench.splits import JobSpec

ROOT = Path(__file__).resolve().parents[1]
FEATURES = ROOT / "resources" / "paper-features"
ACTIVITIES = {
    "acrobatics": "x4921.mat",
    "golf": "x63.mat",
    "michael_jackson": "x131.mat",
    "run": "x09.mat",
}


def load(activity):
    fs = load_feature_mat(
        FEATURES / ACTIVITIES[activity],
        n_frames=600,
        frame_selection="first",
        drop_y_columns=3,
        checksums=FEATURES / "SHA256SUMS",
    )
    return {"X": fs.X, "Y": fs.Y, "heading_column": 2}


def compare(before, after, protocol="contiguous"):
    """Print the mean error and largest |angle| per (activity, N, method) of two runs side by side."""
    res = ROOT / "benchmarks" / "results"
    agg = {
        "error": ("error", "mean"),
        "max_abs_angle": ("max_abs_angle", "max"),
        "seeds": ("seed", "nunique"),
    }
    b, a = (
        pd.read_csv(res / f"{protocol}_{t}.csv")
        .groupby(["activity", "n_train", "method"], sort=False)
        .agg(**agg)
        for t in (before, after)
    )
    t = b.join(a, suffixes=("_before", "_after"), how="inner")
    t["change"] = t["error_after"] - t["error_before"]
    cols = [
        "error_before",
        "error_after",
        "change",
        "max_abs_angle_before",
        "max_abs_angle_after",
        "seeds_after",
    ]
    print(t[cols].to_markdown(floatfmt=".4g") if hasattr(t, "to_markdown") else t[cols].to_string())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--tag", help="name of the run (results/contiguous_<tag>.csv); required unless --compare"
    )
    ap.add_argument("--activities", nargs="+", default=list(ACTIVITIES), choices=list(ACTIVITIES))
    ap.add_argument("--sizes", nargs="+", type=int, default=[30])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument(
        "--methods", nargs="+", default=None, help="keys of config.yaml's methods (default: run)"
    )
    ap.add_argument("--pm-sweeps", nargs=2, type=int, default=None, metavar=("N_ITER", "N_BURN_IN"))
    ap.add_argument(
        "--protocol",
        default="contiguous",
        choices=["contiguous", "random"],
        help="split protocol (random: the paper's, to see how its tables move)",
    )
    ap.add_argument("--compare", nargs=2, metavar=("TAG_BEFORE", "TAG_AFTER"), default=None)
    args = ap.parse_args(argv)
    if args.compare:
        return compare(*args.compare, protocol=args.protocol)
    if not args.tag:
        ap.error("--tag is required (unless --compare)")

    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    methods = args.methods or cfg["run"]
    rows = []
    with threadpool_limits(1):
        for activity in args.activities:
            features = load(activity)
            for n in args.sizes:
                for seed in range(args.seeds):
                    for m in methods:
                        spec_m = cfg["methods"][m]
                        params = dict(spec_m.get("params") or {})
                        if m == "PM" and args.pm_sweeps:
                            params.update(n_iter=args.pm_sweeps[0], n_burn_in=args.pm_sweeps[1])
                        spec = JobSpec(
                            source="hsc",
                            activity=activity,
                            method=m,
                            n_train=n,
                            seed=seed,
                            protocol=args.protocol,
                            pose_transform=cfg["pose_transform"],
                            min_test=cfg["min_test"],
                            gap=cfg["gap"],
                        )
                        t0 = time.perf_counter()
                        row, arrays = run_job(
                            spec, features, estimator=spec_m["estimator"], params=params
                        )
                        yp = np.asarray(arrays["y_pred"])
                        rows.append(
                            {
                                "activity": activity,
                                "n_train": n,
                                "seed": seed,
                                "method": spec_m["label"],
                                "error": row["error"],
                                "max_abs_angle": float(np.max(np.abs(yp))),
                                "frac_rows_over_1000": float(
                                    np.mean(np.max(np.abs(yp), axis=1) > 1000)
                                ),
                                "seconds": time.perf_counter() - t0,
                            }
                        )
                        r = rows[-1]
                        print(
                            f"{activity} N={n} seed={seed} {r['method']:5s} error {r['error']:7.2f} "
                            f"max|angle| {r['max_abs_angle']:.3g} ({r['seconds']:.1f} s)",
                            flush=True,
                        )
    df = pd.DataFrame(rows)
    out = ROOT / "benchmarks" / "results" / f"{args.protocol}_{args.tag}.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        df.to_csv(tmp, index=False)
    summary = df.groupby(["activity", "n_train", "method"], sort=False).agg(
        error=("error", "mean"), max_abs_angle=("max_abs_angle", "max")
    )
    print(summary.to_string(float_format=lambda v: f"{v:.4g}"))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
