"""The paper's Tables I and II in LaTeX (bold best, mean +- std, missing-data rows, tie marks), aggregation,
summaries and the reading of the aggregate table with its design check."""

import re

import numpy as np
import pandas as pd
import pytest
from reportdata import (
    LABELS,
    assert_std_smaller_than_the_table,
    paired_rows,
    paper_frame,
    result_rows,
)

from bsrbench.errors import DataFileError, InputError
from bsrbench.reporting.tables import (
    aggregate_rows,
    best_mask,
    format_cell,
    latex_table,
    read_results,
    summarize,
)


def test_format_cell_and_bold_best():
    assert format_cell(12.3456, 1.234) == r"12.35 $\pm$ {\scriptsize 1.23}"
    assert format_cell(12.3456, 1.234, bold=True) == r"\textbf{12.35} $\pm$ {\scriptsize 1.23}"
    assert format_cell(7.0, float("nan")) == "7.00"
    assert format_cell(float("nan"), 1.0) == "--"
    assert best_mask([3.0, 2.0, 5.0]) == [False, True, False]
    assert best_mask([2.001, 2.004, 5.0]) == [True, True, False]  # equal when printed: both bold
    assert best_mask([float("nan"), 1.0]) == [False, True]


def test_aggregate_sorts_flattens_and_rejects_duplicates():
    rows = result_rows({("golf", "PM"): [8.0, 9.0], ("acrobatics", "RVM"): [15.0, 16.0]})
    df = aggregate_rows(rows[::-1])
    assert list(df["activity"]) == ["acrobatics", "acrobatics", "golf", "golf"]
    assert list(df["seed"]) == [0, 1, 0, 1]
    assert df["params"].iloc[0] == '{"a": 1}' and df["per_angle_rms"].iloc[0] == "[15.0, 15.0]"
    with pytest.raises(InputError, match="duplicate result rows"):
        aggregate_rows(rows + rows[:1])
    with pytest.raises(InputError, match="lacks"):
        aggregate_rows([{"error": 1.0}])


def test_summarize_mean_and_sample_std():
    df = aggregate_rows(result_rows({("golf", "PM"): [8.0, 9.0, 13.0]}))
    s = summarize(df)
    assert s["mean"].iloc[0] == pytest.approx(10.0)
    assert s["std"].iloc[0] == pytest.approx(np.std([8.0, 9.0, 13.0], ddof=1))
    assert s["n"].iloc[0] == 3 and s["key"].iloc[0] == "golf"


def test_latex_table_layout_bold_paper_rows_and_missing_data():
    df = aggregate_rows(
        result_rows(
            {
                ("golf", "PM"): [8.0, 10.0],
                ("golf", "RVM"): [12.0, 14.0],
                ("golf", "NN1"): [6.0, 7.0],
            }
        )
    )
    text = latex_table(
        summarize(df),
        paper_frame(),
        source="hsc",
        table="I",
        methods=["RVM", "PM", "NN1"],
        labels=LABELS,
        n_train=[30],
        protocols=["random"],
        status={"Golf": "golf", "Acrobatics": {"kind": "download", "activity": "acrobatics"}},
    )
    assert "toprule" in text and "multirow" not in text and "siunitx" not in text
    lines = [ln for ln in text.splitlines() if ln.endswith(r"\\")]
    assert re.sub(r"\\makebox\[[^]]*\]\{([^}]*)\}", r"\1", lines[0]).startswith(
        r"Activity & Tr.\ \# & RVM & PM & 1-NN"
    )
    golf = [ln for ln in lines if ln.startswith("Golf & 30")]
    assert len(golf) == 1
    cells = golf[0][:-2].split(" & ")
    assert cells[2] == r"13.00 $\pm$ {\scriptsize 1.41}"
    assert_std_smaller_than_the_table(text)
    assert cells[4].startswith(r"\textbf{6.50}")  # the reference is best here: bold, PM not
    assert not cells[3].startswith(r"\textbf")
    paper = lines[lines.index(golf[0]) + 1]
    assert (
        paper.startswith(r"\emph{\quad paper}") and r"\textbf{8.24}" in paper and "14.51" in paper
    )
    # rows of results only (before: a filler row per activity without data, "data not on this machine"); one line
    # under the table names those activities and why
    assert [ln.split(" & ")[0] for ln in lines[1:] if not ln.startswith(r"\emph")] == ["Golf"]
    under = [ln for ln in text.splitlines() if "Not shown" in ln]
    assert len(under) == 1
    assert (
        "Acrobatics (data not on this machine); Navigate (no data set of this source)" in under[0]
    )
    assert "see the note below the tables" in under[0]
    # every activity with a row: no line
    full = {"Golf": "golf", "Acrobatics": "golf", "Navigate": "golf"}
    assert "Not shown" not in latex_table(
        summarize(df),
        paper_frame(),
        source="hsc",
        table="I",
        methods=["PM"],
        labels=LABELS,
        n_train=[30],
        protocols=["random"],
        status=full,
    )


