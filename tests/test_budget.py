"""PM with a fair budget beside the headline PM (bsrbench.reporting.budget): per-cell means, R-hat and the paired
comparison checked by hand; the generated tables of docs/results.md equal what the published tables give."""

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from bsrbench.errors import InputError
from bsrbench.reporting import budget, headline, reconcile
from bsrbench.reporting.published import main, reconcile_markdown

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "reports" / "published"
PAPER = pd.DataFrame(
    [("I", "Golf", n, "PM", 10.0, 2.0) for n in (30, 60)],
    columns=["table", "activity", "n_train", "method", "mean_deg", "std_deg"],
).assign(key="golf")


def _rows(name, n, errors, **extra):
    return [
        dict(
            source="hsc",
            activity="golf",
            paper_activity="Golf",
            n_train=n,
            seed=s,
            error=e,
            name=name,
        )
        | {k: v[s] if isinstance(v, list) else v for k, v in extra.items()}
        for s, e in enumerate(errors)
    ]


def test_cells_are_means_r_hats_and_holm_adjusted_paired_tests_by_hand():
    fair30, pm30 = [5.0, 5.2, 4.9, 5.1, 5.0], [7.0, 7.3, 6.8, 7.1, 7.2]
    fair60, pm60 = [6.0, 6.4, 5.8, 6.1, 6.2], [6.1, 6.2, 6.0, 6.3, 5.9]
    rows = pd.DataFrame(
        _rows("PM", 30, pm30)
        + _rows("PM", 60, pm60)
        + _rows("1-NN", 30, [6.0] * 5)
        + _rows("1-NN", 60, [6.5] * 5)
        + _rows("SR", 30, [5.5] * 5)
        + _rows("TGP", 30, [5.4, 5.6, 5.4, 5.6, 5.5])
        + _rows("SR", 60, [5.0] * 5)
        + _rows(
            "PM (fair budget)",
            30,
            fair30,
            r_hat_test_error=[1.0, 1.02, 1.005, 1.3, 1.01],
            train_error=1.0,
            params='{"n_atoms": 64, "n_neighbors": 5, "b_xy": 1e-06}',
        )
        + _rows(
            "PM (fair budget)",
            60,
            fair60,
            r_hat_test_error=1.0,
            train_error=2.0,
            params='{"n_atoms": 128, "n_neighbors": 3, "b_xy": 1.0}',
        )
    )
    c = budget.cells(rows, ["PM", "PM (fair budget)"], PAPER).set_index("n_train")
    assert c.loc[30, "fair"] == pytest.approx(np.mean(fair30))
    assert c.loc[30, "pm"] == pytest.approx(np.mean(pm30))
    assert c.loc[30, "best"] == "TGP" and c.loc[30, "best_error"] == pytest.approx(5.5)
    assert c.loc[60, "best"] == "SR" and c.loc[60, "nn"] == pytest.approx(6.5)
    assert c.loc[30, "r_hat_median"] == pytest.approx(1.01) and c.loc[30, "r_hat_max"] == 1.3
    assert c.loc[30, "converged"] == 3 and c.loc[60, "converged"] == 5
    assert c.loc[30, "choice"] == "K 64, j 5, b 1e-06" and c.loc[60, "choice"] == "K 128, j 3, b 1"
    assert c.loc[30, "paper_pm"] == 10.0
    # by hand: paired t over the seeds per cell, Holm over the two cells
    p30, p60 = stats.ttest_rel(fair30, pm30).pvalue, stats.ttest_rel(fair60, pm60).pvalue
    lo, hi = sorted([p30, p60])
    holm = {lo: 2 * lo, hi: max(2 * lo, hi)}
    assert c.loc[30, "p_holm"] == pytest.approx(holm[p30])
    assert c.loc[60, "p_holm"] == pytest.approx(holm[p60])
    assert holm[p30] < 0.05 <= holm[p60]
    assert (c.loc[30, "fair_vs_pm"], c.loc[60, "fair_vs_pm"]) == ("better", "tied")
    text = budget.markdown(c.reset_index(), [])
    assert (
        "| hsc golf N = 30 | 7.08 | 5.04 | 1.00 | 10.00 | 6.00 | 5.50 (TGP) | 1.010, 1.300 |"
        in text
    )
    assert "8 of 10 splits" in text and "better 1, tied 1, worse 0" in text


