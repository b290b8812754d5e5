"""The metric, the pose transforms, seed derivation and atomic output."""

import hashlib

import numpy as np
import pytest

from bsrbench.errors import InputError
from bsrbench.io import atomic_path
from bsrbench.metrics import interval_coverage, mean_angle_error, per_angle_rms, wrap_degrees
from bsrbench.poses import HeadingTransform, get_pose_transform
from bsrbench.seeds import derive_seed, method_seed, split_seed


def test_wrap_degrees_maps_into_half_open_interval():
    d = np.array([-540.0, -181.0, -180.0, 0.0, 179.0, 180.0, 359.0, 721.0])
    w = wrap_degrees(d)
    assert np.all(w >= -180) and np.all(w < 180)
    np.testing.assert_allclose(np.cos(np.deg2rad(w)), np.cos(np.deg2rad(d)), atol=1e-12)
    np.testing.assert_allclose(w[[1, 4, 6]], [179.0, 179.0, -1.0])


def test_metric_is_mean_of_per_angle_rms_with_wrapping():
    rng = np.random.default_rng(0)
    y = rng.uniform(-180, 180, size=(50, 4))
    err = rng.normal(0, [1.0, 2.0, 5.0, 10.0], size=(50, 4))
    pred = y + err + 360.0 * rng.integers(-2, 3, size=(50, 4))  # full turns must not count
    rms = per_angle_rms(y, pred)
    np.testing.assert_allclose(rms, np.sqrt(np.mean(err**2, axis=0)), rtol=1e-10)
    assert mean_angle_error(y, pred) == pytest.approx(rms.mean())
    # The authors' form acos(cos(a - b)) gives the same RMS.
    acos_form = np.sqrt(np.mean(np.rad2deg(np.arccos(np.cos(np.deg2rad(pred - y)))) ** 2, axis=0))
    np.testing.assert_allclose(rms, acos_form, rtol=1e-6)
    # Without wrapping the full turns count: the plain difference, by hand.
    plain = np.sqrt(np.mean((pred - y) ** 2, axis=0))
    np.testing.assert_allclose(per_angle_rms(y, pred, wrap=False), plain, rtol=1e-12)
    assert mean_angle_error(y, pred, wrap=False) == pytest.approx(plain.mean())
    assert mean_angle_error(y, pred, wrap=False) > 10 * mean_angle_error(y, pred)


def test_metric_rejects_shape_mismatch_and_nan():
    with pytest.raises(InputError, match=r"same shape.*\(3, 2\).*\(3, 3\)"):
        mean_angle_error(np.zeros((3, 2)), np.zeros((3, 3)))
    bad = np.zeros((3, 2))
    bad[1, 1] = np.nan
    with pytest.raises(InputError, match="y_pred has a non-finite value at row 1, column 1"):
        mean_angle_error(np.zeros((3, 2)), bad)


def test_interval_coverage_of_gaussian_residuals_is_near_nominal():
    rng = np.random.default_rng(1)
    y = rng.normal(size=(4000, 3))
    mean = np.zeros_like(y)
    assert interval_coverage(y, mean, np.ones_like(y), level=0.9) == pytest.approx(0.9, abs=0.02)
    assert interval_coverage(y, mean, 0.5 * np.ones_like(y), level=0.9) < 0.8
    with pytest.raises(InputError, match="level"):
        interval_coverage(y, mean, np.ones_like(y), level=1.5)


def test_heading_transform_round_trip_and_layout():
    rng = np.random.default_rng(2)
    Y = rng.uniform(-179.9, 179.9, size=(20, 57))
    t = HeadingTransform()
    Z = t.forward(Y)
    assert Z.shape == (20, 58)
    np.testing.assert_allclose(np.hypot(Z[:, -2], Z[:, -1]), 20.0)
    np.testing.assert_allclose(Z[:, :2], Y[:, :2])
    np.testing.assert_allclose(Z[:, 2:-2], Y[:, 3:])
    back = t.inverse(Z)
    np.testing.assert_allclose(wrap_degrees(back - Y), 0.0, atol=1e-9)
    assert get_pose_transform("none").forward(Y) is not None
    with pytest.raises(
        InputError, match="pose_transform must be 'none' or 'heading'; got 'sincos'"
    ):
        get_pose_transform("sincos")


def test_seeds_are_stable_and_distinct():
    # the first 4 bytes of SHA-256 of the parts joined by the unit separator, little-endian
    by_hand = int.from_bytes(hashlib.sha256(b"a\x1f1").digest()[:4], "little")
    assert derive_seed("a", 1) == by_hand
    assert derive_seed("split", "hsc", "golf", 30, 0) == int.from_bytes(
        hashlib.sha256("\x1f".join(["split", "hsc", "golf", "30", "0"]).encode()).digest()[:4],
        "little",
    )
    assert derive_seed("a", 1) != derive_seed("a", 2)
    s = split_seed("hsc", "golf", 30, 0)
    assert s == split_seed("hsc", "golf", 30, 0)
    assert s != split_seed("hsc", "golf", 60, 0)
    assert method_seed("hsc", "golf", 30, 0, "PM") != method_seed("hsc", "golf", 30, 0, "SR")
    assert 0 <= s < 2**32


def test_atomic_path_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out" / "a.npz"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            np.savez(tmp, x=np.arange(3))
            raise RuntimeError("interrupted")
    assert not target.exists()
    assert list((tmp_path / "out").iterdir()) == []
    with atomic_path(target) as tmp:
        np.savez(tmp, x=np.arange(3))
    assert np.load(target)["x"].tolist() == [0, 1, 2]
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["a.npz"]


def test_atomic_path_output_has_umask_permissions(tmp_path):
    import os

    mask = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "b.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(mask)
    assert (tmp_path / "b.txt").stat().st_mode & 0o777 == 0o644


def test_heading_column_comes_from_the_features_file(tmp_path):
    from bsrbench.io import load_features

    rng = np.random.default_rng(3)
    X, Y = rng.normal(size=(10, 4)), rng.uniform(-170, 170, size=(10, 6))
    np.savez(tmp_path / "bvh.npz", X=X, Y=Y, heading_column=1)
    np.savez(tmp_path / "mat.npz", X=X, Y=Y)
    for name, col in (("bvh.npz", 1), ("mat.npz", 2)):
        feats = load_features(tmp_path / name)
        assert feats["heading_column"] == col
        t = get_pose_transform("heading", column=feats["heading_column"])
        Z = t.forward(Y)
        np.testing.assert_allclose(np.rad2deg(np.arctan2(Z[:, -2], Z[:, -1])), Y[:, col], atol=1e-9)
        np.testing.assert_allclose(t.inverse(Z), Y, atol=1e-9)
