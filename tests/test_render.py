"""Silhouette renderer: geometry of a synthetic T-pose, symmetry, view direction, determinism, input errors."""

import numpy as np
import pytest

from bsrbench.errors import InputError
from bsrbench.render import fit_camera, joint_part, render_silhouettes, save_montage
from bsrbench.render._kernels import rasterize, rasterize_numpy
from bsrbench.render.body import PART_RADIUS, ellipsoid_frames

STATURE = 170.0


def t_pose():
    """A Daz-named skeleton (hip, abdomen, ..., rFoot_End) in a T-pose facing +z, root at (5, 95, -3).

    Returns positions (1, J, 3), parents, names. Arms along x at shoulder height, legs straight down, feet
    pointing +z; the skeleton is exactly mirror-symmetric in x about the root.
    """
    joints = [
        ("hip", None, (0.0, 0.0, 0.0)),
        ("abdomen", "hip", (0.0, 20.0, 0.0)),
        ("chest", "abdomen", (0.0, 12.0, 0.0)),
        ("neck", "chest", (0.0, 22.0, 0.0)),
        ("head", "neck", (0.0, 8.0, 0.0)),
        ("head_End", "head", (0.0, 14.0, 0.0)),
    ]
    for s, sign in (("l", 1.0), ("r", -1.0)):
        joints += [
            (f"{s}Collar", "chest", (sign * 3.0, 19.0, 0.0)),
            (f"{s}Shldr", f"{s}Collar", (sign * 10.0, 0.0, 0.0)),
            (f"{s}ForeArm", f"{s}Shldr", (sign * 28.0, 0.0, 0.0)),
            (f"{s}Hand", f"{s}ForeArm", (sign * 23.0, 0.0, 0.0)),
            (f"{s}Hand_End", f"{s}Hand", (sign * 9.0, 0.0, 0.0)),
            (f"{s}Buttock", "hip", (sign * 9.0, 0.0, 0.0)),
            (f"{s}Thigh", f"{s}Buttock", (0.0, -2.0, 0.0)),
            (f"{s}Shin", f"{s}Thigh", (0.0, -41.0, 0.0)),
            (f"{s}Foot", f"{s}Shin", (0.0, -42.0, 0.0)),
            (f"{s}Foot_End", f"{s}Foot", (0.0, -5.0, 14.0)),
        ]
    names = [j[0] for j in joints]
    parents = np.array([-1 if j[1] is None else names.index(j[1]) for j in joints])
    pos = np.zeros((len(joints), 3))
    for k, (_, parent, offset) in enumerate(joints):
        pos[k] = (pos[names.index(parent)] if parent else np.array([5.0, 95.0, -3.0])) + offset
    return pos[None], parents, names


def extent(mask):
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    return (
        rows[-1] - rows[0] + 1,
        cols[-1] - cols[0] + 1,
        (rows[0] + rows[-1] + 1) / 2,
        (cols[0] + cols[-1] + 1) / 2,
    )


def radius_of(body, part):
    return body.capsule_radii[body.capsule_parts.index(part)]


def ellipsoid(body, name):
    return next(e for e in body.ellipsoids if e.name == name)


def world_extent(body, pos, axis):
    """Extent of the body along a world axis: capsule ends +- radii, ellipsoid centre +- |A^T e| (the half
    extent of {c + A u : |u| <= 1} along the unit vector e)."""
    rel = pos - pos[:, :1]
    ends = rel[0][body.capsule_joints, axis]  # (C, 2)
    r = body.capsule_radii[:, None]
    lo, hi = (ends - r).min(), (ends + r).max()
    for e in body.ellipsoids:
        centre, axes = ellipsoid_frames(e, rel)
        half = np.linalg.norm(axes[0][axis])
        lo, hi = min(lo, centre[0, axis] - half), max(hi, centre[0, axis] + half)
    return hi - lo


