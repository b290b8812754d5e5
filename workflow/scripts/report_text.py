"""Snakemake adapter of rule report_text: setup and findings text, and the list of tables and figures."""

import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")  # noqa: F821

from bsrbench.reporting.report import write_body, write_generated  # noqa: E402
from bsrbench.reporting.tables import read_paper_tables, read_results  # noqa: E402

sm = snakemake  # noqa: F821
CAPTIONS = {
    "error_vs_ntrain": "Error against training-set size, mean $\\pm$ std over seeds; open markers: the paper.",
    "subjective": "Subjective comparison (the paper's Fig.~2 idea), one test frame per activity (largest $N$, "
    "seed 0). Motion-capture data: the rendered silhouette and 3-D stick figures of the true and predicted poses "
    "(forward kinematics of the trial's skeleton). Precomputed features (hsc): they come with joint angles only, "
    "in an undocumented skeleton convention, so the input histogram and angle profiles are drawn instead.",
    "calibration": "Calibration: empirical against nominal coverage of the central predictive intervals.",
    "trace": "MCMC traces of one PM fit (first activity, largest $N$, seed 0).",
}
write_generated(
    sm.output.findings,
    read_results(sm.input.results),
    read_paper_tables(sm.input.paper),
    labels=dict(sm.params.labels),
    study=(sm.params.study, Path(sm.input.results).parent.parent.as_posix()),  # results/{study}/aggregate/..
)
figures = []
for f in sm.params.figures:
    stem = Path(f).stem
    key = next(k for k in CAPTIONS if stem.startswith(k))
    src = stem[len(key) + 1 :]
    figures.append((Path(f).relative_to("reports"), CAPTIONS[key] + (f" Data: {src}." if src else "")))
write_body(
    sm.output.body,
    tables=[Path(t).relative_to("reports") for t in sm.params.tables],
    figures=figures,
)
