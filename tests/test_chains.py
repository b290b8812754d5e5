"""Several MCMC chains per split: chain seeds, pooling of the chains' predictions, R-hat and ESS across
chains, and the scores of pooled chains (the reporting of them: test_convergence.py, test_ablation.py)."""

import math

import numpy as np
import pytest

from bsrbench.convergence import convergence_summary
from bsrbench.errors import InputError
from bsrbench.io import load_features
from bsrbench.models.bsr import BayesianSR
from bsrbench.poses import get_pose_transform
from bsrbench.runs import chain_seed, pool_chains, run_chain, run_job
from bsrbench.splits import JobSpec

BSR = "bsrbench.models.bsr:BayesianSR"
PARAMS = {"n_atoms": 8, "n_neighbors": 3, "n_iter": 40, "n_burn_in": 20, "thin": 2}


def _features(tmp_path, n=160):
    rng = np.random.default_rng(3)
    X = np.abs(rng.normal(size=(n, 6)))
    Y = np.column_stack(
        [X[:, :3] @ rng.normal(size=(3, 4)) * 10, np.rad2deg(np.arctan2(X[:, 4], X[:, 5]))]
    )
    Y = Y[:, [0, 1, 4, 2, 3]]  # heading in column 2, as in the data
    path = tmp_path / "f.npz"
    np.savez(path, X=X, Y=Y, frames=np.arange(n))
    return load_features(path)


def test_chain_seeds_start_at_the_method_seed_and_differ():
    assert chain_seed(12345, 0) == 12345
    assert [chain_seed(2**32 - 2, c) for c in range(4)] == [2**32 - 2, 2**32 - 1, 0, 1]


@pytest.fixture(scope="module")
def chains(tmp_path_factory):
    feats = _features(tmp_path_factory.mktemp("chains"))
    spec = JobSpec("syn", "act", "PM", 40, 0, min_test=50)
    return (
        spec,
        feats,
        [run_chain(spec, feats, estimator=BSR, params=PARAMS, chain=c) for c in range(3)],
    )


def test_chain_zero_is_the_one_chain_fit(chains):
    spec, feats, cs = chains
    row, arrays = run_job(spec, feats, estimator=BSR, params=PARAMS)
    np.testing.assert_array_equal(cs[0]["trace_g_xy"], arrays["trace_g_xy"])
    transform = get_pose_transform("heading", column=2)
    np.testing.assert_allclose(transform.inverse(cs[0]["z_mean"]), arrays["y_pred"], rtol=1e-12)
    assert not np.array_equal(cs[0]["trace_g_xy"], cs[1]["trace_g_xy"])  # other seed, other chain
    assert [int(c["seed"]) for c in cs] == [spec.method_seed + c for c in range(3)]


def test_pooled_prediction_is_the_mixture_of_the_chains(chains):
    spec, feats, cs = chains
    row, arrays = pool_chains(spec, feats, cs, estimator=BSR, params=PARAMS)
    transform = get_pose_transform("heading", column=2)
    means = np.stack([c["z_mean"] for c in cs])
    # independent form of the mixture variance: mean within-chain variance + variance of the chain means
    var = np.mean([c["z_var"] for c in cs], axis=0) + means.var(axis=0)
    np.testing.assert_allclose(arrays["y_pred"], transform.inverse(means.mean(axis=0)), rtol=1e-12)
    from bsrbench.runs import inverse_std

    np.testing.assert_allclose(
        arrays["y_std"], inverse_std(transform, means.mean(axis=0), np.sqrt(var)), rtol=1e-9
    )
    assert row["n_chains"] == 3 and row["chain_seeds"] == [int(c["seed"]) for c in cs]
    assert arrays["chain_trace_g_xy"].shape == (3, 40)
    assert 0 <= row["coverage_90"] <= 1


def test_rhat_and_ess_are_arviz_on_the_post_burn_in_sweeps(chains):
    import arviz as az

    spec, feats, cs = chains
    out = convergence_summary(cs)
    x = np.stack([c["trace_log_likelihood"][20:] for c in cs])
    assert out["r_hat_log_likelihood"] == pytest.approx(
        float(az.rhat(az.convert_to_dataset(x))["x"])
    )
    assert out["ess_bulk_g_xy"] == pytest.approx(
        float(
            az.ess(
                az.convert_to_dataset(np.stack([c["trace_g_xy"][20:] for c in cs])), method="bulk"
            )["x"]
        )
    )
    assert math.isnan(out["r_hat_g_nx"])  # shared noise: no g_nx trace
    if hasattr(BayesianSR, "predict_draws"):
        assert np.isfinite(out["r_hat_test_error"]) and all(c["draw_error"].size == 10 for c in cs)
    else:
        assert math.isnan(out["r_hat_test_error"]) and "draw_error" not in cs[0]
    assert all(
        math.isnan(v) for v in convergence_summary(cs[:1]).values()
    )  # one chain: not computed


