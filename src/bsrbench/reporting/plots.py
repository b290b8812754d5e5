"""Figures of the study report (matplotlib, Agg backend, no TeX).

Every figure is drawn at the size it is printed (at most :data:`TEXT_WIDTH` inches wide; the report includes
it unscaled), so the font sizes below are printed sizes, none under :data:`MIN_FONT_PT`.

* :func:`plot_error_vs_ntrain`: error against training-set size per activity of one source, every method
  with error bars (std over seeds), the paper's values at the sizes run for each activity as open markers.
* :func:`plot_calibration`: nominal against empirical coverage of the central predictive intervals, one
  figure per source.
* :func:`plot_subjective_sticks`: the paper's Fig. 2 (silhouette, true pose, predicted poses as 3-D stick
  figures) for one test frame per activity of a motion-capture source.
* :func:`plot_subjective`: the same comparison for the precomputed features, which come with joint angles
  only, in an undocumented (Poser) skeleton convention: the input histogram and the angle profiles.
"""

import math
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..io import atomic_path
from ..metrics import wrap_degrees
from ..paper import PAPER_METHODS
from .tables import activity_label, paper_key, paper_names, summarize

#: Figures are drawn at the size they are printed (the report includes them unscaled; at most TEXT_WIDTH
#: inches wide), so these are the printed font sizes: none below 7 pt.
MIN_FONT_PT = 7
TEXT_WIDTH = 6.9  # inches: A4 with the report's 1.6 cm margins leaves 7.0 in
plt.rcParams.update(
    {
        "font.size": 8,
        "axes.titlesize": 8,
        "axes.labelsize": 8,
        "xtick.labelsize": 7,
        "ytick.labelsize": 7,
        "legend.fontsize": 7,
        "legend.title_fontsize": 7,
        "figure.titlesize": 9,
        "svg.hashsalt": "bsrbench",
        "pdf.fonttype": 42,
    }
)
_MARKERS = "osD^v<>ph*"


def save(fig, paths):
    """Save ``fig`` to every path (format from the suffix; no timestamps in PDF metadata), atomically."""
    for path in paths:
        with atomic_path(path) as tmp:
            kw = (
                {"metadata": {"CreationDate": None}}
                if str(path).endswith(".pdf")
                else {"metadata": {"Software": None}}
            )
            fig.savefig(
                tmp,
                format=str(path).rsplit(".", 1)[-1],
                dpi=150,
                bbox_inches="tight",
                pad_inches=0.02,
                **kw,
            )
    plt.close(fig)


def _grid(n):
    cols = min(3, n)
    rows = math.ceil(n / cols)
    # at least two panels wide, so that a one-panel figure is not blown up to the text width
    fig, axes = plt.subplots(
        rows, cols, figsize=(min(TEXT_WIDTH, 3.2 * max(cols, 2)), 2.6 * rows), squeeze=False
    )
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat)


def _size_axis(ax, sizes):
    """Log-scaled x axis with ticks at exactly the studied training sizes."""
    ax.set_xscale("log")
    ax.set_xticks(sizes)
    ax.set_xticklabels([str(n) for n in sizes])
    ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    ax.set_xlim(min(sizes) / 1.25, max(sizes) * 1.25)


#: Leading digits of the labelled ticks of a log axis, sparsest first: :func:`_log_ticks` takes the first set
#: that labels the shown range evenly enough.
_LOG_TICK_SETS = (
    (1,),
    (1, 2, 5),
    (1, 2, 3, 5),
    (1, 1.5, 2, 3, 5, 7),
    (1, 1.5, 2, 3, 4, 5, 6, 8),
    (1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 7, 8, 9),
)


