"""How hard is each data set? Pose spread, frame-to-frame change and 1-NN error, before and after the frame
protocol change (issue 13), for the authors' features (hsc) and ours (mocap).

Per data set:
  spread   mean over the 57 angles of the std over frames (degrees);
  change   mean |wrapped difference| between consecutive frames, over frames and angles (degrees);
  1-NN     error (bsrbench.metrics.mean_angle_error) of the 1-nearest-neighbour regressor at N = 30 random
           training frames, the rest test, heading transform on, mean over 10 splits.

hsc: the first 600 rows of each .mat file (the protocol is unchanged). mocap "before": 600 frames spread evenly
over the 120 fps frames (frame_step 1, spread); "after": one frame in 4 (30 fps), trials in order, the first 600
or all there are (config/datasets.yaml). Both mocap versions are built with the pipeline's own functions
(bsrbench.datasets.prepare_motion and compute_mocap_features, the codebook results/features/codebook.npz and
the render settings of config/datasets.yaml) into benchmarks/results/protocol_stats_cache/.

hsc "rows matched to the trials here": only the rows of x09/x131 that come from the trials in resources/cmu-mocap
(resources/paper-features/alignment), the frames of the mocap "after" sets.

"in their convention": the mocap poses written as the authors' 57 angles (bsrbench.authors, the mapping of
resources/paper-features/alignment/x09_mapping.csv for the Daz skeleton, x131 for the 3dsMax one), to tell the
convention's share of the spread (their knees and elbows flip between Euler branches) from the frames' share.

Writes benchmarks/tables/protocol_stats.csv.

    .venv/bin/python benchmarks/protocol_stats.py
"""

from pathlib import Path

import numpy as np
import pandas as pd
import scipy.io as sio
import yaml
from threadpoolctl import threadpool_limits

from bsrbench.authors import HSC_ROLE_ORDER, load_angle_mapping, ours_to_hsc_angles
from bsrbench.datasets import compute_mocap_features, prepare_motion
from bsrbench.io import atomic_path
from bsrbench.metrics import mean_angle_error
from bsrbench.mocap import parse_bvh
from bsrbench.mocap.skeleton import local_transforms
from bsrbench.models.reference import NearestNeighbourRegressor
from bsrbench.poses import HeadingTransform
from bsrbench.seeds import derive_seed

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"
CACHE = OUT / "protocol_stats_cache"
HSC = {
    "run": "x09.mat",
    "michael_jackson": "x131.mat",
    "acrobatics": "x4921.mat",
    "golf": "x63.mat",
}
MOCAP = ["run", "michael_jackson", "kick_soccer_ball", "walk"]
MAPPING = {"daz": "x09_mapping.csv", "3dsmax": "x131_mapping.csv"}


def spread(Y):
    return float(np.mean(np.std(Y, axis=0)))


def change(Y):
    d = (np.diff(Y, axis=0) + 180.0) % 360.0 - 180.0
    return float(np.mean(np.abs(d)))


def nn1(X, Y, heading_column, name, n_train=30, seeds=10):
    H = HeadingTransform(column=heading_column)
    errs = []
    for s in range(seeds):
        perm = np.random.default_rng(derive_seed("protocol_stats", name, n_train, s)).permutation(
            len(X)
        )
        tr, te = perm[:n_train], perm[n_train:]
        m = NearestNeighbourRegressor(n_neighbors=1).fit(X[tr], H.forward(Y[tr]))
        errs.append(mean_angle_error(Y[te], H.inverse(m.predict(X[te]))))
    return float(np.mean(errs))


def their_convention(motion_npz):
    """The prepared motion's poses as the authors' 57 angles (via the fitted joint mapping)."""
    with np.load(motion_npz) as z:
        files, kind = [str(f) for f in z["files"]], str(z["skeleton_kind"])
        tidx, tfr, pose_joints = (
            z["trial_index"],
            z["trial_frames"],
            [str(j) for j in z["pose_joints"]],
        )
    A, B, our_joints, mkind = load_angle_mapping(
        ROOT / "resources" / "paper-features" / "alignment" / MAPPING[kind]
    )
    assert mkind == kind and our_joints == pose_joints, (mkind, kind, our_joints, pose_joints)
    R = np.empty((len(tidx), len(HSC_ROLE_ORDER), 3, 3))
    for k, f in enumerate(files):
        b = parse_bvh(f)
        Rl, _ = local_transforms(b.skeleton, b.motion)
        idx = [b.skeleton.index(j) for j in pose_joints]
        sel = tidx == k
        R[sel] = Rl[tfr[sel]][:, idx]
    return ours_to_hsc_angles(R, A, B)


