"""The root's pose angles: AMC trials in the authors' Z X Y Euler order, BVH trials as their files give them."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from bsrbench.config import load_datasets
from bsrbench.datasets import prepare_motion
from bsrbench.errors import InputError
from bsrbench.kinematics import features_pose_skeleton
from bsrbench.mocap import (
    AMC_ROOT_ORDER,
    JOINT_MAPS,
    load_motion,
    parse_amc,
    parse_asf,
    parse_bvh,
    read_trial,
    reexpress_amc_rotation,
    trial_pose_positions,
    unwrap_degrees,
)
from bsrbench.mocap.asf import _order_matrix, asf_positions
from bsrbench.mocap.skeleton import ROTATION_AXES, euler_matrix

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "resources" / "cmu-mocap"
DATA = Path(__file__).resolve().parent / "data"
ZXY = [ROTATION_AXES[ch] for ch in AMC_ROOT_ORDER]


def _datasets():
    return load_datasets(yaml.safe_load((ROOT / "config" / "datasets.yaml").read_text()))


def _max_step(a):
    return float(np.abs(np.diff(a, axis=0)).max())


@pytest.mark.parametrize("amc_axes", ["XYZ", "ZYX", "YZX", "XZY"])
def test_reexpressed_angles_are_the_same_rotation(amc_axes):
    """For random angles, the Z X Y angles give the rotation matrix of the AMC angles (the AMC reader's own
    composition, ``_order_matrix``, against the BVH one, ``euler_matrix``), with X in [-90, 90]."""
    rng = np.random.default_rng(12)
    angles = rng.uniform(-180.0, 180.0, size=(500, 3))
    channels = [f"{a}rotation" for a in amc_axes]
    out = reexpress_amc_rotation(angles, channels)
    np.testing.assert_allclose(
        euler_matrix(ZXY, out), _order_matrix(amc_axes, angles), rtol=0, atol=1e-12
    )
    assert np.all(np.abs(out[:, 1]) <= 90.0) and np.all(np.abs(out) <= 180.0)
    # in X Y Z order the same angles read as Z X Y would be another rotation (the test can fail)
    assert np.abs(euler_matrix(ZXY, angles) - _order_matrix(amc_axes, angles)).max() > 0.5


def _turn(n=240):
    """A figure turning twice round (heading 0 -> 720 degrees) with a small sway: the authors' Z X Y angles
    and the same rotations as AMC X Y Z angles (R = Rz Ry Rx, the heading the middle angle)."""
    t = np.linspace(0.0, 1.0, n)
    zxy = np.column_stack([8 * np.sin(6 * np.pi * t), 5 * np.cos(4 * np.pi * t), 720.0 * t])
    R = euler_matrix(ZXY, zxy)
    xyz = Rotation.from_matrix(R).as_euler("xyz", degrees=True)  # extrinsic: x applied first
    return zxy, xyz


def test_reexpression_is_continuous_through_a_turn():
    """As AMC X Y Z angles the turn swings by about 180 degrees in X and Z each time the heading passes 90;
    re-expressed and unwrapped, every angle moves by at most a few degrees a frame and the heading is the
    turn's own."""
    zxy, xyz = _turn()
    assert _max_step(unwrap_degrees(xyz)) > 150.0
    out = unwrap_degrees(reexpress_amc_rotation(xyz, ["Xrotation", "Yrotation", "Zrotation"]))
    assert _max_step(out) < 5.0
    np.testing.assert_allclose(out, zxy, atol=1e-9)


def _amc_with_root(tmp_path, root_angles):
    """The test AMC's first frame repeated with the root rotation of each row of ``root_angles`` (X Y Z)."""
    lines = (DATA / "01_01.amc").read_text().splitlines()
    head = lines[: lines.index("1")]
    body = lines[lines.index("1") + 1 : lines.index("2")]
    out = list(head)
    for k, (rx, ry, rz) in enumerate(root_angles):
        out.append(str(k + 1))
        for ln in body:
            if ln.startswith("root "):
                tx, ty, tz = ln.split()[1:4]
                ln = f"root {tx} {ty} {tz} {rx:.10f} {ry:.10f} {rz:.10f}"
            out.append(ln)
    (tmp_path / "01.asf").write_text((DATA / "01.asf").read_text())
    (tmp_path / "01_01.amc").write_text("\n".join(out) + "\n")
    return tmp_path / "01_01.amc"