def _log_ticks(lo, hi, min_labels=4, max_gap=0.4):
    """Labelled tick values of a log axis shown over [lo, hi] (lo > 0).

    The ticks are ``lead x 10^k`` with ``lead`` from the sparsest set of :data:`_LOG_TICK_SETS` that puts at
    least ``min_labels`` ticks in the range, leaves no gap between two ticks wider than ``max_gap`` times the
    range and none between an end of the axis and its nearest tick wider than half that (in log scale). If no
    set meets both bounds, the set with at least ``min_labels`` ticks that exceeds them least; if none has that
    many (a range narrower than about a factor 1.5), evenly spaced ticks (matplotlib's MaxNLocator). So a range
    that crosses a power of ten is labelled on both sides of it (7-20: 7, 10, 15, 20), and 3-25 gets 3, 5, 10, 20.

    Not matplotlib's LogLocator and LogFormatter: the formatter labels a fixed set of leading digits chosen by the
    number of decades shown (``minor_thresholds``: 1; 1, 2, 3, 4, 6; or 1-9), and ``subs`` fixes one set for every
    range, so no setting gives 3, 5, 10, 20 on 3-25 (it gets 3, 4, 6, 10, 20 or 3-10, 20) together with labels
    above 10 on 7-18 (it gets 10 alone, or 7, 8, 9, 10) and four labels on 9.6-10.4 (checked with matplotlib 3.11).
    """
    llo, lhi = math.log10(lo), math.log10(hi)
    span = max(lhi - llo, 1e-12)
    best = None
    for leads in _LOG_TICK_SETS:
        ticks = [
            lead * 10.0**k for k in range(math.floor(llo) - 1, math.ceil(lhi) + 1) for lead in leads
        ]
        ticks = [float(f"{t:.6g}") for t in ticks if lo <= t <= hi]
        if len(ticks) < min_labels:
            continue
        logs = [math.log10(t) for t in ticks]
        inner = max((b - a for a, b in zip(logs, logs[1:])), default=0.0)
        excess = max(
            inner / (max_gap * span), max(logs[0] - llo, lhi - logs[-1]) / (max_gap * span / 2)
        )
        if excess <= 1.0:
            return ticks
        if best is None or excess < best[0]:
            best = (excess, ticks)
    if best is not None:
        return best[1]
    linear = matplotlib.ticker.MaxNLocator(
        nbins=min_labels + 1, steps=[1, 2, 2.5, 5, 10], min_n_ticks=min_labels
    ).tick_values(lo, hi)
    return [float(f"{t:.6g}") for t in linear if lo <= t <= hi]


class _LogTickLocator(matplotlib.ticker.Locator):
    """Labelled ticks of a log axis at :func:`_log_ticks` of the range shown when the axis is drawn (so limits set
    after it, and axes that share it, are labelled too)."""

    def __call__(self):
        return self.tick_values(*self.axis.get_view_interval())

    def tick_values(self, vmin, vmax):
        lo, hi = sorted((float(vmin), float(vmax)))
        return _log_ticks(lo, hi) if lo > 0 and np.isfinite(hi) and hi > lo else []


def label_log_axis(ax):
    """Make ``ax``'s y axis logarithmic with plain labels (``%g``: no superscripts, which print below 7 pt) at
    :class:`_LogTickLocator`'s ticks, and bare minor ticks (for grid lines) at 2..9 times a power of ten."""
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(_LogTickLocator())
    ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    ax.yaxis.set_minor_locator(matplotlib.ticker.LogLocator(subs=np.arange(2, 10)))
    ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())


def _panels(n, *, legend_width=1.3, panel_height=2.3, max_cols=3):
    """A figure of ``n`` panels (at most ``max_cols`` a row) that fits TEXT_WIDTH with a legend at the right."""
    cols = min(max_cols, max(1, n))
    rows = math.ceil(max(1, n) / cols)
    width = min(TEXT_WIDTH, legend_width + (4.0 if cols == 1 else 2.6 * cols))
    fig, axes = plt.subplots(
        rows, cols, figsize=(width, panel_height * rows), squeeze=False, layout="constrained"
    )
    for ax in axes.flat[n:]:
        ax.remove()
    return fig, list(axes.flat)[:n]


def _ran_sizes(s, activity):
    """The training sizes with results for ``activity`` in the summary ``s`` (any protocol)."""
    return {int(n) for n in s.loc[s["activity"] == activity, "n_train"]}


