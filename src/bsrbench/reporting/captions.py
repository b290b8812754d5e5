"""The captions of the report's figures (section "Figures"): each says what its figure draws for this study, from the
aggregate table and the workflow's description of the study (protocols run, sizes, stick figures drawn)."""

from dataclasses import dataclass, field
from pathlib import Path

from .convergence import gxy_caption
from .latex import escape
from .plots import (
    PROTOCOL_LINE_NAMES,
    PROTOCOL_LINESTYLES,
    figure_blocks,
    paper_points_not_drawn,
)
from .tables import paper_names

#: The figure kinds of the section, as their file names begin (``<kind>_<source>.pdf``).
KINDS = ("error_vs_ntrain", "subjective", "calibration")


def calibration_protocol(protocols):
    """The calibration figure's protocol in words (:func:`bsrbench.reporting.plots.plot_calibration` draws the
    random one, the paper's, if run, else the first)."""
    protocols = sorted(set(protocols))
    if "random" in protocols or not protocols:
        return "random protocol"
    return f"{escape(protocols[0])} protocol, as named in the panel titles; this study did not run the random one"


def study_lines(protocols):
    """Fig. 1's line styles of the protocols run (:data:`bsrbench.reporting.plots.PROTOCOL_LINESTYLES`): "solid
    lines: random protocol; dashed lines: contiguous protocol"."""
    return "; ".join(
        f"{PROTOCOL_LINE_NAMES[ls]} lines: {escape(p.replace('_', '-'))} protocol"
        for p, ls in PROTOCOL_LINESTYLES.items()
        if p in set(protocols)
    )


@dataclass
class Study:
    """What the captions say about a study.

    ``df``: the aggregate table; ``paper``: the paper's tables; ``labels``: {method: label}; ``figure_methods``:
    the methods Fig. 1 draws; ``n_train``: the study's sizes; ``stick_kinds``: {source: [the skeleton kinds of its
    activities, as the workflow's ``stick_kind`` names them]}; ``subjective_first``: the method whose median-error
    frame the subjective figure shows; ``seed0``: the split drawn (the study's first seed).
    """

    df: object
    paper: object
    labels: dict = field(default_factory=dict)
    figure_methods: list = field(default_factory=list)
    n_train: list = field(default_factory=list)
    stick_kinds: dict = field(default_factory=dict)
    subjective_first: str = ""
    seed0: int = 0


def not_drawn(study, source):
    """The sentence naming the paper's points Fig. 1 leaves out on ``source``
    (:func:`bsrbench.reporting.plots.paper_points_not_drawn`), or ""."""
    left = paper_points_not_drawn(
        study.df,
        study.paper,
        source=source,
        methods=list(study.figure_methods),
        labels=study.labels,
        n_train=list(study.n_train),
    )
    if not left:
        return ""
    where = "; ".join(f"{escape(a)} at $N = {', '.join(map(str, ns))}$" for a, ns in left.items())
    return (
        f" Not drawn: the paper's points at the sizes this study skipped for an activity (too few test frames "
        f"would remain; see the tables): {where}."
    )


def blocks_text(study):
    """The sentence on Fig. 1's two rows of panels (:func:`bsrbench.reporting.plots.figure_blocks`), or ""."""
    blocks = figure_blocks(list(study.figure_methods), paper_names(study.df))
    if len(blocks) == 1:
        return ""
    beside = " beside PM" if blocks[1][1][:1] == ["PM"] else ""
    return (
        " Top: the paper's methods, with the paper's numbers; below: the references and today's baselines"
        f"{beside}, on the same error axis."
    )


