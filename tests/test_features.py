"""Shape-context features: contour tracing and sampling, shape contexts, codebook and soft-voted histograms."""

import numpy as np
import pytest

from bsrbench.errors import InputError
from bsrbench.features import (
    contour_length,
    default_soft_sigma,
    histogram_features,
    learn_codebook,
    outer_contour,
    sample_contour,
    shape_contexts,
    silhouette_descriptors,
)


def disc(size, centre, radius):
    yy, xx = np.mgrid[0:size, 0:size]
    return (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2 <= radius**2


def boundary_pixels(mask):
    """Foreground pixels with a background 4-neighbour (outside the image counts as background)."""
    p = np.pad(mask, 1)
    inner = p[1:-1, 1:-1] & p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    return mask & ~inner


def assert_closed_8_chain(contour):
    steps = np.abs(np.diff(contour, axis=0, append=contour[:1]))
    assert steps.max() == 1 and (steps.sum(axis=1) > 0).all()


def test_contour_of_rectangle():
    mask = np.zeros((30, 40), dtype=bool)
    mask[5:15, 10:30] = True  # 10 rows x 20 columns
    c = outer_contour(mask)
    assert_closed_8_chain(c)
    # Pixel centres of the border: 2 * (20 - 1) + 2 * (10 - 1) unit steps, each border pixel once.
    assert contour_length(c) == pytest.approx(56.0)
    assert len(c) == 56 and len(np.unique(c, axis=0)) == 56
    assert set(map(tuple, c.astype(int))) == {
        (x, y) for y, x in zip(*np.nonzero(boundary_pixels(mask)))
    }


def test_contour_of_disc():
    radius = 20.0
    mask = disc(64, (31.5, 30.2), radius)
    c = outer_contour(mask)
    assert_closed_8_chain(c)
    r = np.hypot(c[:, 0] - 31.5, c[:, 1] - 30.2)
    assert r.min() > radius - 1.5 and r.max() <= radius
    # 8-connected chains over-estimate a circle's perimeter by a few percent (steps of 1 and sqrt 2).
    assert contour_length(c) == pytest.approx(2 * np.pi * (radius - 0.5), rel=0.08)
    assert mask[c[:, 1].astype(int), c[:, 0].astype(int)].all()
    assert boundary_pixels(mask)[c[:, 1].astype(int), c[:, 0].astype(int)].all()


def test_contour_takes_largest_component_and_ignores_holes():
    mask = disc(80, (45, 40), 25) & ~disc(80, (45, 40), 10)  # a ring
    mask[2:6, 2:6] = True  # a small separate blob
    c = outer_contour(mask)
    r = np.hypot(c[:, 0] - 45, c[:, 1] - 40)
    assert r.min() > 23
    assert outer_contour(np.zeros((5, 5), dtype=bool)).shape == (0, 2)
    with pytest.raises(InputError, match="binary"):
        outer_contour(np.full((4, 4), 2))


def test_sample_contour_even_spacing_and_seed():
    t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    circle = np.stack([50 + 30 * np.cos(t), 50 + 30 * np.sin(t)], axis=1)
    pts = sample_contour(circle, 100)
    chords = np.linalg.norm(np.diff(pts, axis=0, append=pts[:1]), axis=1)
    assert np.allclose(chords, chords.mean(), rtol=1e-3)
    assert np.allclose(np.hypot(pts[:, 0] - 50, pts[:, 1] - 50), 30, atol=1e-3)
    assert np.array_equal(pts[0], circle[0])
    a, b, c = (sample_contour(circle, 100, rng=s) for s in (1, 1, 2))
    assert np.array_equal(a, b) and not np.allclose(a, c)
    j = sample_contour(circle, 100, rng=np.random.default_rng(0), jitter=0.3)
    chords = np.linalg.norm(np.diff(j, axis=0, append=j[:1]), axis=1)
    assert chords.std() > 0.05 * chords.mean()
    with pytest.raises(InputError, match="n_points"):
        sample_contour(circle, 2)
    with pytest.raises(InputError, match="jitter"):
        sample_contour(circle, 10, jitter=0.2)


def naive_shape_contexts(points, n_radial=5, n_angular=12, r_inner=0.125, r_outer=2.0):
    """Loop reference: bins from the definition (log-polar, innermost bin down to 0, outer points dropped)."""
    n = len(points)
    dists = [np.hypot(*(points[j] - points[i])) for i in range(n) for j in range(n) if i != j]
    mean = np.mean(dists)
    edges = np.logspace(np.log10(r_inner), np.log10(r_outer), n_radial)
    out = np.zeros((n, n_radial * n_angular))
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            dx, dy = points[j] - points[i]
            r = np.hypot(dx, dy) / mean
            if r >= r_outer:
                continue
            rb = 0 if r < r_inner else int(np.searchsorted(edges, r, side="right"))
            ab = int((np.arctan2(dy, dx) % (2 * np.pi)) // (2 * np.pi / n_angular))
            out[i, rb * n_angular + min(ab, n_angular - 1)] += 1
    return out


@pytest.fixture
def blob_points():
    t = np.sort(np.random.default_rng(7).uniform(0, 2 * np.pi, 150))
    r = 20 + 6 * np.sin(3 * t) + 3 * np.cos(5 * t)
    return np.stack([r * np.cos(t) + 40, 1.6 * r * np.sin(t) + 60], axis=1)


def test_shape_contexts_match_loop_reference(blob_points):
    sc = shape_contexts(blob_points)
    assert sc.shape == (150, 60)
    assert np.array_equal(sc, naive_shape_contexts(blob_points))


def test_shape_contexts_row_sums(blob_points):
    sc = shape_contexts(blob_points)
    d = np.linalg.norm(blob_points[:, None] - blob_points[None], axis=2)
    mean = d[~np.eye(len(d), dtype=bool)].mean()
    beyond = (d / mean >= 2.0).sum(axis=1)
    assert np.array_equal(sc.sum(axis=1), len(d) - 1 - beyond)
    assert beyond.sum() > 0  # the check covers dropped points too
    assert sc[:, :12].sum() > 0  # and the innermost bin


def test_shape_contexts_translation_scale_invariant_not_rotation(blob_points):
    sc = shape_contexts(blob_points)
    assert np.array_equal(sc, shape_contexts(blob_points + np.array([123.25, -7.5])))
    assert np.array_equal(sc, shape_contexts(blob_points * 2.0))
    assert np.array_equal(sc, shape_contexts(blob_points * 0.37 + 5.0))
    # A quarter turn (x, y) -> (-y, x) adds 90 deg to every angle: three 30-deg sectors, not the same descriptor.
    turned = shape_contexts(np.stack([-blob_points[:, 1], blob_points[:, 0]], axis=1))
    assert not np.array_equal(sc, turned)
    assert np.array_equal(turned.reshape(-1, 5, 12), np.roll(sc.reshape(-1, 5, 12), 3, axis=2))
    with pytest.raises(InputError, match="coincide"):
        shape_contexts(np.ones((5, 2)))


def test_silhouette_descriptors_and_errors():
    masks = np.stack([disc(48, (24, 24), 15), disc(48, (20, 26), 9)])
    desc = silhouette_descriptors(masks, n_points=120, seed=3)
    assert [d.shape for d in desc] == [(120, 60), (120, 60)]
    again = silhouette_descriptors(masks, n_points=120, seed=3)
    assert all(np.array_equal(a, b) for a, b in zip(desc, again))
    bad = masks.copy()
    bad[1] = False
    with pytest.raises(InputError, match="frame 1 is empty"):
        silhouette_descriptors(bad)
    bad[1, 10, 10:12] = True
    with pytest.raises(InputError, match="contour of frame 1 has 2 pixels"):
        silhouette_descriptors(bad)


@pytest.fixture
def descriptors():
    rng = np.random.default_rng(11)
    centres = rng.uniform(0, 10, size=(12, 60))
    return [
        centres[rng.integers(0, 12, size=40)] + rng.normal(scale=0.8, size=(40, 60))
        for _ in range(30)
    ]


def test_codebook_deterministic_for_seed(descriptors):
    a = learn_codebook(descriptors, n_centres=12, seed=1)
    b = learn_codebook(descriptors, n_centres=12, seed=1)
    c = learn_codebook(descriptors, n_centres=12, seed=2, max_descriptors=600)
    assert a.shape == (12, 60) and np.array_equal(a, b)
    assert not np.array_equal(a, c)
    with pytest.raises(InputError, match="n_centres"):
        learn_codebook(descriptors, n_centres=0)
    with pytest.raises(InputError, match="cannot make"):
        learn_codebook(descriptors[:1], n_centres=100)


def test_histograms_soft_and_hard(descriptors):
    codebook = learn_codebook(descriptors, n_centres=12, seed=0)
    soft = histogram_features(descriptors, codebook)
    hard = histogram_features(descriptors, codebook, soft=False)
    assert soft.shape == hard.shape == (30, 12)
    assert np.allclose(soft.sum(axis=1), 40) and np.allclose(hard.sum(axis=1), 40)
    # Hard votes = counts of nearest centres, computed directly.
    d = np.linalg.norm(descriptors[4][:, None] - codebook[None], axis=2)
    assert np.array_equal(hard[4], np.bincount(d.argmin(axis=1), minlength=12))
    # Soft votes spread mass: not integers, and a very narrow kernel reduces them to hard votes.
    assert not np.allclose(soft, np.round(soft))
    assert np.allclose(histogram_features(descriptors, codebook, soft_sigma=1e-3), hard)
    # A descriptor equal to a centre gives that centre the largest weight; votes go only to its 5 nearest.
    one = histogram_features([codebook[3:4] + 0.01], codebook)[0]
    assert one.argmax() == 3 and np.count_nonzero(one) <= 5 and one.sum() == pytest.approx(1.0)
    # Gaussian weights, normalised per descriptor, with the documented default kernel width.
    sigma = default_soft_sigma(codebook)
    x = descriptors[0][0]
    d2 = np.sum((codebook - x) ** 2, axis=1)
    near = np.argsort(d2)[:5]
    w = np.exp(-(d2[near] - d2[near].min()) / (2 * sigma**2))
    expected = np.zeros(12)
    expected[near] = w / w.sum()
    assert np.allclose(histogram_features([x[None]], codebook)[0], expected)
    with pytest.raises(InputError, match="codebook"):
        histogram_features(descriptors, codebook[:, :10])
    with pytest.raises(InputError, match="soft_sigma"):
        histogram_features(descriptors, codebook, soft_sigma=-1.0)
