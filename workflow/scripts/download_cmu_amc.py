"""Download a CMU trial (AMC) and verify it (digest if known; it must parse with the subject's ASF)."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.datasets import download_cmu_trial

sm = snakemake
download_cmu_trial(
    sm.wildcards.subject,
    sm.wildcards.trial,
    sm.output.amc,
    sm.input.asf,
    base_url=sm.params.base_url,
    expected_sha256=sm.params.expected,
)