def test_load_motion_writes_an_amc_root_in_zxy_without_a_swing(tmp_path):
    """Through load_motion and prepare_motion: the AMC root columns are root_Z/X/Yrotation, continuous over the
    turn, the heading column (2) is the turn's heading, and the other joints keep the file's angles."""
    zxy, xyz = _turn()
    path = _amc_with_root(tmp_path, xyz)
    m = load_motion(path, drop_first_frame=False)
    assert m.angle_names[:3] == ["root_Zrotation", "root_Xrotation", "root_Yrotation"]
    assert _max_step(m.angles[:, :3]) < 5.0
    np.testing.assert_allclose(m.angles[:, :3], zxy, atol=1e-6)  # the file prints 10 decimals
    raw = parse_amc(path, tmp_path / "01.asf").motion
    sk = parse_asf(tmp_path / "01.asf").skeleton
    j, k = sk.index("lfemur"), 3 * JOINT_MAPS["asf"].index("lfemur")
    start = sk.channel_starts()[j]
    np.testing.assert_array_equal(m.angles[:, k : k + 3], raw[:, start : start + 3])
    with np.load(_prepared(path, tmp_path)) as z:
        hc = int(z["heading_column"])
        assert hc == 2 and str(z["angle_names"][hc]) == "root_Yrotation"
        np.testing.assert_allclose(z["angles"][:, hc], zxy[:, 2], atol=1e-6)


def _prepared(path, tmp_path):
    out = tmp_path / "prepared.npz"
    prepare_motion(
        [path], out, n_frames=10_000, frame_selection="first", fewer_frames="use_all", skip_frames=0
    )
    return out


def test_navigate_root_has_no_jump_at_30_fps(tmp_path):
    """Navigate (09_12.amc) as the workflow prepares it: the file's X Y Z root angles step by more than 30
    degrees between consecutive 30 fps frames as the figure turns; the pose's Z X Y root columns do not."""
    data = _datasets()
    d = data.dataset("mocap", "navigate")
    sel = prepare_motion(
        [ROOT / f for f in d["files"]],
        tmp_path / "navigate.npz",
        asf=ROOT / d["asf"],
        **{**data.motion_params("mocap", "navigate"), "checksums": ROOT / d["checksums"]},
    )
    amc = parse_amc(ROOT / d["files"][0], parse_asf(ROOT / d["asf"]))
    stored = unwrap_degrees(amc.motion[sel.trial_frames, 3:6])
    assert _max_step(stored) > 30.0
    assert sel.angle_names[:3] == ["root_Zrotation", "root_Xrotation", "root_Yrotation"]
    assert _max_step(sel.angles[:, :3]) < 30.0
    # the same rotations, frame by frame
    np.testing.assert_allclose(
        euler_matrix(ZXY, sel.angles[:, :3]), _order_matrix("XYZ", stored), atol=1e-12
    )


def _file_angles(entry, data, activity):
    """The pose angles read straight from the BVH files: each pose joint's rotation channels in the file's
    order (from the CHANNELS lines), the leading frames skipped, unwrapped over the concatenation."""
    params = data.motion_params("mocap", activity)
    joints = JOINT_MAPS[params["skeleton_kind"] or _kind(entry)]
    rows = []
    for f in entry["files"]:
        b = parse_bvh(ROOT / f)
        starts = b.skeleton.channel_starts()
        cols = [
            starts[b.skeleton.index(jn)] + k
            for jn in joints
            for k, ch in enumerate(b.skeleton.channels[b.skeleton.index(jn)])
            if ch.endswith("rotation")
        ]
        rows.append(b.motion[int(params["skip_frames"]) :, cols])
    return np.unwrap(np.concatenate(rows), period=360.0, axis=0)


def _kind(entry):
    return "3dsmax" if any("131_" in f for f in entry["files"]) else "daz"