def test_t_pose_extent_matches_geometry():
    pos, parents, names = t_pose()
    size = (160, 200)
    masks = render_silhouettes(pos, parents, names, image_size=size, body_scale=STATURE)
    body, cam = fit_camera(pos, parents, names, image_size=size, body_scale=STATURE)
    assert masks.shape == (1, *size) and masks.dtype == bool
    h_px, w_px, row_c, col_c = extent(masks[0])
    # Width: hand tip to hand tip (x = +-(3 + 10 + 28 + 23 + 9) from the root) plus the hand capsule radius.
    width = 2 * (73.0 + radius_of(body, "hand"))
    # Height: feet (root - 2 - 41 - 42 - 5, minus the foot radius) to the skull top (head joint + offset + semi-axis).
    head = ellipsoid(body, "head")
    top = 20 + 12 + 22 + 8 + head.centre_offset + head.semi_axes[0]
    bottom = -(2 + 41 + 42 + 5) - radius_of(body, "foot")
    height = top - bottom
    # Pixel-centre sampling loses up to one pixel at each end and never gains one.
    assert cam.scale * width - 2 <= w_px <= cam.scale * width + 1
    assert cam.scale * height - 2 <= h_px <= cam.scale * height + 1
    # The figure is centred in the image and fills it.
    assert abs(row_c - size[0] / 2) <= 1 and abs(col_c - size[1] / 2) <= 1
    assert max(h_px / size[0], w_px / size[1]) > 0.75
    # Nothing touches the border.
    assert not (
        masks[0, 0].any() or masks[0, -1].any() or masks[0, :, 0].any() or masks[0, :, -1].any()
    )


def test_scale_from_first_frame_stature_and_unit_invariance():
    pos, parents, names = t_pose()
    body, _ = fit_camera(pos, parents, names)
    # Joints span y = -90 (foot ends) .. +76 (head end); with the skull top estimated from the head joint
    # (62 above the root) the stature lies between the joint span and that span plus a head.
    assert 166 <= body.stature < 185
    # A sequence that starts crouched (both knees bent 90 deg) still gets the standing height.
    crouch = bend(bend(pos, names, "lShin", rot("x", 90)), names, "rShin", rot("x", 90))
    crouch_body, _ = fit_camera(crouch, parents, names)
    assert crouch_body.stature < body.stature - 30
    seq_body, _ = fit_camera(np.concatenate([crouch, pos, pos]), parents, names)
    assert seq_body.stature == body.stature
    # Arms raised above the head do not make the body taller.
    reach = bend(bend(pos, names, "lShldr", rot("z", 80)), names, "rShldr", rot("z", -80))
    assert reach[0, names.index("lHand_End"), 1] > pos[0, names.index("head_End"), 1] + 20
    assert fit_camera(np.concatenate([reach] * 3), parents, names)[0].stature == body.stature
    a = render_silhouettes(pos, parents, names)
    b = render_silhouettes(
        pos * 0.0254 + 7.0, parents, names
    )  # other units and origin: same picture
    assert np.mean(a != b) < 0.002


def mirrored(pos, names):
    """Mirror x about the root and swap the left and right joints (l* <-> r*)."""
    m = pos.copy()
    m[..., 0] = 2 * pos[:, :1, 0] - pos[..., 0]
    swapped = m.copy()
    for k, name in enumerate(names):
        if name[0] in "lr" and name[1].isupper():
            other = ("r" if name[0] == "l" else "l") + name[1:]
            swapped[:, k] = m[:, names.index(other)]
    return swapped


def bend(pos, names, joint, rotation):
    """Rotate the subtree below ``joint`` about that joint (parents listed before children in ``t_pose``)."""
    out = pos.copy()
    j = names.index(joint)
    prefix = joint[:1]
    chain = {"Shldr": ["ForeArm", "Hand", "Hand_End"], "Shin": ["Foot", "Foot_End"]}
    for suffix in chain[joint[1:]]:
        k = names.index(prefix + suffix)
        out[0, k] = pos[0, j] + rotation @ (pos[0, k] - pos[0, j])
    return out


def rot(axis, deg):
    c, s = np.cos(np.deg2rad(deg)), np.sin(np.deg2rad(deg))
    if axis == "z":
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def test_left_right_symmetry():
    pos, parents, names = t_pose()
    sym = render_silhouettes(pos, parents, names)[0]
    assert np.sum(sym != sym[:, ::-1]) <= 2
    # An asymmetric pose: left arm raised 60 deg, right knee bent 70 deg backwards.
    pose = bend(pos, names, "lShldr", rot("z", 60))
    pose = bend(pose, names, "rShin", rot("x", 70))
    img = render_silhouettes(pose, parents, names)[0]
    assert np.sum(img != img[:, ::-1]) > 50
    mirror_img = render_silhouettes(mirrored(pose, names), parents, names)[0]
    assert np.sum(mirror_img != img[:, ::-1]) <= 2
    # The raised left arm (+x in the world, facing the camera) is on the image's right, above the shoulders.
    h, w = img.shape
    top_rows = np.flatnonzero(img.any(axis=1))[:5]
    assert img[top_rows].nonzero()[1].mean() > w / 2 + 10


