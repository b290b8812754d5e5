"""Several MCMC chains per split: chain seeds, pooling of the chains' predictions, R-hat and ESS across
chains, and the convergence tables, ablation table, sentences and trace figures drawn from the aggregate."""

import json
import math
import re

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from bsrbench.convergence import convergence_summary
from bsrbench.errors import InputError
from bsrbench.io import load_features
from bsrbench.models.bsr import BayesianSR
from bsrbench.poses import get_pose_transform
from bsrbench.reporting import convergence as conv
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


# ------------------------------------------------------------------------------------------- reporting
def _aggregate():
    rows = []
    for m, err, rhat in (
        ("PM", 9.0, 1.3),
        ("PMK16", 6.0, 1.01),
        ("NN1", 7.0, None),
        ("SR", 5.5, None),
    ):
        for n in (30, 100):
            for seed in (100, 101):
                r = {
                    "protocol": "contiguous",
                    "source": "hsc",
                    "activity": "golf",
                    "paper_activity": "Golf",
                    "method": m,
                    "n_train": n,
                    "seed": seed,
                    "error": err + 0.1 * seed - 10 + (n == 100),
                }
                if rhat is not None:
                    r.update(
                        n_chains=4,
                        r_hat_log_likelihood=rhat,
                        r_hat_g_xy=rhat + 0.05 * (seed - 100),
                        ess_bulk_log_likelihood=100.0 + seed,
                    )
                rows.append(r)
    return conv.with_convergence_columns(pd.DataFrame(rows))


def _paper():
    return pd.DataFrame(
        {
            "table": "I",
            "activity": "Golf",
            "n_train": [30, 100],
            "method": "PM",
            "mean_deg": [8.24, 3.93],
            "std_deg": [1.0, 1.0],
            "key": "golf",
        }
    )


def test_convergence_columns_and_summary():
    df = _aggregate()
    assert set(conv.CONVERGENCE_COLUMNS) <= set(df.columns)
    assert df.loc[df["method"] == "NN1", "r_hat_g_xy"].isna().all()
    t = conv.convergence_summary_table(df).set_index(["method", "n_train"])
    assert t.at[("PM", 30), "r_hat_log_likelihood"] == 1.3
    assert t.at[("PMK16", 30), "r_hat_g_xy"] == pytest.approx(1.06)  # the largest over splits
    assert t.at[("PMK16", 30), "ess_bulk_log_likelihood"] == 200.0  # the smallest over splits
    assert t.at[("PMK16", 30), "converged"] == 0.5 and t.at[("PM", 100), "converged"] == 0.0
    tex = conv.convergence_latex(df, labels={"PM": "PM", "PMK16": "PM K=16"})
    assert "PM K=16 & 30 & 2 & 4 & 1.01 & 1.06" in tex


def test_ablation_table_bolds_the_best_and_shows_the_references():
    df = _aggregate()
    tex = conv.ablation_latex(df, _paper(), variants=["PM", "PMK16"], labels={"NN1": "1-NN"})
    lines = tex.splitlines()
    sr_line = next(ln for ln in lines if ln.startswith("best other method"))
    assert r"\textbf{5.55}" in sr_line and "(SR)" in sr_line  # SR is the best of each column
    assert not any(r"\textbf" in ln for ln in lines if ln.startswith("PMK16"))
    assert any(
        ln.startswith(r"\emph{paper's PM}") and "8.24" in ln and "3.93" in ln for ln in lines
    )
    # the std prints smaller than the mean: one size below the table's \footnotesize (it was {\small ...})
    assert "\\footnotesize" in tex and set(re.findall(r"\$\\pm\$ \{\\([a-z]+) ", tex)) == {
        "scriptsize"
    }


