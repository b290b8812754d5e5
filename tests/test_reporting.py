"""Aggregation, LaTeX tables (paper layout, bold best, mean +- std, missing-data rows) and generated findings."""

import io
import re

import numpy as np
import pandas as pd
import pytest

from bsrbench.errors import InputError
from bsrbench.reporting.report import findings
from bsrbench.reporting.tables import (
    aggregate_rows,
    best_mask,
    format_cell,
    latex_table,
    paper_key,
    summarize,
)

PAPER_CSV = """table,activity,n_train,method,mean_deg,std_deg
I,Golf,30,RVM,14.514,2.88
I,Golf,30,PM,8.241,1.13
I,Acrobatics,30,RVM,15.963,2.73
I,Acrobatics,30,PM,12.595,1.24
"""
LABELS = {"RVM": "RVM", "PM": "PM", "NN1": "1-NN"}


def _paper():
    df = pd.read_csv(io.StringIO(PAPER_CSV))
    df["key"] = df["activity"].map(paper_key)
    return df


def _rows(errors):
    """errors: {(activity, method): [error per seed]} -> result rows (hsc, random, N=30)."""
    rows = []
    for (act, m), errs in errors.items():
        for seed, e in enumerate(errs):
            rows.append({"protocol": "random", "source": "hsc", "activity": act, "paper_activity": act.capitalize(),
                         "method": m, "n_train": 30, "seed": seed, "error": e, "params": {"a": 1},
                         "per_angle_rms": [e, e], "cv": "none", "pose_transform": "heading"})
    return rows


def test_format_cell_and_bold_best():
    assert format_cell(12.3456, 1.234) == r"12.35 $\pm$ {\small 1.23}"
    assert format_cell(12.3456, 1.234, bold=True) == r"\textbf{12.35} $\pm$ {\small 1.23}"
    assert format_cell(7.0, float("nan")) == "7.00"
    assert format_cell(float("nan"), 1.0) == "--"
    assert best_mask([3.0, 2.0, 5.0]) == [False, True, False]
    assert best_mask([2.001, 2.004, 5.0]) == [True, True, False]  # equal when printed: both bold
    assert best_mask([float("nan"), 1.0]) == [False, True]


def test_aggregate_sorts_flattens_and_rejects_duplicates():
    rows = _rows({("golf", "PM"): [8.0, 9.0], ("acrobatics", "RVM"): [15.0, 16.0]})
    df = aggregate_rows(rows[::-1])
    assert list(df["activity"]) == ["acrobatics", "acrobatics", "golf", "golf"]
    assert list(df["seed"]) == [0, 1, 0, 1]
    assert df["params"].iloc[0] == '{"a": 1}' and df["per_angle_rms"].iloc[0] == "[15.0, 15.0]"
    with pytest.raises(InputError, match="duplicate result rows"):
        aggregate_rows(rows + rows[:1])
    with pytest.raises(InputError, match="lacks"):
        aggregate_rows([{"error": 1.0}])


def test_summarize_mean_and_sample_std():
    df = aggregate_rows(_rows({("golf", "PM"): [8.0, 9.0, 13.0]}))
    s = summarize(df)
    assert s["mean"].iloc[0] == pytest.approx(10.0)
    assert s["std"].iloc[0] == pytest.approx(np.std([8.0, 9.0, 13.0], ddof=1))
    assert s["n"].iloc[0] == 3 and s["key"].iloc[0] == "golf"


def test_latex_table_layout_bold_paper_rows_and_missing_data():
    df = aggregate_rows(_rows({("golf", "PM"): [8.0, 10.0], ("golf", "RVM"): [12.0, 14.0],
                               ("golf", "NN1"): [6.0, 7.0]}))
    text = latex_table(summarize(df), _paper(), source="hsc", table="I", methods=["RVM", "PM", "NN1"],
                       labels=LABELS, n_train=[30], protocols=["random"],
                       status={"Golf": "golf", "Acrobatics": "get it with: snakemake acrobatics_rule"})
    assert "toprule" in text and "multirow" not in text and "siunitx" not in text
    lines = [ln for ln in text.splitlines() if ln.endswith(r"\\")]
    assert re.sub(r"\\makebox\[[^]]*\]\{([^}]*)\}", r"\1", lines[0]).startswith(r"Activity & Tr.\ \# & RVM & PM & 1-NN")
    golf = [ln for ln in lines if ln.startswith("Golf & 30")]
    assert len(golf) == 1
    cells = golf[0][:-2].split(" & ")
    assert cells[2] == r"13.00 $\pm$ {\small 1.41}"
    assert cells[4].startswith(r"\textbf{6.50}")  # the reference is best here: bold, PM not
    assert not cells[3].startswith(r"\textbf")
    paper = lines[lines.index(golf[0]) + 1]
    assert paper.startswith(r"\emph{\quad paper}") and r"\textbf{8.24}" in paper and "14.51" in paper
    acro = [ln for ln in lines if ln.startswith("Acrobatics")]
    assert len(acro) == 1 and "multicolumn{4}" in acro[0] and "acrobatics\\_rule" in acro[0]
    assert any(ln.startswith("Navigate &") and "no hsc data" in ln for ln in lines)
    # every one of the paper's Table I activities has a row
    assert [ln.split(" & ")[0] for ln in lines[1:] if not ln.startswith(r"\emph")] == ["Acrobatics", "Navigate", "Golf"]


def test_latex_table_notes_skipped_sizes_and_states_the_frames():
    df = aggregate_rows(_rows({("golf", "PM"): [8.0, 10.0], ("golf", "NN1"): [6.0, 7.0]}))
    note = "N = 200 skipped: 167 frames leave -33 test frames, fewer than min_test = 100"
    text = latex_table(summarize(df), _paper(), source="hsc", table="I", methods=["PM", "NN1"], labels=LABELS,
                       n_train=[30, 200], protocols=["random"], status={"Golf": "golf"},
                       skipped={"random": {"golf": [note]}}, frames={"golf": "one frame in 4, first 600 frames"})
    lines = [ln for ln in text.splitlines() if ln.endswith("\\\\")]
    golf = [ln for ln in lines if ln.startswith("Golf &")]
    assert golf[0].startswith("Golf & 30 & ") and r"$\pm$" in golf[0]
    assert golf[-1].startswith("Golf & 200 & ") and "N = 200 skipped: 167 frames" in golf[-1]
    assert "pm" not in golf[-1]
    assert r"Frames. golf: one frame in 4, first 600 frames." in text


def test_findings_count_where_the_claim_holds():
    df = aggregate_rows(_rows({
        ("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0], ("golf", "NN1"): [7.0, 7.5],
        ("acrobatics", "PM"): [16.0, 17.0], ("acrobatics", "RVM"): [12.0, 13.0], ("acrobatics", "NN1"): [9.0, 9.5],
    }))
    text = "\n".join(findings(df, _paper(), labels=LABELS))
    assert re.search(r"PM beats every baseline \(RVM\) at \$N=30\$'': holds only partly, for 1 of 2 activities", text)
    assert "fails for Acrobatics (hsc)" in text
    assert "lowest among the paper's methods in 1 of 2 (activity, $N$) rows" in text
    assert "including the references in 0 of 2" in text
    assert "PM is lower for 0 of 2 activities" in text  # 1-NN beats PM on both
    assert "on 2 of 4 random splits" in text
    # ours / paper: PM golf 8.5/8.241, acrobatics 16.5/12.595 -> median of the two ratios
    ratio = np.median([8.5 / 8.241, 16.5 / 12.595])
    assert f"PM {ratio:.2f}" in text
