"""A volumetric body made of capsules and ellipsoids around a mocap skeleton.

The body is what the paper's silhouettes were rendered from (the paper used Poser figures; Agarwal & Triggs,
"Recovering 3D human pose from monocular images", PAMI 28(1), 2006, Sec. 2, rendered Poser bodies too). Here a
much simpler stand-in is used, in the spirit of the cylinder/capsule bodies of classic model-based tracking:

* every bone (parent joint -> child joint) is a capsule, i.e. the set of points within a radius of the bone
  segment, with the radius chosen from the *part* the bone belongs to (upper arm, thigh, ...);
* the head and the torso are ellipsoids placed from the joints around them (the neck and shoulders, the root);
* bones of tiny parts (fingers, eyes, an end site below the head) are skipped.

Parts are recognised from the joint names of the two CMU BVH releases in ``resources/cmu-mocap`` (Daz-friendly:
``hip, abdomen, chest, neck, head, rCollar, rShldr, rForeArm, rHand, rThigh, rShin, rFoot, ...``;
3dsMax-friendly: ``Hips, LHipJoint, LeftHip, LeftKnee, LeftAnkle, LeftToe, lowerback, Chest, Chest2, lowerneck,
Neck, Head, LeftCollar, LeftShoulder, LeftElbow, LeftWrist, lhand, LFingers, LThumb``), from the CMU ASF bone
names (``lfemur, ltibia, lhumerus, lradius, thorax, upperneck, lclavicle, ...``) and from the common
``LeftUpLeg/LeftLeg/LeftArm/Spine`` style. End sites are named ``<joint>_End`` (see ``bsrbench.mocap``) and
take the part of their parent. A joint whose name is not recognised gets a generic radius.

All radii are fractions of the body's *stature* (its standing height in the motion's length units), so the same
body model serves skeletons in any unit.
"""

import re
from dataclasses import dataclass

import numpy as np

from bsrbench.errors import InputError

#: Capsule radius of each part, as a fraction of the stature.
PART_RADIUS = {
    "pelvis": 0.052,
    "abdomen": 0.062,
    "chest": 0.068,
    "collar": 0.040,
    "neck": 0.030,
    "upperarm": 0.032,
    "forearm": 0.027,
    "hand": 0.020,
    "thigh": 0.050,
    "shin": 0.036,
    "foot": 0.026,
    "toe": 0.022,
    "generic": 0.030,
}

#: Head ellipsoid: semi-axes (along the neck, left-right, front-back) and the offset of its centre from the head
#: joint along the neck direction, as fractions of the stature.
HEAD_SEMI_AXES = (0.068, 0.052, 0.060)
HEAD_CENTRE_OFFSET = 0.040

#: Torso ellipsoid, along the trunk from the middle of the hip joints to the middle of the shoulder joints (length
#: L): centre at ``TORSO_CENTRE_AT`` * L, semi-axis ``TORSO_LENGTH_FACTOR`` * L along the trunk, left-right and
#: front-back semi-axes as fractions of the stature.
TORSO_CENTRE_AT = 0.55
TORSO_LENGTH_FACTOR = 0.55
TORSO_SEMI_AXES = (0.095, 0.062)

#: Pelvis ellipsoid, centred above the middle of the hip joints: semi-axes (along the trunk, left-right,
#: front-back) and the centre's offset along the trunk, as fractions of the stature.
PELVIS_SEMI_AXES = (0.085, 0.095, 0.068)
PELVIS_CENTRE_OFFSET = 0.03

#: Parts left out when measuring the stature (raised arms reach above the head).
ARM_PARTS = frozenset({"collar", "upperarm", "forearm", "hand", "finger"})

#: Parts whose bones are not drawn (too small to matter at silhouette resolution, or inside the head).
SKIPPED_PARTS = frozenset({"finger", "eye", "head"})