def paper_points_not_drawn(df, paper, *, source, methods, labels, n_train=None):
    """The paper's points Fig. 1 leaves out: ``{activity label: [N, ...]}`` of the sizes that the study
    configures and the paper reports for an activity of ``source`` (for a method drawn), but that the study
    did not run for that activity (a cell skipped because too few test frames would remain), in activity order.

    Arguments as :func:`plot_error_vs_ntrain`; ``paper`` from
    :func:`bsrbench.reporting.tables.read_paper_tables`.
    """
    s = summarize(df[df["source"] == source])
    sizes = {int(n) for n in (n_train if n_train is not None else df["n_train"].unique())}
    drawn = {labels.get(m, m) for m in methods}
    out = {}
    for act in dict.fromkeys(df.loc[df["source"] == source, "activity"]):
        pa = s.loc[s["activity"] == act, "paper_activity"].iloc[0]
        pp = paper[(paper["key"] == paper_key(pa)) & paper["method"].isin(drawn)]
        left = sorted({int(n) for n in pp["n_train"]} & sizes - _ran_sizes(s, act))
        if left:
            out[activity_label(act, pa)] = left
    return out


#: Fig. 1's line style of each protocol (matplotlib ``ls``) and its name in the caption.
PROTOCOL_LINESTYLES = {"random": "-", "contiguous": "--", "blocked": ":", "cross_trial": "-."}
PROTOCOL_LINE_NAMES = {"-": "solid", "--": "dashed", "-.": "dash-dotted"}


def figure_blocks(methods, names, reference="PM"):
    """Fig. 1's blocks of methods, each drawn in panels of its own so that a dozen methods stay legible:
    ``[(title, methods), ...]``: the paper's methods (those whose estimator reproduces a column of the paper's
    tables, ``names`` from :func:`.tables.paper_names`, with the paper's dotted lines), then the others (references and today's baselines) beside ``reference`` (the paper's PM, when
    drawn), which keeps its colour. One block ``(None, methods)`` when either is empty."""
    paper = [m for m in methods if names.get(m) in PAPER_METHODS]
    rest = [m for m in methods if m not in paper]
    if not paper or not rest:
        return [(None, list(methods))]
    return [
        ("the paper's methods", paper),
        ("references and today's baselines", ([reference] if reference in paper else []) + rest),
    ]


def plot_error_vs_ntrain(df, paper, *, source, methods, labels, n_train=None):
    """Error (mean +- std over seeds) against n_train, one panel per activity of ``source``.

    Log-log axes, ticks at the studied sizes only, methods told apart by colour and marker (and slightly
    dodged sideways), the paper's values as open markers on dotted lines at the sizes the study ran for that
    activity (none at a size skipped for it: :func:`paper_points_not_drawn` names those, for the caption), the
    contiguous protocol (if run) dashed, the cross-trial one dash-dotted (:data:`PROTOCOL_LINESTYLES`). With both
    the paper's methods and others, each block of :func:`figure_blocks` has a row of panels (and a legend) of its
    own, the same y range per activity in both. The legend is outside the panels and names only the protocols run.
    """
    s = summarize(df[df["source"] == source])
    acts = list(dict.fromkeys(df.loc[df["source"] == source, "activity"]))
    sizes = sorted(int(n) for n in (n_train if n_train is not None else df["n_train"].unique()))
    blocks = figure_blocks(methods, paper_names(df))
    if len(blocks) == 1:
        fig, axes = _panels(len(acts), panel_height=2.6 if len(acts) == 1 else 2.3)
        _error_block(fig, axes, s, acts, methods, methods, paper, labels, sizes)
        return fig
    cols = min(3, max(1, len(acts)))
    rows = math.ceil(max(1, len(acts)) / cols)
    width = min(TEXT_WIDTH, 1.6 + (4.0 if cols == 1 else 2.6 * cols))
    fig = plt.figure(figsize=(width, (2.5 * rows + 0.25) * len(blocks)), layout="constrained")
    per_activity = []
    for k, (sub, (title, ms)) in enumerate(zip(fig.subfigures(len(blocks), 1), blocks)):
        axes = sub.subplots(rows, cols, squeeze=False)
        for ax in axes.flat[len(acts) :]:
            ax.remove()
        axes = list(axes.flat)[: len(acts)]
        # the paper's lines in the paper's block only (PM beside the others is this study's PM)
        _error_block(sub, axes, s, acts, ms, methods, paper if k == 0 else paper[:0], labels, sizes)
        sub.suptitle(title[0].upper() + title[1:], fontsize=8, fontweight="bold")
        per_activity.append(axes)
    for same in zip(*per_activity):  # one activity's panels: one y range, so the blocks compare
        lo = min(ax.get_ylim()[0] for ax in same)
        hi = max(ax.get_ylim()[1] for ax in same)
        for ax in same:
            ax.set_ylim(lo, hi)
    return fig


