"""The convergence summary, its LaTeX, the g_xy caption and the trace figures (bsrbench.reporting.convergence)."""

import json

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from reportdata import chained_aggregate

from bsrbench.reporting import ablation as abl
from bsrbench.reporting import convergence as conv


def _chained(rhats, *, extra=None):
    """Rows of PMK16 and NN1 (golf, contiguous, N = 30), one per split, PMK16 with 4 chains and these R-hats of
    the log-likelihood and g_xy; ``extra``: {column: value per split} (tail ESS, MCSE)."""
    rows = []
    for seed, (rl, rg) in enumerate(rhats):
        base = dict(
            protocol="contiguous", source="hsc", activity="golf", paper_activity="Golf", n_train=30
        )
        rows.append(dict(base, method="NN1", seed=seed, error=7.0))
        r = dict(
            base,
            method="PMK16",
            seed=seed,
            error=6.0,
            n_chains=4,
            r_hat_log_likelihood=rl,
            r_hat_g_xy=rg,
            ess_bulk_log_likelihood=300.0 + seed,
            ess_bulk_test_error=200.0 + seed,
            params='{"n_atoms": 16}',
        )
        for k, v in (extra or {}).items():
            r[k] = v[seed]
        rows.append(r)
    return conv.with_convergence_columns(pd.DataFrame(rows))


def test_convergence_at_both_thresholds_with_tail_ess_and_mcse():
    # splits: both below 1.01; 1.02 (below 1.05 only); 1.005 and 1.2 (neither)
    df = _chained([(1.001, 1.009), (1.02, 1.0), (1.005, 1.2)])
    t = conv.convergence_summary_table(df).set_index("method")
    assert t.at["PMK16", "converged"] == pytest.approx(2 / 3)
    assert t.at["PMK16", "converged_strict"] == pytest.approx(1 / 3)
    assert np.isnan(t.at["PMK16", "ess_tail_log_likelihood"]) and np.isnan(
        t.at["PMK16", "mcse_test_error"]
    )
    tex = conv.convergence_latex(df, labels={})
    row = next(ln for ln in tex.splitlines() if ln.startswith("PMK16 &"))
    # R-hat l, g_xy, g_s, err; bulk ESS l, err; tail ESS l, err; MCSE err; shares < 1.01, < 1.05
    assert row == (
        r"PMK16 & 30 & 3 & 4 & 1.02 & 1.20 & -- & -- & 300 & 200 & -- & -- & -- & 33\% & 67\% \\"
    )
    assert r"$\hat R < 1.01$ (Vehtari et al.\ 2021) and $< 1.05$" in tex
    # with the per-job tail ESS and MCSE columns: the smallest tail ESS and the largest MCSE over splits
    df = _chained(
        [(1.001, 1.009), (1.02, 1.0), (1.005, 1.2)],
        extra={
            "ess_tail_log_likelihood": [150.0, 90.0, 120.0],
            "ess_tail_test_error": [80.0, 95.0, 70.0],
            "mcse_test_error": [0.012, 0.034, 0.021],
        },
    )
    t = conv.convergence_summary_table(df).set_index("method")
    assert (
        t.at["PMK16", "ess_tail_log_likelihood"] == 90.0
        and t.at["PMK16", "mcse_test_error"] == 0.034
    )
    row = next(
        ln for ln in conv.convergence_latex(df, labels={}).splitlines() if ln.startswith("PMK16 &")
    )
    assert "& 300 & 200 & 90 & 70 & 0.034 & 33\\% & 67\\%" in row
    # the goal table keeps 1.05 and adds 1.01: one cell, converged at 1.05 only if every split is
    g = abl.goal_table(_chained([(1.001, 1.009), (1.02, 1.0)]), variants=["PMK16"]).iloc[0]
    assert (g["converged"], g["both"], g["converged_strict"], g["both_strict"]) == (1, 1, 0, 0)
    g = abl.goal_table(_chained([(1.001, 1.009), (1.002, 1.0)]), variants=["PMK16"]).iloc[0]
    assert (g["converged_strict"], g["both_strict"]) == (1, 1)
    tex = abl.goal_latex(_chained([(1.001, 1.009), (1.02, 1.0)]), variants=["PMK16"], labels={})
    assert "PMK16 & yes & 1 & 1 & 1 & 1 & 1.0 & 0 & 0" in tex and r"$\hat R < 1.01$" in tex
    text = abl.goal_sentence(_chained([(1.001, 1.009), (1.02, 1.0)]), variants=["PMK16"], labels={})
    assert r"At $\hat R < 1.01$ every split converged in 0 of its cells" in text


def test_convergence_columns_and_summary():
    df = chained_aggregate()
    assert set(conv.CONVERGENCE_COLUMNS) <= set(df.columns)
    assert df.loc[df["method"] == "NN1", "r_hat_g_xy"].isna().all()
    t = conv.convergence_summary_table(df).set_index(["method", "n_train"])
    assert t.at[("PM", 30), "r_hat_log_likelihood"] == 1.3
    assert t.at[("PMK16", 30), "r_hat_g_xy"] == pytest.approx(1.06)  # the largest over splits
    assert t.at[("PMK16", 30), "ess_bulk_log_likelihood"] == 200.0  # the smallest over splits
    assert t.at[("PMK16", 30), "converged"] == 0.5 and t.at[("PM", 100), "converged"] == 0.0
    tex = conv.convergence_latex(df, labels={"PM": "PM", "PMK16": "PM K=16"})
    assert "PM K=16 & 30 & 2 & 4 & 1.01 & 1.06" in tex


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


def test_saved_fit_finds_the_row_of_a_fit_file():
    df = pd.DataFrame(
        [
            dict(
                protocol="random",
                source="hsc",
                activity="golf",
                method="PM",
                n_train=30,
                seed=s,
                params=json.dumps({"n_atoms": 10 + s}),
            )
            for s in (0, 1)
        ]
    )
    key, params = conv.saved_fit(df, "results/s/fit/random/hsc/golf/PM/n30/seed1.npz")
    assert key == dict(
        protocol="random", source="hsc", activity="golf", method="PM", n_train=30, seed=1
    )
    assert params == {"n_atoms": 11}
    assert conv.saved_fit(df, "results/s/fit/random/hsc/golf/PM/n60/seed1.npz")[1] == {}
