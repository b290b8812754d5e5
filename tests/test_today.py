"""The section "Today's metrics and baselines": MPJPE tables, PM's standing against today's baselines, the
uncertainty table, PIT histograms and the two blocks of Tables I-II, against hand computations."""

import numpy as np
import pandas as pd
import pytest

from bsrbench.reporting import today
from bsrbench.reporting.latex import power_of_ten
from bsrbench.reporting.tables import latex_tables, summarize, table_blocks


def _rows():
    rows = []
    for seed in (0, 1):
        for method, err, mp, nlpd in (
            ("PM", 5.0, 40.0, 3.0),
            ("NN1", 4.0, 30.0, None),
            ("GP", 3.0 + seed, 20.0 + seed, 2.0 + seed),
        ):
            rows.append(
                {
                    "protocol": "random",
                    "source": "hsc",
                    "activity": "golf",
                    "paper_activity": "Golf",
                    "method": method,
                    "n_train": 30,
                    "seed": seed,
                    "error": err,
                    "mpjpe_mm": mp,
                    "pa_mpjpe_mm": mp / 2,
                    "nlpd": nlpd,
                    "crps": None if nlpd is None else nlpd + 1,
                    "coverage_90": None if nlpd is None else 0.8,
                    "conformal_coverage": None if nlpd is None else 0.9,
                }
            )
    return pd.DataFrame(rows)


def test_position_table_gives_the_mean_over_seeds_and_bolds_the_best():
    t = today.position_table(
        _rows(),
        source="hsc",
        protocol="random",
        methods=["PM", "NN1", "GP"],
        labels={"GP": "GP (ARD)"},
    )
    assert "Golf & 30 & 40.0 & 30.0 & \\textbf{20.5}" in t  # GP: mean of 20 and 21
    pa = today.position_table(
        _rows(),
        source="hsc",
        protocol="random",
        methods=["PM", "GP"],
        labels={},
        column="pa_mpjpe_mm",
    )
    assert "PA-MPJPE" in pa and "20.0 & \\textbf{10.2}" in pa  # 10.25 rounds half to even
    assert (
        today.position_table(_rows(), source="mocap", protocol="random", methods=["PM"], labels={})
        is None
    )


def test_scores_summary_skips_methods_without_a_predictive_distribution():
    s = today.scores_summary(_rows(), methods=["PM", "NN1", "GP"])
    assert list(s["method"]) == ["PM", "GP"]
    gp = s.set_index("method").loc["GP"]
    assert gp["nlpd"] == pytest.approx(2.5) and gp["crps"] == pytest.approx(3.5) and gp["n"] == 2
    text = today.scores_latex(s, labels={"GP": "GP (ARD)"})
    assert "random & hsc & GP (ARD) & 3.50 & 2.50 & 2.50 & 3.50 & 0.80 & 0.90" in text
    assert (
        gp["nlpd_median"] == pytest.approx(2.5) and power_of_ten(696966.9) == r"$6.97\times 10^{5}$"
    )


def test_standing_counts_cells_by_the_sign_and_the_holm_p():
    comp = pd.DataFrame(
        {
            "protocol": "random",
            "source": "hsc",
            "activity": ["a", "b", "c", "d", "a"],
            "n_train": 30,
            "method": ["GP", "GP", "GP", "GP", "KNN"],
            "versus": "PM",
            # error(method) - error(PM): negative = the baseline is better, so PM is worse
            "mean_diff": [-1.0, -0.5, 0.7, 0.2, 1.0],
            "p_holm": [0.01, 0.20, 0.04, np.nan, 0.5],
        }
    )
    st = today.standing(comp, today=["GP", "KNN"]).set_index("method")
    assert st.loc["GP", ["worse", "tied", "better"]].tolist() == [
        1,
        1,
        1,
    ]  # the untested cell counts nowhere
    assert st.loc["KNN", ["worse", "tied", "better"]].tolist() == [0, 1, 0]
    (sentence,) = today.standing_sentences(st.reset_index(), labels={"GP": "GP (ARD)"})
    assert "GP (ARD) 1/1/1; KNN 0/1/0" in sentence


def test_pit_histogram_of_uniform_values_is_flat():
    rng = np.random.default_rng(0)
    h = today.pit_histograms(rng.uniform(size=100_000), bins=10)
    assert h.shape == (10,) and np.allclose(h, 1.0, atol=0.03)
    assert np.allclose(today.pit_histograms(np.full(10, 0.05), bins=10), [10] + [0] * 9)