# Base name (lower case, side prefix and "_End" removed) -> part of the joint. Order matters: first match wins.
_NAME_RULES = [
    (r"(hips?|pelvis|root)", "root_or_hip"),
    (r"(hipjoint|buttock)", "pelvis"),
    (r"(abdomen|lowerback|spine|spine0)", "abdomen"),
    (r"(chest\d*|thorax|upperback|spine\d+|upperchest)", "chest"),
    (r"(lowerneck|neck\d*|upperneck)", "neck"),
    (r"(head|headtop|skull)", "head"),
    (r"(eye|eyes|jaw|nose|ear)", "eye"),
    (r"(collar|clavicle|shoulderblade)", "collar"),
    (r"(shldr|shoulder|humerus|upperarm|arm)", "upperarm"),
    (r"(forearm|elbow|radius|lowerarm)", "forearm"),
    (r"(wrist|hand|palm)", "hand"),
    (r"(thumb\d*|index\d*|mid\d*|middle\d*|ring\d*|pinky\d*|fingers?\d*)", "finger"),
    (r"(thigh|femur|upleg|upperleg)", "thigh"),
    (r"(shin|knee|tibia|leg|lowerleg|calf)", "shin"),
    (r"(foot|ankle)", "foot"),
    (r"(toes?|toebase)", "toe"),
]
_NAME_RULES = [(re.compile(rf"^{pattern}$"), part) for pattern, part in _NAME_RULES]
_SIDE_WORDS = re.compile(
    r"^(hipjoint|buttock|collar|clavicle|shldr|shoulder|humerus|upperarm|arm|forearm|elbow|radius|lowerarm|"
    r"wrist|hand|thumb\d*|index\d*|mid\d*|ring\d*|pinky\d*|fingers?\d*|thigh|femur|upleg|hip|shin|knee|tibia|"
    r"leg|foot|ankle|toes?|toebase|eye)$"
)


def joint_side_and_base(name):
    """Split a joint name into (side, base): side is 'L', 'R' or '' and base the lower-case rest.

    Recognises ``leftX/rightX`` (any case), ``lX/rX`` with an upper-case second letter (``rShldr``, ``LHipJoint``)
    and lower-case ``lhand``/``rfemur`` style where the rest is a known limb word. A trailing ``_End`` (end site)
    is removed first.
    """
    raw = re.sub(r"[_\s]*(end\s*site|end)$", "", str(name), flags=re.IGNORECASE)
    raw = re.sub(r"[^A-Za-z0-9]", "", raw)
    low = raw.lower()
    for word, side in (("left", "L"), ("right", "R")):
        if low.startswith(word) and len(low) > len(word):
            return side, low[len(word) :]
    if len(raw) > 1 and raw[0] in "lLrR":
        rest = low[1:]
        if raw[1].isupper() or _SIDE_WORDS.match(rest):
            return raw[0].upper(), rest
    return "", low


def joint_part(name, is_root):
    """(side, part) of a joint from its name; part is one of PART_RADIUS's keys, 'finger', 'eye' or 'head'.

    'hip'/'Hips' is the pelvis when it is the root (Daz ``hip``, 3dsMax ``Hips``) and the thigh when it has a
    side (3dsMax ``LeftHip``: the bone from it to the knee is the thigh).
    """
    side, base = joint_side_and_base(name)
    for pattern, part in _NAME_RULES:
        if pattern.match(base):
            if part == "root_or_hip":
                part = "thigh" if (side and not is_root) else "pelvis"
            return side, part
    return side, "generic"


@dataclass(frozen=True)
class Ellipsoid:
    """An ellipsoid placed per frame from joint positions.

    Its first axis runs from ``axis_from`` (the mean of those joints) to ``axis_to`` (the mean of those joints),
    of current length L; the centre is ``axis_from + centre_at * (axis_to - axis_from)`` moved by
    ``centre_offset`` along the axis. The second axis is the direction from ``lateral_joints[1]`` (right) to
    ``lateral_joints[0]`` (left), made orthogonal to the first; the third is their cross product. ``semi_axes``
    are the three semi-axis lengths in motion units; a first semi-axis of ``None`` means ``length_factor * L``
    (the torso follows the spine's current length).
    """

    name: str
    axis_from: tuple
    axis_to: tuple
    lateral_joints: tuple | None
    semi_axes: tuple
    centre_at: float = 0.5
    centre_offset: float = 0.0
    length_factor: float | None = None


