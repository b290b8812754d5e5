"""Pose extraction: trials (BVH or AMC) -> joint world positions and the 57-angle pose (19 joints x 3).

The paper (Babagholami-Mohamadabadi et al. 2014, Section IV) describes a pose as 57 joint angles of CMU motion
capture rendered in Poser. The Daz/Poser-friendly BVH release of CMU moves 17 joints; these plus the two collars
give 19 joints x 3 Euler angles = 57. For other skeletons a matching 19-joint set is used (same order, same
roles): see :data:`JOINT_MAPS`.

Angles are the joints' rotation channels in degrees, in the file's channel order, named
``<joint>_<channel>`` (e.g. ``rShldr_Zrotation``); a joint with fewer than three rotation channels gets constant
zero columns for the missing axes (in X, Y, Z order). The one exception is the root of AMC trials, whose rotation
is written in the authors' Z X Y order (:data:`AMC_ROOT_ORDER`, :func:`reexpress_amc_rotation`). Each angle is
unwrapped over time (``numpy.unwrap`` with a period of 360 degrees), so a 179 -> -179 step becomes 179 -> 181.
"""

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import DataFileError, InputError
from .asf import ASFSkeleton, parse_amc, parse_asf
from .bvh import parse_bvh
from .skeleton import ROTATION_AXES

#: The 19 pose joints of each known skeleton, in one common role order:
#: root, lower spine, upper spine, neck, head, right collar, shoulder, elbow, wrist, left collar, shoulder,
#: elbow, wrist, right hip, knee, ankle, left hip, knee, ankle.
JOINT_MAPS = {
    # cgspeed Daz/Poser-friendly CMU BVH: the 17 joints that move + rCollar, lCollar.
    "daz": [
        "hip",
        "abdomen",
        "chest",
        "neck",
        "head",
        "rCollar",
        "rShldr",
        "rForeArm",
        "rHand",
        "lCollar",
        "lShldr",
        "lForeArm",
        "lHand",
        "rThigh",
        "rShin",
        "rFoot",
        "lThigh",
        "lShin",
        "lFoot",
    ],
    # cgspeed 3dsMax-friendly CMU BVH (topology of the CMU ASF skeleton). Of the six spine/neck joints the
    # ones at the Daz joints' heights are used (lowerback ~ abdomen, Chest ~ chest, Neck ~ neck); the toes
    # are left out as the Daz skeleton has none that move.
    "3dsmax": [
        "Hips",
        "lowerback",
        "Chest",
        "Neck",
        "Head",
        "RightCollar",
        "RightShoulder",
        "RightElbow",
        "RightWrist",
        "LeftCollar",
        "LeftShoulder",
        "LeftElbow",
        "LeftWrist",
        "RightHip",
        "RightKnee",
        "RightAnkle",
        "LeftHip",
        "LeftKnee",
        "LeftAnkle",
    ],
    # CMU ASF/AMC bone names (the 3dsMax release renames these: upperback -> Chest, upperneck -> Neck, ...).
    "asf": [
        "root",
        "lowerback",
        "upperback",
        "upperneck",
        "head",
        "rclavicle",
        "rhumerus",
        "rradius",
        "rwrist",
        "lclavicle",
        "lhumerus",
        "lradius",
        "lwrist",
        "rfemur",
        "rtibia",
        "rfoot",
        "lfemur",
        "ltibia",
        "lfoot",
    ],
}

#: Euler order of the root's pose angles from AMC trials: the authors' (``bsrbench.authors``; BVH channel names,
#: the first the outermost, so R = Rz @ Rx @ Ry), whose last angle, about the vertical y axis, is the heading and
#: free over the whole circle. The AMC files give the root in X Y Z order (R = Rz @ Ry @ Rx): there the heading is
#: the middle angle, confined to [-90, 90], and as the figure turns past 90 degrees X and Z swing by 180 degrees
#: within a few frames. BVH trials keep their files' order: their roots show no such swing (docs/data.md).
AMC_ROOT_ORDER = ("Zrotation", "Xrotation", "Yrotation")

#: Joints whose presence identifies a skeleton kind.
_SIGNATURES = {
    "daz": {"hip", "abdomen", "rShldr", "lShldr", "rThigh"},
    "3dsmax": {"Hips", "lowerback", "RightShoulder", "LeftShoulder", "RightHip"},
    "asf": {"root", "lowerback", "rhumerus", "lhumerus", "rfemur"},
}