def test_sentences_count_the_cells_where_a_variant_beats_1nn():
    text = " ".join(
        conv.why_pm_sentences(_aggregate(), _paper(), variants=["PM", "PMK16"], labels={})
    )
    assert "beats NN1 in 2 of 2 cells" in text  # PMK16 (6.05, 7.05) < NN1 (7.05, 8.05)
    assert "lower in 0 of 2 cells" in text  # SR is better still
    assert "Convergence" in text and "PMK16 50\\%" in text and "PM 0\\%" in text
    df = _aggregate()
    df.loc[df["method"] == "PMK16", ["r_hat_log_likelihood", "r_hat_g_xy"]] = 1.0
    text = " ".join(conv.why_pm_sentences(df, _paper(), variants=["PM", "PMK16"], labels={}))
    assert "three quarters of their cells (the goal): PMK16." in text


def test_goal_table_counts_converged_cells_below_1nn_and_flags_inexact_variants():
    df = _aggregate()
    # PMK16 converges in every split at N = 30 only; PM (1.3) nowhere
    df.loc[
        (df["method"] == "PMK16") & (df["n_train"] == 30), ["r_hat_log_likelihood", "r_hat_g_xy"]
    ] = 1.02
    # an inexact variant: lowest error and converged everywhere, but the paper's printed ratio
    lit = df[df["method"] == "PMK16"].copy()
    lit["method"], lit["error"] = "PMprinted", lit["error"] - 3.0
    lit[["r_hat_log_likelihood", "r_hat_g_xy"]] = 1.0
    lit["params"] = '{"n_atoms": 64, "w_update": "paper-printed-ratio"}'
    df = pd.concat([df, lit], ignore_index=True)
    df["params"] = df["params"].fillna('{"n_atoms": 64}')
    t = conv.goal_table(df, variants=["PM", "PMK16", "PMprinted"]).set_index("method")
    assert t.at["PMK16", "exact"] and not t.at["PMprinted", "exact"] and t.at["PM", "exact"]
    assert t.at["PMK16", "cells"] == 2 and t.at["PMK16", "converged"] == 1
    assert t.at["PMK16", "beats_nn"] == 2 and t.at["PMK16", "both"] == 1
    assert t.at["PM", "converged"] == 0 and t.at["PM", "beats_nn"] == 0 and t.at["PM", "both"] == 0
    assert t.at["PMprinted", "both"] == 2 and t.at["PMprinted", "mean_rank"] == 1.0
    # exact variants first, then by cells with both: the inexact one never heads the table
    assert list(conv.goal_table(df, variants=["PM", "PMK16", "PMprinted"])["method"]) == [
        "PMK16",
        "PM",
        "PMprinted",
    ]
    text = conv.goal_sentence(df, variants=["PM", "PMK16", "PMprinted"], labels={"NN1": "1-NN"})
    assert (
        "closest to the goal is PMK16" in text
        and "in 1 of 2 cells" in text
        and "does not meet" in text
    )
    tex = conv.goal_latex(df, variants=["PM", "PMK16", "PMprinted"], labels={"NN1": "1-NN"})
    assert "PMprinted & no & 2 & 2 & 2 & 2 & 1.0" in tex and "PMK16 & yes & 2 & 1 & 2 & 1" in tex
    # the sentence of variants that converge and beat 1-NN leaves out inexact ones
    text = " ".join(
        conv.why_pm_sentences(df, _paper(), variants=["PM", "PMK16", "PMprinted"], labels={})
    )
    assert "three quarters of their cells (the goal): none." in text
    df.loc[df["method"] == "PMK16", ["r_hat_log_likelihood", "r_hat_g_xy"]] = 1.0
    assert "meets the goal" in conv.goal_sentence(df, variants=["PM", "PMK16"], labels={})
    # the bullet and the goal sentence count the goal alike: 3 of 4 cells converged and below 1-NN meets it
    # (before, the bullet also required every split of every cell to converge)
    four = pd.concat(
        [df[df["method"].isin(["PMK16", "NN1"])].assign(activity=a) for a in ("golf", "run")],
        ignore_index=True,
    )
    four.loc[
        (four["method"] == "PMK16") & (four["activity"] == "run") & (four["n_train"] == 100),
        ["r_hat_log_likelihood", "r_hat_g_xy"],
    ] = 1.3
    assert "meets the goal of at least 3 cells" in conv.goal_sentence(
        four, variants=["PMK16"], labels={}
    )
    bullets = " ".join(conv.why_pm_sentences(four, None, variants=["PMK16"], labels={}))
    assert "three quarters of their cells (the goal): PMK16." in bullets
    no_nn = four[four["method"] != "NN1"]
    assert conv.goal_sentence(no_nn, variants=["PMK16"], labels={}) == (
        "Protocol ``contiguous'': NN1 was not run, so the goal is not judged."
    )
    # one chain per split (the quick study): no R-hat, so no goal table, not "converged in 0 of 2 cells"
    one = df.copy()
    one.loc[one["method"] == "PM", ["n_chains", "r_hat_log_likelihood", "r_hat_g_xy"]] = [
        1,
        np.nan,
        np.nan,
    ]
    assert list(conv.goal_table(one, variants=["PM", "PMK16"])["method"]) == ["PMK16"]
    one.loc[one["method"] == "PMK16", ["n_chains", "r_hat_log_likelihood", "r_hat_g_xy"]] = [
        1,
        np.nan,
        np.nan,
    ]
    assert conv.goal_table(one, variants=["PM", "PMK16"]).empty
    assert "The goal" not in conv.why_pm_section(
        one, _paper(), variants=["PM", "PMK16"], labels={}, figures=[]
    )