def test_across_motions_the_unit_is_the_distinct_motion_by_hand():
    """Three motions, one of them seen by both sources (hsc run and mocap run): the motion's error is the mean of
    its cells, the fair PM's difference to each method is tested over the 3 motions (two-sided Wilcoxon, Holm
    over the methods) and shown with its bootstrap interval; with 3 motions no p can reach 0.05."""
    fair = "PM (fair budget)"
    cells_ = [("hsc", "golf"), ("hsc", "run"), ("mocap", "run"), ("mocap", "walk")]
    err = {fair: [5.0, 6.0, 8.0, 7.0], "SR": [4.0, 5.5, 6.5, 6.0], "1-NN": [6.0, 7.0, 9.0, 6.5]}
    rows = pd.DataFrame(
        [
            dict(protocol="random", source=s, activity=a, n_train=30, seed=seed, name=m, error=e[k])
            for m, e in err.items()
            for k, (s, a) in enumerate(cells_)
            for seed in range(2)
        ]
    )
    motions = {(s, a): a for s, a in cells_}  # hsc run and mocap run: one motion
    v = budget.across_motions(rows, fair, motions)
    assert set(v.index) == {"SR", "1-NN"} and (v["n_blocks"] == 3).all()
    # by hand: motion means (run: the mean of its two cells), fair minus each method
    d_sr = np.array([5.0 - 4.0, (6.0 + 8.0) / 2 - (5.5 + 6.5) / 2, 7.0 - 6.0])
    d_nn = np.array([5.0 - 6.0, (6.0 + 8.0) / 2 - (7.0 + 9.0) / 2, 7.0 - 6.5])
    assert v.loc["SR", "mean_diff"] == pytest.approx(d_sr.mean())
    assert v.loc["1-NN", "mean_diff"] == pytest.approx(d_nn.mean())
    assert v.loc["SR", "versus_worse_blocks"] == 3 and v.loc["1-NN", "versus_worse_blocks"] == 1
    p = [stats.wilcoxon(d_sr).pvalue, stats.wilcoxon(d_nn).pvalue]
    lo = min(p)
    holm = [max(2 * lo, x) if x != lo else 2 * lo for x in p]
    assert v.loc["SR", "p_wilcoxon_holm"] == pytest.approx(min(1.0, holm[0]))
    assert v.loc["1-NN", "p_wilcoxon_holm"] == pytest.approx(min(1.0, holm[1]))
    assert v.loc["SR", "diff_ci_low"] <= d_sr.mean() <= v.loc["SR", "diff_ci_high"]
    lines, reach = budget._motions_markdown(v, fair)
    assert lines[0].startswith("Across the 3 distinct motions")
    assert f"| SR | +{d_sr.mean():.2f} [" in "\n".join(lines) and "| 3 of 3 |" in "\n".join(lines)
    # 3 motions, 2 methods: the smallest two-sided Holm p is 2 * 2 * 2**-3 = 0.5
    assert reach.startswith(
        "With 3 motions and Holm over 2 methods the smallest possible p is 0.5: no test"
    )


def test_a_table_pair_without_both_pms_is_refused():
    rows = pd.DataFrame(_rows("PM", 30, [1.0, 2.0]))
    with pytest.raises(InputError, match="expected the headline PM and one fair-budget PM"):
        budget.cells(rows, ["PM"], PAPER)


def _block_is_fresh(tmp_path, block, text):
    """The block ``block`` of docs/results.md, regenerated from ``text``, leaves the file unchanged."""
    copy = tmp_path / "results.md"
    shutil.copy(ROOT / "docs" / "results.md", copy)
    headline.update_blocks(copy, {block: text}, required={block: block})
    assert copy.read_text() == (ROOT / "docs" / "results.md").read_text(), (
        f"docs/results.md's <!-- {block} --> block differs from the published table's; run "
        f"python -m bsrbench.reporting.published ... --update docs/results.md"
    )


@pytest.mark.parametrize("study", ["reconcile", "reconcile-pm"])
def test_the_reconciliation_tables_of_the_docs_are_the_published_tables(tmp_path, study):
    _block_is_fresh(tmp_path, study, reconcile_markdown(PUBLISHED / f"{study}.csv"))