def _error_block(fig, axes, s, acts, methods, colour_order, paper, labels, sizes):
    """Draw ``methods`` in ``axes`` (one per activity) of :func:`plot_error_vs_ntrain` and the legend of ``fig`` (a
    figure or subfigure); a method's colour and marker are those of its place in ``colour_order``."""
    from matplotlib.lines import Line2D

    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    protocols = [p for p in PROTOCOL_LINESTYLES if p in set(s["protocol"])]
    place = {m: colour_order.index(m) for m in methods}
    shown_paper = False
    for ax, act in zip(axes, acts):
        pa = s.loc[s["activity"] == act, "paper_activity"].iloc[0]
        ran = _ran_sizes(s, act)  # the paper's points only where this study has one to compare with
        for i, m in enumerate(methods):
            c, mk = colors[place[m] % len(colors)], _MARKERS[place[m] % len(_MARKERS)]
            dodge = 1.0 + 0.018 * (i - (len(methods) - 1) / 2)
            for protocol, ls in PROTOCOL_LINESTYLES.items():
                d = s[
                    (s["activity"] == act) & (s["method"] == m) & (s["protocol"] == protocol)
                ].sort_values("n_train")
                if d.empty:
                    continue
                ax.errorbar(
                    d["n_train"] * dodge,
                    d["mean"],
                    yerr=d["std"].fillna(0),
                    color=c,
                    ls=ls,
                    marker=mk,
                    ms=3.5,
                    capsize=1.5,
                    lw=1,
                )
            pp = paper[
                (paper["key"] == paper_key(pa))
                & (paper["method"] == labels.get(m, m))
                & paper["n_train"].isin(sorted(ran))
            ].sort_values("n_train")
            if not pp.empty:
                shown_paper = True
                ax.plot(
                    pp["n_train"] * dodge,
                    pp["mean_deg"],
                    ls=":",
                    lw=0.9,
                    color=c,
                    marker=mk,
                    mfc="white",
                    ms=4.5,
                )
        ax.set_title(activity_label(act, pa))
        label_log_axis(ax)  # labelled on both sides of a power of ten, whatever the range
        _size_axis(ax, sizes)
        ax.set_xlabel("training frames N")
        ax.set_ylabel("mean angle error (degrees)")
        ax.grid(alpha=0.3, which="both")
    handles = [
        Line2D(
            [],
            [],
            color=colors[place[m] % len(colors)],
            marker=_MARKERS[place[m] % len(_MARKERS)],
            ms=3.5,
            lw=1,
            label=labels.get(m, m),
        )
        for m in methods
    ]
    # only the protocols in the data (a contiguous-only study has no "random" line to explain)
    style = [
        Line2D(
            [],
            [],
            color="0.3",
            marker="o",
            ms=3.5,
            lw=1,
            ls=ls,
            label=f"this study ({protocol.replace('_', '-')})",
        )
        for protocol, ls in PROTOCOL_LINESTYLES.items()
        if protocol in protocols
    ]
    if shown_paper:
        style.append(
            Line2D(
                [],
                [],
                color="0.3",
                marker="o",
                mfc="white",
                ms=4.5,
                lw=0.9,
                ls=":",
                label="the paper",
            )
        )
    fig.legend(handles=handles + style, loc="outside right upper", frameon=False)


