"""MPJPE and PA-MPJPE by forward kinematics: hand-computed chains, alignment invariances, the sources' skeletons."""

from pathlib import Path

import naive
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bsrbench import kinematics as K
from bsrbench.authors import HSC_JOINTS, hsc_positions
from bsrbench.errors import InputError
from bsrbench.mocap import JOINT_MAPS, Skeleton, parse_bvh

ROOT = Path(__file__).resolve().parents[1]
DAZ_BVH = ROOT / "resources" / "cmu-mocap" / "12_02.bvh"
MAX_BVH = ROOT / "resources" / "cmu-mocap" / "131_02.bvh"


def _two_bone_chain(mm_per_unit=10.0):
    """root (Z rotation) -> joint 1 at (1, 0, 0) (X rotation) -> end at (0, 1, 0) from joint 1; all 3 scored."""
    skel = Skeleton(
        ["root", "j1", "j1_End"],
        [-1, 0, 1],
        [(0, 0, 0), (1, 0, 0), (0, 1, 0)],
        [("Zrotation",), ("Xrotation",), ()],
        [False, False, True],
    )
    return K.PoseSkeleton(
        source="chain",
        parents=skel.parents,
        offsets=skel.offsets,
        local_rotations=K._bvh_rotations(skel),
        n_channels=2,
        columns=[0, 1],
        angle_names=["root_Zrotation", "j1_Xrotation"],
        scored=[0, 1, 2],
        mm_per_unit=mm_per_unit,
    )


def test_two_bone_chain_positions_and_errors_by_hand():
    ps = _two_bone_chain()
    # zero pose: root at 0, j1 at (1,0,0), end at (1,1,0); times 10 mm per unit
    np.testing.assert_allclose(ps.positions([0.0, 0.0])[0], [[0, 0, 0], [10, 0, 0], [10, 10, 0]])
    # Rz(90): j1 at (0,1,0); then Rz(90) Rx(90) (0,1,0) = Rz(90) (0,0,1) = (0,0,1): end at (0,1,1)
    np.testing.assert_allclose(
        ps.positions([90.0, 90.0])[0], [[0, 0, 0], [0, 10, 0], [0, 10, 10]], atol=1e-12
    )
    # Rx(-90) (0,1,0) = (0,0,-1): end at (1,0,-1)
    np.testing.assert_allclose(
        ps.positions([0.0, -90.0])[0], [[0, 0, 0], [10, 0, 0], [10, 0, -10]], atol=1e-12
    )
    truth = np.zeros((2, 2))
    pred = np.array([[90.0, 90.0], [0.0, -90.0]])
    # frame 0: errors 0, |(0,1,0)-(1,0,0)| = sqrt 2, |(0,1,1)-(1,1,0)| = sqrt 2; frame 1: 0, 0, |(0,-1,-1)| = sqrt 2
    expected = 10 * (0 + np.sqrt(2) + np.sqrt(2) + 0 + 0 + np.sqrt(2)) / 6
    assert K.mpjpe(truth, pred, ps) == pytest.approx(expected, rel=1e-12)
    # each predicted triangle (legs 1, 1, hypotenuse sqrt 2) is congruent to the true one: PA-MPJPE 0
    assert K.pa_mpjpe(truth, pred, ps) == pytest.approx(0.0, abs=1e-9)
    assert K.mpjpe(truth, truth, ps) == 0.0


def test_similarity_align_undoes_rotation_scale_translation_but_not_a_mirror():
    rng = np.random.default_rng(0)
    P = rng.normal(size=(19, 3)) * 300
    R = Rotation.from_rotvec([0.3, -1.2, 2.0]).as_matrix()
    Q = 1.7 * P @ R.T + np.array([40.0, -5.0, 900.0])
    np.testing.assert_allclose(K.similarity_align(Q, P), P, atol=1e-8)
    mirrored = P * np.array(
        [-1.0, 1.0, 1.0]
    )  # no proper rotation maps a mirror image of 19 points onto them
    assert np.linalg.norm(K.similarity_align(mirrored, P) - P, axis=1).mean() > 10.0