def caption(kind, source, study):
    """The caption of one figure of ``kind`` (:data:`KINDS` or ``"cd"``) on ``source``."""
    first = escape(study.labels.get(study.subjective_first, study.subjective_first))
    seed0 = study.seed0
    if kind == "error_vs_ntrain":
        return (
            f"Error against the number of training frames $N$ on the {source} data, one panel per activity "
            "(log-log axes, ticks at the sizes studied): mean $\\pm$ std over seeds, methods dodged sideways so "
            f"that their error bars do not overlap. Filled markers: this study ({study_lines(study.df['protocol'])}); "
            "open markers, dotted lines: the paper's Tables I and II at the same $N$."
            + blocks_text(study)
            + not_drawn(study, source)
        )
    kinds = dict(study.stick_kinds).get(source, [])
    if kind == "subjective" and not study.subjective_first:
        return (
            f"Subjective comparison on the {source} data: none of the methods of the configuration key "
            r"report.subjective\_methods was run, so no frame is drawn."
        )
    if kind == "subjective" and kinds == ["authors"]:
        return (
            f"Subjective comparison in the layout of the paper's Fig.~2 on the {source} data: for each activity "
            f"one test frame (largest $N$, seed {seed0}; the test frame with the median error of {first}). These "
            "precomputed features come without images, so the first panel shows the input shape-context "
            "histogram; then the true pose and each method's predicted pose (in colour, over the true pose in "
            "grey) as 3-D stick figures of the authors' 19-joint skeleton from one oblique viewpoint (their "
            "angle convention, reconstructed in resources/paper-features/README.md); in brackets the method's "
            "error on this frame."
        )
    if kind == "subjective" and "None" not in kinds:
        return (
            f"Subjective comparison in the layout of the paper's Fig.~2 on the {source} data: for each activity "
            f"one test frame (largest $N$, seed {seed0}; the test frame with the median error of {first}). From the "
            "left: the rendered silhouette (the input), the true pose, and each method's predicted pose (in "
            "colour, over the true pose in grey), as 3-D stick figures from one oblique viewpoint (forward "
            "kinematics of the trial's skeleton); in brackets the method's error on this frame."
        )
    if kind == "subjective":
        return (
            f"Subjective comparison on the {source} data: for each activity one test frame (largest $N$, seed {seed0}; "
            f"the test frame with the median error of {first}). These features come with joint angles in a "
            r"skeleton convention that is not configured (data set key pose\_convention), so no stick figure is drawn: "
            "left the input shape-context histogram, right the true and predicted joint angles; in brackets "
            "each method's error on this frame."
        )
    if kind == "calibration":
        return (
            f"Calibration on the {source} data ({calibration_protocol(study.df['protocol'])}), one panel per $N$: "
            "the share of the test angles "
            "inside the central predictive interval against the interval's nominal level, for the methods "
            "with predictive intervals; line: mean over seeds, band: minimum to maximum. A calibrated method "
            "follows the dashed diagonal."
        )
    if kind == "cd":
        return (
            f"Critical-difference diagrams on the {source} data, one per protocol (Dem\\v{{s}}ar 2006): each "
            "method at its mean rank over the (activity, $N$) cells in which every method ran, by mean error over "
            "the splits (1: lowest error); a bar joins methods that pairwise Wilcoxon signed-rank tests over the "
            "cells, Holm-corrected, do not tell apart ($p \\geq 0.05$; Benavoli, Corani and Mangili 2016)."
        )
    raise ValueError(f"no caption for figure kind {kind!r}")


def figure_captions(figures, cd_figures, study, *, root):
    """(path relative to ``root``, caption) of each figure: ``figures`` (``<kind>_<source>.pdf``, kinds of
    :data:`KINDS`) in their order, then the critical-difference diagrams ``cd_figures`` (``cd_<source>.pdf``)."""
    out = []
    for f in figures:
        stem = Path(f).stem
        kind = next((k for k in KINDS if stem.startswith(k + "_")), None)
        if kind is None:
            raise ValueError(f"figure {f}: its name should begin with one of {', '.join(KINDS)}")
        out.append((Path(f).relative_to(root), caption(kind, stem[len(kind) + 1 :], study)))
    out += [(Path(f).relative_to(root), caption("cd", Path(f).stem[3:], study)) for f in cd_figures]
    return out


#: The caption of the MCMC trace figure (rule plot_trace).
TRACE = (
    "MCMC traces of one PM split (first activity, largest $N$, first seed), every chain overlaid; "
    "precisions on a log axis; shaded: burn-in."
)


def why_pm_captions(df, figures, *, gxy_methods, protocol, n_train, labels, root):
    """(path relative to ``root``, caption) of each figure of the section "Why PM trails the paper here":
    ``figures`` are ``trace.pdf`` (:data:`TRACE`) and ``gxy.pdf``, whose panels rule plot_gxy draws for the
    methods ``gxy_methods`` (configuration key ``report.gxy_methods``) at ``protocol`` and ``n_train`` (the
    study's first protocol and smallest $N$; :func:`bsrbench.reporting.convergence.gxy_caption`)."""
    out = []
    for f in figures:
        stem = Path(f).stem
        if stem == "trace":
            text = TRACE
        elif stem == "gxy":
            text = gxy_caption(df, gxy_methods, protocol=protocol, n_train=n_train, labels=labels)
        else:
            raise ValueError(
                f"figure {f}: no caption for it in the section (expected trace or gxy)"
            )
        out.append((Path(f).relative_to(root).as_posix(), text))
    return out
