"""Train/test splits of the protocols and the split every method sees (bsrbench.splits)."""

import numpy as np
import pytest

from bsrbench.errors import InputError
from bsrbench.splits import JobSpec, make_split, max_n_train


@pytest.mark.parametrize("protocol", ["random", "contiguous"])
@pytest.mark.parametrize("n_train", [30, 200])
def test_split_is_disjoint_sized_and_reproducible(protocol, n_train):
    tr, te = make_split(600, n_train, protocol=protocol, seed=7, min_test=100, gap=30)
    assert tr.size == n_train
    assert np.intersect1d(tr, te).size == 0
    assert te.size >= 100
    tr2, te2 = make_split(600, n_train, protocol=protocol, seed=7, min_test=100, gap=30)
    assert np.array_equal(tr, tr2) and np.array_equal(te, te2)
    if protocol == "random":
        assert tr.size + te.size == 600
    else:
        assert np.array_equal(tr, np.arange(tr[0], tr[0] + n_train))
        # every test frame is more than `gap` frames from the training block
        dist = np.minimum(np.abs(te[:, None] - tr[None, :]), 10**9).min(axis=1)
        assert dist.min() > 30


def test_split_differs_between_seeds_and_rejects_too_few_test_frames():
    a, _ = make_split(600, 30, seed=0)
    b, _ = make_split(600, 30, seed=1)
    assert not np.array_equal(a, b)
    with pytest.raises(InputError, match="min_test=100"):
        make_split(600, 550, seed=0, min_test=100)
    with pytest.raises(InputError, match="protocol"):
        make_split(600, 30, protocol="blocks")
    assert max_n_train(600, min_test=100) == 500
    make_split(
        600, max_n_train(600, protocol="contiguous", min_test=100, gap=30), protocol="contiguous"
    )


def test_every_method_sees_the_same_split():
    a = JobSpec("hsc", "golf", "PM", 60, 3).split(600)
    b = JobSpec("hsc", "golf", "RVM", 60, 3).split(600)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert (
        JobSpec("hsc", "golf", "PM", 60, 3).method_seed
        != JobSpec("hsc", "golf", "RVM", 60, 3).method_seed
    )


@pytest.mark.parametrize("n_train, gap", [(30, 5), (60, 0), (100, 5), (200, 5), (70, 30)])
def test_blocked_splits_train_in_runs_and_test_away_from_them(n_train, gap):
    from bsrbench.splits import BLOCK, max_n_train

    for seed in range(20):
        train, test = make_split(600, n_train, protocol="blocked", seed=seed, gap=gap)
        assert len(train) == n_train and len(set(train)) == n_train
        runs = np.split(train, np.flatnonzero(np.diff(train) != 1) + 1)
        # runs start on a slot boundary and are whole slots (runs of adjacent slots merge), the last one cut short
        assert all(r[0] % BLOCK == 0 for r in runs)
        assert sum(len(r) % BLOCK != 0 for r in runs) <= 1
        distance = np.abs(test[:, None] - train[None, :]).min(axis=1)
        assert distance.min() > gap
        kept = np.setdiff1d(np.arange(600), train)
        near = np.abs(kept[:, None] - train[None, :]).min(axis=1) <= gap
        assert np.array_equal(np.sort(test), kept[~near])  # every frame far enough is a test frame
    assert n_train <= max_n_train(600, protocol="blocked", gap=gap)


def test_blocked_max_n_train_is_a_guarantee_and_too_many_runs_are_refused():
    from bsrbench.splits import max_n_train

    limit = max_n_train(600, protocol="blocked", gap=30)  # 500 // 70 = 7 runs of 10
    assert limit == 70
    for seed in range(50):  # the worst placement still leaves min_test frames
        assert len(make_split(600, limit, protocol="blocked", seed=seed, gap=30)[1]) >= 100
    with pytest.raises(
        InputError, match="blocked protocol: n_train=200 in runs of 10 with gap=30 leaves"
    ):
        for seed in range(50):
            make_split(600, 200, protocol="blocked", seed=seed, gap=30)
