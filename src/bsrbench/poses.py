"""Pose transforms applied before regression and undone before scoring.

``HeadingTransform`` is the authors' group's handling of the heading angle (their Run.m "dewrap"): the
third pose angle (the root's heading, which wraps around) is replaced by ``scale*sin`` and ``scale*cos``
for regression, and recovered with ``atan2`` for scoring.
"""

import numpy as np

from .errors import InputError


class HeadingTransform:
    """Replace angle column ``column`` (degrees) by ``scale*sin`` and ``scale*cos`` columns appended last."""

    def __init__(self, column=2, scale=20.0):
        self.column = column
        self.scale = scale

    def forward(self, Y):
        Y = np.asarray(Y, dtype=float)
        if Y.ndim != 2 or not 0 <= self.column < Y.shape[1]:
            raise InputError(
                f"HeadingTransform: column={self.column} is outside Y with shape {Y.shape}"
            )
        a = np.deg2rad(Y[:, self.column])
        rest = np.delete(Y, self.column, axis=1)
        return np.column_stack([rest, self.scale * np.sin(a), self.scale * np.cos(a)])

    def inverse(self, Z):
        Z = np.asarray(Z, dtype=float)
        if Z.ndim != 2 or Z.shape[1] < 3:
            raise InputError(
                f"HeadingTransform.inverse: expected a 2-D array with >= 3 columns, got {Z.shape}"
            )
        heading = np.rad2deg(np.arctan2(Z[:, -2], Z[:, -1]))
        rest = Z[:, :-2]
        return np.insert(rest, self.column, heading, axis=1)


class IdentityTransform:
    """No transform."""

    def forward(self, Y):
        return np.asarray(Y, dtype=float)

    def inverse(self, Z):
        return np.asarray(Z, dtype=float)


def get_pose_transform(name, column=2):
    """``"none"`` or ``"heading"`` (20 sin / 20 cos of the heading angle, column ``column``: 2 in the
    authors' features, 1 in the CMU BVH joint maps, as stored in each features file)."""
    if name in (None, "none"):
        return IdentityTransform()
    if name == "heading":
        return HeadingTransform(column=column)
    raise InputError(f"pose_transform must be 'none' or 'heading'; got {name!r}")
