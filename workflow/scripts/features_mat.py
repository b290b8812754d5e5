"""Load a verified .mat feature file (X, Y) and save it as a features file."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.datasets import build_mat_features

sm = snakemake
fs = build_mat_features(sm.input.mat, sm.output[0], **sm.params.options)
print(f"{sm.output[0]}: X {fs.X.shape}, Y {fs.Y.shape}", file=sys.stderr)
