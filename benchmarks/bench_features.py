"""Time per frame of silhouette rendering, shape-context descriptors and histograms; vectorised vs loop shape contexts.

Usage: python benchmarks/bench_features.py [--frames 200] [--repeats 5] [--points 200] [--size 128]

Frames come from resources/cmu-mocap/12_02.bvh (walk) when bsrbench.mocap can read it. Every time is the median
over repeats, measured in this run; the numba kernels are compiled (or loaded from cache) before timing.
"""

import argparse
import time
from pathlib import Path

import numpy as np

from bsrbench.features import (
    histogram_features,
    learn_codebook,
    outer_contour,
    sample_contour,
    shape_contexts,
    silhouette_descriptors,
)
from bsrbench.render import render_silhouettes

ROOT = Path(__file__).resolve().parents[1]


def loop_shape_contexts(points, n_radial=5, n_angular=12, r_inner=0.125, r_outer=2.0):
    """Point-by-point reference with the same binning as ``shape_contexts`` (Belongie et al. 2002)."""
    n = len(points)
    total, count = 0.0, 0
    for i in range(n):
        for j in range(n):
            if i != j:
                total += float(np.hypot(*(points[j] - points[i])))
                count += 1
    mean = total / count
    edges = np.logspace(np.log10(r_inner), np.log10(r_outer), n_radial)
    out = np.zeros((n, n_radial * n_angular))
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            dx, dy = points[j] - points[i]
            r = np.hypot(dx, dy) / mean
            q = int(np.sum(r < edges))
            if q == 0:
                continue
            a = min(
                int((np.arctan2(dy, dx) % (2 * np.pi)) / (2 * np.pi / n_angular)), n_angular - 1
            )
            out[i, (n_radial - q) * n_angular + a] += 1
    return out


def median_time(fn, repeats):
    times = []
    result = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), result


def load_frames(n_frames):
    from bsrbench.mocap import load_motion

    m = load_motion(ROOT / "resources" / "cmu-mocap" / "12_02.bvh")
    idx = np.linspace(0, len(m.positions) - 1, n_frames).round().astype(int)
    return m.positions[idx], m.parents, m.joint_names


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--points", type=int, default=200)
    ap.add_argument("--size", type=int, default=128)
    args = ap.parse_args()
    pos, parents, names = load_frames(args.frames)
    size = (args.size, args.size)

    render_silhouettes(pos[:2], parents, names, image_size=size)  # compile / load the numba cache
    t_render, masks = median_time(
        lambda: render_silhouettes(pos, parents, names, image_size=size), args.repeats
    )
    t_desc, desc = median_time(
        lambda: silhouette_descriptors(masks, n_points=args.points, seed=0), args.repeats
    )
    codebook = learn_codebook(desc, n_centres=100, seed=0, max_descriptors=20000)
    t_hist, _ = median_time(lambda: histogram_features(desc, codebook), args.repeats)

    f = len(pos)
    rows = [
        ("render (numba raster)", t_render / f),
        (f"descriptors ({args.points} pts: contour + sampling + shape contexts)", t_desc / f),
        ("histogram (soft voting, 100 centres)", t_hist / f),
    ]
    rows.append(("total", sum(r[1] for r in rows)))
    print(
        f"{f} frames of 12_02.bvh at {args.size}x{args.size}, {args.points} contour points, median of {args.repeats}"
    )
    print(f"{'step':<62} {'ms/frame':>9}")
    for name, t in rows:
        print(f"{name:<62} {1e3 * t:>9.3f}")

    points = sample_contour(outer_contour(masks[0]), args.points, rng=0)
    t_vec, a = median_time(lambda: shape_contexts(points), args.repeats)
    t_loop, b = median_time(lambda: loop_shape_contexts(points), max(1, min(args.repeats, 3)))
    assert np.array_equal(a, b), "vectorised and loop shape contexts disagree"
    print()
    print(f"{'shape contexts of one frame':<40} {'ms':>9}")
    print(f"{'vectorised (NumPy)':<40} {1e3 * t_vec:>9.3f}")
    print(f"{'loop reference':<40} {1e3 * t_loop:>9.3f}")
    print(f"{'speed-up (loop / vectorised)':<40} {t_loop / t_vec:>9.1f}")


if __name__ == "__main__":
    main()
