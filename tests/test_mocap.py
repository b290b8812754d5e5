"""BVH and ASF/AMC readers, forward kinematics, joint maps and pose extraction (bsrbench.mocap)."""

from pathlib import Path

import numpy as np
import pytest

from bsrbench.errors import DataFileError, InputError
from bsrbench.mocap import (
    JOINT_MAPS,
    Skeleton,
    bone_lengths,
    detect_skeleton_kind,
    forward_kinematics,
    load_motion,
    parse_amc,
    parse_asf,
    parse_bvh,
    skeleton_positions,
    spread_indices,
    write_bvh,
)
from bsrbench.mocap.skeleton import axis_rotation, euler_matrix

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT / "resources" / "cmu-mocap"
DATA = Path(__file__).resolve().parent / "data"


def _header_channels(path):
    """(joint, channels) pairs straight from the file's CHANNELS lines (an independent reading of the header)."""
    out, name = [], None
    for line in Path(path).read_text().splitlines():
        t = line.split()
        if t and t[0] in ("ROOT", "JOINT"):
            name = t[1]
        elif t and t[0] == "CHANNELS":
            out.append((name, tuple(t[2:])))
        elif t and t[0] == "MOTION":
            break
    return out


@pytest.mark.parametrize("name", ["10_01.bvh", "131_02.bvh"])
def test_parse_real_bvh_reads_channel_orders_from_header(name):
    d = parse_bvh(CMU / name)
    header = _header_channels(CMU / name)
    parsed = [
        (n, c)
        for n, c, e in zip(d.skeleton.joint_names, d.skeleton.channels, d.skeleton.end_site)
        if not e
    ]
    assert parsed == header
    lines = (CMU / name).read_text().splitlines()
    frames_line = next(ln for ln in lines if ln.startswith("Frames:"))
    assert d.n_frames == int(frames_line.split()[1])
    assert d.motion.shape[1] == sum(len(c) for _, c in header)
    # Motion rows are read as written: compare the last row with the file's last line.
    last = np.array([ln for ln in lines if ln.strip()][-1].split(), dtype=float)
    np.testing.assert_array_equal(d.motion[-1], last)


@pytest.mark.parametrize("name", ["10_01.bvh", "131_02.bvh"])
def test_fk_bone_lengths_constant_and_equal_offsets(name):
    d = parse_bvh(CMU / name)
    pos = d.positions()
    lengths = bone_lengths(pos, d.skeleton.parents)
    np.testing.assert_allclose(lengths, np.broadcast_to(lengths[0], lengths.shape), atol=1e-9)
    np.testing.assert_allclose(
        lengths[0, 1:], np.linalg.norm(d.skeleton.offsets[1:], axis=1), atol=1e-9
    )
    # y is up: the head is above the feet in every frame (frame 0 is the converter's rest pose).
    names = d.skeleton.joint_names
    head = names.index("head" if "head" in names else "Head")
    foot = names.index("lFoot" if "lFoot" in names else "LeftAnkle")
    assert np.all(pos[:, head, 1] > pos[:, foot, 1])


def test_fk_single_rotation_matches_hand_computation():
    skel = Skeleton(
        ["a", "b", "b_End"],
        [-1, 0, 1],
        [[0, 0, 0], [1, 0, 0], [0, 2, 0]],
        [("Xposition", "Yposition", "Zposition", "Zrotation"), ("Xrotation",), ()],
        [False, False, True],
    )
    motion = np.array([[1.0, 2.0, 3.0, 90.0, 90.0]])
    pos = skeleton_positions(skel, motion)[0]
    # Root at (1,2,3); Rz(90) maps the offset (1,0,0) to (0,1,0); Rx(90) maps (0,2,0) to (0,0,2) and Rz(90)
    # leaves z unchanged, so the end site is at b + (0, 0, 2).
    np.testing.assert_allclose(pos[0], [1, 2, 3], atol=1e-12)
    np.testing.assert_allclose(pos[1], [1, 3, 3], atol=1e-12)
    np.testing.assert_allclose(pos[2], [1, 3, 5], atol=1e-12)


