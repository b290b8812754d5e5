"""Codebook of shape contexts and the per-frame histogram-of-shape-contexts feature.

Agarwal & Triggs, "Recovering 3D human pose from monocular images", IEEE PAMI 28(1), 2006, Sec. 2.1: the
shape contexts of many silhouettes are vector-quantised by k-means into 100 centres; a silhouette is then
described by the 100-D histogram of its shape contexts over the centres, where, to reduce quantisation effects,
each shape context votes *softly* into the few centres nearest to it with Gaussian weights. The paper gives no
number of centres per vote nor the kernel width; the rule used here (``histogram_features``) is:

    for a descriptor x with squared distances d_k^2 to its ``n_neighbours`` nearest centres k,
    w_k = exp(-(d_k^2 - d_min^2) / (2 sigma^2)) / sum_k' exp(-(d_k'^2 - d_min^2) / (2 sigma^2)),

and the frame's histogram is the sum of w over its descriptors (one unit of mass per descriptor, no further
normalisation: the authors' features are soft-voted counts). Subtracting d_min^2 leaves the weights unchanged
and avoids underflow. ``sigma`` defaults to half the median distance between a centre and its nearest other
centre, a property of the codebook alone, so every frame is encoded the same way.
"""

import numpy as np
from sklearn.cluster import KMeans

from bsrbench.errors import InputError

#: Centres each descriptor votes into when soft voting.
DEFAULT_NEIGHBOURS = 5


def _stack(descriptor_list, name="descriptor_list"):
    if isinstance(descriptor_list, np.ndarray) and descriptor_list.ndim == 2:
        descriptor_list = [descriptor_list]
    arrays = []
    width = None
    for i, d in enumerate(descriptor_list):
        d = np.asarray(d, dtype=float)
        if d.ndim != 2 or d.shape[0] < 1:
            raise InputError(
                f"{name}[{i}]: expected an (n >= 1, dim) array of descriptors, got shape {d.shape}"
            )
        if width is None:
            width = d.shape[1]
        elif d.shape[1] != width:
            raise InputError(
                f"{name}[{i}]: descriptors have {d.shape[1]} columns, expected {width} like item 0"
            )
        if not np.all(np.isfinite(d)):
            raise InputError(f"{name}[{i}]: contains non-finite values")
        arrays.append(d)
    if not arrays:
        raise InputError(f"{name}: no descriptor arrays given")
    return arrays


def learn_codebook(
    descriptor_list, n_centres=100, seed=0, max_descriptors=None, n_init=3, max_iter=300
):
    """(n_centres, dim) k-means centres of all descriptors (scikit-learn ``KMeans``, k-means++ initialisation,
    ``n_init`` restarts, ``random_state=seed``): deterministic for a seed.

    ``max_descriptors``: if given and smaller than the number of descriptors, k-means runs on that many
    descriptors drawn without replacement with ``np.random.default_rng(seed)``.
    """
    x = np.vstack(_stack(descriptor_list))
    if int(n_centres) != n_centres or n_centres < 1:
        raise InputError(f"n_centres: expected a positive integer, got {n_centres!r}")
    if max_descriptors is not None:
        if int(max_descriptors) != max_descriptors or max_descriptors < n_centres:
            raise InputError(
                f"max_descriptors: expected an integer >= n_centres ({n_centres}), got {max_descriptors!r}"
            )
        if len(x) > max_descriptors:
            rng = np.random.default_rng(seed)
            x = x[np.sort(rng.choice(len(x), size=int(max_descriptors), replace=False))]
    if len(x) < n_centres:
        raise InputError(f"descriptor_list: {len(x)} descriptors cannot make {n_centres} centres")
    if len(np.unique(x, axis=0)) < n_centres:
        raise InputError(f"descriptor_list: fewer than n_centres={n_centres} distinct descriptors")
    km = KMeans(
        n_clusters=int(n_centres), n_init=int(n_init), max_iter=int(max_iter), random_state=seed
    )
    km.fit(x)
    return np.asarray(km.cluster_centers_, dtype=float)


def default_soft_sigma(codebook):
    """Half the median distance from a centre to its nearest other centre."""
    c = np.asarray(codebook, dtype=float)
    d2 = np.sum(c**2, 1)[:, None] - 2 * c @ c.T + np.sum(c**2, 1)[None, :]
    np.fill_diagonal(d2, np.inf)
    return 0.5 * float(np.median(np.sqrt(np.maximum(d2.min(axis=1), 0))))


def histogram_features(
    descriptor_list,
    codebook,
    soft=True,
    soft_sigma=None,
    n_neighbours=DEFAULT_NEIGHBOURS,
    chunk_rows=65536,
):
    """(F, n_centres) histograms of shape contexts, one row per item of ``descriptor_list``.

    ``soft=True``: Gaussian soft voting into the ``n_neighbours`` nearest centres, weights normalised per
    descriptor (rule in the module docstring; ``soft_sigma`` defaults to ``default_soft_sigma(codebook)``).
    ``soft=False``: each descriptor votes 1 for its nearest centre. Either way row f sums to the number of
    descriptors of frame f.
    """
    arrays = _stack(descriptor_list)
    c = np.asarray(codebook, dtype=float)
    if (
        c.ndim != 2
        or c.shape[0] < 1
        or c.shape[1] != arrays[0].shape[1]
        or not np.all(np.isfinite(c))
    ):
        raise InputError(
            f"codebook: expected a finite (n_centres, {arrays[0].shape[1]}) array matching the descriptors, "
            f"got shape {c.shape}"
        )
    k = c.shape[0]
    if soft:
        if int(n_neighbours) != n_neighbours or n_neighbours < 1:
            raise InputError(f"n_neighbours: expected a positive integer, got {n_neighbours!r}")
        m = min(int(n_neighbours), k)
        sigma = default_soft_sigma(c) if soft_sigma is None else float(soft_sigma)
        if not (np.isfinite(sigma) and sigma > 0):
            raise InputError(
                f"soft_sigma: expected a positive kernel width, got {soft_sigma!r} (resolved {sigma!r})"
            )
    else:
        m = 1
    x = np.vstack(arrays)
    frame = np.repeat(np.arange(len(arrays)), [len(a) for a in arrays])
    hist = np.zeros(len(arrays) * k)
    c2 = np.sum(c**2, axis=1)
    for start in range(0, len(x), int(chunk_rows)):
        xs = x[start : start + chunk_rows]
        d2 = np.maximum(np.sum(xs**2, 1)[:, None] - 2 * xs @ c.T + c2[None, :], 0.0)
        if m < k:
            idx = np.argpartition(d2, m - 1, axis=1)[:, :m]
        else:
            idx = np.broadcast_to(np.arange(k), d2.shape)
        dn = np.take_along_axis(d2, idx, axis=1)
        if soft:
            w = np.exp(-(dn - dn.min(axis=1, keepdims=True)) / (2 * sigma**2))
            w /= w.sum(axis=1, keepdims=True)
        else:
            w = np.ones_like(dn)
        f = frame[start : start + chunk_rows]
        hist += np.bincount((f[:, None] * k + idx).ravel(), weights=w.ravel(), minlength=len(hist))
    return hist.reshape(len(arrays), k)
