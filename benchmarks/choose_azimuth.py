"""Choose the camera azimuth of the silhouettes on the codebook trials only (never on evaluation trials).

benchmarks/same_frames.py found the camera azimuth to be the stage that separates our features from the
authors' on the run and Michael Jackson frames. Choosing it there would tune the renderer on the evaluation
data, so this script chooses it on the codebook trials of config/datasets.yaml (other subjects and motions):
for each azimuth, the codebook is learned as the pipeline learns it (bsrbench.datasets.learn_codebook_from_trials,
at that azimuth), the trials' frames are prepared with the study's frame protocol (one frame in 4, skip_frames)
and encoded (bsrbench.datasets.compute_mocap_features), and the 1-NN error (heading transform) is measured per
trial with N = 30 random training frames, the rest test, over 10 splits; the score is the mean over trials.

Writes benchmarks/tables/choose_azimuth.csv (one line per azimuth and trial).

    .venv/bin/python benchmarks/choose_azimuth.py [--azimuths 0 45 90 135]
"""

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from threadpoolctl import threadpool_limits

from bsrbench.datasets import compute_mocap_features, learn_codebook_from_trials, prepare_motion
from bsrbench.io import atomic_path
from bsrbench.metrics import mean_angle_error
from bsrbench.models.reference import NearestNeighbourRegressor
from bsrbench.poses import HeadingTransform
from bsrbench.seeds import derive_seed

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "benchmarks" / "results" / "choose_azimuth_cache"


def nn1(X, Y, column, name, n_train=30, seeds=10):
    H = HeadingTransform(column=column)
    errs = []
    for s in range(seeds):
        perm = np.random.default_rng(derive_seed("choose_azimuth", name, n_train, s)).permutation(
            len(X)
        )
        tr, te = perm[:n_train], perm[n_train:]
        m = NearestNeighbourRegressor(n_neighbors=1).fit(X[tr], H.forward(Y[tr]))
        errs.append(mean_angle_error(Y[te], H.inverse(m.predict(X[te]))))
    return float(np.mean(errs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--azimuths", nargs="+", type=float, default=[0.0, 45.0, 90.0, 135.0])
    a = ap.parse_args()
    with open(ROOT / "config" / "datasets.yaml") as fh:
        f = yaml.safe_load(fh)["features"]
    cb = f["codebook"]
    trials = [ROOT / p for p in cb["files"]]
    CACHE.mkdir(parents=True, exist_ok=True)
    rows = []
    for az in a.azimuths:
        render = {**f["render"], "view_azimuth_deg": az}
        cpath = CACHE / f"codebook_az{az:g}.npz"
        learn_codebook_from_trials(
            trials,
            cpath,
            frames_per_trial=cb["frames_per_trial"],
            n_centres=cb["n_centres"],
            render=render,
            n_points=f["shape_context"]["n_points"],
            seed=f["seed"],
            checksums=ROOT / cb["checksums"],
            skip_frames=cb["skip_frames"],
        )
        for t in trials:
            mpath, fpath = CACHE / f"{t.stem}_motion.npz", CACHE / f"{t.stem}_az{az:g}.npz"
            prepare_motion(
                [t],
                mpath,
                n_frames=600,
                frame_selection="first",
                skip_frames=cb["skip_frames"],
                frame_step=4,
                fewer_frames="use_all",
            )
            fs = compute_mocap_features(
                mpath,
                cpath,
                fpath,
                render=render,
                n_points=f["shape_context"]["n_points"],
                soft=f["histogram"]["soft"],
                seed=f["seed"],
                name=f"codebook/{t.stem}",
            )
            err = nn1(fs.X, fs.Y, int(fs.meta["heading_column"]), t.stem)
            rows.append({"azimuth_deg": az, "trial": t.stem, "frames": len(fs.Y), "nn1_n30": err})
            print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    out = ROOT / "benchmarks" / "tables" / "choose_azimuth.csv"
    with atomic_path(out) as tmp:
        df.to_csv(tmp, index=False, float_format="%.3f")
    print(
        df.groupby("azimuth_deg")["nn1_n30"]
        .agg(["mean", "median"])
        .to_string(float_format=lambda v: f"{v:.2f}")
    )
    print(f"wrote {out}")


if __name__ == "__main__":
    with threadpool_limits(1):
        main()