def test_forward_kinematics_composes_parent_rotations():
    parents = np.array([-1, 0, 1])
    F = 4
    rng = np.random.default_rng(0)
    ang = rng.uniform(-180, 180, size=(F, 3))
    R = np.stack(
        [axis_rotation(2, ang[:, 0]), axis_rotation(0, ang[:, 1]), axis_rotation(1, ang[:, 2])],
        axis=1,
    )
    T = np.broadcast_to(np.array([[0.0, 0, 0], [0, 1, 0], [0, 0, 1]]), (F, 3, 3)).copy()
    P, G = forward_kinematics(parents, R, T)
    for f in range(F):
        np.testing.assert_allclose(P[f, 2], P[f, 1] + R[f, 0] @ R[f, 1] @ T[f, 2], atol=1e-12)
        np.testing.assert_allclose(G[f, 2], R[f, 0] @ R[f, 1] @ R[f, 2], atol=1e-12)


def test_round_trip_real_file(tmp_path):
    d = parse_bvh(CMU / "131_02.bvh")
    out = tmp_path / "copy.bvh"
    write_bvh(out, d.skeleton, d.motion, d.frame_time)
    e = parse_bvh(out)
    assert e.skeleton.joint_names == d.skeleton.joint_names
    assert e.skeleton.channels == d.skeleton.channels
    np.testing.assert_array_equal(e.skeleton.parents, d.skeleton.parents)
    np.testing.assert_array_equal(e.skeleton.offsets, d.skeleton.offsets)
    np.testing.assert_array_equal(e.motion, d.motion)
    assert e.frame_time == d.frame_time


def test_round_trip_unusual_channel_order_and_equivalence(tmp_path):
    """A joint written with its channels in another order (values permuted alike) has the same FK."""
    rng = np.random.default_rng(1)
    names = ["r", "j", "j_End"]
    offsets = [[0, 0, 0], [0, 1, 0], [1, 0, 0]]
    motion = rng.uniform(-90, 90, size=(5, 6))
    a = Skeleton(
        names,
        [-1, 0, 1],
        offsets,
        [("Yposition", "Xrotation", "Yrotation"), ("Zrotation", "Xrotation", "Yrotation"), ()],
        [0, 0, 1],
    )
    # Same rotations, positions channel moved: only non-rotation channels may be reordered freely.
    b = Skeleton(
        names,
        [-1, 0, 1],
        offsets,
        [("Xrotation", "Yrotation", "Yposition"), ("Zrotation", "Xrotation", "Yrotation"), ()],
        [0, 0, 1],
    )
    mb = motion[:, [1, 2, 0, 3, 4, 5]]
    write_bvh(tmp_path / "a.bvh", a, motion, 0.01)
    write_bvh(tmp_path / "b.bvh", b, mb, 0.01)
    pa, pb = parse_bvh(tmp_path / "a.bvh"), parse_bvh(tmp_path / "b.bvh")
    assert pb.skeleton.channels[0] == ("Xrotation", "Yrotation", "Yposition")
    np.testing.assert_allclose(pa.positions(), pb.positions(), atol=1e-9)
    # Reordering rotation channels changes the rotation (Euler order matters), so the header must be obeyed.
    c = Skeleton(
        names,
        [-1, 0, 1],
        offsets,
        [("Yposition", "Xrotation", "Yrotation"), ("Xrotation", "Zrotation", "Yrotation"), ()],
        [0, 0, 1],
    )
    assert not np.allclose(skeleton_positions(c, motion[:, [0, 1, 2, 4, 3, 5]]), pa.positions())


# ------------------------------------------------------------------------------------------- bad BVH input


def _lines(name="10_01.bvh"):
    return (CMU / name).read_text().splitlines()


def _motion_start(lines):
    return next(i for i, ln in enumerate(lines) if ln.startswith("Frame Time")) + 1


def test_truncated_bvh(tmp_path):
    lines = _lines()
    p = tmp_path / "t.bvh"
    p.write_text("\n".join(lines[:-5]) + "\n")
    with pytest.raises(DataFileError, match=r"t\.bvh.*truncated.*Frames: 802.*797 motion rows"):
        parse_bvh(p)


