"""Snakemake adapter of rule plot_pit: PIT histograms per source and method from the fits' predictions."""

import sys

sys.stderr = open(snakemake.log[0], "w")

import numpy as np

from bsrbench.io import read_npz
from bsrbench.reporting.plots import save
from bsrbench.reporting.today import plot_pit

sm = snakemake
panels = {}
for path, (source, method) in zip(sm.input.predictions, sm.params.panels):
    arrays = read_npz(path)
    if "pit" in arrays:
        panels.setdefault((source, method), []).append(
            np.asarray(arrays["pit"], dtype=float).ravel()
        )
panels = {k: np.concatenate(v) for k, v in panels.items()}
fig = plot_pit(panels, labels=dict(sm.params.labels))
save(fig, [sm.output.pdf, sm.output.png])
print(f"{len(panels)} panels: {sorted(panels)}", file=sys.stderr)
