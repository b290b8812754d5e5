"""Snakemake adapter of rule plot_subjective: one test frame per activity, true and predicted poses.

Motion-capture sources (BVH trials) get the paper's Fig. 2 layout: the rendered silhouette and 3-D stick
figures of the true and predicted poses (forward kinematics of the trial's skeleton). Features files in the
authors' skeleton convention (the hsc source, data set key `pose_convention: authors`) get the input histogram
and stick figures of the authors' 19-joint skeleton (bsrbench.authors.hsc_stick_figure). Other sources with
joint angles only get the input histogram and angle profiles.
"""

import sys
from pathlib import Path

import numpy as np

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.io import load_features, read_npz
from bsrbench.metrics import wrap_degrees
from bsrbench.reporting.plots import (
    plot_subjective,
    plot_subjective_sticks,
    pose_positions,
    save,
    subjective_panels,
)
from bsrbench.reporting.tables import read_results

sm = snakemake
# the predictions drawn here are those of the configured study: fail on an aggregate of another one
read_results(sm.input.results, design=dict(sm.params.design))
methods = list(sm.params.methods)
activities = list(sm.params.activities)
labels = dict(sm.params.labels)
motion = dict(sm.params.motion)


def frame_errors(y_true, y_pred):
    """Per-frame error: mean over angles of the absolute wrapped difference (degrees)."""
    return np.mean(np.abs(wrap_degrees(np.asarray(y_pred) - np.asarray(y_true))), axis=1)


items = []
for i, activity in enumerate(activities):
    preds = {}
    for j, m in enumerate(methods):
        preds[m] = read_npz(
            sm.input.predictions[i * len(methods) + j], ("test", "y_true", "y_pred")
        )
    items.append(
        (
            activity,
            dict(sm.params.labels_activity)[activity],
            load_features(sm.input.features[i]),
            preds,
        )
    )
panels = subjective_panels(items, methods, frame_errors)

kinds = dict(sm.params.sticks)
if panels and all(kinds.get(a) for a in activities):
    from bsrbench.authors import hsc_stick_figure
    from bsrbench.mocap import parse_bvh
    from bsrbench.render import render_silhouettes

    stick_panels = []
    for pnl in panels:
        a = pnl["activity"]
        if kinds[a] == "authors":
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
        bvh = parse_bvh(path)
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
                "true": pose_positions(bvh, tf, pj, pnl["y_true"]),
                "preds": {m: pose_positions(bvh, tf, pj, y) for m, y in pnl["preds"].items()},
                "errors": pnl["errors"],
            }
        )
    fig = plot_subjective_sticks(stick_panels, labels=labels)
else:
    fig = plot_subjective(panels, labels=labels)
save(fig, [sm.output.pdf, sm.output.png])
