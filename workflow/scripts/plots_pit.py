"""Snakemake adapter of rule plot_pit: PIT histograms per source and method from the fits' predictions."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.io import read_npz
from bsrbench.reporting.plots import save
from bsrbench.reporting.today import pit_panels, plot_pit

sm = snakemake
panels = pit_panels((read_npz(p) for p in sm.input.predictions), sm.params.panels)
save(plot_pit(panels, labels=dict(sm.params.labels)), [sm.output.pdf, sm.output.png])
print(f"{len(panels)} panels: {sorted(panels)}", file=sys.stderr)
