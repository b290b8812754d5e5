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


@pytest.fixture
def published_ci_table(tmp_path, synthetic_features):
    """A published table ``published/ci.csv`` (study ci: config/ci.yaml) of four 1-NN rows and one ridge row made
    by today's code on synthetic features in ``features/hsc/golf.npz``, with its provenance."""
    import shutil

    from bsrbench.io import load_features
    from bsrbench.reporting import freshness
    from bsrbench.results import aggregate_rows
    from bsrbench.runs import run_job
    from bsrbench.splits import JobSpec

    folder = tmp_path / "features" / "hsc"
    folder.mkdir(parents=True)
    path = folder / "golf.npz"
    shutil.move(synthetic_features(tmp_path), path)
    features = load_features(path)

    def row(method, estimator, seed, params):
        spec = JobSpec("hsc", "golf", method, 30, seed)
        return run_job(spec, features, estimator=estimator, params=params)[0]

    rows = [
        row("NN1", "bsrbench.models.reference:NearestNeighbourRegressor", s, {"n_neighbors": 1})
        for s in range(4)
    ]
    rows.append(row("Ridge", "bsrbench.models.reference:RidgeRegressor", 0, {"alpha": 1.0}))
    table = tmp_path / "published" / "ci.csv"
    table.parent.mkdir()
    df = aggregate_rows(rows)
    df.to_csv(table, index=False)
    freshness.write_table_provenance(table, df)
    return table