def detect_skeleton_kind(joint_names, source="<skeleton>"):
    """``"daz"``, ``"3dsmax"`` or ``"asf"`` from the joint names; InputError if none matches."""
    names = set(joint_names)
    for kind, sig in _SIGNATURES.items():
        if sig <= names:
            return kind
    raise InputError(
        f"{source}: cannot tell the skeleton kind from its joints {sorted(names)[:8]}...; "
        f"expected one of {sorted(_SIGNATURES)} or an explicit joint_map (a list of joint names)"
    )


def resolve_joint_map(joint_map, skeleton_kind, joint_names, source="<skeleton>"):
    """The list of pose joints: ``joint_map`` if given (list of names), else the map of ``skeleton_kind``
    (detected from the names when None). Every name must be a joint of the skeleton."""
    if joint_map is None:
        kind = skeleton_kind or detect_skeleton_kind(joint_names, source)
        if kind not in JOINT_MAPS:
            raise InputError(
                f"{source}: skeleton_kind must be one of {sorted(JOINT_MAPS)}; got {kind!r}"
            )
        joint_map = JOINT_MAPS[kind]
    joint_map = list(joint_map)
    if len(set(joint_map)) != len(joint_map):
        raise InputError(f"{source}: joint_map repeats a joint: {joint_map}")
    missing = [j for j in joint_map if j not in joint_names]
    if missing:
        raise InputError(
            f"{source}: joint_map names joint(s) {missing} that the file lacks; its joints are {list(joint_names)}"
        )
    return joint_map


def pose_columns(skeleton, joint_map, root_order=None):
    """For each pose angle: (column in a motion row or -1 for a constant zero, name ``joint_channel``).

    ``root_order`` (three rotation channel names), when given, lists the root's three angles in that order
    instead of the file's (see :data:`AMC_ROOT_ORDER`); the root must then have exactly those rotations."""
    starts = skeleton.channel_starts()
    cols, names = [], []
    for jn in joint_map:
        j = skeleton.index(jn)
        rot = [
            (starts[j] + k, ch) for k, ch in enumerate(skeleton.channels[j]) if ch in ROTATION_AXES
        ]
        if len(rot) > 3:
            raise InputError(f"joint {jn!r} has {len(rot)} rotation channels; expected at most 3")
        if j == 0 and root_order is not None:
            have = {ch: c for c, ch in rot}
            if sorted(have) != sorted(root_order):
                raise InputError(
                    f"root joint {jn!r} rotates about {sorted(have)}; the order {list(root_order)} "
                    f"needs the same three rotations"
                )
            rot = [(have[ch], ch) for ch in root_order]
        elif len(rot) < 3:
            have = {ch: c for c, ch in rot}
            rot = [(have.get(ch, -1), ch) for ch in ("Xrotation", "Yrotation", "Zrotation")]
        for c, ch in rot:
            cols.append(c)
            names.append(f"{jn}_{ch}")
    return np.array(cols, dtype=int), names


def amc_root_order(skeleton):
    """:data:`AMC_ROOT_ORDER` if the root of an ASF ``skeleton`` rotates about all three axes, else None
    (a root with fewer rotations keeps its file's order, with zero columns as any joint)."""
    rot = sorted(ch for ch in skeleton.channels[0] if ch in ROTATION_AXES)
    return AMC_ROOT_ORDER if rot == sorted(AMC_ROOT_ORDER) else None


def reexpress_amc_rotation(angles, channels, order=AMC_ROOT_ORDER):
    """AMC Euler angles ``angles`` (F, 3) in degrees, applied in the order of ``channels`` (AMC dof order:
    ``rx ry rz`` gives R = Rz @ Ry @ Rx), written as Euler angles in ``order`` with the first the outermost
    (R = R_order[0] @ R_order[1] @ R_order[2], the BVH convention): the same rotations, with the first and last
    angles in (-180, 180] and the middle in [-90, 90]. Unwrap them over time afterwards (:func:`unwrap_degrees`)."""
    angles = np.asarray(angles, dtype=float)
    axes_in = "".join(ch[0] for ch in channels)
    axes_out = "".join(ch[0] for ch in order)
    # scipy's lower-case (extrinsic) axes apply the rotations in the listed order; upper-case (intrinsic)
    # axes make the first listed the outermost.
    R = Rotation.from_euler(axes_in.lower(), angles.reshape(-1, 3), degrees=True)
    return R.as_euler(axes_out.upper(), degrees=True).reshape(angles.shape)


def unwrap_degrees(angles, axis=0):
    """Unwrap angles (degrees) along ``axis`` so that no step exceeds 180 degrees."""
    return np.unwrap(np.asarray(angles, dtype=float), period=360.0, axis=axis)


