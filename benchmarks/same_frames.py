"""Our features beside the authors' on the same frames: how close is the from-scratch pipeline to theirs?

For x09 (run) and x131 (Michael Jackson), the rows matched to a CMU trial here (resources/paper-features/
alignment/*_rows.csv, written by benchmarks/align_authors.py) are rendered by our pipeline (bsrbench.render,
shape contexts, the codebook results/features/codebook.npz, soft histogram), at the render settings of
config/datasets.yaml unless a variant changes one stage. Both feature sets regress the SAME poses (their Y,
57 angles, heading transform on column 2) with the SAME random splits (N training rows of the matched rows, the
rest test): 1-NN, SR and TGP, tuned by 5-fold CV on the training rows (each module's DEFAULT_GRID), scored by
bsrbench.metrics.mean_angle_error. Ratio = error with our features / error with theirs.

Variants (one stage changed at a time) locate a difference:
  ours            the pipeline as configured (200 contour points, unit soft votes: rows sum to 200);
  ours_scaled     ours, each row multiplied by (their row sum / 200): their histograms are unnormalised, so a
                  row's total (the contour length) carries the silhouette's size; this gives ours the same total;
  theirs_unit     theirs, each row divided by its sum (x 200): their features without the size information;
  az<deg>         ours rendered with another camera azimuth (e.g. az90: a side view);
  pts<k>          ours with k contour points per silhouette.

Writes benchmarks/tables/same_frames.csv (one line per file, variant, method, N, seed) and
same_frames_summary.csv (mean ± std over seeds, and each variant's mean / the mean with their features). Silhouettes and descriptors are cached in benchmarks/results/same_frames_cache/.

    .venv/bin/python benchmarks/same_frames.py [--variants ours ours_scaled theirs_unit az90] [--seeds 5]
        [--azimuth 0] [--methods 1-NN]

The committed tables (benchmarks/tables/same_frames*.csv) were made, before the configured azimuth changed from
0 to 135, by: the defaults (ours, ours_scaled, theirs_unit at azimuth 0), then --variants az45, then
--variants az135, and the 1-NN sweep --variants ours az45 az90 az135 az180 az270 pts100 pts400 --methods 1-NN;
each run is deterministic, so the concatenation equals one run with all variants.
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.io as sio
import sklearn
import yaml
from threadpoolctl import threadpool_limits

from bsrbench.features import histogram_features, silhouette_descriptors
from bsrbench.io import atomic_path
from bsrbench.metrics import mean_angle_error
from bsrbench.mocap import load_motion
from bsrbench.models import reference, sr, tgp
from bsrbench.poses import HeadingTransform
from bsrbench.render import render_silhouettes
from bsrbench.seeds import derive_seed
from bsrbench.tuning import tune

ROOT = Path(__file__).resolve().parents[1]
FEATURES = ROOT / "resources" / "paper-features"
MOCAP = ROOT / "resources" / "cmu-mocap"
OUT = ROOT / "benchmarks" / "results"
CACHE = OUT / "same_frames_cache"
FILES = {"x09": "run", "x131": "michael_jackson"}


def methods():
    return [
        ("1-NN", reference.NearestNeighbourRegressor(n_neighbors=1), {"n_neighbors": [1]}),
        ("SR", sr.SR(), sr.DEFAULT_GRID),
        ("TGP", tgp.TGP(), tgp.DEFAULT_GRID),
    ]


def config():
    with open(ROOT / "config" / "datasets.yaml") as fh:
        return yaml.safe_load(fh)["features"]


def matched_rows(name):
    """Rows of the authors' file matched to a trial here: DataFrame(row, trial, frame_120fps)."""
    df = pd.read_csv(FEATURES / "alignment" / f"{name}_rows.csv", dtype={"trial": str})
    return df[df["frame_120fps"] >= 0].reset_index(drop=True)


def positions_of(rows):
    """Joint positions (M, J, 3), parents and joint names of the matched rows (each trial parsed once)."""
    out, parents, names = [None] * len(rows), None, None
    for tid, g in rows.groupby("trial", sort=False):
        m = load_motion([MOCAP / f"{tid}.bvh"], skip_frames=0)
        parents, names = m.parents, m.joint_names
        for i, f in zip(g.index, g["frame_120fps"]):
            out[i] = m.positions[int(f)]
    return np.stack(out), parents, names


def render_kwargs(cfg, azimuth=None):
    r = dict(cfg["render"])
    r["image_size"] = tuple(int(v) for v in r["image_size"])
    if azimuth is not None:
        r["view_azimuth_deg"] = float(azimuth)
    return r


def descriptors(name, rows, cfg, azimuth=None, n_points=None):
    """Shape contexts of the matched rows' silhouettes (cached by file, azimuth and number of points)."""
    az = cfg["render"]["view_azimuth_deg"] if azimuth is None else azimuth
    k = cfg["shape_context"]["n_points"] if n_points is None else n_points
    path = CACHE / f"{name}_az{az:g}_pts{k}.npz"
    if path.is_file():
        with np.load(path) as z:
            if len(z["rows"]) == len(rows) and np.array_equal(z["rows"], rows["row"].to_numpy()):
                counts = z["counts"]
                flat = z["descriptors"]
                return np.split(flat, np.cumsum(counts)[:-1]), z["masks"]
    P, parents, names = positions_of(rows)
    t0 = time.perf_counter()
    masks = render_silhouettes(P, parents, names, **render_kwargs(cfg, az))
    d = silhouette_descriptors(
        masks, n_points=k, seed=derive_seed("same_frames", name, cfg["seed"])
    )
    print(
        f"{name}: rendered and described {len(masks)} silhouettes (azimuth {az:g}, {k} points) in "
        f"{time.perf_counter() - t0:.0f} s",
        flush=True,
    )
    CACHE.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        np.savez_compressed(
            tmp,
            rows=rows["row"].to_numpy(),
            counts=np.array([len(x) for x in d]),
            descriptors=np.vstack(d),
            masks=masks,
        )
    return d, masks