def test_the_fair_budget_table_of_the_docs_is_the_published_table(tmp_path):
    table = PUBLISHED / "paper-pmfair.csv"
    text = budget.published_markdown(
        table, PUBLISHED / "paper.csv", ROOT / "resources" / "paper-tables.csv"
    )
    _block_is_fresh(tmp_path, "paper-pmfair", text)
    assert reconcile.PM in text


def _table(tmp_path, change):
    """A copy of the published fair-budget table, with its provenance, changed by ``change(df) -> df``."""
    shutil.copy(PUBLISHED / "paper-pmfair.provenance.json", tmp_path)
    change(pd.read_csv(PUBLISHED / "paper-pmfair.csv")).to_csv(
        tmp_path / "paper-pmfair.csv", index=False
    )
    return tmp_path / "paper-pmfair.csv"


def _set(column, value, row=3):
    """A change that writes ``value`` to ``column`` of the ``row``-th row (line ``row + 2`` of the CSV)."""

    def change(df):
        df[column] = df[column].astype(object)
        df.loc[row, column] = value
        return df

    return change


def _budget_error(capsys, *argv):
    """The one line of error of ``published budget ARGV`` (exit 2)."""
    assert main(["budget", *map(str, argv)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith("error: ")
    return err.removeprefix("error: ").rstrip("\n")


def test_a_table_without_the_columns_of_the_caption_is_refused_and_not_written(tmp_path, capsys):
    cols = ["r_hat_test_error", "params", "train_error"]
    table = _table(tmp_path, lambda df: df.drop(columns=cols))
    docs = tmp_path / "results.md"
    shutil.copy(ROOT / "docs" / "results.md", docs)
    expected = (
        f"{table}: lacks columns ['train_error', 'r_hat_test_error', 'params'], which the budget table needs; "
        "expected rows of today's code (rerun the study)"
    )
    assert _budget_error(capsys, table) == expected
    assert _budget_error(capsys, table, "--update", docs) == expected
    assert docs.read_text() == (ROOT / "docs" / "results.md").read_text()


@pytest.mark.parametrize(
    "value, told",
    [
        (
            '{"n_atoms": 64, "n_neighbors": 5}',
            """is '{"n_atoms": 64, "n_neighbors": 5}': 'b_xy' is missing""",
        ),
        (
            '{"n_atoms": 64, "n_neighbors": 5, "b_xy": "1"}',
            """is '{"n_atoms": 64, "n_neighbors": 5, "b_xy": "1"}': 'b_xy' is '1'""",
        ),
        ("[64, 5, 1.0]", "is '[64, 5, 1.0]'"),
    ],
    ids=["no b_xy", "b_xy a string", "a list"],
)
def test_params_without_the_cv_choice_are_named_by_line(tmp_path, capsys, value, told):
    table = _table(tmp_path, _set("params", value))
    assert _budget_error(capsys, table) == (
        f"{table} line 5: column 'params' {told}; expected a JSON object with a number for each of "
        "['n_atoms', 'n_neighbors', 'b_xy'] (the CV's choice)"
    )


def test_a_non_numeric_r_hat_is_named_by_line(tmp_path, capsys):
    table = _table(tmp_path, _set("r_hat_test_error", "1.0O"))
    assert _budget_error(capsys, table) == (
        f"{table} line 5: column 'r_hat_test_error' is '1.0O'; expected a finite number (the split R-hat of "
        "the test error over the chains)"
    )


def test_tables_without_shared_cells_are_named(tmp_path, capsys):
    beside = PUBLISHED / "paper.csv"
    table = _table(tmp_path, lambda df: df.assign(n_train=df["n_train"] + 1))
    assert _budget_error(capsys, table) == (
        f"{table} beside {beside}: found the PMs ['PM (fair budget)'] on the cells of {table}; expected the "
        "headline PM and one fair-budget PM"
    )

    table = _table(
        tmp_path, lambda df: df.assign(paper_activity=df["paper_activity"] + " (renamed)")
    )
    assert _budget_error(capsys, table) == (
        f"{table} and {beside} share no cell (source, activity, N) holding both PMs; expected the headline "
        "table to hold the fair-budget table's cells"
    )


def test_a_row_of_a_data_set_outside_the_study_is_named_by_line(tmp_path, capsys):
    table = _table(tmp_path, lambda df: df.assign(activity=df["activity"] + "_late"))
    assert _budget_error(capsys, table) == (
        f"{table} line 2: columns 'source', 'activity' are 'hsc', 'acrobatics_late'; expected a data set of the "
        "study's configuration (the configuration files the table's provenance names)"
    )


def _beside(tmp_path, change):
    """A copy of the published headline table, with its provenance, changed by ``change(df) -> df``."""
    folder = tmp_path / "headline"
    folder.mkdir()
    shutil.copy(PUBLISHED / "paper.provenance.json", folder)
    change(pd.read_csv(PUBLISHED / "paper.csv")).to_csv(folder / "paper.csv", index=False)
    return folder / "paper.csv"


def _drop(methods, source=None, activity=None, n_train=None):
    """A change that drops the rows of ``methods`` (the headline table's names) in the cells given."""

    def change(df):
        hit = df["method"].isin(methods)
        for col, v in (("source", source), ("activity", activity), ("n_train", n_train)):
            if v is not None:
                hit &= df[col] == v
        return df[~hit]

    return change


def test_a_fair_cell_over_other_seeds_than_the_headline_pms_is_refused(tmp_path, capsys):
    table = _table(tmp_path, lambda df: df[df["seed"] <= 2])
    beside = PUBLISHED / "paper.csv"
    assert _budget_error(capsys, table, "--beside", beside) == (
        f"{table} beside {beside}: the cell (source 'hsc', activity 'acrobatics', N 30) has the seeds "
        f"[0, 1, 2] of PM (fair budget) in {table} and {list(range(10))} of PM in {beside}; expected the same "
        "seeds (the means and the paired test are over the cell's seeds)"
    )


def test_the_caption_states_the_number_of_seeds_it_averages():
    rows = pd.DataFrame(
        _rows("PM", 30, [7.0, 7.3, 6.8])
        + _rows(
            "PM (fair budget)",
            30,
            [5.0, 5.2, 4.9],
            r_hat_test_error=1.0,
            train_error=1.0,
            params='{"n_atoms": 64, "n_neighbors": 5, "b_xy": 1.0}',
        )
    )
    text = budget.markdown(budget.cells(rows, ["PM", "PM (fair budget)"], PAPER), [])
    assert "Mean errors over the 3 seeds (degrees)" in text and "10 seeds" not in text


@pytest.mark.parametrize(
    "change, cell, missing",
    [
        (_drop(["PM"], "mocap", "run", 60), "(source 'mocap', activity 'run', N 60)", ["PM"]),
        (
            _drop(["PM", "NN1", "RVM", "TGP", "SR", "DDL"], "mocap"),
            "(source 'mocap', activity 'kick_soccer_ball', N 30)",
            ["PM", "1-NN", "RVM", "TGP", "SR", "DDL"],
        ),
        (_drop(["NN1"]), "(source 'hsc', activity 'acrobatics', N 30)", ["1-NN"]),
        (
            _drop(["RVM", "TGP", "SR", "DDL"]),
            "(source 'hsc', activity 'acrobatics', N 30)",
            ["RVM", "TGP", "SR", "DDL"],
        ),
        (_drop(["NN1"], "hsc", "golf", 60), "(source 'hsc', activity 'golf', N 60)", ["1-NN"]),
    ],
    ids=["PM in one cell", "a whole source", "1-NN", "the baselines", "1-NN in one cell"],
)
def test_a_headline_table_lacking_a_method_in_a_fair_cell_is_refused(
    tmp_path, capsys, change, cell, missing
):
    table = PUBLISHED / "paper-pmfair.csv"
    beside = _beside(tmp_path, change)
    docs = tmp_path / "results.md"
    shutil.copy(ROOT / "docs" / "results.md", docs)
    expected = (
        f"{beside}: the cell {cell} of {table} lacks method(s) {missing}; expected the headline table to hold "
        "PM, 1-NN, RVM, TGP, SR, DDL in every cell of the fair-budget table"
    )
    assert _budget_error(capsys, table, "--beside", beside) == expected
    assert _budget_error(capsys, table, "--beside", beside, "--update", docs) == expected
    assert docs.read_text() == (ROOT / "docs" / "results.md").read_text()
