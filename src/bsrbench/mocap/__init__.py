"""Motion capture input: BVH and ASF/AMC readers, forward kinematics, joint maps and pose extraction.

Public API:

* :func:`parse_bvh`, :func:`write_bvh`, :class:`BVHData` -- any hierarchy, channel order read from the header.
* :func:`parse_asf`, :func:`parse_amc`, :class:`ASFSkeleton`, :class:`AMCData` -- Acclaim skeleton/motion.
* :class:`Skeleton`, :func:`forward_kinematics`, :func:`local_transforms`, :func:`skeleton_positions`,
  :func:`bone_lengths`.
* :func:`load_motion` -> :class:`Motion` (positions, 57 unwrapped angles, frame bookkeeping),
  :data:`JOINT_MAPS`, :func:`detect_skeleton_kind`, :func:`spread_indices`, :func:`unwrap_degrees`;
  :data:`AMC_ROOT_ORDER`, :func:`reexpress_amc_rotation` (the Euler order of an AMC trial's root pose angles),
  :func:`trial_pose_positions` (a trial frame's joints with its pose angles replaced).
"""

from .asf import AMCData, ASFSkeleton, asf_local_rotations, asf_positions, parse_amc, parse_asf
from .bvh import BVHData, format_bvh, parse_bvh, write_bvh
from .motion import (
    AMC_ROOT_ORDER,
    JOINT_MAPS,
    Motion,
    detect_skeleton_kind,
    load_motion,
    pose_columns,
    read_trial,
    reexpress_amc_rotation,
    resolve_joint_map,
    spread_indices,
    trial_pose_positions,
    unwrap_degrees,
)
from .skeleton import (
    Skeleton,
    bone_lengths,
    forward_kinematics,
    local_transforms,
    skeleton_positions,
)

__all__ = [
    "AMC_ROOT_ORDER",
    "AMCData",
    "ASFSkeleton",
    "BVHData",
    "JOINT_MAPS",
    "Motion",
    "Skeleton",
    "asf_local_rotations",
    "asf_positions",
    "bone_lengths",
    "detect_skeleton_kind",
    "format_bvh",
    "forward_kinematics",
    "load_motion",
    "local_transforms",
    "parse_amc",
    "parse_asf",
    "parse_bvh",
    "pose_columns",
    "read_trial",
    "reexpress_amc_rotation",
    "resolve_joint_map",
    "skeleton_positions",
    "spread_indices",
    "trial_pose_positions",
    "unwrap_degrees",
    "write_bvh",
]
