"""PNG montage of a few silhouettes of a sequence, for looking at what was rendered."""

import numpy as np

from bsrbench.errors import InputError
from bsrbench.io import atomic_path


def save_montage(masks, path, n=16, titles=None):
    """Save ``n`` frames of ``masks`` (F, H, W), spread evenly over the sequence, as one PNG grid at ``path``.

    ``titles`` (optional, one str per frame of ``masks``) labels each panel; by default the frame index.
    Written atomically (``bsrbench.io.atomic_path``). Returns the indices of the frames shown.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    masks = np.asarray(masks)
    if masks.ndim != 3 or masks.shape[0] < 1:
        raise InputError(
            f"masks: expected a (frames >= 1, height, width) array, got shape {masks.shape}"
        )
    if int(n) != n or n < 1:
        raise InputError(f"n: expected a positive integer number of panels, got {n!r}")
    if titles is not None and len(titles) != masks.shape[0]:
        raise InputError(
            f"titles: expected {masks.shape[0]} titles (one per frame), got {len(titles)}"
        )
    n = min(int(n), masks.shape[0])
    idx = np.unique(np.round(np.linspace(0, masks.shape[0] - 1, n)).astype(int))
    cols = int(np.ceil(np.sqrt(len(idx))))
    rows = int(np.ceil(len(idx) / cols))
    h, w = masks.shape[1:]
    fig, axes = plt.subplots(
        rows, cols, figsize=(2.4 * cols * w / max(h, w) + 0.2, 2.6 * rows), squeeze=False
    )
    for ax in axes.ravel():
        ax.set_axis_off()
    for ax, f in zip(axes.ravel(), idx):
        ax.imshow(masks[f], cmap="gray_r", vmin=0, vmax=1, interpolation="nearest")
        ax.set_title(str(titles[f]) if titles is not None else f"frame {f}", fontsize=7)
        # A thin frame shows the image border, so clipping at the edge is visible.
        ax.add_patch(
            plt.Rectangle((-0.5, -0.5), w, h, fill=False, lw=0.8, ec="tab:red", clip_on=False)
        )
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return idx