def plot_calibration(df, *, methods, labels, source=None):
    """Empirical coverage of the central predictive intervals against the nominal level, one panel per N.

    Only jobs of ``source`` (all if None) under one protocol: the random protocol (the paper's) if the results
    have it, else the first in alphabetical order; it is named in the panel titles. Line: mean over seeds, band:
    min-max.
    """
    if source is not None:
        df = df[df["source"] == source]
    protocols = sorted(df["protocol"].unique()) if "protocol" in df.columns else []
    protocol = "random" if "random" in protocols or not protocols else protocols[0]
    cols = sorted(
        (c for c in df.columns if c.startswith("coverage_")), key=lambda c: int(c.split("_")[1])
    )
    levels = np.array([int(c.split("_")[1]) / 100 for c in cols])
    sizes = sorted(df["n_train"].unique())
    fig, axes = _panels(max(1, len(sizes)), panel_height=2.2)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    any_line = False
    for ax, n in zip(axes, sizes):
        ax.plot([0, 1], [0, 1], color="0.5", lw=0.8, ls="--", label="ideal")
        for i, m in enumerate(methods):
            d = df[(df["method"] == m) & (df["n_train"] == n) & (df["protocol"] == protocol)]
            if d.empty or not cols or d[cols].isna().all().all():
                continue
            mean = d[cols].mean().to_numpy(float)
            lo, hi = d[cols].min().to_numpy(float), d[cols].max().to_numpy(float)
            c = colors[i % len(colors)]
            ax.plot(
                levels,
                mean,
                marker=_MARKERS[i % len(_MARKERS)],
                ms=3,
                lw=1,
                color=c,
                label=labels.get(m, m),
            )
            ax.fill_between(levels, lo, hi, alpha=0.15, color=c)
            any_line = True
        ax.set_title(f"N = {n}" + ("" if protocol == "random" else f" ({protocol})"))
        ax.set_xlabel("nominal coverage")
        ax.set_ylabel("empirical coverage")
        ax.set_xlim(0.4, 1)
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
    if any_line:
        handles, names = [], []
        for ax in axes:
            for h, nm in zip(*ax.get_legend_handles_labels()):
                if nm not in names:
                    handles.append(h)
                    names.append(nm)
        fig.legend(handles, names, loc="outside right upper", frameon=False)
    else:
        axes[0].text(
            0.7,
            0.5,
            "no method with predictive\nintervals was run",
            ha="center",
            fontsize=MIN_FONT_PT,
        )
    return fig


def plot_subjective(panels, *, labels):
    """Rows of (features of a test frame, its true angles and each method's predicted angles).

    ``panels``: list of dicts with keys ``activity``, ``label``, ``x`` (feature vector), ``y_true`` (angles),
    ``preds`` ({method: predicted angles}), ``frame`` (frame index), ``errors`` ({method: error on this frame}).
    Row titles and method labels are those of :func:`plot_subjective_sticks`.
    """
    if not panels:
        # none of the methods drawn was run: one line instead of empty axes (the caption says so too)
        fig, ax = plt.subplots(figsize=(3.0, 0.6))
        ax.set_axis_off()
        ax.text(
            0.5, 0.5, "no method of report.subjective_methods was run", ha="center", va="center"
        )
        return fig
    n = len(panels)
    fig, axes = plt.subplots(
        n,
        2,
        figsize=(TEXT_WIDTH, 2.4 * n),
        squeeze=False,
        layout="constrained",
        gridspec_kw={"width_ratios": [1, 2.6]},
    )
    for (axx, axy), pnl in zip(axes, panels):
        axx.bar(np.arange(pnl["x"].size), pnl["x"], width=1.0, color="0.3")
        axx.set_title(
            f"{pnl['label']}, test frame {pnl['frame']}:\nthe input histogram", loc="left"
        )
        axx.set_xlabel("shape-context histogram bin")
        axx.set_ylabel("weight")
        idx = np.arange(pnl["y_true"].size)
        axy.plot(idx, pnl["y_true"], color="k", lw=1.5, marker="o", ms=2.5, label="true pose")
        for i, (m, y) in enumerate(pnl["preds"].items()):
            axy.plot(
                idx,
                y,
                lw=0.9,
                color=f"C{i}",
                marker=_MARKERS[i % 10],
                ms=3,
                mfc="none",
                label=f"{labels.get(m, m)} ({pnl['errors'][m]:.1f} deg)",
            )
        axy.set_title(
            "the true pose and the predicted poses\n(57 joint angles; error on this frame)",
            loc="left",
        )
        axy.set_xlabel("joint angle index")
        axy.set_ylabel("degrees")
        axy.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        axy.grid(alpha=0.3)
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
                raise ValueError(
                    f"{activity}: method {m} was tested on other frames than {shown[0]}"
                )
            panel["preds"][m] = np.asarray(preds[m]["y_pred"])[k]
            panel["errors"][m] = float(
                error_fn(preds[m]["y_true"][k : k + 1], preds[m]["y_pred"][k : k + 1])[0]
            )
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
        raise ValueError(
            f"expected {cols.size} pose angles for joints {list(pose_joints)}; got {angles.shape}"
        )
    keep = cols >= 0
    row[cols[keep]] = angles[keep]
    pos = skeleton_positions(bvh.skeleton, row[None])[0]
    return pos - pos[0]


