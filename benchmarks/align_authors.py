"""Align the authors' pose files with the CMU trials here, and relate their angle convention to ours.

For x09 (run; trials 09_01 .. 09_11) and x131 (Michael Jackson; trial 131_02), with bsrbench.authors:

1. rows -> (trial, frame): every trial at every 4th frame of its 120 fps file (each of the 4 phases) is slid
   along the rows and matched by the root trajectory (the first 3 columns of Y; per-axis affine fit);
2. the angle convention: per joint, constant rotations A, B with R_theirs = A R_ours B on the matched rows
   (our joint map, by role), fitted on the even matched rows and checked on the odd ones; the per-column
   residual of our angles written in their convention; and the plain column-to-column correlations.

Writes resources/paper-features/alignment/{x09,x131}_rows.csv (one line per row of the file),
{x09,x131}_trials.csv (one line per trial), {x09,x131}_joints.csv (A, B and residuals per joint) and
{x09,x131}_columns.csv (per hsc column: our best-correlated column, its line, and the residual after the
rotation mapping) and {x09,x131}_mapping.csv (A and B as rotation vectors, read by
bsrbench.authors.load_angle_mapping). Deterministic, numpy only (a few seconds).

    .venv/bin/python benchmarks/align_authors.py
"""

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.io as sio
from scipy.spatial.transform import Rotation

from bsrbench.authors import (
    HSC_JOINTS,
    HSC_ROLE_ORDER,
    align_rows,
    align_rows_by_angles,
    column_correlations,
    fit_joint_rotations,
    geodesic_deg,
    hsc_rotations,
    ours_to_hsc_angles,
    save_angle_mapping,
    translation_residuals,
    wrapped_diff,
)
from bsrbench.io import atomic_path
from bsrbench.mocap import detect_skeleton_kind, parse_bvh, pose_columns, resolve_joint_map
from bsrbench.mocap.skeleton import local_transforms

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT / "resources" / "cmu-mocap"
FEATURES = ROOT / "resources" / "paper-features"
OUT = FEATURES / "alignment"
FILES = {
    "x09": [f"09_{k:02d}" for k in range(1, 12)],
    "x131": ["131_02"],
}
#: A window matches by the root trajectory when its scale-free residual (RMS residual / RMS spread of the
#: rows) is below this; a trial that does not is matched by its angles (median abs difference below
#: ANGLE_MATCH_DEG, once the mapping is fitted on the trajectory-matched trials).
MATCH_SCORE = 0.05
ANGLE_MATCH_DEG = 3.0


def load_trial(tid):
    """Parsed BVH, root positions (n, 3) of every frame, our 19 pose joints and their local rotations."""
    b = parse_bvh(MOCAP / f"{tid}.bvh")
    kind = detect_skeleton_kind(b.skeleton.joint_names, tid)
    joints = resolve_joint_map(None, kind, b.skeleton.joint_names, tid)
    R, _ = local_transforms(b.skeleton, b.motion)
    idx = [b.skeleton.index(j) for j in joints]
    cols, names = pose_columns(b.skeleton, joints)
    angles = np.where(cols >= 0, b.motion[:, np.maximum(cols, 0)], 0.0)
    return {
        "bvh": b,
        "kind": kind,
        "root": b.motion[:, :3],
        "R": R[:, idx],
        "angles": angles,
        "names": names,
        "joints": joints,
    }


def csv(df, path):
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False, float_format="%.4g")