@dataclass(frozen=True)
class BodyModel:
    """The volumetric body of one skeleton: capsules around bones plus ellipsoids.

    Attributes
    ----------
    stature : float
        Body height in the motion's length units; every size below scales with it.
    capsule_joints : (C, 2) int array
        (parent, child) joint indices of each drawn bone.
    capsule_radii : (C,) float array
        Capsule radius of each bone, in the motion's length units.
    capsule_parts : tuple of str
        Part name of each bone (a key of ``PART_RADIUS``).
    ellipsoids : tuple of Ellipsoid
        Head and torso (when the joints that place them are recognised).
    joint_parts : tuple of (side, part)
        What each joint was recognised as.
    """

    stature: float
    capsule_joints: np.ndarray
    capsule_radii: np.ndarray
    capsule_parts: tuple
    ellipsoids: tuple
    joint_parts: tuple


def _bone_part(parent_part, child_part):
    """Part of the bone from a joint of ``parent_part`` to one of ``child_part``; None = do not draw it."""
    if child_part in ("finger", "eye") and parent_part != "hand":
        return None
    if parent_part in SKIPPED_PARTS:
        return None
    if parent_part == "pelvis" and child_part in ("abdomen", "chest"):
        return "abdomen"
    if parent_part == "chest" and child_part == "collar":
        return "chest"
    return parent_part


def build_body_model(parents, joint_names, stature):
    """The capsules and ellipsoids of a skeleton (see the module docstring for the rules).

    Parameters
    ----------
    parents : (J,) int array, -1 for the root.
    joint_names : sequence of J str.
    stature : float > 0, body height in the motion's length units.
    """
    parents = np.asarray(parents)
    n = len(parents)
    roots = np.flatnonzero(parents < 0)
    parts = tuple(joint_part(name, is_root=(j in roots)) for j, name in enumerate(joint_names))
    caps, radii, cap_parts = [], [], []
    for j in range(n):
        p = int(parents[j])
        if p < 0:
            continue
        part = _bone_part(parts[p][1], parts[j][1])
        if part is None:
            continue
        caps.append((p, j))
        radii.append(PART_RADIUS[part] * stature)
        cap_parts.append(part)

    def find(part, side=""):
        """Joints of a part (and side), ordered from the root outwards (index order of a BVH/ASF tree)."""
        return [j for j, (s, q) in enumerate(parts) if q == part and (not side or s == side)]

    ellipsoids = []
    root = int(roots[0]) if len(roots) else 0
    shoulders = (find("upperarm", "L"), find("upperarm", "R"))
    thighs = (find("thigh", "L"), find("thigh", "R"))
    necks, heads = find("neck"), find("head")
    lateral = None
    if shoulders[0] and shoulders[1]:
        lateral = (shoulders[0][0], shoulders[1][0])
    elif thighs[0] and thighs[1]:
        lateral = (thighs[0][0], thighs[1][0])
    # The trunk runs from between the hip joints to between the shoulder joints (the root's own height in
    # the body differs between skeletons: the 3dsMax root sits above the hip joints, the Daz one between them).
    hips = (thighs[0][0], thighs[1][0]) if thighs[0] and thighs[1] else (root,)
    if shoulders[0] and shoulders[1]:
        top = (shoulders[0][0], shoulders[1][0])
    elif necks:
        top = (necks[0],)
    else:
        top = None
    if top is not None:
        ellipsoids.append(
            Ellipsoid(
                name="torso",
                axis_from=hips,
                axis_to=top,
                lateral_joints=lateral,
                semi_axes=(None, TORSO_SEMI_AXES[0] * stature, TORSO_SEMI_AXES[1] * stature),
                centre_at=TORSO_CENTRE_AT,
                length_factor=TORSO_LENGTH_FACTOR,
            )
        )
        ellipsoids.append(
            Ellipsoid(
                name="pelvis",
                axis_from=hips,
                axis_to=top,
                lateral_joints=lateral,
                semi_axes=tuple(a * stature for a in PELVIS_SEMI_AXES),
                centre_offset=PELVIS_CENTRE_OFFSET * stature,
                centre_at=0.0,
            )
        )
    if heads:
        head = heads[0]
        p = int(parents[head])
        ellipsoids.append(
            Ellipsoid(
                name="head",
                axis_from=(p if p >= 0 else head,),
                axis_to=(head,),
                lateral_joints=lateral,
                semi_axes=tuple(a * stature for a in HEAD_SEMI_AXES),
                centre_at=1.0,
                centre_offset=HEAD_CENTRE_OFFSET * stature,
            )
        )
    return BodyModel(
        stature=float(stature),
        capsule_joints=np.asarray(caps, dtype=np.int64).reshape(-1, 2),
        capsule_radii=np.asarray(radii, dtype=float),
        capsule_parts=tuple(cap_parts),
        ellipsoids=tuple(ellipsoids),
        joint_parts=parts,
    )


