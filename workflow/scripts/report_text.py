"""Snakemake adapter of rule report_text: the setup, parameters and findings text, and the tables and figures with
their captions (bsrbench.reporting.body.write_report_text)."""

import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.reporting.body import write_report_text
from bsrbench.reporting.captions import Study
from bsrbench.reporting.comparisons import read_comparisons
from bsrbench.reporting.tables import read_paper_tables, read_results

sm = snakemake
study = Study(
    df=read_results(sm.input.results, design=dict(sm.params.design)),
    paper=read_paper_tables(sm.input.paper),
    labels=dict(sm.params.labels),
    figure_methods=list(sm.params.figure_methods),
    n_train=list(sm.params.design["n_train"]),
    stick_kinds=dict(sm.params.stick_kinds),
    subjective_first=sm.params.subjective_first,
    # the split drawn: the first seed of the study (config key seed_start; 0 in the paper protocol)
    seed0=int(sm.config.get("seed_start", 0)),
)
write_report_text(
    sm.output.findings,
    sm.output.body,
    study,
    comparisons=read_comparisons(sm.input.comparisons),
    name=sm.params.study,
    results_folder=Path(sm.input.results).parent.parent,  # results/{study}/aggregate/..
    root=Path(sm.output.body).parent.parent,  # reports/{study}: the LaTeX paths are relative to it
    tables=list(sm.params.tables),
    figures=list(sm.params.figures),
    cd_figures=list(sm.params.cd_figures),
    status=dict(sm.params.status),
)