def test_activities_table_has_the_rows_of_activities_without_a_paper_row_and_no_paper_numbers():
    """An activity added by configuration with paper_activity null (before: no error table at all)."""
    from bsrbench.reporting.comparisons import comparisons, tied_with_best
    from bsrbench.reporting.tables import activities_tables

    df = paired_rows(
        {
            ("golf", "PM"): [8.0, 9.0, 10.0],
            ("golf", "NN1"): [8.5, 8.9, 10.4],
            ("golf", "KNN"): [20.0, 21.0, 22.0],
        }
    ).assign(activity="walk_one", paper_activity="")
    text = activities_tables(
        summarize(df),
        source="hsc",
        activities={"walk_one": "Walk one"},
        methods=["PM", "NN1", "KNN"],
        groups={"KNN": "today"},
        labels=LABELS,
        n_train=[30],
        protocols=["random"],
        ties=tied_with_best(comparisons(df)),
        frames={"walk_one": "first 167 frames"},
    )
    blocks = text.split(r"\end{table}")[:2]
    assert "(today's baselines)" in blocks[1]
    walk = [ln for ln in text.splitlines() if ln.startswith("Walk one & 30")]
    # a row per block: PM and 1-NN, then PM beside k-NN; the best (PM) bold in both, 1-NN tied with it
    assert [ln.count(r"$\pm$") for ln in walk] == [2, 2]
    assert walk[0].split(" & ")[2].startswith(r"\textbf{9.00}")
    assert walk[0].split(" & ")[3].startswith(r"9.27$^{\dagger}$")
    assert "paper" not in text.replace(
        "paper's tables", ""
    )  # no paper rows, no italic-row sentence
    assert r"Frames. walk\_one: first 167 frames." in text
    assert r"\label{tab:activities-hsc-random}" in text


def test_latex_table_notes_skipped_sizes_and_states_the_frames():
    df = aggregate_rows(result_rows({("golf", "PM"): [8.0, 10.0], ("golf", "NN1"): [6.0, 7.0]}))
    note = "N = 200 skipped: the 167 frames leave at most 0 test frames, fewer than min_test = 100"
    text = latex_table(
        summarize(df),
        paper_frame(),
        source="hsc",
        table="I",
        methods=["PM", "NN1"],
        labels=LABELS,
        n_train=[30, 200],
        protocols=["random"],
        status={"Golf": "golf"},
        skipped={"random": {"golf": [note]}},
        frames={"golf": "one frame in 4, first 600 frames"},
    )
    lines = [ln for ln in text.splitlines() if ln.endswith("\\\\")]
    golf = [ln for ln in lines if ln.startswith("Golf &")]
    assert golf[0].startswith("Golf & 30 & ") and r"$\pm$" in golf[0]
    assert golf[-1].startswith("Golf & 200 & ") and "N = 200 skipped: the 167 frames" in golf[-1]
    assert "pm" not in golf[-1]
    assert r"Frames. golf: one frame in 4, first 600 frames." in text


DESIGN = {
    "protocols": ["random"],
    "pairs": [["hsc", "golf"]],
    "methods": ["PM", "RVM"],
    "n_train": [30],
    "seeds": [0, 1],
}


