"""Kinematic tree shared by the BVH and ASF/AMC readers, and forward kinematics.

A skeleton is a list of joints, each with a parent (-1 for the root), a fixed offset from its parent expressed
in the parent's frame, and the names of its channels (empty for end sites). Forward kinematics composes local
rotation matrices down the tree: ``G_j = G_parent(j) @ R_j`` and ``p_j = p_parent(j) + G_parent(j) @ offset_j``,
the convention of the BVH format (Meredith & Maddock, "Motion capture file formats explained", 2001) and of the
Acclaim ASF/AMC format once its bone axes are folded into the local rotation (see ``asf.py``).
"""

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

ROTATION_AXES = {"Xrotation": 0, "Yrotation": 1, "Zrotation": 2}
POSITION_AXES = {"Xposition": 0, "Yposition": 1, "Zposition": 2}
CHANNEL_NAMES = tuple(ROTATION_AXES) + tuple(POSITION_AXES)


@dataclass
class Skeleton:
    """A kinematic tree.

    ``joint_names`` (J,), ``parents`` (J,) int with -1 for the root and every parent listed before its
    children, ``offsets`` (J, 3) in the parent's frame, ``channels``: per joint a tuple of channel names
    (``"Zrotation"``, ``"Xposition"``...; empty for end sites), ``end_site`` (J,) bool.
    """

    joint_names: list
    parents: np.ndarray
    offsets: np.ndarray
    channels: list
    end_site: np.ndarray = field(default=None)

    def __post_init__(self):
        self.parents = np.asarray(self.parents, dtype=int)
        self.offsets = np.asarray(self.offsets, dtype=float).reshape(-1, 3)
        if self.end_site is None:
            self.end_site = np.zeros(len(self.joint_names), dtype=bool)
        self.end_site = np.asarray(self.end_site, dtype=bool)
        n = len(self.joint_names)
        if not (
            len(self.parents) == len(self.offsets) == len(self.channels) == len(self.end_site) == n
        ):
            raise InputError(
                "Skeleton: joint_names, parents, offsets, channels and end_site must have equal length"
            )
        for j, p in enumerate(self.parents):
            if not (p == -1 if j == 0 else 0 <= p < j):
                raise InputError(
                    f"Skeleton: joint {self.joint_names[j]!r} has parent index {p}; parents must precede children"
                )

    @property
    def n_channels(self):
        return sum(len(c) for c in self.channels)

    def channel_starts(self):
        """Index of each joint's first channel in a motion row."""
        return np.concatenate([[0], np.cumsum([len(c) for c in self.channels])[:-1]]).astype(int)

    def index(self, name):
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise InputError(f"skeleton has no joint {name!r}") from None

    def same_topology(self, other):
        return self.joint_names == other.joint_names and np.array_equal(self.parents, other.parents)


def axis_rotation(axis, angles_deg):
    """Rotation matrices (..., 3, 3) about ``axis`` (0=x, 1=y, 2=z) by ``angles_deg`` degrees (right-handed)."""
    a = np.deg2rad(np.asarray(angles_deg, dtype=float))
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def euler_matrix(axes, angles_deg):
    """Product ``R_{axes[0]}(a_0) @ R_{axes[1]}(a_1) @ ...`` for angles (F, k) in degrees; identity if k = 0.

    This is the BVH convention: the first listed channel is the outermost rotation.
    """
    angles_deg = np.asarray(angles_deg, dtype=float)
    F = angles_deg.shape[0]
    R = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
    for k, ax in enumerate(axes):
        R = R @ axis_rotation(ax, angles_deg[:, k])
    return R


def local_transforms(skeleton, motion):
    """Local rotations (F, J, 3, 3) and translations (F, J, 3) of every joint from BVH-style channel values.

    Rotation channels compose in the listed order (first listed is outermost); position channels are added to
    the joint's offset.
    """
    motion = np.asarray(motion, dtype=float)
    F = motion.shape[0]
    J = len(skeleton.joint_names)
    R = np.empty((F, J, 3, 3))
    T = np.broadcast_to(skeleton.offsets, (F, J, 3)).copy()
    for j, (chans, start) in enumerate(zip(skeleton.channels, skeleton.channel_starts())):
        axes, cols = [], []
        for k, ch in enumerate(chans):
            if ch in ROTATION_AXES:
                axes.append(ROTATION_AXES[ch])
                cols.append(start + k)
            else:
                T[:, j, POSITION_AXES[ch]] += motion[:, start + k]
        R[:, j] = euler_matrix(axes, motion[:, cols])
    return R, T


def forward_kinematics(parents, local_rotations, local_translations):
    """World positions (F, J, 3) and world rotations (F, J, 3, 3) of every joint.

    ``parents`` (J,) with -1 for the root (parents precede children); ``local_rotations`` (F, J, 3, 3);
    ``local_translations`` (F, J, 3): the joint's position in its parent's frame (for the root, in the world).
    """
    parents = np.asarray(parents, dtype=int)
    R = np.asarray(local_rotations, dtype=float)
    T = np.asarray(local_translations, dtype=float)
    F, J = T.shape[:2]
    G = np.empty_like(R)
    P = np.empty_like(T)
    for j in range(J):
        p = parents[j]
        if p < 0:
            G[:, j] = R[:, j]
            P[:, j] = T[:, j]
        else:
            G[:, j] = G[:, p] @ R[:, j]
            P[:, j] = P[:, p] + np.einsum("fab,fb->fa", G[:, p], T[:, j])
    return P, G


def skeleton_positions(skeleton, motion):
    """World joint positions (F, J, 3) of a BVH-style skeleton for channel values ``motion`` (F, C)."""
    R, T = local_transforms(skeleton, motion)
    return forward_kinematics(skeleton.parents, R, T)[0]


def bone_lengths(positions, parents):
    """Length of every bone (F, J) (0 for the root): distance from each joint to its parent."""
    positions = np.asarray(positions, dtype=float)
    parents = np.asarray(parents, dtype=int)
    par = np.where(parents < 0, np.arange(len(parents)), parents)
    return np.linalg.norm(positions - positions[:, par], axis=-1)