def test_azimuth_90_turns_width_into_depth():
    pos, parents, names = t_pose()
    size = (160, 160)
    front = render_silhouettes(pos, parents, names, image_size=size, body_scale=STATURE)[0]
    side = render_silhouettes(
        pos, parents, names, image_size=size, body_scale=STATURE, view_azimuth_deg=90.0
    )[0]
    body, cam_front = fit_camera(pos, parents, names, image_size=size, body_scale=STATURE)
    _, cam_side = fit_camera(
        pos, parents, names, image_size=size, body_scale=STATURE, view_azimuth_deg=90.0
    )
    _, w_front, _, _ = extent(front)
    h_side, w_side, _, _ = extent(side)
    depth = world_extent(body, pos, axis=2)
    width = world_extent(body, pos, axis=0)
    height = world_extent(body, pos, axis=1)
    assert cam_front.scale * width - 2 <= w_front <= cam_front.scale * width + 1
    assert cam_side.scale * depth - 2 <= w_side <= cam_side.scale * depth + 1
    assert cam_side.scale * height - 2 <= h_side <= cam_side.scale * height + 1
    assert w_side < 0.45 * w_front
    # Feet point +z, i.e. to the image's left when the camera sits on +x (right vector = -z).
    low = side[np.flatnonzero(side.any(axis=1))[-3:]]
    assert low.nonzero()[1].mean() < np.flatnonzero(side.any(axis=0)).mean()


def test_deterministic_and_kernel_matches_numpy_reference():
    pos, parents, names = t_pose()
    rng = np.random.default_rng(3)
    frames = pos + rng.normal(scale=3.0, size=(6, *pos.shape[1:]))
    a = render_silhouettes(frames, parents, names, view_azimuth_deg=30, view_elevation_deg=10)
    b = render_silhouettes(frames, parents, names, view_azimuth_deg=30, view_elevation_deg=10)
    assert np.array_equal(a, b) and a.any(axis=(1, 2)).all()
    seg = rng.uniform(-10, 70, size=(3, 7, 4))
    rad = rng.uniform(0, 8, size=7)
    centres = rng.uniform(0, 60, size=(3, 2, 2))
    q = np.array([1 / 100.0, 0.003, 1 / 40.0])
    q = np.broadcast_to(q, (3, 2, 3)).copy()
    half = np.broadcast_to(np.sqrt([1 / q[0, 0, 0] * 1.2, 1 / q[0, 0, 2] * 1.2]), (3, 2, 2)).copy()
    out = np.empty((3, 60, 50), dtype=bool)
    rasterize(out, seg, rad, centres, q, half)
    ref = rasterize_numpy(out.shape, seg, rad, centres, q, half)
    assert out.any() and np.array_equal(out, ref)


def test_projected_interior_points_are_covered():
    """Points sampled inside every 3-D primitive (shrunk by more than half a pixel diagonal) project onto set
    pixels, for a leaning pose seen from an oblique view (tilted ellipses, slanted capsules)."""
    pos, parents, names = t_pose()
    lean = rot("z", 30) @ rot("x", -15)
    root = pos[0, 0]
    upper = [
        k
        for k, n in enumerate(names)
        if not any(t in n for t in ("Buttock", "Thigh", "Shin", "Foot", "hip"))
    ]
    pose = pos.copy()
    pose[0, upper] = root + (pos[0, upper] - root) @ lean.T
    kw = dict(image_size=(96, 80), view_azimuth_deg=-25.0, view_elevation_deg=20.0)
    mask = render_silhouettes(pose, parents, names, **kw)[0]
    body, cam = fit_camera(pose, parents, names, **kw)
    rel = pose - pose[:, :1]
    rng = np.random.default_rng(0)
    margin = 0.75 / cam.scale
    pts = []
    for (a, b), r in zip(body.capsule_joints, body.capsule_radii):
        if r <= margin:
            continue
        t = rng.uniform(size=(200, 1))
        v = rng.normal(size=(200, 3))
        v *= (
            (r - margin)
            * rng.uniform(size=(200, 1)) ** (1 / 3)
            / np.linalg.norm(v, axis=1, keepdims=True)
        )
        pts.append(rel[0, a] + t * (rel[0, b] - rel[0, a]) + v)
    for e in body.ellipsoids:
        centre, axes = ellipsoid_frames(e, rel)
        u = rng.normal(size=(400, 3))
        u *= 0.85 * rng.uniform(size=(400, 1)) ** (1 / 3) / np.linalg.norm(u, axis=1, keepdims=True)
        pts.append(centre[0] + u @ axes[0].T)
    xy = cam.project(np.vstack(pts))
    cols, rows = np.floor(xy[:, 0]).astype(int), np.floor(xy[:, 1]).astype(int)
    assert mask[rows, cols].all()
    # And the silhouette is not much larger than the union of the primitives (a loose upper bound).
    assert mask.sum() < 1.5 * len(np.unique(rows * 1000 + cols))