def test_rhat_separates_stuck_chains_from_mixed_ones():
    rng = np.random.default_rng(0)
    mixed = [{"trace_log_likelihood": rng.normal(size=500), "n_burn_in": 0} for _ in range(4)]
    stuck = [
        {"trace_log_likelihood": rng.normal(size=500) + 3 * c, "n_burn_in": 0} for c in range(4)
    ]
    assert convergence_summary(mixed)["r_hat_log_likelihood"] < 1.02
    assert convergence_summary(stuck)["r_hat_log_likelihood"] > 2
    assert convergence_summary(mixed)["ess_bulk_log_likelihood"] > 1000


def test_tail_ess_and_mcse_of_independent_draws():
    """4 chains of 2000 independent N(0, 1) draws: the tail ESS is about the 8000 draws and the MCSE of the mean
    about sd / sqrt(8000); AR(1) chains with rho = 0.8 have about (1 - rho) / (1 + rho) of that ESS, so their
    MCSE is about sd / sqrt(8000 / 9)."""
    rng = np.random.default_rng(1)
    iid = rng.normal(size=(4, 2000))
    out = convergence_summary([{"trace_g_s": a, "n_burn_in": 0} for a in iid])
    assert out["ess_tail_g_s"] == pytest.approx(8000, rel=0.15)
    assert out["mcse_g_s"] == pytest.approx(iid.std() / np.sqrt(8000), rel=0.1)
    rho = 0.8
    ar = np.empty((4, 20000))
    ar[:, 0] = rng.standard_normal(4)
    for t in range(1, ar.shape[1]):
        ar[:, t] = rho * ar[:, t - 1] + np.sqrt(1 - rho**2) * rng.standard_normal(4)
    out = convergence_summary([{"trace_g_s": a, "n_burn_in": 0} for a in ar])
    n_eff = ar.size * (1 - rho) / (1 + rho)
    assert out["mcse_g_s"] == pytest.approx(ar.std() / np.sqrt(n_eff), rel=0.15)
    assert set(out) == {
        f"{stat}_{name}"
        for stat in ("r_hat", "ess_bulk", "ess_tail", "mcse")
        for name in ("log_likelihood", "g_xy", "g_s", "g_nx", "g_ny", "test_error")
    }


def test_a_stale_chain_of_another_split_is_rejected(chains):
    spec, feats, cs = chains
    other = JobSpec("syn", "act", "PM", 40, 1, min_test=50)
    with pytest.raises(InputError, match="another split"):
        pool_chains(other, feats, cs, estimator=BSR, params=PARAMS)


def test_a_damaged_job_npz_names_the_file_and_what_to_do(tmp_path):
    """Before: a truncated chain or prediction file ended pool_chains / plot_subjective in a bare
    zipfile.BadZipFile naming no file."""
    from bsrbench.errors import DataFileError
    from bsrbench.io import read_npz

    good = tmp_path / "chain0.npz"
    np.savez(good, trace_g_xy=np.arange(3.0), y_pred=np.zeros((2, 2)))
    assert set(read_npz(good)) == {"trace_g_xy", "y_pred"}
    truncated = tmp_path / "chain1.npz"
    truncated.write_bytes(good.read_bytes()[:40])
    text = tmp_path / "chain2.npz"
    text.write_text("not an archive")
    for bad in (truncated, text):
        with pytest.raises(
            DataFileError, match=rf"{bad.name}.*cannot read as \.npz.*delete it and rerun"
        ):
            read_npz(bad)
    with pytest.raises(DataFileError, match=r"chain0\.npz.*missing array\(s\) \['test'\]"):
        read_npz(good, ("test", "y_pred"))


