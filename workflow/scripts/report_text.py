"""Snakemake adapter of rule report_text: setup, parameters and findings text, and the tables and figures."""

import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.estimators import estimator_defaults
from bsrbench.reporting.comparisons import read_comparisons
from bsrbench.reporting.plots import (
    PROTOCOL_LINE_NAMES,
    PROTOCOL_LINESTYLES,
    paper_points_not_drawn,
)
from bsrbench.reporting.report import missing_data_note, write_body, write_generated
from bsrbench.reporting.tables import latex_escape, read_paper_tables, read_results

sm = snakemake
root = Path(
    sm.output.body
).parent.parent  # the study's report folder reports/{study}: LaTeX paths are relative to it
labels = dict(sm.params.labels)
first = latex_escape(
    labels.get(sm.params.subjective_first, sm.params.subjective_first)
)  # in captions
# the split drawn: the first seed of the study (config key seed_start; 0 in the paper protocol)
seed0 = int(sm.config.get("seed_start", 0))
df = read_results(sm.input.results, design=dict(sm.params.design))
paper = read_paper_tables(sm.input.paper)
# the estimators' defaults: the parameter table shows every value a method ran with
estimators = df.drop_duplicates("method")[["method", "estimator"]].itertuples(index=False)
defaults = {m: estimator_defaults(e) for m, e in estimators}


# the calibration figure's protocol (plots.plot_calibration): the random one (the paper's) if run, else the first
_protocols = sorted(set(df["protocol"]))
calibration_protocol = (
    "random protocol"
    if "random" in _protocols or not _protocols
    else f"{latex_escape(_protocols[0])} protocol, as named in the panel titles; this study did not run the random one"
)
# Fig. 1's line styles (plots.plot_error_vs_ntrain): solid for the random protocol, dashed for the contiguous one, ...
study_lines = "; ".join(
    f"{PROTOCOL_LINE_NAMES[ls]} lines: {latex_escape(p.replace('_', '-'))} protocol"
    for p, ls in PROTOCOL_LINESTYLES.items()
    if p in _protocols
)


def not_drawn(source):
    """The sentence naming the paper's points Fig. 1 leaves out on ``source`` (plots.paper_points_not_drawn), or ""."""
    left = paper_points_not_drawn(
        df,
        paper,
        source=source,
        methods=list(sm.params.figure_methods),
        labels=labels,
        n_train=list(sm.params.design["n_train"]),
    )
    if not left:
        return ""
    where = "; ".join(
        f"{latex_escape(a)} at $N = {', '.join(map(str, ns))}$" for a, ns in left.items()
    )
    return (
        f" Not drawn: the paper's points at the sizes this study skipped for an activity (too few test frames "
        f"would remain; see the tables): {where}."
    )


def caption(kind, source):
    """The caption of one figure (one per source and kind)."""
    if kind == "error_vs_ntrain":
        return (
            f"Error against the number of training frames $N$ on the {source} data, one panel per activity "
            "(log-log axes, ticks at the sizes studied): mean $\\pm$ std over seeds, methods dodged sideways so "
            f"that their error bars do not overlap. Filled markers: this study ({study_lines}); open markers, "
            "dotted lines: the paper's Tables I and II at the same $N$." + not_drawn(source)
        )
    kinds = dict(sm.params.stick_kinds).get(source, [])
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
            f"Calibration on the {source} data ({calibration_protocol}), one panel per $N$: the share of the "
            "test angles "
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


write_generated(
    sm.output.findings,
    df,
    paper,
    labels=labels,
    defaults=defaults,
    study=(
        sm.params.study,
        Path(sm.input.results).parent.parent.as_posix(),
    ),  # results/{study}/aggregate/..
    comparisons=read_comparisons(sm.input.comparisons),
)
KINDS = ("error_vs_ntrain", "subjective", "calibration")
figures = []
for f in sm.params.figures:
    stem = Path(f).stem
    kind = next(k for k in KINDS if stem.startswith(k))
    figures.append((Path(f).relative_to(root), caption(kind, stem[len(kind) + 1 :])))
figures += [
    (Path(f).relative_to(root), caption("cd", Path(f).stem[3:])) for f in sm.params.cd_figures
]
status = dict(sm.params.status)
write_body(
    sm.output.body,
    tables=[Path(t).relative_to(root) for t in sm.params.tables],
    figures=figures,
    notes={s: missing_data_note(s, dict(st)) for s, st in status.items()},
)