def test_an_aggregate_of_another_configuration_is_never_reported(tmp_path):
    df = aggregate_rows(result_rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]}))
    path = tmp_path / "results.csv"
    df.to_csv(path, index=False)
    assert len(read_results(path, design=DESIGN)) == 4
    # a method added to the configuration (the stale-results case), a seed or a size more, an activity less
    for change, message in [
        (
            {"methods": ["PM", "RVM", "GPR"]},
            r"2 configured job\(s\) without a row.*method: the table has \['PM', 'RVM'\], the configuration \['GPR', 'PM', 'RVM'\]",
        ),
        ({"seeds": [0, 1, 2]}, r"seed: the table has \[0, 1\], the configuration \[0, 1, 2\]"),
        ({"n_train": [60]}, r"n_train: the table has \[30\], the configuration \[60\]"),
        ({"methods": ["PM"]}, r"2 row\(s\) of jobs not configured"),
        ({"protocols": ["contiguous"]}, r"protocol: the table has \['random'\]"),
    ]:
        with pytest.raises(
            DataFileError,
            match=re.escape(str(path)) + ".*does not match the configuration.*" + message,
        ):
            read_results(path, design={**DESIGN, **change})
    # every value present but one job missing
    df.drop(index=0).to_csv(path, index=False)
    with pytest.raises(
        DataFileError, match=r"1 configured job\(s\) without a row.*e\.g\. no row for"
    ):
        read_results(path, design=DESIGN)


def test_design_changes_name_what_differs_and_the_error_says_what_to_do(tmp_path):
    """The early warning (workflow/rules/common.smk) and the report rules' check share design_changes; the
    check's error names the study and the three ways out (before: 'rebuild it (snakemake <table>)', which does
    nothing when Snakemake has no record of the old design)."""
    from bsrbench.config import design_changes, study_of

    df = aggregate_rows(result_rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]}))
    assert design_changes(df, DESIGN) == (0, 0, [])
    assert design_changes(
        df[["protocol", "source", "activity", "method", "n_train", "seed"]],
        {**DESIGN, "n_train": [30, 60]},
    ) == (4, 0, ["n_train: the table has [30], the configuration [30, 60]"])
    assert design_changes(df, {**DESIGN, "methods": ["PM"]}) == (
        0,
        2,
        ["method: the table has ['PM', 'RVM'], the configuration ['PM']"],
    )
    assert study_of("results/quick/aggregate/results.csv") == "quick"
    assert study_of(tmp_path / "results.csv") is None
    path = tmp_path / "results" / "quick" / "aggregate" / "results.csv"
    path.parent.mkdir(parents=True)
    df.to_csv(path, index=False)
    with pytest.raises(DataFileError) as err:
        read_results(path, design={**DESIGN, "seeds": [0, 1, 2]})
    msg = str(err.value)
    assert "the design of study 'quick' has changed" in msg and "add --forcerun aggregate" in msg
    assert "(--config study=NAME)" in msg and msg.endswith("delete results/quick/ to start afresh")


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda df: pd.concat([df, df.iloc[[1]]]), r"row 6, column 'seed'.*appears twice"),
        (
            lambda df: df.assign(error=df["error"].where(df.index != 2)),
            r"row 4, column 'error': nan; expected a finite",
        ),
        (
            lambda df: df.assign(error=df["error"].where(df.index != 0, -5.0)),
            r"row 2, column 'error': -5.0",
        ),
        (
            lambda df: df.assign(error=df["error"].astype(object).where(df.index != 0, "abc")),
            r"'abc'; expected a finite",
        ),
        (
            lambda df: df.assign(
                n_train=df["n_train"].astype(object).where(df.index != 3, "thirty")
            ),
            r"row 5, column 'n_train': 'thirty'; expected a whole number",
        ),
        (
            lambda df: df.assign(seed=df["seed"].where(df.index != 1, 1.5)),
            r"row 3, column 'seed': 1.5",
        ),
        (
            lambda df: df.drop(index=3),
            r"cell \{.*'activity': 'golf'.*\} has seeds \[0\]; expected all of \[0, 1\]",
        ),
    ],
)
def test_a_damaged_aggregate_table_is_never_summarised(tmp_path, damage, message):
    """A duplicated, missing, non-finite, negative or mistyped value names its row and column (CSV numbering)."""
    df = aggregate_rows(result_rows({("acrobatics", "PM"): [8.0, 9.0], ("golf", "PM"): [5.0, 6.0]}))
    path = tmp_path / "results.csv"
    df.to_csv(path, index=False)
    assert len(read_results(path)) == 4
    damage(df).to_csv(path, index=False)
    with pytest.raises(DataFileError, match=message):
        read_results(path)