def test_row_with_wrong_number_of_channels(tmp_path):
    lines = _lines()
    k = _motion_start(lines) + 10
    lines[k] = " ".join(lines[k].split()[:-1])
    p = tmp_path / "w.bvh"
    p.write_text("\n".join(lines))
    with pytest.raises(
        DataFileError, match=rf"w\.bvh: line {k + 1}: motion row 10 has 131 values; expected 132"
    ):
        parse_bvh(p)


def test_non_number_in_motion(tmp_path):
    lines = _lines()
    k = _motion_start(lines) + 3
    t = lines[k].split()
    t[7] = "abc"
    lines[k] = " ".join(t)
    p = tmp_path / "n.bvh"
    p.write_text("\n".join(lines))
    with pytest.raises(
        DataFileError, match=rf"n\.bvh: line {k + 1}, value 8: 'abc' is not a number"
    ):
        parse_bvh(p)


def test_non_number_in_offset(tmp_path):
    lines = _lines()
    k = next(i for i, ln in enumerate(lines) if "OFFSET" in ln and i > 5)
    lines[k] = lines[k].replace("OFFSET", "OFFSET x1")
    lines[k] = " ".join(lines[k].split()[:4])
    p = tmp_path / "o.bvh"
    p.write_text("\n".join(lines))
    with pytest.raises(DataFileError, match=rf"line {k + 1}: OFFSET: 'x1' is not a number"):
        parse_bvh(p)


def test_missing_file(tmp_path):
    with pytest.raises(DataFileError, match=r"nope\.bvh: file not found"):
        parse_bvh(tmp_path / "nope.bvh")
    with pytest.raises(DataFileError, match=r"nope\.bvh: file not found"):
        load_motion([tmp_path / "nope.bvh"])


def test_joint_map_naming_missing_joint():
    jm = list(JOINT_MAPS["daz"])
    jm[3] = "tail"
    with pytest.raises(
        InputError, match=r"10_01\.bvh: joint_map names joint\(s\) \['tail'\] that the file lacks"
    ):
        load_motion([CMU / "10_01.bvh"], joint_map=jm)
    with pytest.raises(InputError, match=r"lacks"):
        load_motion([CMU / "131_02.bvh"], skeleton_kind="daz")


# ------------------------------------------------------------------------------------------------ poses


def test_daz_and_3dsmax_poses():
    kick = load_motion([CMU / "10_01.bvh"])
    assert kick.skeleton_kind == "daz"
    assert kick.angles.shape == (801, 57) and kick.positions.shape[0] == 801
    assert kick.angle_names[:3] == ["hip_Zrotation", "hip_Yrotation", "hip_Xrotation"]
    assert kick.angle_names[18:21] == ["rShldr_Zrotation", "rShldr_Xrotation", "rShldr_Yrotation"]
    raw = parse_bvh(CMU / "10_01.bvh")
    j = raw.skeleton.index("rShldr")
    col = raw.skeleton.channel_starts()[j]
    # Angles are the file's values (unwrapped: equal modulo 360), frame 0 dropped.
    d = kick.angles[:, 18] - raw.motion[1:, col]
    np.testing.assert_allclose(np.mod(d + 180, 360) - 180, 0, atol=1e-9)
    mj = load_motion([CMU / "131_02.bvh"])
    assert mj.skeleton_kind == "3dsmax" and mj.angles.shape == (1246, 57)
    assert mj.angle_names[0].startswith("Hips_")
    assert detect_skeleton_kind(parse_bvh(CMU / "131_02.bvh").skeleton.joint_names) == "3dsmax"
    for m in (kick, mj):
        assert np.all(np.abs(np.diff(m.angles, axis=0)) <= 180)