def feature_sets(name, rows, variants, codebook, cfg):
    """{variant: X (M, D)} on the matched rows."""
    Xt = np.asarray(sio.loadmat(FEATURES / f"{name}.mat")["X"], dtype=float)[rows["row"].to_numpy()]
    out = {"theirs": Xt}
    soft = cfg["histogram"]["soft"]
    base = None
    for v in variants:
        if v in ("ours", "ours_scaled"):
            if base is None:
                base = histogram_features(descriptors(name, rows, cfg)[0], codebook, soft=soft)
            out[v] = base if v == "ours" else base * (Xt.sum(1) / base.sum(1))[:, None]
        elif v == "theirs_unit":
            out[v] = Xt / Xt.sum(1, keepdims=True) * 200.0
        elif v.startswith("az"):
            out[v] = histogram_features(
                descriptors(name, rows, cfg, azimuth=float(v[2:]))[0], codebook, soft=soft
            )
        elif v.startswith("pts"):
            out[v] = histogram_features(
                descriptors(name, rows, cfg, n_points=int(v[3:]))[0], codebook, soft=soft
            )
        else:
            raise SystemExit(f"unknown variant {v!r}")
    return out


def run(files, variants, sizes, seeds, cv, only=None, azimuth=None):
    cfg = config()
    if azimuth is not None:
        cfg["render"]["view_azimuth_deg"] = float(azimuth)
    with np.load(ROOT / "results" / "features" / "codebook.npz") as z:
        codebook = z["centres"]
    H = HeadingTransform(column=2)
    rows_out = []
    for name in files:
        rows = matched_rows(name)
        Y = np.asarray(sio.loadmat(FEATURES / f"{name}.mat")["Y"], dtype=float)[
            rows["row"].to_numpy(), 3:
        ]
        sets = feature_sets(name, rows, variants, codebook, cfg)
        M = len(rows)
        for n_train in sizes:
            for seed in seeds:
                perm = np.random.default_rng(
                    derive_seed("same_frames", name, n_train, seed)
                ).permutation(M)
                tr, te = perm[:n_train], perm[n_train:]
                for fs, X in sets.items():
                    for mname, est, grid in methods():
                        if only and mname not in only:
                            continue
                        res = tune(
                            est,
                            grid,
                            X[tr],
                            Y[tr],
                            cv=cv,
                            random_state=derive_seed("cv", name, n_train, seed),
                            pose_transform=H,
                            n_jobs=1,
                        )
                        model = sklearn.clone(est).set_params(**res.best_params)
                        model.fit(X[tr], H.forward(Y[tr]))
                        err = mean_angle_error(Y[te], H.inverse(model.predict(X[te])))
                        az = (
                            (
                                float(fs[2:])
                                if fs.startswith("az")
                                else cfg["render"]["view_azimuth_deg"]
                            )
                            if fs.startswith(("az", "ours", "pts"))
                            else np.nan
                        )
                        rows_out.append(
                            {
                                "file": name,
                                "activity": FILES[name],
                                "features": fs,
                                "method": mname,
                                "azimuth_deg": az,
                                "n_train": n_train,
                                "seed": seed,
                                "n_rows": M,
                                "error_deg": err,
                                "best_params": json.dumps(res.best_params, sort_keys=True),
                            }
                        )
                print(
                    f"{name} N={n_train} seed={seed}: "
                    + ", ".join(
                        f"{r['features']}/{r['method']} {r['error_deg']:.2f}"
                        for r in rows_out[-len(sets) * (len(only) if only else 3) :]
                    ),
                    flush=True,
                )
    return pd.DataFrame(rows_out)


def table(df):
    g = df.groupby(["file", "method", "n_train", "features"], sort=False)["error_deg"]
    m = g.mean().unstack("features")
    s = g.std(ddof=1).unstack("features")
    out = m.copy()
    for c in m.columns:
        out[c] = [f"{a:.2f} ± {b:.2f}" for a, b in zip(m[c], s[c])]
        if c != "theirs":
            out[f"{c}/theirs"] = (m[c] / m["theirs"]).round(2)
    return out.reset_index()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--files", nargs="+", default=list(FILES), choices=list(FILES))
    ap.add_argument("--variants", nargs="+", default=["ours", "ours_scaled", "theirs_unit"])
    ap.add_argument("--sizes", nargs="+", type=int, default=[30, 100])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--cv", type=int, default=5)
    ap.add_argument("--methods", nargs="+", default=None, choices=["1-NN", "SR", "TGP"])
    ap.add_argument(
        "--azimuth",
        type=float,
        default=None,
        help="camera azimuth of the ours* and pts* variants (default: config/datasets.yaml)",
    )
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "tables" / "same_frames.csv")
    a = ap.parse_args()
    with threadpool_limits(1):
        df = run(a.files, a.variants, a.sizes, list(range(a.seeds)), a.cv, a.methods, a.azimuth)
    with atomic_path(a.out) as tmp:
        df.to_csv(tmp, index=False, float_format="%.4f")
    summary = a.out.with_name(a.out.stem + "_summary.csv")
    with atomic_path(summary) as tmp:
        table(df).to_csv(tmp, index=False)
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        print(table(df).to_string(index=False))
    print(f"wrote {a.out} and {summary}")


if __name__ == "__main__":
    main()
