"""Learn the shape-context codebook from the codebook trials only."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.datasets import learn_codebook_from_trials

sm = snakemake
centres = learn_codebook_from_trials(
    list(sm.input.trials),
    sm.output[0],
    frames_per_trial=sm.params.frames_per_trial,
    n_centres=sm.params.n_centres,
    render=sm.params.render,
    n_points=sm.params.n_points,
    seed=sm.params.seed,
    skip_frames=sm.params.skip_frames,
    checksums=sm.params.checksums,
)
print(
    f"{sm.output[0]}: {centres.shape[0]} centres of dimension {centres.shape[1]}", file=sys.stderr
)