def test_similarity_align_of_many_poses_equals_scipy_pose_by_pose():
    rng = np.random.default_rng(3)
    P_true = rng.normal(size=(50, 19, 3)) * 300
    P_pred = P_true + rng.normal(size=P_true.shape) * 120  # noisy copies: well-posed alignments
    P_pred[1] = rng.normal(size=(19, 3)) * 300  # unrelated pose: a large residual
    # mirror image: det(V U^T) < 0 before the correction
    P_pred[2] = P_true[2] * np.array([1.0, -1.0, 1.0])
    P_pred[3] = np.array([5.0, -2.0, 7.0])  # all joints at one point: translation only
    got = K.similarity_align(P_pred, P_true)
    want = naive.similarity_align_per_pose(P_pred, P_true)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got[3], np.broadcast_to(P_true[3].mean(axis=0), (19, 3)), atol=1e-12)
    np.testing.assert_allclose(K.similarity_align(P_pred[0], P_true[0]), want[0], atol=1e-9)


def test_pa_mpjpe_is_zero_for_a_root_rotated_copy_of_the_truth():
    ps = K.hsc_pose_skeleton()
    rng = np.random.default_rng(1)
    truth = rng.uniform(-40, 40, size=(6, 57))
    rotated = truth.copy()
    rotated[:, :3] += np.array(
        [70.0, -30.0, 120.0]
    )  # the root's Z X Y angles: the whole body turns
    assert K.mpjpe(truth, rotated, ps) > 100.0
    assert K.pa_mpjpe(truth, rotated, ps) == pytest.approx(0.0, abs=1e-6)
    other = truth + rng.normal(scale=10.0, size=truth.shape)
    assert 0 < K.pa_mpjpe(truth, other, ps) < K.mpjpe(truth, other, ps)


def test_hsc_skeleton_matches_the_authors_forward_kinematics_in_inches():
    ps = K.hsc_pose_skeleton()
    Y = np.random.default_rng(2).uniform(-90, 90, size=(4, 57))
    theirs = hsc_positions(Y)  # (F, 24, 3) in the file's units (inches), root at the origin
    ours = ps.positions(Y) / 25.4
    np.testing.assert_allclose(ours, theirs, atol=1e-9)
    assert [ps.angle_names[3 * k].rsplit("_", 1)[0] for k in range(19)] == HSC_JOINTS
    assert ps.scored.size == 19


@pytest.mark.parametrize("path", [DAZ_BVH, MAX_BVH])
def test_mocap_skeleton_keeps_bone_lengths_in_mm(path):
    ps = K.mocap_pose_skeleton(path)
    skel = parse_bvh(path).skeleton
    kind = "daz" if path == DAZ_BVH else "3dsmax"
    assert ps.mm_per_unit == K.MM_PER_UNIT[kind]
    Y = np.random.default_rng(3).uniform(-120, 120, size=(3, 57))
    P = ps.positions(Y)
    np.testing.assert_allclose(P[:, 0], 0.0, atol=1e-12)
    # every bone keeps its rest length |offset| in any pose (forward kinematics only rotates offsets)
    for j in range(1, len(skel.joint_names)):
        p = skel.parents[j]
        length = np.linalg.norm(P[:, j] - P[:, p], axis=1)
        np.testing.assert_allclose(length, np.linalg.norm(skel.offsets[j]) * ps.mm_per_unit)
    assert [skel.joint_names[j] for j in ps.scored] == JOINT_MAPS[kind]


def test_mocap_angle_names_are_those_of_the_features():
    from bsrbench.mocap import load_motion

    m = load_motion(DAZ_BVH)
    ps = K.mocap_pose_skeleton(DAZ_BVH)
    ps.check_angle_names(m.angle_names)
    names = list(m.angle_names)
    names[18] = "rShldr_Qrotation"
    with pytest.raises(
        InputError, match=r"12_02.bvh: angle_names\[18\] is 'rShldr_Qrotation'.*joint 'rShldr'"
    ):
        ps.check_angle_names(names)


