"""Test-wide settings: one BLAS/OpenMP/numba thread per process (the machine has 2 cores and tests run
small problems, where threaded BLAS is slower), headless matplotlib."""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MPLBACKEND", "Agg")


import numpy as np  # noqa: E402
import pytest  # noqa: E402


def _write_synthetic_features(tmp_path, n=200):
    """A features file of ``n`` frames: 6 features, 5 angles with the heading in column 2, as in the data."""
    rng = np.random.default_rng(1)
    X = rng.normal(size=(n, 6))
    Y = np.column_stack(
        [X[:, :3] @ rng.normal(size=(3, 4)) * 10, np.rad2deg(np.arctan2(X[:, 4], X[:, 5]))]
    )
    Y = Y[:, [0, 1, 4, 2, 3]]  # heading in column 2, as in the data
    path = tmp_path / "f.npz"
    np.savez(path, X=X, Y=Y, frames=np.arange(n), angle_names=np.array([f"a{i}" for i in range(5)]))
    return path


@pytest.fixture
def synthetic_features():
    """Writes a small features file (:func:`_write_synthetic_features`) into a folder; returns its path."""
    return _write_synthetic_features
