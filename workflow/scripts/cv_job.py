"""Snakemake adapter of rule cv: K-fold grid search on the training frames of one split."""

import os
import sys

# Thread counts must be set before numba/BLAS are imported; Snakemake does not do it for scripts.
for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = str(snakemake.threads)  # noqa: F821

sys.stderr = open(snakemake.log[0], "w")  # noqa: F821

from bsrbench.study import JobSpec, cross_validate, load_features, write_json  # noqa: E402

sm = snakemake  # noqa: F821
w, p = sm.wildcards, sm.params
spec = JobSpec.from_wildcards(w, p)
result = cross_validate(
    spec,
    load_features(sm.input.features),
    estimator=p.estimator,
    params=p.fixed,
    cv_params=p.cv_params,
    grid=p.grid,
    folds=p.folds,
)
write_json(sm.output[0], result)
print(f"{spec}: chose {result['best_params']} (CV error {result['best_score']})", file=sys.stderr)
