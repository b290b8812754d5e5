"""Download a CMU subject's ASF skeleton and verify it (digest if known; it must parse)."""

import sys

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.datasets import download_cmu_skeleton

sm = snakemake
download_cmu_skeleton(
    sm.wildcards.subject,
    sm.output.asf,
    base_url=sm.params.base_url,
    expected_sha256=sm.params.expected,
)
