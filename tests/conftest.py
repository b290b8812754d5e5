"""Test-wide settings: one BLAS/OpenMP/numba thread per process (the machine has 2 cores and tests run
small problems, where threaded BLAS is slower), headless matplotlib."""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MPLBACKEND", "Agg")