def test_pm_against_the_paper_is_like_for_like_or_not_at_all():
    """Before: contiguous-protocol errors were set against the paper's random-frame numbers, with medians over
    hsc and mocap together."""
    df = _aggregate()  # contiguous only
    text = " ".join(conv.why_pm_sentences(df, _paper(), variants=["PM", "PMK16"], labels={}))
    assert "against the paper's 8.24" not in text
    assert (
        "The paper's numbers are for random frames; this study ran only the contiguous protocol, so PM is not "
        "compared with the paper's PM like for like."
    ) in text
    rnd = df.copy()
    rnd["protocol"] = "random"
    rnd.loc[rnd["method"] == "PM", "error"] += (
        10  # contiguous PM stays at ~9-10: must not enter the medians
    )
    mocap = rnd.copy()
    mocap["source"] = "mocap"
    mocap["error"] /= 4
    both = pd.concat([df, rnd, mocap], ignore_index=True)
    text = " ".join(conv.why_pm_sentences(both, _paper(), variants=["PM", "PMK16"], labels={}))
    assert (
        "PM here against the paper's PM (random protocol, as in the paper; median over activities): "
        "on the hsc data, $N=30$: 19.05 against the paper's 8.24; $N=100$: 20.05 against the paper's 3.93; "
        "on the mocap data, $N=30$: 4.76 against the paper's 8.24; $N=100$: 5.01 against the paper's 3.93 "
        "degrees."
    ) in text
    assert "like for like" not in text


def test_gxy_caption_describes_the_panels_drawn():
    """Before: the caption was fixed text naming three panels (K >= N, K < N, a proper Gamma prior) although the
    CI ablation draws two (PM, PMK16)."""
    rows = [
        {"protocol": "contiguous", "method": m, "n_train": 30, "params": json.dumps(p)}
        for m, p in (
            ("PM", {"n_atoms": 64}),
            ("PMK16", {"n_atoms": 16}),
            ("PMgxy", {"n_atoms": 64, "a_xy": 1.0, "b_xy": 2.0}),
        )
    ]
    df = pd.DataFrame(rows)
    two = conv.gxy_caption(
        df, ["PM", "PMK16"], protocol="contiguous", n_train=30, labels={"PMK16": "PM K=16"}
    )
    assert "Gamma" not in two and "the 2 methods" in two
    assert (
        "PM: $K = 64 \\geq N = 30$ (a code set can interpolate the training pairs); "
        "PM K=16: $K = 16 < N = 30$."
    ) in two
    three = conv.gxy_caption(
        df, ["PM", "PMK16", "PMgxy"], protocol="contiguous", n_train=30, labels={}
    )
    assert "the 3 methods" in three
    assert (
        "PMgxy: $K = 64 \\geq N = 30$ (a code set can interpolate the training pairs), "
        "with a proper Gamma(1, 2)"
    ) in three
    assert conv.gxy_panel({"n_atoms": 16}, 30) == (16, "<", None)


