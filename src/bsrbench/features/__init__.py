"""Histogram-of-shape-contexts features of silhouettes (Agarwal & Triggs, PAMI 2006).

Public API: ``outer_contour``, ``contour_length``, ``sample_contour``, ``shape_contexts``,
``silhouette_descriptors``, ``learn_codebook``, ``histogram_features``, ``default_soft_sigma``.
"""

from bsrbench.features.codebook import default_soft_sigma, histogram_features, learn_codebook
from bsrbench.features.contour import (
    MIN_CONTOUR_POINTS,
    contour_length,
    outer_contour,
    sample_contour,
)
from bsrbench.features.shape_context import shape_contexts, silhouette_descriptors

__all__ = [
    "MIN_CONTOUR_POINTS",
    "contour_length",
    "default_soft_sigma",
    "histogram_features",
    "learn_codebook",
    "outer_contour",
    "sample_contour",
    "shape_contexts",
    "silhouette_descriptors",
]