@dataclass
class Motion:
    """Joint positions and poses of one or more concatenated trials.

    ``joint_names`` (J,), ``parents`` (J,) (-1 for the root), ``positions`` (F, J, 3) world coordinates
    (y up, the file's length units), ``angles`` (F, 57) degrees unwrapped over time, ``angle_names`` (57,),
    ``frame_time`` (s), ``source_frames`` (F,) index of each frame within the concatenated usable frames,
    ``trial_ids`` (one per trial, e.g. ``"09_01"``), ``trial_index`` (F,) which trial each frame comes from,
    ``trial_frames`` (F,) frame index within its file, ``skeleton_kind``, ``pose_joints`` (19 names).
    """

    joint_names: list
    parents: np.ndarray
    positions: np.ndarray
    angles: np.ndarray
    angle_names: list
    frame_time: float
    source_frames: np.ndarray
    trial_ids: list
    trial_index: np.ndarray = field(default=None)
    trial_frames: np.ndarray = field(default=None)
    skeleton_kind: str = ""
    pose_joints: list = field(default_factory=list)

    @property
    def n_frames(self):
        return self.positions.shape[0]

    def take(self, idx):
        """The frames ``idx`` (indices into this motion) as a new Motion."""
        idx = np.asarray(idx, dtype=int)
        if idx.size and (idx.min() < 0 or idx.max() >= self.n_frames):
            raise InputError(
                f"frame indices must be in [0, {self.n_frames}); got [{idx.min()}, {idx.max()}]"
            )
        return replace(
            self,
            positions=self.positions[idx],
            angles=self.angles[idx],
            source_frames=self.source_frames[idx],
            trial_index=self.trial_index[idx],
            trial_frames=self.trial_frames[idx],
        )


def _trial_id(path):
    return Path(path).stem