def test_trace_figure_overlays_chains_and_has_no_empty_panel():
    rng = np.random.default_rng(0)
    arrays = {
        "chain_trace_log_likelihood": rng.normal(size=(4, 60)),
        "chain_trace_g_xy": np.exp(rng.normal(size=(4, 60))),
        "chain_trace_g_s": np.exp(rng.normal(size=(4, 60))),
        "chain_trace_acceptance": np.ones((4, 60)),  # elliptical slice sampling: constant, no panel
        "chain_draw_error": rng.normal(size=(4, 10)),
        "n_burn_in": np.int64(30),
    }
    fig = conv.plot_chain_traces(arrays, title="t")
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 4 and all(ax.has_data() for ax in axes)
    titles = {ax.get_title(): ax for ax in axes}
    assert titles[conv.TRACE_LABELS["g_xy"]].get_yscale() == "log"
    assert titles[conv.TRACE_LABELS["log_likelihood"]].get_yscale() == "linear"
    assert all(len(ax.get_lines()) >= 4 for ax in axes)  # one line per chain
    # active atoms is a count: whole-number ticks even over a narrow range (it had 62.5)
    atoms = conv.plot_chain_traces(
        {"chain_trace_active_atoms": 62 + rng.integers(0, 2, size=(2, 60)).astype(float)},
        title="atoms",
    )
    atoms.canvas.draw()
    lo, hi = atoms.axes[0].get_ylim()
    ticks = [v for v in atoms.axes[0].get_yticks() if lo <= v <= hi]
    assert len(ticks) >= 2 and all(float(v).is_integer() for v in ticks), ticks
    one = conv.plot_chain_traces(
        {"trace_g_xy": np.exp(rng.normal(size=50))}, title="one chain", n_burn_in=10
    )
    assert len([ax for ax in one.axes if ax.get_visible()]) == 1


def _labelled_ticks(ax):
    """Values of the labelled y ticks inside the drawn axis's limits (major and minor)."""
    lo, hi = ax.get_ylim()
    out = []
    for minor in (False, True):
        for t in ax.get_yticklabels(minor=minor):
            v = t.get_position()[1]
            if t.get_text() and lo <= v <= hi:
                assert float(t.get_text()) == pytest.approx(v, rel=1e-6)
                out.append(v)
    return sorted(out)


def test_log_trace_axes_are_labelled_across_their_range():
    """Before: the g_xy axes (log) labelled only 1, 2, 3, 5 (or every integer) times a power of ten, so a trace
    between 7 and 18 had no label above 10. Now at least four labels spread over the range, for the shared axis
    of the g_xy figure (limits set by the last panel) and for a trace over seven decades."""
    rng = np.random.default_rng(1)
    narrow = {"chain_trace_g_xy": 7.0 + 11.0 * rng.random((2, 80)), "n_burn_in": np.int64(20)}
    narrow["chain_trace_g_xy"][0, :2] = [7.0, 18.0]
    wide = {"trace_g_xy": np.geomspace(30.0, 5e7, 80)}
    figs = [
        conv.plot_gxy([("PM", narrow), ("PMK16", narrow)]),
        conv.plot_chain_traces(wide, title="wide"),
    ]
    for fig in figs:
        fig.canvas.draw()
        axes = [a for a in fig.axes if a.get_visible() and a.get_yscale() == "log"]
        assert axes
        for ax in axes:
            if len(ax.get_shared_y_axes().get_siblings(ax)) > 1 and ax is not axes[0]:
                continue  # an inner panel of a shared axis: labelled on the first panel only
            lo, hi = ax.get_ylim()
            ticks = _labelled_ticks(ax)
            assert len(ticks) >= 4, ticks
            logs = np.log10([lo, *ticks, hi])
            assert np.diff(logs).max() <= 0.4 * (logs[-1] - logs[0]) + 1e-9, (lo, hi, ticks)
            if hi > 12:
                assert max(ticks) > 10, ticks
        plt.close(fig)


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
