"""Parse and concatenate a data set's trials and save positions and poses of the chosen frames."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.datasets import prepare_motion

sm = snakemake
motion = prepare_motion(
    list(sm.input.trials), sm.output[0], asf=sm.input.get("asf"), **sm.params.options
)
print(
    f"{sm.output[0]}: {motion.n_frames} frames of {motion.trial_ids}, {len(motion.joint_names)} joints",
    file=sys.stderr,
)
