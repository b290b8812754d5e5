"""Reading a features file checks it (bsrbench.io)."""

import numpy as np
import pytest

from bsrbench.errors import DataFileError
from bsrbench.io import load_features


def test_load_features_checks_the_file(tmp_path, synthetic_features):
    f = load_features(synthetic_features(tmp_path))
    assert f["X"].shape == (200, 6) and f["Y"].shape == (200, 5) and len(f["angle_names"]) == 5
    with pytest.raises(DataFileError, match="does not exist"):
        load_features(tmp_path / "none.npz")
    bad = tmp_path / "bad.npz"
    np.savez(bad, X=np.ones((3, 2)), Y=np.ones((4, 2)))
    with pytest.raises(DataFileError, match="same number of rows"):
        load_features(bad)
    nan = tmp_path / "nan.npz"
    np.savez(nan, X=np.array([[1.0, np.nan]]), Y=np.ones((1, 2)))
    with pytest.raises(DataFileError, match=r"non-finite value\(s\), first at row 0"):
        load_features(nan)
    # a truncated file (an interrupted copy): numpy raises zipfile.BadZipFile, which used to reach the job's log
    good = synthetic_features(tmp_path)
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[:100])
    with pytest.raises(DataFileError, match=r"cut\.npz.*cannot read as \.npz.*delete it and rerun"):
        load_features(cut)
