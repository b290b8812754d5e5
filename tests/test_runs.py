"""One job on its split: the pose-transform std, the result row, CV (bsrbench.runs)."""

import json

import numpy as np
import pytest
from scipy.stats import norm

from bsrbench import scores as S
from bsrbench.errors import InputError
from bsrbench.io import load_features, write_arrays, write_json
from bsrbench.kinematics import hsc_pose_skeleton, mpjpe, pa_mpjpe
from bsrbench.poses import HeadingTransform
from bsrbench.runs import cross_validate, extra_scores, inverse_std, run_job
from bsrbench.splits import JobSpec

REF = "bsrbench.models.reference"


def test_inverse_std_of_heading_matches_monte_carlo():
    rng = np.random.default_rng(0)
    t = HeadingTransform()
    Z_mean = np.array([[1.0, 2.0, 20 * np.sin(0.7), 20 * np.cos(0.7)]])
    Z_std = np.array([[0.5, 0.25, 0.4, 0.3]])
    sd = inverse_std(t, Z_mean, Z_std)
    assert sd.shape == (1, 3)
    assert np.allclose(sd[0, [0, 1]], [0.5, 0.25])
    draws = Z_mean + Z_std * rng.standard_normal((200000, 4))
    heading = t.inverse(draws)[:, 2]
    assert sd[0, 2] == pytest.approx(np.std(heading), rel=0.02)


def test_run_job_scores_in_degrees_after_undoing_the_transform(tmp_path, synthetic_features):
    feats = load_features(synthetic_features(tmp_path))
    spec = JobSpec("syn", "act", "NN1", 50, 0, min_test=50, paper_activity="Act")
    row, arrays = run_job(
        spec, feats, estimator=f"{REF}:NearestNeighbourRegressor", params={"n_neighbors": 1}
    )
    train, test = spec.split(200)
    assert np.array_equal(arrays["test"], test) and np.array_equal(arrays["train"], train)
    # independent check of the error: 1-NN in feature space, wrapped degrees, RMS per angle, mean
    d2 = ((feats["X"][test][:, None] - feats["X"][train][None]) ** 2).sum(-1)
    pred = feats["Y"][train][d2.argmin(1)]
    diff = (pred - feats["Y"][test] + 180) % 360 - 180
    assert row["error"] == pytest.approx(np.sqrt((diff**2).mean(0)).mean(), rel=1e-9)
    assert row["coverage"] is None and row["n_test"] == test.size and row["paper_activity"] == "Act"
    assert {"fit_seconds", "predict_seconds", "versions", "per_angle_rms", "split_seed"} <= set(row)
    json.dumps(row)  # JSON-ready
    write_json(tmp_path / "r.json", row)
    write_arrays(tmp_path / "p.npz", arrays)
    assert json.loads((tmp_path / "r.json").read_text())["error"] == row["error"]


def test_cross_validate_picks_from_the_grid_and_keeps_fixed_params(tmp_path, synthetic_features):
    feats = load_features(synthetic_features(tmp_path))
    spec = JobSpec("syn", "act", "Ridge", 60, 0, min_test=50)
    res = cross_validate(
        spec,
        feats,
        estimator=f"{REF}:RidgeRegressor",
        params={"standardize": True},
        grid={"alpha": [0.01, 1e6]},
        folds=3,
    )
    assert res["best_params"] == {"standardize": True, "alpha": 0.01}
    assert len(res["cv_results"]) == 2 and res["best_score"] > 0


def test_extra_scores_for_the_job_layer():
    ps = hsc_pose_skeleton()
    rng = np.random.default_rng(7)
    y = rng.uniform(-30, 30, size=(8, 57))
    p = y + rng.normal(scale=4, size=y.shape)
    sd = np.full_like(y, 4.0)
    out = extra_scores(y, p, source="hsc", skeleton=ps)
    assert out["mpjpe_mm"] == pytest.approx(mpjpe(y, p, ps))
    assert out["pa_mpjpe_mm"] == pytest.approx(pa_mpjpe(y, p, ps))
    assert out["nlpd"] is None and out["crps"] is None and out["scores_from"] is None
    g = extra_scores(y, p, source="hsc", skeleton=ps, std=sd)
    assert g["nlpd"] == pytest.approx(-norm.logpdf(p - y, 0, 4).mean())
    assert g["scores_from"] == "gaussian" and g["crps"] > 0
    draws = p[:, None] + 4 * rng.normal(size=(8, 50, 57))
    s = extra_scores(y, p, source="hsc", skeleton=ps, std=sd, samples=draws)
    assert s["scores_from"] == "samples" and s["crps"] == pytest.approx(S.sample_crps(y, draws))
    # the NLPD takes the std when given (the draws' exact moments), the draws' moment match otherwise
    assert s["nlpd"] == pytest.approx(g["nlpd"])
    m = extra_scores(y, p, source="hsc", skeleton=ps, samples=draws)
    assert m["nlpd"] == pytest.approx(S.sample_nlpd(y, draws, p)) and m["nlpd"] != s["nlpd"]
    p[3, 10] = np.nan
    with pytest.raises(InputError, match=r"hsc \(hsc\): y_pred contains NaN at row 3, column 10"):
        extra_scores(y, p, source="hsc", skeleton=ps, std=sd)
    with pytest.raises(InputError, match=r"the skeleton expects 57"):
        extra_scores(y[:, :56], y[:, :56], source="hsc", skeleton=ps)
