"""Numba rasterisation kernel: pixel-centre inside/outside tests for 2-D capsules and ellipses.

Under an orthographic camera the image of a 3-D capsule (segment swept by a ball of radius r) is exactly the 2-D
capsule of the projected segment with radius r, and the image of an ellipsoid ``{c + A u : |u| <= 1}`` is the
ellipse ``{P c + (P A) u : |u| <= 1}``, i.e. ``(y - P c)^T (P A A^T P^T)^{-1} (y - P c) <= 1``. Each primitive
only visits the pixels of its own bounding box.
"""

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _raster_frame(out, seg, rad, ell_c, ell_q, ell_half):
    """Rasterise one frame into ``out`` (H, W) bool.

    seg (C, 4): x0, y0, x1, y1 of each capsule axis in pixel units (x = column, y = row, pixel (i, j) has its
    centre at (j + 0.5, i + 0.5)); rad (C,): radii in pixels; ell_c (E, 2) ellipse centres, ell_q (E, 3) the
    quadratic form (q_xx, q_xy, q_yy) of the inverse shape matrix, ell_half (E, 2) half-extents in x and y.
    """
    h, w = out.shape
    for c in range(seg.shape[0]):
        x0, y0, x1, y1 = seg[c, 0], seg[c, 1], seg[c, 2], seg[c, 3]
        r = rad[c]
        r2 = r * r
        dx, dy = x1 - x0, y1 - y0
        len2 = dx * dx + dy * dy
        j_lo = max(0, int(math.floor(min(x0, x1) - r - 0.5)))
        j_hi = min(w - 1, int(math.ceil(max(x0, x1) + r - 0.5)))
        i_lo = max(0, int(math.floor(min(y0, y1) - r - 0.5)))
        i_hi = min(h - 1, int(math.ceil(max(y0, y1) + r - 0.5)))
        for i in range(i_lo, i_hi + 1):
            py = i + 0.5
            for j in range(j_lo, j_hi + 1):
                px = j + 0.5
                t = 0.0
                if len2 > 0.0:
                    t = ((px - x0) * dx + (py - y0) * dy) / len2
                    if t < 0.0:
                        t = 0.0
                    elif t > 1.0:
                        t = 1.0
                ex = px - (x0 + t * dx)
                ey = py - (y0 + t * dy)
                if ex * ex + ey * ey <= r2:
                    out[i, j] = True
    for e in range(ell_c.shape[0]):
        cx, cy = ell_c[e, 0], ell_c[e, 1]
        qxx, qxy, qyy = ell_q[e, 0], ell_q[e, 1], ell_q[e, 2]
        hx, hy = ell_half[e, 0], ell_half[e, 1]
        j_lo = max(0, int(math.floor(cx - hx - 0.5)))
        j_hi = min(w - 1, int(math.ceil(cx + hx - 0.5)))
        i_lo = max(0, int(math.floor(cy - hy - 0.5)))
        i_hi = min(h - 1, int(math.ceil(cy + hy - 0.5)))
        for i in range(i_lo, i_hi + 1):
            ey = i + 0.5 - cy
            for j in range(j_lo, j_hi + 1):
                ex = j + 0.5 - cx
                if qxx * ex * ex + 2.0 * qxy * ex * ey + qyy * ey * ey <= 1.0:
                    out[i, j] = True


@numba.njit(cache=True)
def rasterize(out, seg, rad, ell_c, ell_q, ell_half):
    """Rasterise every frame: out (F, H, W) bool (cleared here), seg (F, C, 4), rad (C,), ell_c (F, E, 2),
    ell_q (F, E, 3), ell_half (F, E, 2); see ``_raster_frame``."""
    out[:] = False
    for f in range(out.shape[0]):
        _raster_frame(out[f], seg[f], rad, ell_c[f], ell_q[f], ell_half[f])


def rasterize_numpy(shape, seg, rad, ell_c, ell_q, ell_half):
    """Slow NumPy reference of ``rasterize`` (whole pixel grid per primitive), for tests."""
    n_frames, h, w = shape
    ii, jj = np.mgrid[0:h, 0:w]
    py, px = ii + 0.5, jj + 0.5
    out = np.zeros(shape, dtype=bool)
    for f in range(n_frames):
        for c in range(seg.shape[1]):
            x0, y0, x1, y1 = seg[f, c]
            dx, dy = x1 - x0, y1 - y0
            len2 = dx * dx + dy * dy
            t = (
                np.zeros_like(px)
                if len2 == 0
                else np.clip(((px - x0) * dx + (py - y0) * dy) / len2, 0, 1)
            )
            out[f] |= (px - x0 - t * dx) ** 2 + (py - y0 - t * dy) ** 2 <= rad[c] ** 2
        for e in range(ell_c.shape[1]):
            ex, ey = px - ell_c[f, e, 0], py - ell_c[f, e, 1]
            qxx, qxy, qyy = ell_q[f, e]
            out[f] |= qxx * ex * ex + 2 * qxy * ex * ey + qyy * ey * ey <= 1.0
    return out
