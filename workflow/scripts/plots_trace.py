"""Snakemake adapter of rule plot_trace: the MCMC traces of one split, every chain overlaid."""

import json
import sys
from pathlib import Path

sys.stderr = open(snakemake.log[0], "w")

from bsrbench.io import read_npz
from bsrbench.reporting.convergence import plot_chain_traces
from bsrbench.reporting.plots import save
from bsrbench.reporting.tables import read_results

sm = snakemake
path = Path(sm.input.predictions)
# .../fit/{protocol}/{source}/{activity}/{method}/n{N}/seed{seed}.npz
protocol, source, activity, method, n, seed = path.parts[-6:-1] + (path.stem,)
df = read_results(sm.input.results)
row = df[
    (df["protocol"] == protocol)
    & (df["source"] == source)
    & (df["activity"] == activity)
    & (df["method"] == method)
    & (df["n_train"] == int(n[1:]))
    & (df["seed"] == int(seed[4:]))
]
params = json.loads(row["params"].iloc[0]) if len(row) else {}
arrays = read_npz(path)
label = dict(sm.params.labels).get(method, method)
fig = plot_chain_traces(
    arrays,
    title=f"{label} on {source}/{activity}, N={n[1:]}, seed {seed[4:]}",
    n_burn_in=int(arrays["n_burn_in"]) if "n_burn_in" in arrays else params.get("n_burn_in"),
)
save(fig, [sm.output.pdf, sm.output.png])