def test_the_today_block_sits_beside_pm_and_bold_is_the_best_of_both_blocks():
    groups = {"PM": "paper", "NN1": "paper", "GP": "today"}
    assert table_blocks(["PM", "NN1", "GP"], groups) == [
        (None, ["PM", "NN1"]),
        ("today's baselines", ["PM", "GP"]),
    ]
    assert table_blocks(["PM", "NN1"], groups) == [(None, ["PM", "NN1"])]
    paper = pd.DataFrame(columns=["table", "key", "n_train", "method", "mean_deg", "std_deg"])
    text = latex_tables(
        summarize(_rows()),
        paper,
        methods=["PM", "NN1", "GP"],
        groups=groups,
        source="hsc",
        table="I",
        labels={},
        n_train=[30],
        status={"Golf": "golf"},
        protocols=["random"],
    )
    first, second = text.split("(today's baselines)")
    assert (
        "\\textbf" not in first.split("\\toprule")[1]
    )  # GP (3.5) beats NN1 (4.0): no bold in block 1
    assert "\\textbf{3.50}" in second and "tab:I-hsc-random-today" in second


def test_readme_summary_is_the_mean_over_cells_with_ranks_and_the_paper_s_mean(tmp_path):
    from bsrbench.reporting.published import readme_summary, update_readme

    rows = []
    for activity, paper_activity in (("golf", "Golf"), ("run", "Run")):
        for seed in (0, 1):
            for method, err in (("PM", 5.0), ("SR", 4.0), ("GP", 3.0)):
                e = err + (1.0 if activity == "run" else 0.0) + 0.1 * seed
                if activity == "run" and method == "SR":
                    e = 2.0 + 0.1 * seed  # SR best on run: ranks SR 1, GP 2, PM 3
                rows.append(
                    dict(
                        protocol="random",
                        source="hsc",
                        activity=activity,
                        paper_activity=paper_activity,
                        method=method,
                        n_train=30,
                        seed=seed,
                        error=e,
                        mpjpe_mm=10 * e,
                        n_test=100,
                    )
                )
    df = pd.DataFrame(rows)
    paper = pd.DataFrame(
        {
            "table": ["I", "II", "I", "II"],
            "key": ["golf", "run", "golf", "run"],
            "n_train": 30,
            "method": ["PM", "PM", "SR", "SR"],
            "mean_deg": [8.0, 6.0, 10.0, 12.0],
            "std_deg": 1.0,
        }
    )
    text = readme_summary(df, paper, labels={"GP": "GP (ARD)"})
    lines = {ln.split(" | ")[0]: ln for ln in text.splitlines() if ln.startswith("| ")}
    # PM: errors 5.05 (golf) and 6.05 (run) -> 5.55; paper (8 + 6) / 2 = 7; ranks 3 and 3
    assert lines["| PM"].startswith("| PM | 5.55 (7.00) | 55.5 | 3.0 |")
    # SR: 4.05 and 2.05 -> 3.05; ranks 2 and 1 -> 1.5
    assert lines["| SR"].startswith("| SR | 3.05 (11.00) | 30.5 | 1.5 |")
    # today's baseline in italics, no paper number
    assert lines["| *GP (ARD)*"].startswith("| *GP (ARD)* | 3.55 | 35.5 | 1.5 |")
    readme = tmp_path / "README.md"
    readme.write_text("a\n<!-- results-summary -->\nSTALE\n<!-- /results-summary -->\nb\n")
    update_readme(
        readme, {"hsc": "TABLE"}, None, text
    )  # no table markers: the summary alone is written
    assert "STALE" not in readme.read_text() and "| PM | 5.55" in readme.read_text()


def test_pit_panels_pool_the_fits_of_each_source_and_method():
    fits = [{"pit": np.array([[0.1, 0.2]])}, {"pit": np.array([0.9])}, {}, {"pit": [0.5]}]
    keys = [["hsc", "PM"], ("hsc", "PM"), ("hsc", "NN1"), ("mocap", "PM")]
    panels = today.pit_panels(fits, keys)
    assert sorted(panels) == [("hsc", "PM"), ("mocap", "PM")]  # NN1 saved no PIT values: no panel
    np.testing.assert_array_equal(panels[("hsc", "PM")], [0.1, 0.2, 0.9])
    np.testing.assert_array_equal(panels[("mocap", "PM")], [0.5])
