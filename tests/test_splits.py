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
