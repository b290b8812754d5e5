"""Binary silhouettes of a mocap sequence under an orthographic camera that follows the root.

Pipeline per sequence:

1. ``build_body_model``: capsules around the bones and ellipsoids for head and torso, sized from the stature
   (``estimate_stature``: the first frame's height, or the median over frames if larger; or ``body_scale``).
2. ``fit_camera``: a fixed view direction (azimuth about the vertical axis, then elevation), the root's
   translation removed per frame, and one scale per sequence: ``fill`` * image height / stature pixels per
   length unit, reduced if needed so that every frame of the sequence stays inside the image with a margin; the
   union of the root-relative figures over the sequence is centred in the image.
3. ``rasterize``: every pixel whose centre lies inside a projected capsule or ellipse is set.

View convention (y up, the CMU BVH figures face +z in their rest pose): azimuth 0 and elevation 0 put the
camera on the +z axis looking towards -z, so the image shows the front of a figure facing +z, with world +x to
the image's right. Azimuth a rotates the camera about +y (a = 90 deg: camera on +x looking towards -x);
elevation e raises it (e > 0 looks down on the figure).
"""

from dataclasses import dataclass

import numpy as np

from bsrbench.errors import InputError
from bsrbench.render._kernels import rasterize
from bsrbench.render.body import build_body_model, ellipsoid_frames, estimate_stature

#: Default fraction of the image height taken by the standing stature (before any shrinking to fit).
DEFAULT_FILL = 0.80
#: Minimum free margin on each side of the image, as a fraction of the image size (and at least one pixel).
MARGIN_FRACTION = 0.03


def view_basis(view_azimuth_deg, view_elevation_deg):
    """(right, up, towards_camera) unit vectors (3,) of the orthographic view; see the module docstring."""
    az = np.deg2rad(float(view_azimuth_deg))
    el = np.deg2rad(float(view_elevation_deg))
    towards = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    right = np.array([np.cos(az), 0.0, -np.sin(az)])
    up = np.cross(towards, right)
    return right, up, towards


@dataclass(frozen=True)
class OrthoCamera:
    """Orthographic camera of one sequence.

    A root-relative world point ``X`` maps to view coordinates ``a = X . right``, ``b = X . up`` and to the
    image point ``x = width / 2 + scale * (a - centre[0])`` (column, pixel units, pixel j spans [j, j + 1]) and
    ``y = height / 2 - scale * (b - centre[1])`` (row).
    """

    right: np.ndarray
    up: np.ndarray
    scale: float
    centre: tuple
    image_size: tuple

    def project(self, points):
        """Image coordinates (..., 2) = (x, y) of root-relative world points (..., 3)."""
        a = points @ self.right
        b = points @ self.up
        h, w = self.image_size
        return np.stack(
            [w / 2 + self.scale * (a - self.centre[0]), h / 2 - self.scale * (b - self.centre[1])],
            -1,
        )


def _check_int_pair(value, name, minimum):
    try:
        h, w = (int(v) for v in value)
        ok = (h, w) == tuple(value)
    except (TypeError, ValueError):
        ok = False
    if not ok or h < minimum or w < minimum:
        raise InputError(
            f"{name}: expected two integers (height, width) >= {minimum}, got {value!r}"
        )
    return h, w