def oblique_projection(pos, *, elev=12.0, azim=35.0):
    """Screen coordinates (J, 2) of joint positions (J, 3; y up) seen from an oblique viewpoint.

    The body is turned by ``azim`` degrees about the vertical axis, then seen from ``elev`` degrees above
    the horizontal (orthographic projection): screen x is the turned x, screen y the height tilted
    towards the viewer.
    """
    pos = np.asarray(pos, dtype=float)
    a, e = np.deg2rad(azim), np.deg2rad(elev)
    x = pos[:, 0] * np.cos(a) + pos[:, 2] * np.sin(a)
    depth = -pos[:, 0] * np.sin(a) + pos[:, 2] * np.cos(a)
    y = pos[:, 1] * np.cos(e) - depth * np.sin(e)
    return np.column_stack([x, y])


def _stick(ax, xy, parents, color, lw=1.4):
    for j, p in enumerate(parents):
        if p >= 0:
            ax.plot(
                [xy[p, 0], xy[j, 0]],
                [xy[p, 1], xy[j, 1]],
                color=color,
                lw=lw,
                solid_capstyle="round",
            )


def plot_subjective_sticks(panels, *, labels, elev=12.0, azim=35.0):
    """The paper's Fig. 2 layout: silhouette, true pose and each method's pose as stick figures.

    ``panels``: dicts with ``label``, ``frame``, ``silhouette`` (H, W bool) or, for features without images,
    ``x`` (the input feature vector, drawn as a histogram), ``parents``, ``true`` (J, 3), ``preds``
    ({method: (J, 3)}), ``errors`` ({method: error on this frame, degrees}). Every 3-D pose is drawn from the
    same oblique viewpoint (:func:`oblique_projection`) at the same scale within a row; each prediction is
    drawn over the true pose in light grey.
    """
    n = max(1, len(panels))
    ncol = 2 + max((len(p["preds"]) for p in panels), default=0)
    row_h = 2.5
    fig, axes = plt.subplots(
        n, ncol, figsize=(TEXT_WIDTH, row_h * n), squeeze=False, layout="constrained"
    )
    for axrow, pnl in zip(axes, panels):
        ax = axrow[0]
        if pnl.get("silhouette") is None:
            x = np.asarray(pnl["x"], dtype=float)
            ax.bar(np.arange(x.size), x, width=1.0, color="0.3")
            ax.set_xlabel("histogram bin")
            ax.set_ylabel("weight")
            ax.yaxis.set_major_locator(matplotlib.ticker.MaxNLocator(3))
            for side in ("top", "right"):
                ax.spines[side].set_visible(False)
            ax.set_title(f"{pnl['label']}, test frame {pnl['frame']}:\nthe input histogram")
        else:
            sil = np.asarray(pnl["silhouette"], dtype=bool)
            rows, cols = np.nonzero(sil)
            if rows.size:  # crop to the silhouette, with a margin
                m = max(2, int(0.05 * sil.shape[0]))
                sil = sil[
                    max(rows.min() - m, 0) : rows.max() + m + 1,
                    max(cols.min() - m, 0) : cols.max() + m + 1,
                ]
            ax.imshow(sil, cmap="gray_r", interpolation="nearest")
            ax.set_axis_off()
            ax.set_title(f"{pnl['label']}, test frame {pnl['frame']}:\nthe input silhouette")
        view = {
            k: oblique_projection(v, elev=elev, azim=azim)
            for k, v in [("true", pnl["true"])] + list(pnl["preds"].items())
        }
        allxy = np.concatenate(list(view.values()))
        lo, hi = allxy.min(axis=0), allxy.max(axis=0)
        pad = 0.05 * float((hi - lo).max())
        # a method's title wrapped to its panel's width (about 13 characters per inch at the title's size), so
        # long variant labels do not run into the neighbouring panel's
        chars = max(10, int(13 * TEXT_WIDTH / ncol))
        figs = [("true pose", "true", "k")] + [
            (textwrap.fill(f"{labels.get(m, m)} ({pnl['errors'][m]:.1f} deg)", chars), m, f"C{i}")
            for i, m in enumerate(pnl["preds"])
        ]
        for ax, (title, key, color) in zip(axrow[1:], figs):
            if key != "true":
                _stick(ax, view["true"], pnl["parents"], "0.78", lw=1.3)
            _stick(ax, view[key], pnl["parents"], color, lw=1.8)
            ax.set_xlim(lo[0] - pad, hi[0] + pad)
            ax.set_ylim(lo[1] - pad, hi[1] + pad)
            ax.set_aspect("equal")
            ax.set_axis_off()
            ax.set_title(title)
        for ax in axrow[2 + len(pnl["preds"]) :]:
            ax.set_visible(False)
    return fig


