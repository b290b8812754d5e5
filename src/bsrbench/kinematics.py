"""Joint-position errors of poses: MPJPE and PA-MPJPE (mm) by forward kinematics on one fixed skeleton.

A pose of the study is 57 joint angles (19 joints x 3, degrees). To score it as positions, the angles are set as
the rotation channels of one fixed skeleton per source, every other channel (root translation, fingers, toes,
in-between spine joints) is held at zero, and forward kinematics gives the joint positions with the root at the
origin:

* mocap: the trial's own skeleton (a BVH file, or an ASF file for AMC trials), with the 19 pose joints of its
  joint map (:data:`bsrbench.mocap.JOINT_MAPS`), in the column order of :func:`bsrbench.mocap.pose_columns`;
* hsc: the authors' skeleton (:func:`bsrbench.authors.hsc_skeleton`, the one the subjective figure draws), whose
  19 joints carry the 57 columns as ``Zrotation Xrotation Yrotation`` each.

The positions scored are those of the 19 pose joints (the root included, at the origin in both poses), as the
17-joint Human3.6M protocol scores its pelvis, knees, wrists, head... (Ionescu et al., PAMI 2014). The errors:

* MPJPE: mean over frames and joints of the Euclidean distance between predicted and true joint positions;
* PA-MPJPE: the same after aligning each predicted pose to the true one by the similarity transform (rotation,
  uniform scale, translation) that minimises the squared distances (Procrustes analysis; the rotation is the
  proper rotation of Kabsch's solution, for all poses at once, and the scale is the least-squares one given that
  rotation, as in the usual PA-MPJPE code, e.g. Kanazawa et al.'s HMR).

Lengths are converted to mm with the skeleton's unit (:data:`MM_PER_UNIT`): the Daz-friendly CMU BVH release is
in cm, the 3dsMax-friendly release and the CMU ASF files in the ASF unit of ``length 0.45`` (1/0.45 inch), and
the authors' Poser skeleton in inches. The vertical extent of all joints in the zero pose (feet to the highest
joint of the head; 1527 mm for the Daz skeleton, 1370 mm for subject 131's 3dsMax skeleton, 1627 mm for the
authors') must then lie in :data:`STATURE_RANGE_MM`, else the unit is wrong and the skeleton is refused.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

#: Pose angles per pose (19 joints x 3 Euler angles).
N_POSE_ANGLES = 57
#: mm per length unit of each skeleton kind (see the module docstring).
MM_PER_UNIT = {
    "daz": 10.0,
    "3dsmax": 25.4 / 0.45,
    "asf": 25.4 / 0.45,
    "hsc": 25.4,
}
#: The zero pose's vertical extent in mm must fall in this range for the skeleton's unit to be believed.
STATURE_RANGE_MM = (1200.0, 2200.0)


@dataclass
class PoseSkeleton:
    """A fixed skeleton on which a row of pose angles gives joint positions.

    ``source``: what the skeleton belongs to (named in every error, e.g. ``"mocap/walk (12_02.bvh)"``);
    ``parents`` (J,) with -1 for the root; ``offsets`` (J, 3) of each joint in its parent's frame (skeleton
    units); ``local_rotations``: a function ``(motion (F, C)) -> (F, J, 3, 3)`` giving each joint's local rotation
    from a motion row of C channels; ``n_channels``: C; ``columns`` (A,): for each pose angle, its channel in a
    motion row, or -1 for an axis the joint does not rotate about (the angle is then a constant zero and ignored);
    ``angle_names`` (A,); ``scored`` (S,): indices of the joints whose positions are scored (the pose joints);
    ``mm_per_unit``: length unit in mm. Raises InputError if the arrays disagree.
    """

    source: str
    parents: np.ndarray
    offsets: np.ndarray
    local_rotations: object
    n_channels: int
    columns: np.ndarray
    angle_names: list
    scored: np.ndarray
    mm_per_unit: float = 1.0

    def __post_init__(self):
        self.parents = np.asarray(self.parents, dtype=int)
        self.offsets = np.asarray(self.offsets, dtype=float).reshape(-1, 3)
        self.columns = np.asarray(self.columns, dtype=int)
        self.scored = np.asarray(self.scored, dtype=int)
        self.angle_names = list(self.angle_names)
        J = self.parents.size
        if self.offsets.shape[0] != J:
            raise InputError(
                f"{self.source}: {self.offsets.shape[0]} offsets for {J} joints; expected one per joint"
            )
        if len(self.angle_names) != self.columns.size:
            raise InputError(
                f"{self.source}: {len(self.angle_names)} angle names for {self.columns.size} angle columns"
            )
        if self.columns.size and (self.columns.max() >= self.n_channels or self.columns.min() < -1):
            raise InputError(
                f"{self.source}: angle columns must be in [-1, {self.n_channels}); got "
                f"[{self.columns.min()}, {self.columns.max()}]"
            )
        if self.scored.size == 0 or self.scored.min() < 0 or self.scored.max() >= J:
            raise InputError(f"{self.source}: scored joints must be indices in [0, {J})")
        if not (np.isfinite(self.mm_per_unit) and self.mm_per_unit > 0):
            raise InputError(f"{self.source}: mm_per_unit must be > 0; got {self.mm_per_unit!r}")

    @property
    def n_angles(self):
        return int(self.columns.size)

    def check_angles(self, Y, name="angles"):
        """``Y`` as a float array (F, n_angles); InputError naming the source and the expected count otherwise."""
        Y = np.asarray(Y, dtype=float)
        if Y.ndim == 1:
            Y = Y[None]
        if Y.ndim != 2 or Y.shape[1] != self.n_angles:
            raise InputError(
                f"{self.source}: {name} have shape {Y.shape}; the skeleton expects rows of "
                f"{self.n_angles} angles ({', '.join(self.angle_names[:3])}, ...)"
            )
        if not np.all(np.isfinite(Y)):
            r, c = (int(i) for i in np.argwhere(~np.isfinite(Y))[0])
            raise InputError(
                f"{self.source}: {name} contain a non-finite value at row {r}, column {c} "
                f"({self.angle_names[c]}); expected finite angles"
            )
        return Y

    def check_angle_names(self, names, what="angle_names"):
        """InputError naming the source and the first joint whose angle differs, unless ``names`` (e.g. a
        features file's ``angle_names``) are this skeleton's angles in its order."""
        names = [str(n) for n in names]
        if names == self.angle_names:
            return
        if len(names) != self.n_angles:
            raise InputError(
                f"{self.source}: {what} has {len(names)} angles; the skeleton expects {self.n_angles} "
                f"({self.n_angles // 3} joints x 3)"
            )
        k = next(i for i, (a, b) in enumerate(zip(names, self.angle_names)) if a != b)
        raise InputError(
            f"{self.source}: {what}[{k}] is {names[k]!r} where the skeleton has {self.angle_names[k]!r} "
            f"(joint {self.angle_names[k].rsplit('_', 1)[0]!r}); expected its {self.n_angles} angles in order"
        )

    def positions(self, Y):
        """Joint positions (F, J, 3) in mm, root at the origin, for pose rows ``Y`` (F, n_angles) in degrees."""
        from .mocap.skeleton import forward_kinematics

        Y = self.check_angles(Y)
        F = Y.shape[0]
        motion = np.zeros((F, self.n_channels))
        keep = self.columns >= 0
        motion[:, self.columns[keep]] = Y[:, keep]
        R = self.local_rotations(motion)
        T = np.broadcast_to(self.offsets, (F,) + self.offsets.shape).copy()
        T[:, 0] = 0.0
        P = forward_kinematics(self.parents, R, T)[0]
        return (P - P[:, :1]) * self.mm_per_unit

    def scored_positions(self, Y):
        """Positions (F, S, 3) in mm of the scored joints (see :meth:`positions`)."""
        return self.positions(Y)[:, self.scored]


# ------------------------------------------------------------------------------------------------ skeletons
def _bvh_rotations(skeleton):
    from .mocap.skeleton import local_transforms

    return lambda motion: local_transforms(skeleton, motion)[0]


def _asf_rotations(asf, root_order):
    from .mocap.asf import asf_local_rotations

    return lambda motion: asf_local_rotations(asf, motion, root_order)


def _pose_skeleton(source, skeleton, rotations, joint_map, kind, n_angles, root_order=None):
    from .mocap.motion import pose_columns

    joint_map = list(joint_map)
    expected = f"expected {n_angles} angles ({n_angles // 3} joints x 3)"
    for jn in joint_map:
        if jn not in skeleton.joint_names:
            raise InputError(
                f"{source}: pose joint {jn!r} is not in the skeleton ({expected}); its joints are "
                f"{list(skeleton.joint_names)[:8]}..."
            )
    try:
        cols, names = pose_columns(skeleton, joint_map, root_order)
    except InputError as exc:
        raise InputError(f"{source}: {exc}; {expected}") from None
    if cols.size != n_angles:
        raise InputError(
            f"{source}: the joint map has {len(joint_map)} joints ({joint_map[0]!r} ... "
            f"{joint_map[-1]!r}) giving {cols.size} angles; {expected}"
        )
    ps = PoseSkeleton(
        source=source,
        parents=skeleton.parents,
        offsets=skeleton.offsets,
        local_rotations=rotations,
        n_channels=skeleton.n_channels,
        columns=cols,
        angle_names=names,
        scored=[skeleton.index(j) for j in joint_map],
        mm_per_unit=MM_PER_UNIT[kind],
    )
    _check_stature(ps, skeleton)
    return ps


def _check_stature(ps, skeleton):
    """InputError unless the zero pose of ``ps`` is a plausible human height in mm (the unit is right)."""
    P = ps.positions(np.zeros((1, ps.n_angles)))[0]
    height = float(P[:, 1].max() - P[:, 1].min())
    lo, hi = STATURE_RANGE_MM
    if not lo <= height <= hi:
        raise InputError(
            f"{ps.source}: the skeleton's zero pose is {height:.0f} mm tall at {ps.mm_per_unit:g} mm per "
            f"unit; expected {lo:.0f}-{hi:.0f} mm (wrong length unit for this skeleton?)"
        )


def hsc_pose_skeleton(source="hsc"):
    """The authors' skeleton (:func:`bsrbench.authors.hsc_skeleton`, inches) for the hsc source's 57 angles."""
    from .authors import HSC_JOINTS, hsc_skeleton

    skel = hsc_skeleton()
    return _pose_skeleton(source, skel, _bvh_rotations(skel), HSC_JOINTS, "hsc", N_POSE_ANGLES)


def mocap_pose_skeleton(path, joint_map=None, skeleton_kind=None, source=None):
    """The skeleton of a mocap trial file for its 57 pose angles: a ``.bvh`` file, or the ``.asf`` file of AMC
    trials. ``joint_map`` (19 names) and ``skeleton_kind`` as for :func:`bsrbench.mocap.load_motion` (None:
    detected from the joint names). ``source`` names the skeleton in errors (default: the path)."""
    from .mocap import parse_asf, parse_bvh
    from .mocap.motion import JOINT_MAPS, amc_root_order, detect_skeleton_kind

    path = Path(path)
    source = source or str(path)
    suffix = path.suffix.lower()
    root_order = None
    if suffix == ".bvh":
        skel = parse_bvh(path).skeleton
        rotations = _bvh_rotations(skel)
    elif suffix == ".asf":
        asf = parse_asf(path)
        skel = asf.skeleton
        # the root's pose angles of AMC trials are in the authors' order (bsrbench.mocap.load_motion)
        root_order = amc_root_order(skel)
        rotations = _asf_rotations(asf, root_order)
        skeleton_kind = skeleton_kind or "asf"
    else:
        raise InputError(f"{source}: expected a .bvh or .asf skeleton file; got {suffix!r}")
    kind = skeleton_kind or detect_skeleton_kind(skel.joint_names, source)
    if kind not in MM_PER_UNIT or kind == "hsc":
        raise InputError(
            f"{source}: skeleton_kind must be one of {sorted(set(JOINT_MAPS))}; got {kind!r}"
        )
    if joint_map is None:
        joint_map = JOINT_MAPS[kind]
    return _pose_skeleton(source, skel, rotations, joint_map, kind, N_POSE_ANGLES, root_order)


# ---------------------------------------------------------------------------------------------------- errors
def _pair(skeleton, y_true, y_pred):
    Yt = skeleton.check_angles(y_true, "true angles")
    Yp = skeleton.check_angles(y_pred, "predicted angles")
    if Yt.shape != Yp.shape:
        raise InputError(
            f"{skeleton.source}: true angles {Yt.shape} and predicted angles {Yp.shape} differ in shape"
        )
    return skeleton.scored_positions(Yt), skeleton.scored_positions(Yp)


def per_joint_position_error(P_true, P_pred):
    """Euclidean distance (F, S) between true and predicted positions (F, S, 3)."""
    return np.linalg.norm(np.asarray(P_pred, float) - np.asarray(P_true, float), axis=-1)


def similarity_align(P_pred, P_true):
    """``P_pred`` (..., S, 3) moved by the similarity transform (proper rotation, scale, translation) that best
    fits it to ``P_true`` (..., S, 3) in least squares, one transform per pose of the leading axes.

    The rotation is Kabsch's: from the SVD ``U S V^T`` of the 3 x 3 cross-covariance of the centred poses,
    ``R = V diag(1, 1, d) U^T`` with ``d = sign det(V U^T)`` so that ``R`` is proper (Umeyama, PAMI 1991)."""
    A = np.asarray(P_pred, dtype=float)
    B = np.asarray(P_true, dtype=float)
    a0, b0 = A.mean(axis=-2, keepdims=True), B.mean(axis=-2, keepdims=True)
    Ac, Bc = A - a0, B - b0
    U, _, Vt = np.linalg.svd(np.swapaxes(Ac, -1, -2) @ Bc)
    d = np.sign(np.linalg.det(U @ Vt))
    Vt[..., 2, :] *= d[..., None]
    RA = Ac @ (U @ Vt)  # row vectors: each row a rotated by R = (U Vt)^T
    norm = np.sum(Ac * Ac, axis=(-2, -1))
    # all joints at one point: only the translation can be fitted
    scale = np.divide(np.sum(RA * Bc, axis=(-2, -1)), norm, out=np.zeros_like(norm), where=norm > 0)
    return scale[..., None, None] * RA + b0


def mpjpe(y_true, y_pred, skeleton):
    """Mean per-joint position error (mm) of pose rows ``y_pred`` against ``y_true`` (F, 57; degrees)."""
    Pt, Pp = _pair(skeleton, y_true, y_pred)
    return float(per_joint_position_error(Pt, Pp).mean())


def pa_mpjpe(y_true, y_pred, skeleton):
    """MPJPE (mm) after aligning every predicted pose to the true one (:func:`similarity_align`)."""
    Pt, Pp = _pair(skeleton, y_true, y_pred)
    return float(per_joint_position_error(Pt, similarity_align(Pp, Pt)).mean())


def features_pose_skeleton(features, source):
    """The :class:`PoseSkeleton` of an activity from its features file (a dict or ``.npz`` of
    :mod:`bsrbench.datasets`): for mocap features (they carry ``pose_joints`` and ``files``) the skeleton of the
    first trial file (a BVH file, or for AMC trials the subject's ASF file beside it), checked against the
    features' ``angle_names``; otherwise the authors' skeleton (hsc features). ``source`` (e.g.
    ``"mocap/walk"``) names the skeleton in errors."""
    keys = set(features.keys()) if hasattr(features, "keys") else set()
    if "pose_joints" in keys and "files" in keys:
        files = [str(f) for f in np.atleast_1d(features["files"])]
        if not files:
            raise InputError(f"{source}: the features name no trial file to take the skeleton from")
        path = Path(files[0])
        if path.suffix.lower() == ".amc":
            path = path.with_name(path.stem.split("_")[0] + ".asf")
        kind = str(features["skeleton_kind"]) if "skeleton_kind" in keys else None
        ps = mocap_pose_skeleton(
            path,
            joint_map=[str(j) for j in np.atleast_1d(features["pose_joints"])],
            skeleton_kind=None if kind in (None, "", "custom") else kind,
            source=f"{source} ({path.name})",
        )
    else:
        ps = hsc_pose_skeleton(source=f"{source} (the authors' skeleton)")
    if "angle_names" in keys and "pose_joints" in keys:
        ps.check_angle_names(np.atleast_1d(features["angle_names"]), "the features' angle_names")
    if "Y" in keys:
        ps.check_angles(np.asarray(features["Y"])[:1], "the features' poses Y")
    return ps


def warm_up():
    """Import the skeleton readers and run forward kinematics once (the authors' skeleton), e.g. in a job server
    before it forks the jobs."""
    hsc_pose_skeleton()
