"""Render a prepared motion's silhouettes, encode them over the codebook and save features and a preview."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.datasets import compute_mocap_features

sm = snakemake
fs = compute_mocap_features(
    sm.input.motion,
    sm.input.codebook,
    sm.output.features,
    preview_path=sm.output.preview,
    render=sm.params.render,
    n_points=sm.params.n_points,
    soft=sm.params.soft,
    seed=sm.params.seed,
    name=f"{sm.wildcards.source}/{sm.wildcards.activity}",
    meta=sm.params.meta,
    preview_frames=sm.params.preview_frames,
)
print(f"{sm.output.features}: X {fs.X.shape}, Y {fs.Y.shape}", file=sys.stderr)