def test_concatenation_and_frame_bookkeeping():
    paths = [CMU / "09_01.bvh", CMU / "09_02.bvh"]
    m = load_motion(paths)
    n1, n2 = parse_bvh(paths[0]).n_frames, parse_bvh(paths[1]).n_frames
    assert m.n_frames == n1 - 1 + n2 - 1
    assert m.trial_ids == ["09_01", "09_02"]
    np.testing.assert_array_equal(m.source_frames, np.arange(m.n_frames))
    assert m.trial_index[n1 - 2] == 0 and m.trial_index[n1 - 1] == 1
    assert m.trial_frames[0] == 1 and m.trial_frames[n1 - 1] == 1
    single = load_motion(paths[1])
    np.testing.assert_allclose(m.positions[n1 - 1 :], single.positions)
    kept = load_motion(paths[1], drop_first_frame=False)
    assert kept.n_frames == n2 and kept.trial_frames[0] == 0
    skipped = load_motion(paths, skip_frames=6)
    assert skipped.n_frames == n1 - 6 + n2 - 6 and skipped.trial_frames[0] == 6
    np.testing.assert_allclose(skipped.positions[0], m.positions[5])
    with pytest.raises(InputError, match=r"skip_frames must be an integer >= 0; got -1"):
        load_motion(paths, skip_frames=-1)
    sub = m.take([0, 5, 200])
    np.testing.assert_array_equal(sub.source_frames, [0, 5, 200])
    np.testing.assert_allclose(sub.angles[2], m.angles[200])


def test_unwrap_removes_360_jumps(tmp_path):
    skel = Skeleton(
        ["r", "r_End"],
        [-1, 0],
        [[0, 0, 0], [0, 1, 0]],
        [("Yrotation", "Xrotation", "Zrotation"), ()],
        [0, 1],
    )
    yrot = np.array(
        [0.0, 170.0, 179.0, -179.0, -170.0, 175.0, -175.0]
    )  # a steady turn, wrapped into (-180, 180]
    motion = np.column_stack([yrot, np.zeros_like(yrot), np.zeros_like(yrot)])
    write_bvh(tmp_path / "turn.bvh", skel, motion, 0.01)
    m = load_motion(tmp_path / "turn.bvh", joint_map=["r"], drop_first_frame=False)
    assert m.angle_names == ["r_Yrotation", "r_Xrotation", "r_Zrotation"]
    assert np.all(np.abs(np.diff(m.angles[:, 0])) < 180)
    np.testing.assert_allclose(np.mod(m.angles[:, 0] - yrot, 360), 0, atol=1e-9)


def test_spread_indices_and_short_trial():
    idx = spread_indices(1000, 600)
    assert idx[0] == 0 and idx[-1] == 999 and len(np.unique(idx)) == 600
    with pytest.raises(InputError, match=r"has 100 usable frames but 600 were asked for"):
        spread_indices(100, 600)


# ------------------------------------------------------------------------------------------------ ASF/AMC


def test_asf_fields():
    asf = parse_asf(DATA / "01.asf")
    assert asf.length_unit == 0.45 and asf.angle_unit == "deg"
    assert asf.root_order == ("TX", "TY", "TZ", "RX", "RY", "RZ")
    sk = asf.skeleton
    assert sk.channels[sk.index("lclavicle")] == ("Yrotation", "Zrotation")
    assert asf.limits["lfemur"] == [(-160.0, 20.0), (-70.0, 70.0), (-60.0, 70.0)]
    np.testing.assert_allclose(sk.offsets[sk.index("ltibia")], [0, -4, 0])
    assert set(JOINT_MAPS["asf"]) <= set(sk.joint_names)


def test_amc_matches_equivalent_bvh():
    amc = parse_amc(DATA / "01_01.amc", DATA / "01.asf")
    bvh = parse_bvh(DATA / "01_01_equivalent.bvh")
    assert amc.skeleton.joint_names == bvh.skeleton.joint_names
    np.testing.assert_allclose(amc.positions(), bvh.positions(), atol=1e-9)
    ma = load_motion(DATA / "01_01.amc", drop_first_frame=False)  # finds 01.asf beside the trial
    mb = load_motion(
        DATA / "01_01_equivalent.bvh", joint_map=JOINT_MAPS["asf"], drop_first_frame=False
    )
    assert ma.skeleton_kind == "asf" and ma.angles.shape == (3, 57)
    assert sorted(ma.angle_names) == sorted(mb.angle_names)
    # every joint but the root has the file's angles; the AMC root is written in Z X Y order
    assert ma.angle_names[:3] == ["root_Zrotation", "root_Xrotation", "root_Yrotation"]
    order = [mb.angle_names.index(n) for n in ma.angle_names]
    np.testing.assert_allclose(ma.angles[:, 3:], mb.angles[:, order][:, 3:])
    assert mb.angle_names[:3] == ["root_Zrotation", "root_Yrotation", "root_Xrotation"]
    np.testing.assert_allclose(
        euler_matrix([2, 0, 1], ma.angles[:, :3]),
        euler_matrix([2, 1, 0], mb.angles[:, :3]),
        atol=1e-12,
    )
    np.testing.assert_allclose(ma.positions, mb.positions, atol=1e-9)
    lengths = bone_lengths(ma.positions, ma.parents)
    np.testing.assert_allclose(lengths, np.broadcast_to(lengths[0], lengths.shape), atol=1e-9)


