"""Shape context descriptors of point sets and of silhouettes.

Belongie, Malik & Puzicha, "Shape matching and object recognition using shape contexts", IEEE PAMI 24(4),
2002, Sec. 3.1: the shape context of point ``p_i`` is the histogram, over log-polar bins centred on ``p_i``, of
the relative positions ``p_j - p_i`` of the other points. Binning as in the authors' ``sc_compute.m``:

* distances are divided by the mean distance over all ordered pairs ``i != j`` (scale invariance);
* the ``n_radial`` radial bin edges are ``logspace(log10(r_inner), log10(r_outer), n_radial)``; a point with
  normalised distance ``r`` goes to radial bin ``n_radial - #{edges > r}``, so bin 0 holds everything closer than
  ``r_inner`` and points at ``r >= r_outer`` are not counted;
* angles ``atan2(dy, dx)`` in [0, 2 pi) go to ``n_angular`` equal sectors. Angles are absolute (measured in the
  image frame, x right, y down), not relative to the tangent, as Agarwal & Triggs use for silhouettes
  ("Recovering 3D human pose from monocular images", IEEE PAMI 28(1), 2006, Sec. 2.1), so the descriptor is not
  rotation invariant.

Histogram column ``radial_bin * n_angular + angular_bin``; with the defaults (5 x 12) that is 60 columns.
"""

import numpy as np

from bsrbench.errors import InputError
from bsrbench.features.contour import MIN_CONTOUR_POINTS, _as_mask, outer_contour, sample_contour


def _check_points(points):
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2 or points.shape[0] < 2:
        raise InputError(
            f"points: expected an (n >= 2, 2) array of (x, y), got shape {points.shape}"
        )
    if not np.all(np.isfinite(points)):
        raise InputError("points: contains non-finite coordinates")
    return points


def shape_contexts(points, n_radial=5, n_angular=12, r_inner=0.125, r_outer=2.0):
    """(n, n_radial * n_angular) float array of shape context counts of each of the n points.

    Row i counts the points j != i with normalised distance < ``r_outer``, so it sums to ``n - 1`` minus the
    number of points at or beyond ``r_outer``. Invariant to translation and scale of ``points``; not to rotation.
    Vectorised over all point pairs (O(n^2) memory).
    """
    points = _check_points(points)
    if int(n_radial) != n_radial or n_radial < 1 or int(n_angular) != n_angular or n_angular < 1:
        raise InputError(
            f"n_radial, n_angular: expected positive integers, got {n_radial!r}, {n_angular!r}"
        )
    if not (0 < r_inner < r_outer) or not np.isfinite(r_outer):
        raise InputError(
            f"r_inner, r_outer: expected 0 < r_inner < r_outer < inf, got {r_inner!r}, {r_outer!r}"
        )
    n_radial, n_angular = int(n_radial), int(n_angular)
    n = len(points)
    diff = points[None, :, :] - points[:, None, :]  # diff[i, j] = p_j - p_i
    dist = np.hypot(diff[..., 0], diff[..., 1])
    off = ~np.eye(n, dtype=bool)
    mean_dist = dist[off].mean()
    if not mean_dist > 0:
        raise InputError("points: all points coincide; shape contexts need distinct points")
    r = dist / mean_dist
    edges = np.logspace(np.log10(r_inner), np.log10(r_outer), n_radial)
    q = n_radial - np.searchsorted(edges, r, side="right")  # number of edges > r
    theta = np.arctan2(diff[..., 1], diff[..., 0]) % (2 * np.pi)
    a_bin = np.minimum((theta * (n_angular / (2 * np.pi))).astype(np.int64), n_angular - 1)
    valid = off & (q > 0)
    col = (n_radial - q) * n_angular + a_bin
    n_bins = n_radial * n_angular
    rows = np.broadcast_to(np.arange(n)[:, None], (n, n))
    flat = rows[valid] * n_bins + col[valid]
    return np.bincount(flat, minlength=n * n_bins).reshape(n, n_bins).astype(float)


def silhouette_descriptors(masks, n_points=200, seed=0, **shape_context_kw):
    """Shape contexts of ``n_points`` points sampled along the outer contour of each silhouette.

    Parameters
    ----------
    masks : (F, H, W) binary images.
    n_points : points per silhouette (Agarwal & Triggs use a few hundred edge points; 100-400 is typical).
    seed : int or None
        Sampling of frame f starts at a random fraction of the spacing drawn from
        ``np.random.default_rng([seed, f])``, so each frame's points depend only on (seed, f); None starts at the
        contour's first point (its top-left pixel).
    **shape_context_kw : passed to ``shape_contexts``.

    Returns a list of F arrays (n_points, 60). Raises ``InputError`` naming the frame if a mask is empty or its
    outer contour has fewer than ``MIN_CONTOUR_POINTS`` pixels.
    """
    masks = np.asarray(masks)
    if masks.ndim != 3 or masks.shape[0] < 1:
        raise InputError(
            f"masks: expected a (frames >= 1, height, width) array, got shape {masks.shape}"
        )
    out = []
    for f in range(masks.shape[0]):
        mask = _as_mask(masks[f], name=f"masks[{f}]")
        if not mask.any():
            raise InputError(f"masks[{f}]: the silhouette of frame {f} is empty")
        contour = outer_contour(mask)
        if len(np.unique(contour, axis=0)) < MIN_CONTOUR_POINTS:
            raise InputError(
                f"masks[{f}]: the outer contour of frame {f} has {len(contour)} pixels, "
                f"fewer than the {MIN_CONTOUR_POINTS} needed"
            )
        rng = None if seed is None else np.random.default_rng([int(seed), f])
        pts = sample_contour(contour, n_points, rng=rng)
        out.append(shape_contexts(pts, **shape_context_kw))
    return out