def run(name):
    Y = np.asarray(sio.loadmat(FEATURES / f"{name}.mat")["Y"], dtype=float)
    trials = {t: load_trial(t) for t in FILES[name]}
    matches = align_rows(Y[:, :3], [(t, d["root"]) for t, d in trials.items()])
    for m in matches:
        m["by"] = "trajectory"
    good = [m for m in matches if m["score"] < MATCH_SCORE]
    # one common scale per axis (the unit change of the renderer's import), from the matched trials
    slope = np.median([m["slope"] for m in good], axis=0)
    res = translation_residuals(Y[:, :3], good, [(t, d["root"]) for t, d in trials.items()], slope)

    # rows -> (trial, frame); overlapping windows (none expected) keep the better score
    R_rows = len(Y)
    row_trial = np.full(R_rows, "", dtype=object)
    row_frame = np.full(R_rows, -1)
    row_tres = np.full(R_rows, np.nan)
    row_score = np.full(R_rows, np.inf)
    row_by = np.full(R_rows, "", dtype=object)
    for m in good:
        rows, frames, r = res[m["trial"]]
        better = m["score"] < row_score[rows]
        row_trial[rows[better]] = m["trial"]
        row_frame[rows[better]] = frames[better]
        row_tres[rows[better]] = np.linalg.norm(r[better], axis=1)
        row_score[rows[better]] = m["score"]
        row_by[rows[better]] = "trajectory"
    matched = np.flatnonzero(row_frame >= 0)

    # our local rotations and angles at the matched rows
    R_ours = np.stack([trials[row_trial[r]]["R"][row_frame[r]] for r in matched])  # (M, 19, 3, 3)
    A_ours = np.stack([trials[row_trial[r]]["angles"][row_frame[r]] for r in matched])
    names_ours = trials[row_trial[matched[0]]]["names"]
    joints_ours = trials[row_trial[matched[0]]]["joints"]
    R_th = hsc_rotations(Y[matched])  # (M, 19, 3, 3) in HSC_JOINTS order
    # fit on even matched rows, check on odd ones; frames where our file has its rest pose (frame 0) are
    # the converter's, not the motion: they are kept in the row table but left out of the fit
    usable = row_frame[matched] > 0
    fit_set = usable & (np.arange(len(matched)) % 2 == 0)
    check_set = usable & (np.arange(len(matched)) % 2 == 1)
    A, B, jrows = [], [], []
    for k, j in enumerate(HSC_ROLE_ORDER):
        c = HSC_JOINTS.index(j)
        a, b, _ = fit_joint_rotations(R_th[fit_set, c], R_ours[fit_set, k])
        A.append(a)
        B.append(b)
        res_all = geodesic_deg(R_th[:, c], a @ R_ours[:, k] @ b)
        ident = geodesic_deg(R_th[:, c], R_ours[:, k])
        jrows.append(
            {
                "hsc_joint": j,
                "our_joint": joints_ours[k],
                "A_rotvec_deg": " ".join(
                    f"{v:.1f}" for v in np.rad2deg(Rotation.from_matrix(a).as_rotvec())
                ),
                "B_rotvec_deg": " ".join(
                    f"{v:.1f}" for v in np.rad2deg(Rotation.from_matrix(b).as_rotvec())
                ),
                "A_angle_deg": float(geodesic_deg(np.eye(3), a)),
                "B_angle_deg": float(geodesic_deg(np.eye(3), b)),
                "residual_median_fit": float(np.median(res_all[fit_set])),
                "residual_median_check": float(np.median(res_all[check_set])),
                "residual_p90_check": float(np.percentile(res_all[check_set], 90)),
                "identity_median": float(np.median(ident[usable])),
                "their_motion_median": float(np.median(geodesic_deg(R_th[usable, c], np.eye(3)))),
            }
        )
    A, B = np.stack(A), np.stack(B)

    # trials the trajectory does not place (09_10: its root channels are broken, in our file and in
    # theirs): place them by their angles in the fitted convention, on rows not yet taken
    for i, m in enumerate(matches):
        if m["score"] < MATCH_SCORE:
            continue
        d = trials[m["trial"]]
        ma = align_rows_by_angles(Y[:, 3:], ours_to_hsc_angles(d["R"], A, B))
        ma.update(trial=m["trial"], by="angles")
        rows = np.arange(ma["start_row"], ma["start_row"] + ma["n_rows"])
        if ma["score"] < ANGLE_MATCH_DEG and (row_frame[rows] < 0).all():
            row_trial[rows] = m["trial"]
            row_frame[rows] = ma["phase"] + 4 * np.arange(ma["n_rows"])
            row_by[rows] = "angles"
            matches[i] = ma
        else:
            matches[i]["by"] = "none"
    new = np.flatnonzero(row_frame >= 0)
    if len(new) > len(matched):
        extra = np.setdiff1d(new, matched)
        R_ours = np.concatenate([R_ours, [trials[row_trial[r]]["R"][row_frame[r]] for r in extra]])
        A_ours = np.concatenate(
            [A_ours, [trials[row_trial[r]]["angles"][row_frame[r]] for r in extra]]
        )
        R_th = np.concatenate([R_th, hsc_rotations(Y[extra])])
        order = np.argsort(np.concatenate([matched, extra]), kind="stable")
        matched = np.concatenate([matched, extra])[order]
        R_ours, A_ours, R_th = R_ours[order], A_ours[order], R_th[order]
        # the added rows are outside both the fit and the check sets
        fit_set = np.concatenate([fit_set, np.zeros(len(extra), bool)])[order]
        check_set = np.concatenate([check_set, np.zeros(len(extra), bool)])[order]
        usable = np.concatenate([usable, row_frame[extra] > 0])[order]
    pred = ours_to_hsc_angles(R_ours, A, B)
    err = np.abs(wrapped_diff(Y[matched, 3:], pred))  # (M, 57)
    row_aerr = np.full(R_rows, np.nan)
    row_aerr[matched] = err.mean(1)
    row_geo = np.full(R_rows, np.nan)
    row_geo[matched] = np.stack(
        [
            geodesic_deg(R_th[:, HSC_JOINTS.index(j)], A[k] @ R_ours[:, k] @ B[k])
            for k, j in enumerate(HSC_ROLE_ORDER)
        ],
        axis=1,
    ).mean(1)

    rows_df = pd.DataFrame(
        {
            "row": np.arange(R_rows),
            "trial": row_trial,
            "frame_120fps": row_frame,
            "matched_by": row_by,
            "translation_residual": row_tres,
            "angle_residual_deg": row_aerr,
            "rotation_residual_deg": row_geo,
        }
    )
    trials_df = pd.DataFrame(
        [
            {
                "trial": m["trial"],
                "frames_120fps": len(trials[m["trial"]]["root"]),
                "phase": m["phase"],
                "start_row": m["start_row"],
                "n_rows": m["n_rows"],
                "matched_by": m["by"],
                "score": m["score"],
                "slope_x": m["slope"][0],
                "slope_y": m["slope"][1],
                "slope_z": m["slope"][2],
                "rms_x": m["rms"][0],
                "rms_y": m["rms"][1],
                "rms_z": m["rms"][2],
            }
            for m in matches
        ]
    )
    corr = column_correlations(Y[matched][usable, 3:], A_ours[usable], names_ours)
    cols_df = pd.DataFrame(corr)
    cols_df["mapped_rms_deg_check"] = np.sqrt((err[check_set] ** 2).mean(0))
    cols_df["mapped_median_abs_deg_check"] = np.median(err[check_set], axis=0)
    cols_df["their_std_deg"] = Y[matched][usable, 3:].std(0)
    OUT.mkdir(parents=True, exist_ok=True)
    csv(rows_df, OUT / f"{name}_rows.csv")
    csv(trials_df, OUT / f"{name}_trials.csv")
    csv(pd.DataFrame(jrows), OUT / f"{name}_joints.csv")
    csv(cols_df, OUT / f"{name}_columns.csv")
    save_angle_mapping(
        OUT / f"{name}_mapping.csv", A, B, joints_ours, trials[row_trial[matched[0]]]["kind"]
    )
    print(
        f"== {name}: {len(matched)} of {R_rows} rows matched; common slope per axis {np.round(slope, 4)}"
    )
    print(trials_df.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(pd.DataFrame(jrows).to_string(index=False, float_format=lambda v: f"{v:.1f}"))
    print(cols_df.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    print(
        "mean angle residual over matched rows (deg):",
        np.nanmean(row_aerr),
        " median translation residual:",
        np.nanmedian(row_tres),
    )
    return rows_df, trials_df


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--files", nargs="*", default=list(FILES), choices=list(FILES))
    args = ap.parse_args()
    for name in args.files:
        run(name)


if __name__ == "__main__":
    main()
