"""The cross-trial protocol: whole trials held out for test, training frames from the other trials."""

import numpy as np
import pytest

from bsrbench.errors import InputError
from bsrbench.io import load_features
from bsrbench.runs import run_job
from bsrbench.splits import JobSpec, make_split

TRIALS = np.repeat(np.arange(10), 60)  # 10 trials of 60 frames, as the mocap run data set


@pytest.mark.parametrize("n_train", [30, 100, 200])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_test_frame_shares_a_trial_with_a_training_frame(n_train, seed):
    train, test = make_split(
        600, n_train, protocol="cross_trial", seed=seed, min_test=100, trials=TRIALS
    )
    assert train.size == n_train and np.unique(train).size == n_train and test.size >= 100
    assert not set(TRIALS[train]) & set(TRIALS[test])
    assert set(test) == set(np.flatnonzero(np.isin(TRIALS, TRIALS[test])))  # whole trials
    again = make_split(600, n_train, protocol="cross_trial", seed=seed, min_test=100, trials=TRIALS)
    assert all(np.array_equal(a, b) for a, b in zip((train, test), again))


def test_the_held_out_trials_change_with_the_seed():
    held = {
        tuple(
            np.unique(TRIALS[make_split(600, 30, protocol="cross_trial", seed=s, trials=TRIALS)[1]])
        )
        for s in range(6)
    }
    assert len(held) > 1


def test_cross_trial_errors_name_the_problem():
    with pytest.raises(InputError, match="needs the trial of each frame"):
        make_split(600, 30, protocol="cross_trial", seed=0)
    with pytest.raises(InputError, match="leaves 120 frames of 2 trials for n_train=200"):
        make_split(600, 200, protocol="cross_trial", seed=0, min_test=450, trials=TRIALS)
    with pytest.raises(InputError, match="1 trial"):
        make_split(600, 30, protocol="cross_trial", seed=0, trials=np.zeros(600, int))


def test_a_job_on_features_with_trials_uses_the_trials(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.normal(size=(600, 5))
    Y = rng.normal(size=(600, 4)) * 10
    np.savez(tmp_path / "f.npz", X=X, Y=Y, trial_index=TRIALS)
    feats = load_features(tmp_path / "f.npz")
    spec = JobSpec("mocap", "run", "NN1", 100, 0, protocol="cross_trial", pose_transform="none")
    row, arrays = run_job(
        spec,
        feats,
        estimator="bsrbench.models.reference:NearestNeighbourRegressor",
        params={"n_neighbors": 1},
    )
    assert not set(TRIALS[arrays["train"]]) & set(TRIALS[arrays["test"]])
    assert row["protocol"] == "cross_trial" and row["n_test"] == arrays["test"].size