def test_asf_bone_axis_is_applied(tmp_path):
    """``axis 0 0 90`` turns the bone's rx into a rotation about the world y axis (C Rx C^-1 with C = Rz(90))."""
    text = (DATA / "01.asf").read_text()
    # Give lhumerus a 90 degree z axis; its rx then rotates the arm (along +x) about +y.
    i = text.index("name lhumerus")
    j = text.index("axis 0 0 0  XYZ", i)
    text = text[:j] + "axis 0 0 90  XYZ" + text[j + len("axis 0 0 0  XYZ") :]
    (tmp_path / "01.asf").write_text(text)
    amc = (DATA / "01_01.amc").read_text().splitlines()
    first_frame = amc[: amc.index("2")]
    rest = [
        ln
        if ln.startswith((":", "#")) or ln == "1"
        else ln.split()[0] + " 0" * (len(ln.split()) - 1)
        for ln in first_frame
    ]
    rest = [ln.replace("lhumerus 0 0 0", "lhumerus 30 0 0") for ln in rest]
    (tmp_path / "01_01.amc").write_text("\n".join(rest) + "\n")
    m = parse_amc(tmp_path / "01_01.amc", tmp_path / "01.asf")
    pos = m.positions()[0]
    sk = m.skeleton
    arm = pos[sk.index("lradius")] - pos[sk.index("lhumerus")]
    c, s = np.cos(np.deg2rad(30)), np.sin(np.deg2rad(30))
    np.testing.assert_allclose(arm, 3 * np.array([c, 0, -s]), atol=1e-9)


def test_amc_bad_input(tmp_path):
    (tmp_path / "01.asf").write_text((DATA / "01.asf").read_text())
    lines = (DATA / "01_01.amc").read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("lradius"))
    bad = list(lines)
    bad[k] = "lradius 45.0 3.0"
    (tmp_path / "01_01.amc").write_text("\n".join(bad))
    with pytest.raises(
        DataFileError, match=rf"01_01\.amc: line {k + 1}: bone 'lradius' has 2 values; expected 1"
    ):
        parse_amc(tmp_path / "01_01.amc", tmp_path / "01.asf")
    bad = list(lines)
    bad[k] = "lradius forty"
    (tmp_path / "01_01.amc").write_text("\n".join(bad))
    with pytest.raises(
        DataFileError, match=rf"line {k + 1}: bone 'lradius': 'forty' is not a number"
    ):
        parse_amc(tmp_path / "01_01.amc", tmp_path / "01.asf")
    bad = [ln for i, ln in enumerate(lines) if i != k]
    (tmp_path / "01_01.amc").write_text("\n".join(bad))
    with pytest.raises(DataFileError, match=r"frame 1 lacks bones \['lradius'\]"):
        parse_amc(tmp_path / "01_01.amc", tmp_path / "01.asf")
    text = (
        (DATA / "01.asf")
        .read_text()
        .replace("    rtibia rfoot\n", "    rtibia rfoot\n    rfoot tail\n")
    )
    (tmp_path / "01.asf").write_text(text)
    with pytest.raises(
        DataFileError, match=r"01\.asf: line \d+: hierarchy names unknown bone 'tail'"
    ):
        parse_asf(tmp_path / "01.asf")