def estimate_stature(positions, parents, joint_names):
    """Standing height of the skeleton, in the motion's units, from its joint positions (y up).

    Per frame: the vertical extent of the joints other than the arms' (``ARM_PARTS``), extended to the top of the skull when a head joint is
    recognised (the head joint of both CMU releases sits at the base of the skull; the skull top is taken to be
    ``HEAD_CENTRE_OFFSET + HEAD_SEMI_AXES[0]`` statures above it). The estimate is that of the first frame, or the
    median over the frames if larger, so a sequence that starts crouched still gets its standing height.
    ``positions``: (J, 3) one frame, or (F, J, 3).
    """
    positions = np.asarray(positions, dtype=float)
    if positions.ndim == 2:
        positions = positions[None]
    parts = [joint_part(name, parents[j] < 0)[1] for j, name in enumerate(joint_names)]
    # Raised arms do not make a body taller: use the other joints when arm joints are recognised.
    core = [j for j, part in enumerate(parts) if part not in ARM_PARTS]
    y = positions[:, core if len(core) >= 2 else slice(None), 1]
    low, high = y.min(axis=1), y.max(axis=1)
    extent = high - low
    y = positions[:, :, 1]
    heads = [j for j, part in enumerate(parts) if part == "head"]
    if heads:
        # Solve stature = max(high, y_head + k * stature) - low for the stature.
        k = HEAD_CENTRE_OFFSET + HEAD_SEMI_AXES[0]
        extent = np.maximum(extent, (y[:, heads[0]] - low) / (1 - k))
    stature = max(float(extent[0]), float(np.median(extent)))
    if not np.isfinite(stature) or stature <= 0:
        raise InputError(
            f"positions: the joints have no vertical extent (estimated stature {stature!r}); "
            "cannot derive the body size, pass body_scale"
        )
    return stature


def ellipsoid_frames(ell, positions):
    """Centres (F, 3) and axis matrices (F, 3, 3) (columns = semi-axis vectors) of an ellipsoid over frames."""
    base = positions[:, list(ell.axis_from), :].mean(axis=1)
    up = positions[:, list(ell.axis_to), :].mean(axis=1) - base
    centre = base + ell.centre_at * up
    length = np.linalg.norm(up, axis=1)
    world_up = np.array([0.0, 1.0, 0.0])
    ok = length > 1e-9
    up = np.where(ok[:, None], up / np.where(ok, length, 1.0)[:, None], world_up)
    centre = centre + ell.centre_offset * up
    if ell.lateral_joints is not None:
        lat = positions[:, ell.lateral_joints[0], :] - positions[:, ell.lateral_joints[1], :]
    else:
        lat = np.broadcast_to(np.array([1.0, 0.0, 0.0]), up.shape)
    lat = lat - np.sum(lat * up, axis=1, keepdims=True) * up
    lat_len = np.linalg.norm(lat, axis=1)
    bad = lat_len < 1e-9
    if bad.any():
        # Lateral direction parallel to the spine (or missing): any direction orthogonal to it will do.
        alt = np.cross(up[bad], np.array([0.0, 0.0, 1.0]))
        alt_len = np.linalg.norm(alt, axis=1)
        alt2 = np.cross(up[bad], np.array([1.0, 0.0, 0.0]))
        alt = np.where((alt_len > 1e-6)[:, None], alt, alt2)
        lat = lat.copy()
        lat[bad] = alt
        lat_len = np.linalg.norm(lat, axis=1)
    lat = lat / lat_len[:, None]
    depth = np.cross(up, lat)
    s0, s1, s2 = ell.semi_axes
    if s0 is None:
        s0 = ell.length_factor * length
    s0 = np.broadcast_to(np.asarray(s0, dtype=float), length.shape)
    axes = np.stack([up * s0[:, None], lat * s1, depth * s2], axis=2)
    return centre, axes