def _check_skeleton(positions, parents, joint_names):
    positions = np.asarray(positions, dtype=float)
    if (
        positions.ndim != 3
        or positions.shape[2] != 3
        or positions.shape[0] < 1
        or positions.shape[1] < 2
    ):
        raise InputError(
            f"positions: expected shape (frames >= 1, joints >= 2, 3), got {positions.shape}"
        )
    n_joints = positions.shape[1]
    if not np.all(np.isfinite(positions)):
        bad = np.argwhere(~np.isfinite(positions))[0]
        raise InputError(f"positions: non-finite value at frame {bad[0]}, joint {bad[1]}")
    parents_arr = np.asarray(parents)
    if parents_arr.shape != (n_joints,) or not np.issubdtype(parents_arr.dtype, np.integer):
        raise InputError(f"parents: expected {n_joints} integers (one per joint), got {parents!r}")
    if (
        np.any(parents_arr < -1)
        or np.any(parents_arr >= n_joints)
        or np.any(parents_arr == np.arange(n_joints))
    ):
        raise InputError(
            f"parents: expected indices in [-1, {n_joints}) other than the joint itself, got {parents!r}"
        )
    roots = np.flatnonzero(parents_arr < 0)
    if len(roots) != 1:
        raise InputError(
            f"parents: expected exactly one root (-1), found {len(roots)} in {parents!r}"
        )
    names = list(joint_names)
    if len(names) != n_joints or not all(isinstance(s, str) for s in names):
        raise InputError(f"joint_names: expected {n_joints} strings, got {joint_names!r}")
    return positions, parents_arr.astype(np.int64), names, int(roots[0])


def _projected_primitives(body, rel, right, up):
    """View coordinates of the primitives: capsule ends (F, C, 2, 2), ellipse centres (F, E, 2) and 2x2 shape
    matrices (F, E, 2, 2) (ellipse = {y : (y - c)^T M^-1 (y - c) <= 1})."""
    proj = np.stack([right, up])  # (2, 3)
    caps = rel[:, body.capsule_joints, :] @ proj.T  # (F, C, 2, 2)
    centres, shapes = [], []
    for ell in body.ellipsoids:
        c, axes = ellipsoid_frames(ell, rel)
        pa = proj @ axes  # (F, 2, 3)
        centres.append(c @ proj.T)
        shapes.append(pa @ np.swapaxes(pa, 1, 2))
    n_frames = rel.shape[0]
    if centres:
        return caps, np.stack(centres, 1), np.stack(shapes, 1)
    return caps, np.zeros((n_frames, 0, 2)), np.zeros((n_frames, 0, 2, 2))


def _view_extent(body, caps, ell_c, ell_m):
    """Union over frames of the primitives' view-plane bounding boxes: (a_min, a_max, b_min, b_max)."""
    lo = [np.inf, np.inf]
    hi = [-np.inf, -np.inf]
    if caps.shape[1]:
        r = body.capsule_radii[None, :, None]
        lo = np.minimum(lo, (caps.min(axis=2) - r).min(axis=(0, 1)))
        hi = np.maximum(hi, (caps.max(axis=2) + r).max(axis=(0, 1)))
    if ell_c.shape[1]:
        half = np.sqrt(np.stack([ell_m[..., 0, 0], ell_m[..., 1, 1]], -1))
        lo = np.minimum(lo, (ell_c - half).min(axis=(0, 1)))
        hi = np.maximum(hi, (ell_c + half).max(axis=(0, 1)))
    return lo[0], hi[0], lo[1], hi[1]


def _prepare(
    positions,
    parents,
    joint_names,
    image_size,
    view_azimuth_deg,
    view_elevation_deg,
    body_scale,
    fill,
):
    image_size = _check_int_pair(image_size, "image_size", 8)
    positions, parents, names, root = _check_skeleton(positions, parents, joint_names)
    for value, name in (
        (view_azimuth_deg, "view_azimuth_deg"),
        (view_elevation_deg, "view_elevation_deg"),
    ):
        if not np.isfinite(float(value)):
            raise InputError(f"{name}: expected a finite angle in degrees, got {value!r}")
    if not (0 < float(fill) <= 1):
        raise InputError(f"fill: expected a fraction in (0, 1], got {fill!r}")
    if body_scale is None:
        stature = estimate_stature(positions, parents, names)
    else:
        stature = float(body_scale)
        if not np.isfinite(stature) or stature <= 0:
            raise InputError(
                f"body_scale: expected a positive body height in the motion's units, got {body_scale!r}"
            )
    body = build_body_model(parents, names, stature)
    rel = positions - positions[:, root : root + 1, :]
    right, up, _ = view_basis(view_azimuth_deg, view_elevation_deg)
    caps, ell_c, ell_m = _projected_primitives(body, rel, right, up)
    a_min, a_max, b_min, b_max = _view_extent(body, caps, ell_c, ell_m)
    h, w = image_size
    scale = float(fill) * h / stature
    usable_h = h - 2 * max(1.0, MARGIN_FRACTION * h)
    usable_w = w - 2 * max(1.0, MARGIN_FRACTION * w)
    if b_max > b_min:
        scale = min(scale, usable_h / (b_max - b_min))
    if a_max > a_min:
        scale = min(scale, usable_w / (a_max - a_min))
    camera = OrthoCamera(
        right=right,
        up=up,
        scale=scale,
        centre=(0.5 * (a_min + a_max), 0.5 * (b_min + b_max)),
        image_size=image_size,
    )
    return body, camera, caps, ell_c, ell_m


