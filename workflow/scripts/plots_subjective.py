"""Snakemake adapter of rule plot_subjective: one test frame per activity, true and predicted poses
(bsrbench.reporting.plots.subjective_figure)."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.io import load_features, read_npz
from bsrbench.reporting.plots import save, subjective_figure
from bsrbench.reporting.tables import read_results

sm = snakemake
# the predictions drawn here are those of the configured study: fail on an aggregate of another one
read_results(sm.input.results, design=dict(sm.params.design))
methods = list(sm.params.methods)
items = [
    (
        activity,
        dict(sm.params.labels_activity)[activity],
        load_features(sm.input.features[i]),
        {
            m: read_npz(sm.input.predictions[i * len(methods) + j], ("test", "y_true", "y_pred"))
            for j, m in enumerate(methods)
        },
    )
    for i, activity in enumerate(sm.params.activities)
]
fig = subjective_figure(
    items,
    methods,
    labels=dict(sm.params.labels),
    sticks=dict(sm.params.sticks),
    motion=dict(sm.params.motion),
)
save(fig, [sm.output.pdf, sm.output.png])
