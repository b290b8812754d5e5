"""Outer contour of a binary silhouette and points sampled along it.

The outer boundary is traced with 8-neighbour boundary following (the Moore-neighbour / chain-code tracing of
Freeman; see e.g. Gonzalez & Woods, "Digital Image Processing", 3rd ed., Sec. 11.1.1): start at the first
foreground pixel in raster order, whose west neighbour is background, walk around the object by scanning the
8 neighbours of the current pixel counter-clockwise starting next to the previous direction, and stop when the
start pixel is reached again with the same outgoing move (Jacob's stopping criterion). Points are pixel centres
as (x, y) = (column, row): x to the right, y downwards.
"""

import numba
import numpy as np
from scipy import ndimage

from bsrbench.errors import InputError

#: Fewest distinct contour pixels a silhouette must have to be described.
MIN_CONTOUR_POINTS = 8

# 8 directions, counter-clockwise on screen (row axis points down): E, NE, N, NW, W, SW, S, SE.
_DROW = np.array([0, -1, -1, -1, 0, 1, 1, 1], dtype=np.int64)
_DCOL = np.array([1, 1, 0, -1, -1, -1, 0, 1], dtype=np.int64)


@numba.njit(cache=True)
def _trace(padded, r0, c0, drow, dcol, out):
    """Trace the boundary of the component containing (r0, c0) in a zero-padded image; fills ``out`` (N, 2)
    with (row, col) and returns the number of points."""
    n = 0
    r, c = r0, c0
    direction = 7
    first_move = -1
    max_steps = out.shape[0]
    while n < max_steps:
        out[n, 0] = r
        out[n, 1] = c
        n += 1
        start = (direction + 7) % 8 if direction % 2 == 0 else (direction + 6) % 8
        found = -1
        for k in range(8):
            d = (start + k) % 8
            if padded[r + drow[d], c + dcol[d]]:
                found = d
                break
        if found < 0:  # isolated pixel
            return n
        if r == r0 and c == c0:
            if first_move < 0:
                first_move = found
            elif found == first_move:
                return n - 1
        direction = found
        r += drow[found]
        c += dcol[found]
    return n


def _as_mask(mask, name="mask"):
    mask = np.asarray(mask)
    if mask.ndim != 2 or min(mask.shape) < 1:
        raise InputError(f"{name}: expected a 2-D binary image, got shape {mask.shape}")
    if mask.dtype != bool:
        if not np.all(np.isin(mask, (0, 1))):
            raise InputError(
                f"{name}: expected a binary image (bool or 0/1), got values other than 0 and 1"
            )
        mask = mask.astype(bool)
    return mask


def outer_contour(mask):
    """Ordered (P, 2) float array of (x, y) = (column, row) pixel centres on the outer boundary of the largest
    8-connected foreground component of ``mask`` (holes are ignored). Each point is an 8-neighbour of the next,
    and the last point is an 8-neighbour of the first (a closed chain). An empty mask gives a (0, 2) array."""
    mask = _as_mask(mask)
    labels, n_labels = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
    if n_labels == 0:
        return np.zeros((0, 2))
    sizes = np.bincount(labels.ravel())[1:]
    keep = labels == (int(np.argmax(sizes)) + 1)
    padded = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), dtype=np.bool_)
    padded[1:-1, 1:-1] = keep
    flat = int(np.argmax(padded))
    r0, c0 = divmod(flat, padded.shape[1])
    # Every boundary pixel is visited at most 4 times by an 8-neighbour tracing.
    out = np.empty((4 * int(keep.sum()) + 8, 2), dtype=np.int64)
    n = _trace(padded, r0, c0, _DROW, _DCOL, out)
    rc = out[:n] - 1
    return np.stack([rc[:, 1], rc[:, 0]], axis=1).astype(float)


def contour_length(contour):
    """Length of the closed polygon through the points of ``contour`` (P, 2)."""
    contour = np.asarray(contour, dtype=float)
    if len(contour) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(contour, axis=0, append=contour[:1]), axis=1).sum())


def sample_contour(contour, n_points, rng=None, jitter=0.0):
    """``n_points`` points (n_points, 2) along the closed contour, evenly spaced by arc length.

    Parameters
    ----------
    contour : (P, 2) ordered points of a closed curve (e.g. from ``outer_contour``), P >= 3.
    n_points : int >= 3.
    rng : None, int seed or numpy Generator
        None starts at the contour's first point; otherwise the start is shifted by a uniform random fraction of
        the spacing, drawn from this generator (or ``np.random.default_rng(seed)``).
    jitter : float in [0, 0.5)
        Each point is further moved along the curve by a uniform offset in [-jitter, jitter] spacings (needs
        ``rng``); 0 keeps the spacing exactly even.

    Points are linear interpolations between the contour's points, so they lie on its polygon.
    """
    contour = np.asarray(contour, dtype=float)
    if (
        contour.ndim != 2
        or contour.shape[1] != 2
        or len(contour) < 3
        or not np.all(np.isfinite(contour))
    ):
        raise InputError(
            f"contour: expected at least 3 finite (x, y) points, got shape {contour.shape}"
        )
    if int(n_points) != n_points or n_points < 3:
        raise InputError(f"n_points: expected an integer >= 3, got {n_points!r}")
    if not (0 <= jitter < 0.5):
        raise InputError(f"jitter: expected a fraction of the spacing in [0, 0.5), got {jitter!r}")
    if jitter > 0 and rng is None:
        raise InputError("jitter: a random generator or seed (rng) is needed when jitter > 0")
    n_points = int(n_points)
    closed = np.vstack([contour, contour[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = cum[-1]
    if total <= 0:
        raise InputError("contour: all points coincide; the curve has zero length")
    if rng is None:
        phase = np.zeros(n_points)
    else:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        phase = np.full(n_points, gen.uniform())
        if jitter > 0:
            phase = phase + gen.uniform(-jitter, jitter, size=n_points)
    t = ((np.arange(n_points) + phase) / n_points * total) % total
    return np.stack([np.interp(t, cum, closed[:, 0]), np.interp(t, cum, closed[:, 1])], axis=1)
