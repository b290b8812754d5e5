"""Figures of the study report (matplotlib, Agg backend, no TeX).

* :func:`plot_error_vs_ntrain`: error against training-set size per activity, every method with error bars
  (std over seeds), the paper's values as open markers.
* :func:`plot_calibration`: nominal against empirical coverage of the central predictive intervals.
* :func:`plot_subjective`: the paper's Fig. 2 idea (input, true pose, predictions of several methods) for
  one test frame per activity. Poses are drawn as angle profiles (the 57 joint angles), because the
  precomputed features come with joint angles only, whose convention (Poser skeleton) is not documented.
"""

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..io import atomic_path  # noqa: E402
from .tables import activity_label, paper_key, summarize  # noqa: E402

plt.rcParams.update({"font.size": 8, "axes.titlesize": 9, "legend.fontsize": 7, "svg.hashsalt": "bsrbench",
                     "pdf.fonttype": 42})
_MARKERS = "osD^v<>ph*"


def save(fig, paths):
    """Save ``fig`` to every path (format from the suffix; no timestamps in PDF metadata), atomically."""
    for path in paths:
        with atomic_path(path) as tmp:
            kw = {"metadata": {"CreationDate": None}} if str(path).endswith(".pdf") else {"metadata": {"Software": None}}
            fig.savefig(tmp, format=str(path).rsplit(".", 1)[-1], dpi=150, bbox_inches="tight", **kw)
    plt.close(fig)


def _grid(n):
    cols = min(3, n)
    rows = math.ceil(n / cols)
    # at least two panels wide, so that a one-panel figure is not blown up to the text width
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * max(cols, 2), 2.6 * rows), squeeze=False)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat)


def plot_error_vs_ntrain(df, paper, *, source, methods, labels):
    """Error (mean +- std over seeds) against n_train, one panel per activity of ``source``."""
    s = summarize(df[df["source"] == source])
    acts = list(dict.fromkeys(df.loc[df["source"] == source, "activity"]))
    fig, axes = _grid(max(1, len(acts)))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, act in zip(axes, acts):
        pa = s.loc[s["activity"] == act, "paper_activity"].iloc[0]
        for i, m in enumerate(methods):
            c = colors[i % len(colors)]
            for protocol, ls in (("random", "-"), ("contiguous", "--")):
                d = s[(s["activity"] == act) & (s["method"] == m) & (s["protocol"] == protocol)].sort_values("n_train")
                if d.empty:
                    continue
                lab = labels.get(m, m) if protocol == "random" else f"{labels.get(m, m)} (contig.)"
                ax.errorbar(d["n_train"], d["mean"], yerr=d["std"].fillna(0), color=c, ls=ls, marker=_MARKERS[i % 10],
                            ms=3, capsize=2, lw=1, label=lab)
            pp = paper[(paper["key"] == paper_key(pa)) & (paper["method"] == labels.get(m, m))].sort_values("n_train")
            if not pp.empty:
                ax.plot(pp["n_train"], pp["mean_deg"], ls=":", lw=0.8, color=c, marker=_MARKERS[i % 10], mfc="none",
                        ms=5, label=f"{labels.get(m, m)} (paper)")
        ax.set_title(activity_label(act, pa))
        ax.set_xlabel("training frames N")
        ax.set_ylabel("mean angle error (deg)")
        ax.grid(alpha=0.3)
    handles, names = [], []
    for ax in axes:
        for h, n in zip(*ax.get_legend_handles_labels()):
            if n not in names:
                handles.append(h)
                names.append(n)
    nrows = math.ceil(len(names) / 4)
    height = fig.get_size_inches()[1]
    fig.set_size_inches(fig.get_size_inches()[0], height + 0.18 * nrows + 0.3)
    bottom = (0.18 * nrows + 0.3) / (height + 0.18 * nrows + 0.3)
    fig.legend(handles, names, loc="lower center", ncol=4, frameon=False)
    fig.suptitle(f"Error against training-set size ({source}); open markers, dotted: the paper")
    fig.tight_layout(rect=(0, bottom, 1, 0.97))
    return fig


