"""The baselines (RVM, TGP, SR, DDL) and the references (1-NN, k-NN, ridge) on the authors' features.

For each activity, training size N and seed: the split of bsrbench.seeds.split_seed("hsc", activity, N, seed)
(N random training frames of the first 600, the rest are test), the heading transform on, every method tuned
by 5-fold cross-validation (bsrbench.tuning.tune with the module's DEFAULT_GRID), refit on the N frames with
the selected parameters and scored by bsrbench.metrics.mean_angle_error. Prints a table beside the paper's
numbers and writes benchmarks/results/baselines_hsc.csv (one row per activity, N, seed, method).

    .venv/bin/python benchmarks/baselines_on_hsc.py [--activities golf run] [--sizes 30 200] [--seeds 3]
"""

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.io as sio
import sklearn
from threadpoolctl import threadpool_limits

from bsrbench.io import atomic_path
from bsrbench.metrics import mean_angle_error
from bsrbench.models import ddl, reference, rvm, sr, tgp
from bsrbench.poses import HeadingTransform
from bsrbench.seeds import derive_seed, method_seed, split_seed
from bsrbench.tuning import tune

ROOT = Path(__file__).resolve().parents[1]
FEATURES = ROOT / "resources" / "paper-features"
ACTIVITIES = {  # name -> (file, name in the paper's tables)
    "acrobatics": ("x4921.mat", "Acrobatics"),
    "golf": ("x63.mat", "Golf"),
    "michael_jackson": ("x131.mat", "Michael jackson styled motions"),
    "run": ("x09.mat", "Run"),
}
N_FRAMES = 600


def methods(activity, n_train, seed):
    """(name, estimator, grid, paper column) of every method compared."""
    return [
        ("1-NN", reference.NearestNeighbourRegressor(n_neighbors=1), {"n_neighbors": [1]}, None),
        (
            "kNN",
            reference.NearestNeighbourRegressor(),
            reference.DEFAULT_GRID["NearestNeighbourRegressor"],
            None,
        ),
        ("ridge", reference.RidgeRegressor(), reference.DEFAULT_GRID["RidgeRegressor"], None),
        ("RVM", rvm.RVM(), rvm.DEFAULT_GRID, "RVM"),
        ("TGP", tgp.TGP(), tgp.DEFAULT_GRID, "TGP"),
        ("SR", sr.SR(), sr.DEFAULT_GRID, "SR"),
        (
            "DDL",
            ddl.DDL(random_state=method_seed("hsc", activity, n_train, seed, "DDL")),
            ddl.DEFAULT_GRID,
            "DDL",
        ),
    ]


def load(activity):
    fname, _ = ACTIVITIES[activity]
    d = sio.loadmat(FEATURES / fname)
    return np.asarray(d["X"][:N_FRAMES], float), np.asarray(d["Y"][:N_FRAMES, 3:], float)


def split(activity, n_train, seed):
    rng = np.random.default_rng(split_seed("hsc", activity, n_train, seed))
    perm = rng.permutation(N_FRAMES)
    return perm[:n_train], perm[n_train:]


def run(activities, sizes, seeds, cv, only=None):
    H = HeadingTransform()
    rows = []
    for activity in activities:
        X, Y = load(activity)
        for n_train in sizes:
            for seed in seeds:
                tr, te = split(activity, n_train, seed)
                for name, est, grid, _ in methods(activity, n_train, seed):
                    if only and name not in only:
                        continue
                    t0 = time.perf_counter()
                    res = tune(
                        est,
                        grid,
                        X[tr],
                        Y[tr],
                        cv=cv,
                        random_state=derive_seed("cv", activity, n_train, seed),
                        pose_transform=H,
                        n_jobs=1,
                    )
                    t_tune = time.perf_counter() - t0
                    model = sklearn.clone(est).set_params(**res.best_params)
                    t0 = time.perf_counter()
                    model.fit(X[tr], H.forward(Y[tr]))
                    t_fit = time.perf_counter() - t0
                    t0 = time.perf_counter()
                    P = H.inverse(model.predict(X[te]))
                    t_pred = time.perf_counter() - t0
                    err = mean_angle_error(Y[te], P)
                    rows.append(
                        {
                            "activity": activity,
                            "method": name,
                            "n_train": n_train,
                            "seed": seed,
                            "error_deg": err,
                            "cv_error_deg": res.best_score,
                            "best_params": json.dumps(res.best_params, sort_keys=True),
                            "grid": json.dumps(grid, sort_keys=True),
                            "n_fits": res.n_fits,
                            "tune_s": t_tune,
                            "fit_s": t_fit,
                            "predict_s": t_pred,
                            "sklearn": sklearn.__version__,
                            "numpy": np.__version__,
                            "python": platform.python_version(),
                        }
                    )
                    print(
                        f"{activity:16s} N={n_train:3d} seed={seed} {name:5s} err={err:6.2f} "
                        f"cv={res.best_score:6.2f} tune={t_tune:6.1f}s {res.best_params}",
                        flush=True,
                    )
    return pd.DataFrame(rows)


def table(df):
    paper = pd.read_csv(ROOT / "resources" / "paper-tables.csv")
    out = []
    for (activity, n_train, method), g in df.groupby(["activity", "n_train", "method"], sort=False):
        row = {
            "activity": activity,
            "N": n_train,
            "method": method,
            "ours": f"{g.error_deg.mean():.2f} ± {g.error_deg.std(ddof=1) if len(g) > 1 else 0:.2f}",
            "seeds": len(g),
            "median_tune_s": round(float(g.tune_s.median()), 1),
        }
        col = {m[0]: m[3] for m in methods(activity, n_train, 0)}[method]
        p = paper[
            (paper.activity == ACTIVITIES[activity][1])
            & (paper.n_train == n_train)
            & (paper.method == col)
        ]
        row["paper"] = f"{p.mean_deg.iloc[0]:.2f} ± {p.std_deg.iloc[0]:.2f}" if len(p) else ""
        out.append(row)
    return pd.DataFrame(out)


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--activities", nargs="+", default=list(ACTIVITIES), choices=list(ACTIVITIES))
    ap.add_argument("--sizes", nargs="+", type=int, default=[30, 60, 100, 200])
    ap.add_argument("--seeds", type=int, default=3, help="number of seeds (0 .. seeds-1)")
    ap.add_argument("--cv", type=int, default=5)
    ap.add_argument("--methods", nargs="+", default=None, help="subset of method names")
    ap.add_argument(
        "--out", type=Path, default=ROOT / "benchmarks" / "results" / "baselines_hsc.csv"
    )
    a = ap.parse_args()
    with threadpool_limits(1):  # one BLAS thread: the machine's cores are shared by parallel jobs
        df = run(a.activities, a.sizes, list(range(a.seeds)), a.cv, a.methods)
    with atomic_path(a.out) as tmp:
        df.to_csv(tmp, index=False)
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(table(df).to_string(index=False))
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
