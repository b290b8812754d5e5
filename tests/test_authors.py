"""The authors' pose files: their skeleton, the row alignment with the CMU trials and the angle mapping."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io
from scipy.spatial.transform import Rotation

from bsrbench.authors import (
    HSC_ANGLE_NAMES,
    HSC_JOINTS,
    HSC_ROLE_ORDER,
    align_rows,
    canonical_euler,
    fit_joint_rotations,
    geodesic_deg,
    hsc_positions,
    hsc_rotations,
    hsc_skeleton,
    hsc_stick_figure,
    load_angle_mapping,
    ours_to_hsc_angles,
    save_angle_mapping,
    wrapped_diff,
)
from bsrbench.errors import DataFileError, InputError
from bsrbench.mocap import JOINT_MAPS, parse_bvh
from bsrbench.mocap.skeleton import euler_matrix, local_transforms

ROOT = Path(__file__).resolve().parents[1]
FEAT = ROOT / "resources" / "paper-features"
CMU = ROOT / "resources" / "cmu-mocap"


def _their_y(name):
    return np.asarray(scipy.io.loadmat(FEAT / name)["Y"], dtype=float)


def test_skeleton_columns_and_role_order():
    sk = hsc_skeleton()
    assert sk.n_channels == 60 and len(HSC_JOINTS) == 19 and len(HSC_ANGLE_NAMES) == 57
    assert HSC_ANGLE_NAMES[2] == "Hips_Yrotation"  # the heading column of the authors' files
    assert sorted(HSC_ROLE_ORDER) == sorted(HSC_JOINTS)
    # role k is a joint of the same side and kind as JOINT_MAPS["daz"][k]
    for ours, theirs in zip(JOINT_MAPS["daz"], HSC_ROLE_ORDER):
        if ours[0] in "lr" and ours[1].isupper():
            assert theirs.startswith({"l": "Left", "r": "Right"}[ours[0]]), (ours, theirs)


def test_rest_rows_pose_a_t_pose_and_zero_angles_hang_the_arms():
    Y = _their_y("x09.mat")
    sk = hsc_skeleton()
    P = hsc_positions(Y[:1, 3:])[0]  # row 0: the converter's rest pose of 09_01 (T-pose)
    for side in ("Left", "Right"):
        sh, wr = P[sk.index(f"{side}Shoulder")], P[sk.index(f"{side}Wrist")]
        assert abs(wr[1] - sh[1]) < 1.0 and abs(wr[0] - sh[0]) > 20.0  # arm horizontal, sideways
        assert P[sk.index(f"{side}Ankle")][1] < -30.0  # legs down
    Z = hsc_positions(np.zeros(57))[0]
    assert (
        Z[sk.index("LeftWrist")][1] < Z[sk.index("LeftShoulder")][1] - 20.0
    )  # their rest pose: arms down
    with pytest.raises(InputError, match=r"expected rows of 57 angles"):
        hsc_positions(np.zeros(56))
    pos, parents = hsc_stick_figure(Y[5, 3:])
    np.testing.assert_allclose(pos, hsc_positions(Y[5:6, 3:])[0])
    np.testing.assert_allclose(pos[0], 0.0)
    bones = np.linalg.norm(pos[1:] - pos[parents[1:]], axis=1)  # FK keeps every bone's length
    np.testing.assert_allclose(bones, np.linalg.norm(sk.offsets[1:], axis=1), rtol=1e-9)
    with pytest.raises(InputError, match=r"hsc_stick_figure: expected the 57 angles of one pose"):
        hsc_stick_figure(Y[5])


def test_canonical_euler_is_their_zxy_decomposition():
    R = Rotation.random(200, random_state=0).as_matrix()
    e = canonical_euler(R)
    assert np.all(np.abs(e[:, 1]) <= 90.0 + 1e-9)
    np.testing.assert_allclose(euler_matrix([2, 0, 1], e), R, atol=1e-9)
    # a knee bent by 120 degrees about x reads (180, 60, 180), as in the authors' rows
    np.testing.assert_allclose(
        np.abs(canonical_euler(euler_matrix([0], [[120.0]]))[0]), [180.0, 60.0, 180.0], atol=1e-9
    )


def test_fit_joint_rotations_recovers_planted_rotations():
    rng = np.random.default_rng(1)
    A = Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix()
    B = Rotation.from_rotvec([-1.2, 0.4, 0.1]).as_matrix()
    Ro = Rotation.random(300, random_state=2).as_matrix()
    noise = Rotation.from_rotvec(rng.normal(scale=0.01, size=(300, 3))).as_matrix()
    Rt = A @ Ro @ B @ noise
    A_hat, B_hat, res = fit_joint_rotations(Rt, Ro)
    assert geodesic_deg(A, A_hat) < 0.5 and geodesic_deg(B, B_hat) < 0.5
    assert np.median(res) < 2.0


def test_align_rows_finds_a_planted_trial():
    rng = np.random.default_rng(3)
    P = np.cumsum(rng.normal(size=(121, 3)), axis=0) * [1.0, 0.3, 5.0]  # a 120 fps root trajectory
    filler = rng.normal(size=(20, 3)) * 40.0
    rows = np.vstack([filler, 0.44 * P[2::4] + [3.0, -10.0, 1.0], filler])
    m = align_rows(rows, [("planted", P)])[0]
    assert (m["phase"], m["start_row"], m["n_rows"]) == (2, 20, 30)
    assert m["score"] < 1e-9
    np.testing.assert_allclose(m["slope"], 0.44)
    with pytest.raises(InputError, match=r"root translation"):
        align_rows(rows[:, :2], [("planted", P)])


def test_x09_rows_are_09_01_at_every_4th_frame():
    Y = _their_y("x09.mat")
    m = align_rows(Y[:80, :3], [("09_01", parse_bvh(CMU / "09_01.bvh").motion[:, :3])])[0]
    assert (m["phase"], m["start_row"], m["n_rows"]) == (0, 0, 38) and m["score"] < 0.05


def test_committed_mapping_reproduces_their_angles():
    """Our 09_02 poses, written in their convention with the committed mapping, equal their rows 39-70."""
    A, B, our_joints, kind = load_angle_mapping(FEAT / "alignment" / "x09_mapping.csv")
    assert kind == "daz" and our_joints == JOINT_MAPS["daz"]
    rows = pd.read_csv(FEAT / "alignment" / "x09_rows.csv", dtype={"trial": str})
    r = rows[(rows["trial"] == "09_02") & (rows["frame_120fps"] > 0)]
    assert len(r) == 32 and list(r["frame_120fps"]) == list(range(4, 131, 4))
    b = parse_bvh(CMU / "09_02.bvh")
    R, _ = local_transforms(b.skeleton, b.motion)
    R = R[r["frame_120fps"].to_numpy()][:, [b.skeleton.index(j) for j in our_joints]]
    theirs = _their_y("x09.mat")[r["row"].to_numpy(), 3:]
    err = np.abs(wrapped_diff(theirs, ours_to_hsc_angles(R, A, B)))
    assert np.median(err) < 1.0 and err.mean() < 4.0
    # without the mapping (A = B = I) their rows are far from ours
    eye = np.broadcast_to(np.eye(3), A.shape)
    assert np.abs(wrapped_diff(theirs, ours_to_hsc_angles(R, eye, eye))).mean() > 3 * err.mean()
    # the mapping is a rotation-level fit: hsc_rotations of their rows are close to A R B
    Rt = hsc_rotations(theirs)
    k = HSC_ROLE_ORDER.index("LeftShoulder")
    assert (
        np.median(geodesic_deg(Rt[:, HSC_JOINTS.index("LeftShoulder")], A[k] @ R[:, k] @ B[k]))
        < 0.5
    )


def test_mapping_file_round_trip_and_errors(tmp_path):
    A = Rotation.random(19, random_state=4).as_matrix()
    B = Rotation.random(19, random_state=5).as_matrix()
    p = tmp_path / "m.csv"
    save_angle_mapping(p, A, B, JOINT_MAPS["daz"], "daz")
    A2, B2, j, kind = load_angle_mapping(p)
    np.testing.assert_allclose(A2, A, atol=1e-12)
    np.testing.assert_allclose(B2, B, atol=1e-12)
    assert j == JOINT_MAPS["daz"] and kind == "daz"
    df = pd.read_csv(p)
    df.drop(columns=["B_z"]).to_csv(p, index=False)
    with pytest.raises(DataFileError, match=r"m\.csv: has no column\(s\) \['B_z'\]"):
        load_angle_mapping(p)