def plot_calibration(df, *, methods, labels):
    """Empirical coverage of the central predictive intervals against the nominal level, per method and N."""
    cols = sorted((c for c in df.columns if c.startswith("coverage_")), key=lambda c: int(c.split("_")[1]))
    levels = np.array([int(c.split("_")[1]) / 100 for c in cols])
    sizes = sorted(df["n_train"].unique())
    fig, axes = _grid(max(1, len(sizes)))
    any_line = False
    for ax, n in zip(axes, sizes):
        ax.plot([0, 1], [0, 1], color="0.5", lw=0.8, ls="--", label="ideal")
        for i, m in enumerate(methods):
            d = df[(df["method"] == m) & (df["n_train"] == n) & (df["protocol"] == "random")]
            if d.empty or not cols or d[cols].isna().all().all():
                continue
            mean = d[cols].mean().to_numpy(float)
            lo, hi = d[cols].min().to_numpy(float), d[cols].max().to_numpy(float)
            ax.plot(levels, mean, marker=_MARKERS[i % 10], ms=3, lw=1, label=labels.get(m, m))
            ax.fill_between(levels, lo, hi, alpha=0.15)
            any_line = True
        ax.set_title(f"N = {n}")
        ax.set_xlabel("nominal coverage")
        ax.set_ylabel("empirical coverage")
        ax.set_xlim(0.4, 1)
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left")
    if not any_line:
        axes[0].text(0.7, 0.5, "no method with predictive intervals was run", ha="center", fontsize=7)
    fig.suptitle("Calibration of the central predictive intervals (random protocol; band: min-max over jobs)", y=1.02)
    fig.tight_layout()
    return fig


def plot_subjective(panels, *, labels):
    """Rows of (features of a test frame, its true angles and each method's predicted angles).

    ``panels``: list of dicts with keys ``activity``, ``label``, ``x`` (feature vector), ``y_true`` (angles),
    ``preds`` ({method: predicted angles}), ``frame`` (frame index), ``errors`` ({method: error on this frame}).
    """
    n = max(1, len(panels))
    fig, axes = plt.subplots(n, 2, figsize=(9, 2.2 * n), squeeze=False, gridspec_kw={"width_ratios": [1, 3]})
    for (axx, axy), pnl in zip(axes, panels):
        axx.bar(np.arange(pnl["x"].size), pnl["x"], width=1.0, color="0.3")
        axx.set_title(f"{pnl['label']}: input, frame {pnl['frame']}", fontsize=7)
        axx.set_xlabel("shape-context bin")
        idx = np.arange(pnl["y_true"].size)
        axy.plot(idx, pnl["y_true"], color="k", lw=1.5, marker="o", ms=2.5, label="true pose")
        for i, (m, y) in enumerate(pnl["preds"].items()):
            axy.plot(idx, y, lw=0.9, marker=_MARKERS[i % 10], ms=2.5, mfc="none",
                     label=f"{labels.get(m, m)} ({pnl['errors'][m]:.1f} deg)")
        axy.set_xlabel("joint angle index")
        axy.set_ylabel("degrees")
        axy.legend(ncol=4, loc="upper right", fontsize=6)
        axy.grid(alpha=0.3)
    fig.suptitle("Subjective comparison (one test frame per activity: median PM error); angle profiles", y=1.01)
    fig.tight_layout()
    return fig


