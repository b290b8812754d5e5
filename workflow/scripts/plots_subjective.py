"""Snakemake adapter of rule plot_subjective: one test frame per activity, true and predicted poses."""

import sys

import numpy as np

sys.stderr = open(snakemake.log[0], "w")  # noqa: F821

from bsrbench.metrics import wrap_degrees  # noqa: E402
from bsrbench.reporting.plots import plot_subjective, save, subjective_panels  # noqa: E402
from bsrbench.study import load_features  # noqa: E402

sm = snakemake  # noqa: F821
methods = list(sm.params.methods)
activities = list(sm.params.activities)


def frame_errors(y_true, y_pred):
    """Per-frame error: mean over angles of the absolute wrapped difference (degrees)."""
    return np.mean(np.abs(wrap_degrees(np.asarray(y_pred) - np.asarray(y_true))), axis=1)


items = []
for i, activity in enumerate(activities):
    preds = {}
    for j, m in enumerate(methods):
        with np.load(sm.input.predictions[i * len(methods) + j]) as f:
            preds[m] = {k: f[k] for k in ("test", "y_true", "y_pred")}
    items.append((activity, dict(sm.params.labels_activity)[activity], load_features(sm.input.features[i]), preds))
fig = plot_subjective(subjective_panels(items, methods, frame_errors), labels=dict(sm.params.labels))
save(fig, [sm.output.pdf, sm.output.png])