def fit_camera(
    positions,
    parents,
    joint_names,
    *,
    image_size=(128, 128),
    view_azimuth_deg=0.0,
    view_elevation_deg=0.0,
    body_scale=None,
    fill=DEFAULT_FILL,
):
    """(BodyModel, OrthoCamera) that ``render_silhouettes`` uses for these arguments (see the module docstring)."""
    body, camera, *_ = _prepare(
        positions,
        parents,
        joint_names,
        image_size,
        view_azimuth_deg,
        view_elevation_deg,
        body_scale,
        fill,
    )
    return body, camera


def render_silhouettes(
    positions,
    parents,
    joint_names,
    *,
    image_size=(128, 128),
    view_azimuth_deg=0.0,
    view_elevation_deg=0.0,
    body_scale=None,
    fill=DEFAULT_FILL,
):
    """Binary silhouettes (F, H, W) bool of a mocap sequence.

    Parameters
    ----------
    positions : (F, J, 3) float
        World joint positions, y up, in the motion file's own length units (any unit: sizes scale with the
        stature).
    parents : (J,) int
        Parent index of each joint, -1 for the (single) root.
    joint_names : sequence of J str
        Joint names; they choose each bone's radius (see ``bsrbench.render.body``).
    image_size : (height, width) in pixels.
    view_azimuth_deg, view_elevation_deg : float
        Fixed camera direction (see the module docstring).
    body_scale : float, optional
        Stature (standing height) in the motion's units; by default ``estimate_stature`` (the first frame's
        height, or the median frame's if larger).
    fill : float in (0, 1]
        Fraction of the image height the stature takes, reduced automatically when some frame would otherwise
        leave the image.

    The camera removes the root's translation in every frame, so the figure stays in place; the scale is fixed
    for the whole sequence, so rendering a different set of frames can give a different scale and centring.
    Deterministic: the same input gives the same images.
    """
    body, camera, caps, ell_c, ell_m = _prepare(
        positions,
        parents,
        joint_names,
        image_size,
        view_azimuth_deg,
        view_elevation_deg,
        body_scale,
        fill,
    )
    h, w = camera.image_size
    s = camera.scale
    ca, cb = camera.centre

    def to_pixels(v):
        return np.stack([w / 2 + s * (v[..., 0] - ca), h / 2 - s * (v[..., 1] - cb)], -1)

    n_frames = caps.shape[0]
    seg = np.ascontiguousarray(to_pixels(caps).reshape(n_frames, -1, 4))
    rad = np.ascontiguousarray(body.capsule_radii * s)
    centres = np.ascontiguousarray(to_pixels(ell_c))
    # Image y points down, so the off-diagonal term of the shape matrix changes sign.
    m = ell_m * s * s
    mxx, mxy, myy = m[..., 0, 0], -m[..., 0, 1], m[..., 1, 1]
    det = mxx * myy - mxy * mxy
    det = np.where(det > 1e-12, det, 1e-12)
    q = np.ascontiguousarray(np.stack([myy / det, -mxy / det, mxx / det], -1))
    half = np.ascontiguousarray(np.sqrt(np.stack([mxx, myy], -1)))
    out = np.empty((n_frames, h, w), dtype=np.bool_)
    rasterize(out, seg, rad, centres, q, half)
    return out