def test_unknown_joint_names_fall_back_to_generic_capsules():
    pos, parents, names = t_pose()
    anonymous = [f"j{k}" for k in range(len(names))]
    body, cam = fit_camera(pos, parents, anonymous, body_scale=STATURE)
    assert set(body.capsule_parts) == {"generic"} and body.ellipsoids == ()
    assert len(body.capsule_joints) == len(names) - 1  # every bone drawn, fingers or not
    h_px, w_px, _, _ = extent(render_silhouettes(pos, parents, anonymous, body_scale=STATURE)[0])
    r = body.capsule_radii[0]
    assert r == pytest.approx(PART_RADIUS["generic"] * STATURE)
    assert cam.scale * (146 + 2 * r) - 2 <= w_px <= cam.scale * (146 + 2 * r) + 1
    assert cam.scale * (166 + 2 * r) - 2 <= h_px <= cam.scale * (166 + 2 * r) + 1


def test_elevation_looks_down():
    pos, parents, names = t_pose()
    level = render_silhouettes(pos, parents, names, body_scale=STATURE)[0]
    above = render_silhouettes(pos, parents, names, body_scale=STATURE, view_elevation_deg=60)[0]
    # Seen from above, the vertical extent shrinks (cos 60) and the feet (pointing +z, towards the camera) show.
    assert extent(above)[0] < 0.8 * extent(level)[0]


@pytest.mark.parametrize(
    "name, is_root, expected",
    [
        ("hip", True, ("", "pelvis")),
        ("rShldr", False, ("R", "upperarm")),
        ("lForeArm", False, ("L", "forearm")),
        ("rThigh", False, ("R", "thigh")),
        ("lButtock", False, ("L", "pelvis")),
        ("leftEye", False, ("L", "eye")),
        ("rIndex2", False, ("R", "finger")),
        ("Hips", True, ("", "pelvis")),
        ("LeftHip", False, ("L", "thigh")),
        ("RightKnee", False, ("R", "shin")),
        ("LHipJoint", False, ("L", "pelvis")),
        ("lowerback", False, ("", "abdomen")),
        ("Chest2", False, ("", "chest")),
        ("lowerneck", False, ("", "neck")),
        ("lhand", False, ("L", "hand")),
        ("LFingers", False, ("L", "finger")),
        ("RightToe", False, ("R", "toe")),
        ("rFoot_End", False, ("R", "foot")),
        ("lhumerus", False, ("L", "upperarm")),
        ("something", False, ("", "generic")),
    ],
)
def test_joint_names_are_recognised(name, is_root, expected):
    assert joint_part(name, is_root) == expected


def test_bad_input_is_rejected():
    pos, parents, names = t_pose()
    with pytest.raises(InputError, match="positions: expected shape"):
        render_silhouettes(pos[0], parents, names)
    bad = pos.copy()
    bad[0, 3, 1] = np.nan
    with pytest.raises(InputError, match="frame 0, joint 3"):
        render_silhouettes(bad, parents, names)
    with pytest.raises(InputError, match="joint_names"):
        render_silhouettes(pos, parents, names[:-1])
    with pytest.raises(InputError, match="parents"):
        render_silhouettes(pos, np.zeros(len(names), dtype=int), names)
    with pytest.raises(InputError, match="image_size"):
        render_silhouettes(pos, parents, names, image_size=(0, 64))
    with pytest.raises(InputError, match="body_scale"):
        render_silhouettes(pos, parents, names, body_scale=-1.0)


def test_save_montage(tmp_path):
    pos, parents, names = t_pose()
    masks = render_silhouettes(np.repeat(pos, 5, axis=0), parents, names, image_size=(48, 40))
    path = tmp_path / "sub" / "montage.png"
    shown = save_montage(masks, path, n=3)
    assert list(shown) == [0, 2, 4]
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(path.parent.glob(".*"))  # no temporary file left behind
    with pytest.raises(InputError, match="titles"):
        save_montage(masks, path, titles=["a"])