def frame_errors(y_true, y_pred):
    """Per-frame error: mean over angles of the absolute wrapped difference (degrees)."""
    return np.mean(np.abs(wrap_degrees(np.asarray(y_pred) - np.asarray(y_true))), axis=1)


def subjective_figure(items, methods, *, labels, sticks, motion):
    """The subjective comparison of one data source: one test frame per activity (:func:`subjective_panels`).

    ``items``: per activity (activity, label, features, {method: predictions}); ``sticks``: {activity: the kind of
    stick figure it gets ("authors", the skeleton of a motion-capture trial, or None)}; ``motion``: {activity:
    {"poses", "files", "render"}} of motion-capture activities. With a stick figure for every activity: the
    paper's Fig. 2 layout (:func:`plot_subjective_sticks`): the input (the rendered silhouette of a BVH trial, or
    the histogram of features in the authors' convention) and 3-D stick figures of the true and predicted poses;
    otherwise the input histogram and angle profiles (:func:`plot_subjective`). Returns the figure.
    """
    panels = subjective_panels(items, methods, frame_errors)
    activities = [it[0] for it in items]
    if not (panels and all(sticks.get(a) for a in activities)):
        return plot_subjective(panels, labels=labels)
    # only figures with stick figures need the skeletons and the renderer
    from ..authors import hsc_stick_figure
    from ..mocap import read_trial, trial_pose_positions
    from ..render import render_silhouettes

    stick_panels = []
    for pnl in panels:
        a = pnl["activity"]
        if sticks[a] == "authors":
            true, parents = hsc_stick_figure(pnl["y_true"])
            stick_panels.append(
                {
                    "label": pnl["label"],
                    "frame": pnl["frame"],
                    "x": pnl["x"],
                    "parents": parents,
                    "true": true,
                    "preds": {m: hsc_stick_figure(y)[0] for m, y in pnl["preds"].items()},
                    "errors": pnl["errors"],
                }
            )
            continue
        with np.load(motion[a]["poses"]) as f:
            mo = {k: f[k] for k in f.files}
        # the features file's rows are the poses file's rows
        k = int(pnl["frame"])
        tid = str(mo["trial_ids"][int(mo["trial_index"][k])])
        path = next(p for p in motion[a]["files"] if Path(p).stem == tid)
        trial = read_trial(path, motion[a].get("asf"))
        tf = int(mo["trial_frames"][k])
        pj = [str(j) for j in mo["pose_joints"]]
        sil = render_silhouettes(
            mo["positions"][k : k + 1],
            mo["parents"],
            [str(j) for j in mo["joint_names"]],
            **motion[a]["render"],
        )[0]
        stick_panels.append(
            {
                "label": pnl["label"],
                "frame": k,
                "silhouette": sil,
                "parents": mo["parents"],
                "true": trial_pose_positions(trial, tf, pj, pnl["y_true"]),
                "preds": {
                    m: trial_pose_positions(trial, tf, pj, y) for m, y in pnl["preds"].items()
                },
                "errors": pnl["errors"],
            }
        )
    return plot_subjective_sticks(stick_panels, labels=labels)
