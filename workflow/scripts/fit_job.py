"""Snakemake adapter of rule fit: one (protocol, source, activity, method, n_train, seed) job."""

import os
import sys

# Thread counts must be set before numba/BLAS are imported; Snakemake does not do it for scripts.
for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = str(snakemake.threads)  # noqa: F821

sys.stderr = open(snakemake.log[0], "w")  # noqa: F821

from bsrbench.study import JobSpec, load_features, read_json, run_job, write_arrays, write_json  # noqa: E402

sm = snakemake  # noqa: F821
w, p = sm.wildcards, sm.params
spec = JobSpec.from_wildcards(w, p)
params, cv_seconds = dict(p.fixed), None
if sm.input.cv:
    cv = read_json(sm.input.cv)
    params, cv_seconds = cv["best_params"], cv["cv_seconds"]
row, arrays = run_job(
    spec,
    load_features(sm.input.features),
    estimator=p.estimator,
    params=params,
    cv_mode=p.cv_mode,
    cv_seconds=cv_seconds,
)
write_arrays(sm.output.predictions, arrays)
write_json(sm.output.row, row)
print(f"{spec}: error {row['error']:.3f} deg, fit {row['fit_seconds']:.2f} s", file=sys.stderr)