def subjective_panels(items, methods, error_fn):
    """Build :func:`plot_subjective` panels.

    ``items``: list of (activity, label, features dict, {method: predictions npz dict}). The frame shown is the
    test frame whose error under the first method is the median over test frames.
    """
    panels = []
    for activity, label, feats, preds in items:
        shown = [m for m in methods if m in preds]
        if not shown:
            continue
        first = preds[shown[0]]
        test = np.asarray(first["test"])
        per_frame = error_fn(first["y_true"], first["y_pred"])
        k = int(np.argsort(per_frame)[len(per_frame) // 2])
        panel = {
            "activity": activity,
            "label": label,
            "frame": int(test[k]),
            "x": np.asarray(feats["X"])[test[k]],
            "y_true": np.asarray(first["y_true"])[k],
            "preds": {},
            "errors": {},
        }
        for m in shown:
            if not np.array_equal(np.asarray(preds[m]["test"]), test):
                raise ValueError(f"{activity}: method {m} was tested on other frames than {shown[0]}")
            panel["preds"][m] = np.asarray(preds[m]["y_pred"])[k]
            panel["errors"][m] = float(error_fn(preds[m]["y_true"][k : k + 1], preds[m]["y_pred"][k : k + 1])[0])
        panels.append(panel)
    return panels


# ------------------------------------------------------------------------------------ stick figures (mocap)
def pose_positions(bvh, trial_frame, pose_joints, angles):
    """Joint positions (J, 3) of a BVH skeleton with the pose angles replaced by ``angles`` (degrees).

    The motion row ``trial_frame`` of ``bvh`` (a :class:`bsrbench.mocap.BVHData`) supplies every channel
    that is not a pose angle (root translation, fingers, ...); the 57 pose angles (``pose_joints`` x 3, in
    the order of :func:`bsrbench.mocap.pose_columns`) come from ``angles``. Forward kinematics gives the
    positions, centred on the root.
    """
    from ..mocap import pose_columns, skeleton_positions

    row = np.array(bvh.motion[int(trial_frame)], dtype=float)
    cols, _ = pose_columns(bvh.skeleton, list(pose_joints))
    angles = np.asarray(angles, dtype=float)
    if angles.shape != cols.shape:
        raise ValueError(f"expected {cols.size} pose angles for joints {list(pose_joints)}; got {angles.shape}")
    keep = cols >= 0
    row[cols[keep]] = angles[keep]
    pos = skeleton_positions(bvh.skeleton, row[None])[0]
    return pos - pos[0]


def _stick(ax, pos, parents, color):
    for j, p in enumerate(parents):
        if p >= 0:
            # world y is up: draw (x, z, y) so that the figure stands upright
            ax.plot([pos[p, 0], pos[j, 0]], [pos[p, 2], pos[j, 2]], [pos[p, 1], pos[j, 1]], color=color, lw=1.2)


def plot_subjective_sticks(panels, *, labels):
    """The paper's Fig. 2 layout: silhouette, true pose and each method's pose as 3-D stick figures.

    ``panels``: dicts with ``label``, ``frame``, ``silhouette`` (H, W bool), ``parents``, ``true`` (J, 3),
    ``preds`` ({method: (J, 3)}), ``errors`` ({method: error on this frame, degrees}).
    """
    n = max(1, len(panels))
    ncol = 2 + max((len(p["preds"]) for p in panels), default=0)
    fig = plt.figure(figsize=(1.6 * ncol, 2.8 * n))
    for r, pnl in enumerate(panels):
        ax = fig.add_subplot(n, ncol, r * ncol + 1)
        ax.imshow(pnl["silhouette"], cmap="gray_r", interpolation="nearest")
        ax.set_axis_off()
        ax.set_title(f"{pnl['label']}\nsilhouette, frame {pnl['frame']}", fontsize=7)
        allpos = np.concatenate([pnl["true"]] + list(pnl["preds"].values()))
        lo, hi = allpos.min(axis=0), allpos.max(axis=0)
        half = 0.5 * float((hi - lo).max())
        mid = 0.5 * (hi + lo)
        figs = [("true pose", pnl["true"], "k")] + [
            (f"{labels.get(m, m)} ({pnl['errors'][m]:.1f} deg)", pos, f"C{i}") for i, (m, pos) in enumerate(pnl["preds"].items())
        ]
        for c, (title, pos, color) in enumerate(figs):
            ax = fig.add_subplot(n, ncol, r * ncol + 2 + c, projection="3d")
            _stick(ax, pos, pnl["parents"], color)
            ax.set_xlim(mid[0] - half, mid[0] + half)
            ax.set_ylim(mid[2] - half, mid[2] + half)
            ax.set_zlim(mid[1] - half, mid[1] + half)
            ax.view_init(elev=10, azim=-90)
            ax.set_box_aspect((1, 1, 1), zoom=1.4)
            ax.set_axis_off()
            ax.set_title(title, fontsize=7)
    fig.suptitle("Subjective comparison (one test frame per activity: median error of the first method)")
    fig.tight_layout()
    return fig