def main():
    with open(ROOT / "config" / "datasets.yaml") as fh:
        dcfg = yaml.safe_load(fh)
    fcfg = dcfg["features"]
    codebook = ROOT / "results" / "features" / "codebook.npz"
    rows = []
    for a, f in HSC.items():
        d = sio.loadmat(ROOT / "resources" / "paper-features" / f)
        X, Y = np.asarray(d["X"][:600], float), np.asarray(d["Y"][:600, 3:], float)
        r = {
            "source": "hsc",
            "activity": a,
            "protocol": "first 600 rows (unchanged)",
            "frames": len(Y),
            "spread": spread(Y),
            "change": change(Y),
            "nn1_n30": nn1(X, Y, 2, f"hsc/{a}"),
        }
        rows.append(r)
        print(r, flush=True)
        aligned = ROOT / "resources" / "paper-features" / "alignment" / f"{Path(f).stem}_rows.csv"
        if aligned.is_file():
            m = pd.read_csv(aligned, dtype={"trial": str})
            k = m.loc[m["frame_120fps"] >= 0, "row"].to_numpy()
            X, Y = np.asarray(d["X"][k], float), np.asarray(d["Y"][k, 3:], float)
            r = {
                "source": "hsc",
                "activity": a,
                "protocol": "rows matched to the trials here",
                "frames": len(Y),
                "spread": spread(Y),
                "change": change(Y),
                "nn1_n30": nn1(X, Y, 2, f"hsc/{a}/aligned"),
            }
            rows.append(r)
            print(r, flush=True)
    CACHE.mkdir(parents=True, exist_ok=True)
    for a in MOCAP:
        e = dcfg["datasets"]["mocap"][a]
        for label, opts in (
            ("before", {"frame_step": 1, "frame_selection": "spread", "fewer_frames": "error"}),
            (
                "after",
                {
                    "frame_step": e.get("frame_step", 1),
                    "frame_selection": e["frame_selection"],
                    "fewer_frames": e.get("fewer_frames", "error"),
                },
            ),
        ):
            mpath, fpath = CACHE / f"{a}_{label}_motion.npz", CACHE / f"{a}_{label}_features.npz"
            prepare_motion(
                [ROOT / p for p in e["files"]],
                mpath,
                n_frames=e["n_frames"],
                skip_frames=e["skip_frames"],
                checksums=ROOT / e["checksums"],
                **opts,
            )
            fs = compute_mocap_features(
                mpath,
                codebook,
                fpath,
                render=fcfg["render"],
                n_points=fcfg["shape_context"]["n_points"],
                soft=fcfg["histogram"]["soft"],
                seed=fcfg["seed"],
                name=f"mocap/{a}",
            )
            Y = fs.Y
            Yt = their_convention(mpath)
            r = {
                "source": "mocap",
                "activity": a,
                "protocol": label,
                "frames": len(Y),
                "spread": spread(Y),
                "change": change(Y),
                "nn1_n30": nn1(fs.X, Y, int(fs.meta["heading_column"]), f"mocap/{a}"),
                "spread_their_convention": spread(Yt),
                "change_their_convention": change(Yt),
                "nn1_n30_their_convention": nn1(fs.X, Yt, 2, f"mocap/{a}"),
            }
            rows.append(r)
            print(r, flush=True)
    df = pd.DataFrame(rows)
    (ROOT / "benchmarks" / "tables").mkdir(exist_ok=True)
    with atomic_path(ROOT / "benchmarks" / "tables" / "protocol_stats.csv") as tmp:
        df.to_csv(tmp, index=False, float_format="%.3f")
    with pd.option_context("display.width", 200):
        print(df.to_string(index=False, float_format=lambda v: f"{v:.2f}"))


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()  # --help: usage only
    with threadpool_limits(1):
        main()