def test_bvh_trials_keep_their_files_angles_byte_for_byte():
    """Every BVH entry's pose angles are its files' rotation channels, unwrapped, bit for bit (the root's
    order is not touched; their roots do not swing), and the heading column stays the file's Yrotation."""
    data = _datasets()
    bvh = [
        a
        for s, a in data.datasets_of("mocap", enabled_only=True)
        if data.dataset(s, a)["format"] == "bvh"
    ]
    assert len(bvh) >= 4
    for activity in bvh:
        entry = data.dataset("mocap", activity)
        params = data.motion_params("mocap", activity)
        m = load_motion(
            [ROOT / f for f in entry["files"]],
            skeleton_kind=params["skeleton_kind"],
            skip_frames=params["skip_frames"],
        )
        expect = _file_angles(entry, data, activity)
        assert m.angles.tobytes() == expect.tobytes(), activity
        assert m.angle_names[1].endswith("_Yrotation"), activity


def test_mpjpe_skeleton_reads_navigate_root_in_zxy():
    """The skeleton that scores navigate's poses turns the Z X Y root columns into the AMC's own root rotation:
    its joint positions equal the AMC's (the root at the origin, the joints outside the pose held at zero)."""
    data = _datasets()
    d = data.dataset("mocap", "navigate")
    asf = parse_asf(ROOT / d["asf"])
    m = load_motion(ROOT / d["files"][0], asf=asf, skip_frames=0)
    idx = np.arange(0, m.n_frames, 97)
    feats = {
        "pose_joints": np.array(m.pose_joints),
        "files": np.array([str(ROOT / d["files"][0])]),
        "skeleton_kind": np.array("asf"),
        "angle_names": np.array(m.angle_names),
        "Y": m.angles[idx],
    }
    ps = features_pose_skeleton(feats, "mocap/navigate")
    got = ps.positions(m.angles[idx])
    amc = parse_amc(ROOT / d["files"][0], asf).motion[idx]
    sk = asf.skeleton
    keep = np.zeros(sk.n_channels, dtype=bool)
    for jn, st in zip(sk.joint_names, sk.channel_starts()):
        if jn in m.pose_joints:
            for k, ch in enumerate(sk.channels[sk.index(jn)]):
                keep[st + k] = ch.endswith("rotation")
    want = asf_positions(asf, np.where(keep, amc, 0.0))
    want = (want - want[:, :1]) * ps.mm_per_unit
    np.testing.assert_allclose(got, want, atol=1e-9)
    # the file's own X Y Z root values in those columns would turn the body elsewhere (the test can fail)
    wrong = m.angles[idx].copy()
    wrong[:, :3] = amc[:, 3:6]
    assert np.abs(ps.positions(wrong) - want).max() > 100.0


@pytest.mark.parametrize(
    "files, asf, skip",
    [
        (["resources/cmu-mocap/09_12.amc"], "resources/cmu-mocap/09.asf", 0),
        (["resources/cmu-mocap/12_02.bvh"], None, 6),
    ],
)
def test_trial_pose_positions_give_the_files_pose_for_the_true_angles(files, asf, skip):
    """A frame's own pose angles (Z X Y root for the AMC) put back into its trial give the file's joint positions
    (root-centred), through the turn for navigate; another frame's angles give another pose."""
    m = load_motion(
        [ROOT / f for f in files], asf=None if asf is None else ROOT / asf, skip_frames=skip
    )
    trial = read_trial(ROOT / files[0], None if asf is None else ROOT / asf)
    for k in (0, 500, 510, 516, 530, m.n_frames - 1):
        tf = int(m.trial_frames[k])
        got = trial_pose_positions(trial, tf, m.pose_joints, m.angles[k])
        np.testing.assert_allclose(got, m.positions[k] - m.positions[k, 0], atol=1e-9)
    other = trial_pose_positions(trial, int(m.trial_frames[0]), m.pose_joints, m.angles[300])
    assert np.abs(other - (m.positions[0] - m.positions[0, 0])).max() > 1.0
    with pytest.raises(InputError, match=r"expected 57 pose angles .* got shape \(56,\)"):
        trial_pose_positions(trial, 0, m.pose_joints, m.angles[0][:56])