def test_skeleton_that_does_not_give_57_angles_names_source_joint_and_count():
    short = JOINT_MAPS["daz"][:-1]
    with pytest.raises(
        InputError, match=r"mocap/walk: the joint map has 18 joints .*'lShin'.* expected 57 angles"
    ):
        K.mocap_pose_skeleton(DAZ_BVH, joint_map=short, source="mocap/walk")
    wrong = JOINT_MAPS["daz"][:-1] + ["lToe"]
    with pytest.raises(
        InputError, match=r"mocap/walk: pose joint 'lToe' is not in the skeleton \(expected 57"
    ):
        K.mocap_pose_skeleton(DAZ_BVH, joint_map=wrong, source="mocap/walk")


def test_rows_of_the_wrong_width_or_non_finite_are_rejected():
    ps = K.hsc_pose_skeleton(source="hsc/golf")
    with pytest.raises(
        InputError,
        match=r"hsc/golf: true angles have shape \(2, 56\); the skeleton expects rows of 57",
    ):
        K.mpjpe(np.zeros((2, 56)), np.zeros((2, 56)), ps)
    Y = np.zeros((2, 57))
    Y[1, 4] = np.nan
    with pytest.raises(
        InputError,
        match=r"hsc/golf: predicted angles contain a non-finite value at row 1, column 4 \(LeftHip_Xrotation",
    ):
        K.pa_mpjpe(np.zeros((2, 57)), Y, ps)


def test_wrong_length_unit_is_caught_by_the_stature_check():
    from bsrbench.authors import hsc_skeleton

    skel = hsc_skeleton()
    with pytest.raises(
        InputError, match=r"the skeleton's zero pose is 163 mm tall at 2.54 mm per unit"
    ):
        K._check_stature(
            K.PoseSkeleton(
                source="hsc",
                parents=skel.parents,
                offsets=skel.offsets,
                local_rotations=K._bvh_rotations(skel),
                n_channels=skel.n_channels,
                columns=K.hsc_pose_skeleton().columns,
                angle_names=K.hsc_pose_skeleton().angle_names,
                scored=K.hsc_pose_skeleton().scored,
                mm_per_unit=2.54,
            ),
            skel,
        )


def test_features_pose_skeleton_picks_the_source_skeleton():
    from bsrbench.mocap import load_motion

    m = load_motion(DAZ_BVH, skip_frames=6)
    feats = {
        "Y": m.angles,
        "angle_names": np.array(m.angle_names),
        "pose_joints": np.array(m.pose_joints),
        "files": np.array([str(DAZ_BVH)]),
        "skeleton_kind": m.skeleton_kind,
    }
    ps = K.features_pose_skeleton(feats, "mocap/walk")
    assert ps.mm_per_unit == 10.0 and ps.source == "mocap/walk (12_02.bvh)"
    assert K.mpjpe(m.angles[:5], m.angles[:5], ps) == 0.0
    hsc = K.features_pose_skeleton(
        {"Y": np.zeros((3, 57)), "files": np.array(["x09.mat"])}, "hsc/run"
    )
    assert hsc.mm_per_unit == 25.4
    with pytest.raises(
        InputError,
        match=r"hsc/run \(the authors' skeleton\): the features' poses Y have shape \(1, 60\)",
    ):
        K.features_pose_skeleton({"Y": np.zeros((3, 60))}, "hsc/run")
    feats["angle_names"] = feats["angle_names"][:-3]
    with pytest.raises(
        InputError,
        match=r"mocap/walk \(12_02.bvh\): the features' angle_names has 54 angles; the skeleton expects 57",
    ):
        K.features_pose_skeleton(feats, "mocap/walk")