def test_tables_do_not_import_the_report_sections():
    """The report's sections import tables, never the other way round (no import cycle)."""
    import subprocess
    import sys

    code = (
        "import sys, bsrbench.reporting.tables as t; "
        "assert not {f'bsrbench.reporting.{m}' for m in ('body', 'findings', 'study_setup', 'build', 'latex')} "
        "& set(sys.modules); print(t.NO_ROW['download'])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "data not on this machine"


def test_latex_table_marks_the_means_tied_with_the_best_and_says_so():
    from bsrbench.reporting.comparisons import comparisons, tied_with_best

    # PM ties NN1 (noise around the same level), RVM is worse by a constant 5 degrees: p = 0, never tied
    df = paired_rows(
        {
            ("golf", "NN1"): [6.0, 7.0, 6.5],
            ("golf", "PM"): [6.2, 6.9, 6.8],
            ("golf", "RVM"): [11.0, 12.0, 11.5],
        }
    )
    ties = tied_with_best(comparisons(df))
    assert ties == {("random", "hsc", "golf", 30): {"NN1", "PM"}}
    kw = dict(
        source="hsc",
        table="I",
        methods=["RVM", "PM", "NN1"],
        labels=LABELS,
        n_train=[30],
        protocols=["random"],
        status={"Golf": "golf"},
    )
    text = latex_table(summarize(df), paper_frame(), ties=ties, **kw)
    golf = next(ln for ln in text.splitlines() if ln.startswith("Golf & 30"))
    cells = golf[:-2].split(" & ")
    assert cells[2].startswith("11.50 $") and r"\dagger" not in cells[2]
    assert cells[3].startswith(r"6.63$^{\dagger}$ $\pm$")
    assert cells[4].startswith(r"\textbf{6.50}") and r"\dagger" not in cells[4]
    assert r"$^{\dagger}$: not distinguishable from the best of its row on these frames" in text
    assert "Holm-adjusted" in text and r"$p \geq 0.05$" in text
    plain = latex_table(summarize(df), paper_frame(), **kw)
    assert r"\dagger" not in plain.split(r"\caption")[1].split("\n", 1)[1]
    assert "No paired comparisons were made" in plain
    # one split: no test, no mark, and the caption says so
    one = df[df["seed"] == 0]
    t1 = latex_table(summarize(one), paper_frame(), ties=tied_with_best(comparisons(one)), **kw)
    assert "no row was tested and none is marked" in t1


def test_error_tables_add_the_table_of_activities_without_a_paper_row():
    from bsrbench.reporting.tables import error_tables, other_activities

    status = {"Walk": "walk", "Run": {"kind": "here", "activity": "run"}}
    # walk_trial has paper_activity null; run_cmu is a second data set of Run, whose row is run's
    assert other_activities(status, ["walk", "walk_trial"]) == {"walk_trial": "Walk trial"}
    assert other_activities({"Run": "run"}, ["run", "run_cmu"]) == {"run_cmu": "Run cmu"}
    assert error_tables(
        "reports/s",
        {"hsc": ({"Golf": "golf"}, ["golf"]), "mocap": (status, ["walk", "walk_trial"])},
    ) == [
        "reports/s/tables/tableI_hsc.tex",
        "reports/s/tables/tableII_mocap.tex",
        "reports/s/tables/activities_mocap.tex",
    ]
    # an activity of one's own only: no Table I-II, its own table
    assert error_tables("r", {"mocap": ({"Walk": {"kind": "here"}}, ["walk_trial"])}) == [
        "r/tables/activities_mocap.tex"
    ]