def read_trial(path, asf=None):
    """Parse one trial: a ``.bvh`` file, or a ``.amc`` file with its ASF skeleton ``asf`` (path or parsed;
    when None, ``<subject>.asf`` beside the AMC, CMU's naming ``SS_TT.amc`` -> ``SS.asf``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return parse_bvh(path)
    if suffix == ".amc":
        if asf is None:
            asf = path.with_name(path.stem.split("_")[0] + ".asf")
        return parse_amc(path, asf if isinstance(asf, ASFSkeleton) else parse_asf(asf))
    raise DataFileError(path, f"unknown motion file type {suffix!r}; expected .bvh or .amc")


def load_motion(
    paths, skeleton_kind=None, joint_map=None, drop_first_frame=True, asf=None, skip_frames=None
):
    """Parse trials, concatenate them and return a :class:`Motion`.

    ``paths``: one path or a list (BVH, or AMC with the ASF skeleton ``asf``); all trials must share one
    skeleton topology. ``skeleton_kind``: ``"daz"``, ``"3dsmax"`` or ``"asf"`` (detected when None) picks the
    joint map; ``joint_map`` (19 joint names) overrides it. ``drop_first_frame`` drops frame 0 of every trial
    (the rest pose that the cgspeed BVH converter adds; CMU's AMC files have none, so pass False for them).
    ``skip_frames`` (int), when given, replaces it: that many leading frames of every trial are dropped (the
    Daz-friendly converter also blends from the rest pose into the motion over frames 1-5).
    Angles are unwrapped over the concatenated sequence; the root of AMC trials is written in
    :data:`AMC_ROOT_ORDER` first.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise InputError("load_motion: no trial files given")
    if isinstance(asf, (str, Path)):
        asf = parse_asf(asf)
    trials = [read_trial(p, asf) for p in paths]
    first = trials[0]
    skel = first.skeleton
    for p, t in zip(paths[1:], trials[1:]):
        if not t.skeleton.same_topology(skel):
            raise DataFileError(
                p,
                f"its skeleton differs from that of {paths[0]}; concatenated trials must share one",
            )
        if not np.isclose(t.frame_time, first.frame_time, rtol=1e-3):
            raise DataFileError(
                p, f"frame time {t.frame_time} differs from {first.frame_time} of {paths[0]}"
            )
    kind = skeleton_kind
    if joint_map is None and kind is None:
        kind = (
            "asf"
            if hasattr(first, "asf")
            else detect_skeleton_kind(skel.joint_names, str(paths[0]))
        )
    pose_joints = resolve_joint_map(joint_map, kind, skel.joint_names, str(paths[0]))
    root_order = amc_root_order(skel) if hasattr(first, "asf") else None
    cols, angle_names = pose_columns(skel, pose_joints, root_order)
    root_pose = (
        3 * pose_joints.index(skel.joint_names[0]) if skel.joint_names[0] in pose_joints else -1
    )
    root_rot = [
        (skel.channel_starts()[0] + k, ch)
        for k, ch in enumerate(skel.channels[0])
        if ch in ROTATION_AXES
    ]

    positions, angles, tidx, tfr = [], [], [], []
    if skip_frames is None:
        start = 1 if drop_first_frame else 0
    elif (
        isinstance(skip_frames, (bool, float))
        or not isinstance(skip_frames, (int, np.integer))
        or skip_frames < 0
    ):
        raise InputError(f"skip_frames must be an integer >= 0; got {skip_frames!r}")
    else:
        start = int(skip_frames)
    for k, (p, t) in enumerate(zip(paths, trials)):
        if t.n_frames <= start:
            raise DataFileError(
                p, f"has {t.n_frames} frame(s); nothing is left after dropping the first {start}"
            )
        motion = t.motion[start:]
        pos = _positions_of(t, motion)
        ang = np.where(cols >= 0, motion[:, np.maximum(cols, 0)], 0.0)
        if root_order is not None and root_pose >= 0:
            ang[:, root_pose : root_pose + 3] = reexpress_amc_rotation(
                motion[:, [c for c, _ in root_rot]], [ch for _, ch in root_rot], root_order
            )
        positions.append(pos)
        angles.append(ang)
        tidx.append(np.full(len(motion), k))
        tfr.append(np.arange(start, t.n_frames))
    angles = unwrap_degrees(np.concatenate(angles))
    F = angles.shape[0]
    return Motion(
        joint_names=list(skel.joint_names),
        parents=skel.parents.copy(),
        positions=np.concatenate(positions),
        angles=angles,
        angle_names=angle_names,
        frame_time=float(first.frame_time),
        source_frames=np.arange(F),
        trial_ids=[_trial_id(p) for p in paths],
        trial_index=np.concatenate(tidx),
        trial_frames=np.concatenate(tfr),
        skeleton_kind=kind or "custom",
        pose_joints=pose_joints,
    )


def _positions_of(trial, motion):
    from .asf import asf_positions
    from .skeleton import skeleton_positions

    if hasattr(trial, "asf"):
        return asf_positions(trial.asf, motion)
    return skeleton_positions(trial.skeleton, motion)


def trial_pose_positions(trial, trial_frame, pose_joints, angles):
    """Joint positions (J, 3), centred on the root, of frame ``trial_frame`` of a parsed trial (a BVH trial or an
    AMC trial, e.g. from :func:`read_trial`) with its pose angles replaced by ``angles`` (the 57 columns of
    :func:`load_motion` for ``pose_joints``: the files' channel order, the AMC root in :data:`AMC_ROOT_ORDER`).
    Every other channel (root translation, fingers, toes, ...) keeps the file's value, so the true angles give
    the file's own pose (for stick figures of true and predicted poses)."""
    from .asf import asf_positions
    from .skeleton import skeleton_positions

    skel = trial.skeleton
    root_order = amc_root_order(skel) if hasattr(trial, "asf") else None
    cols, _ = pose_columns(skel, list(pose_joints), root_order)
    angles = np.asarray(angles, dtype=float)
    if angles.shape != cols.shape:
        raise InputError(
            f"expected {cols.size} pose angles for joints {list(pose_joints)}; got shape {angles.shape}"
        )
    row = np.array(trial.motion[int(trial_frame)], dtype=float)
    keep = cols >= 0
    row[cols[keep]] = angles[keep]
    if hasattr(trial, "asf"):
        pos = asf_positions(trial.asf, row[None], root_order)[0]
    else:
        pos = skeleton_positions(skel, row[None])[0]
    return pos - pos[0]


def spread_indices(n_available, n_frames, source="<motion>"):
    """``n_frames`` indices spread evenly over ``range(n_available)``: ``round(linspace(0, n_available-1, n))``.

    InputError if the motion has fewer usable frames than asked for (no frame is repeated).
    """
    n_available, n_frames = int(n_available), int(n_frames)
    if n_frames < 1:
        raise InputError(f"{source}: n_frames must be >= 1; got {n_frames}")
    if n_available < n_frames:
        raise InputError(
            f"{source}: has {n_available} usable frames but {n_frames} were asked for; "
            f"add trials to concatenate or lower n_frames"
        )
    return np.round(np.linspace(0, n_available - 1, n_frames)).astype(int)