def test_pooled_scores_come_from_the_chains_draws_and_training_predictions(chains):
    """The pooled row's train_error is the error of the chains' mean training prediction, its CRPS and PIT
    values are those of the chains' kept draws (each chain weighted equally)."""
    from bsrbench import scores
    from bsrbench.metrics import mean_angle_error

    spec, feats, cs = chains
    row, arrays = pool_chains(spec, feats, cs, estimator=BSR, params=PARAMS)
    transform = get_pose_transform("heading", column=2)
    train, test = cs[0]["train"], cs[0]["test"]
    z_train = np.mean([c["z_train"] for c in cs], axis=0)
    assert row["train_error"] == pytest.approx(
        mean_angle_error(feats["Y"][train], transform.inverse(z_train)), rel=1e-12
    )
    draws = np.concatenate([c["score_draws"].astype(float) for c in cs], axis=1)
    w = np.concatenate([c["score_weights"] / 3 for c in cs], axis=1)
    assert draws.shape[1] == 3 * cs[0]["score_draws"].shape[1]
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=1e-12)
    y = feats["Y"][test]
    assert row["scores_from"] == "samples"
    assert row["crps"] == pytest.approx(scores.sample_crps(y, draws, w), rel=1e-12)
    # the NLPD takes the pooled predictive std (the mixture's exact moments), not the kept draws' moments
    assert row["nlpd"] == pytest.approx(
        scores.gaussian_nlpd(y, arrays["y_pred"], arrays["y_std"]), rel=1e-12
    )
    np.testing.assert_allclose(arrays["pit"], scores.sample_pit(y, draws, w), atol=1e-6)
    # bare synthetic arrays name no data source, hence no skeleton and no joint-position error
    assert row["mpjpe_mm"] is None and row["pa_mpjpe_mm"] is None


def test_a_gaussian_method_pooled_from_one_chain_scores_as_its_fit(tmp_path):
    """RVM (a predictive std, no draws) as one chain: the pooled row's proper scores, training error and
    split-conformal coverage equal those of the plain fit job on the same split."""
    feats = _features(tmp_path)
    spec = JobSpec("syn", "act", "RVM", 40, 0, min_test=50)
    rvm = "bsrbench.models.rvm:RVM"
    settings = {"level": 0.9, "params": {}}
    row, _ = run_job(spec, feats, estimator=rvm, params={}, conformal=settings)
    chain = run_chain(spec, feats, estimator=rvm, params={}, chain=0, conformal=settings)
    pooled, arrays = pool_chains(spec, feats, [chain], estimator=rvm, params={})
    assert row["scores_from"] == pooled["scores_from"] == "gaussian"
    for key in ("nlpd", "crps", "train_error", "conformal_coverage", "conformal_level"):
        assert pooled[key] == pytest.approx(row[key], rel=1e-9), key
    assert 0 < row["conformal_coverage"] <= 1 and row["conformal_level"] == 0.9
    assert (
        arrays["conformal_radius"].shape == (5,) and np.isfinite(arrays["conformal_radius"]).all()
    )
    # without a level, no conformal refit
    row, arrays = run_job(spec, feats, estimator=rvm, params={})
    assert row["conformal_coverage"] is None and "conformal_radius" not in arrays


def test_a_chain_keeps_every_draw_of_unequal_weights_and_a_subset_of_equal_ones(tmp_path):
    """Self-normalized likelihood weights can put all their mass on draws that an evenly spaced subset leaves
    out (0/0 weights: hsc golf, PMtextbeta); those chains keep every draw with the model's own weights."""
    from bsrbench.runs import SCORE_DRAWS_PER_CHAIN

    feats = _features(tmp_path)
    spec = JobSpec("syn", "act", "PMtextbeta", 40, 0, min_test=50)
    params = dict(PARAMS, n_iter=120, n_burn_in=20, thin=2)  # 50 retained samples
    uniform = run_chain(spec, feats, estimator=BSR, params=params, chain=0)
    assert uniform["score_weights"].shape[1] == SCORE_DRAWS_PER_CHAIN < 50
    np.testing.assert_allclose(uniform["score_weights"], 1.0 / SCORE_DRAWS_PER_CHAIN)
    weighted = dict(params, prediction="paper-text", prediction_weighting="likelihood")
    c = run_chain(spec, feats, estimator=BSR, params=weighted, chain=0)
    w = c["score_weights"]
    assert w.shape == (c["test"].size, 50) and np.isfinite(w).all()
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=1e-12)
    assert (
        w.max(axis=1) > 1.5 / 50
    ).any()  # unequal: the weights are the likelihood's, not uniform
