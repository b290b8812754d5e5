"""Snakemake adapter of rule plot_gxy: g_xy traces, one panel per method of report.gxy_methods."""

import json
import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.io import read_npz
from bsrbench.reporting.convergence import gxy_panel, plot_gxy
from bsrbench.reporting.plots import save
from bsrbench.reporting.tables import read_results

sm = snakemake
df = read_results(sm.input.results)
labels = dict(sm.params.labels)
items = []
for p in sm.input.predictions:
    path = Path(p)
    protocol, source, activity, method, n, seed = path.parts[-6:-1] + (path.stem,)
    row = df[
        (df["protocol"] == protocol)
        & (df["source"] == source)
        & (df["activity"] == activity)
        & (df["method"] == method)
        & (df["n_train"] == int(n[1:]))
        & (df["seed"] == int(seed[4:]))
    ]
    params = json.loads(row["params"].iloc[0]) if len(row) else {}
    k, rel, prior = gxy_panel(params, int(n[1:]))
    title = f"{labels.get(method, method)}: K={k} {rel} N={n[1:]}"
    if prior is not None:
        title += f"\nGamma({prior[0]:g}, {prior[1]:g}) prior"
    items.append((title, read_npz(path)))
save(plot_gxy(items), [sm.output.pdf, sm.output.png])
