"""Silhouettes of mocap sequences: a capsule/ellipsoid body under an orthographic camera.

Public API: ``render_silhouettes``, ``fit_camera``, ``save_montage``, ``build_body_model``, ``estimate_stature``,
``view_basis``, ``BodyModel``, ``OrthoCamera``.
"""

from bsrbench.render.body import BodyModel, build_body_model, estimate_stature, joint_part
from bsrbench.render.montage import save_montage
from bsrbench.render.silhouette import OrthoCamera, fit_camera, render_silhouettes, view_basis

__all__ = [
    "BodyModel",
    "OrthoCamera",
    "build_body_model",
    "estimate_stature",
    "fit_camera",
    "joint_part",
    "render_silhouettes",
    "save_montage",
    "view_basis",
]
