"""Aggregation, LaTeX tables (paper layout, bold best, mean +- std, missing-data rows) and generated findings."""

import io
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bsrbench.errors import DataFileError, InputError
from bsrbench.reporting.report import (
    findings,
    latex_log_problems,
    missing_data_note,
    parameters_table,
    parameters_used,
    write_generated,
)
from bsrbench.reporting.tables import (
    PAPER_TABLES,
    aggregate_rows,
    best_mask,
    format_cell,
    latex_table,
    paper_key,
    read_results,
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
            rows.append(
                {
                    "protocol": "random",
                    "source": "hsc",
                    "activity": act,
                    "paper_activity": act.capitalize(),
                    "method": m,
                    "n_train": 30,
                    "seed": seed,
                    "error": e,
                    "params": {"a": 1},
                    "per_angle_rms": [e, e],
                    "cv": "none",
                    "pose_transform": "heading",
                }
            )
    return rows


def test_format_cell_and_bold_best():
    assert format_cell(12.3456, 1.234) == r"12.35 $\pm$ {\scriptsize 1.23}"
    assert format_cell(12.3456, 1.234, bold=True) == r"\textbf{12.35} $\pm$ {\scriptsize 1.23}"
    assert format_cell(7.0, float("nan")) == "7.00"
    assert format_cell(float("nan"), 1.0) == "--"
    assert best_mask([3.0, 2.0, 5.0]) == [False, True, False]
    assert best_mask([2.001, 2.004, 5.0]) == [True, True, False]  # equal when printed: both bold
    assert best_mask([float("nan"), 1.0]) == [False, True]


LATEX_SIZES = ["tiny", "scriptsize", "footnotesize", "small", "normalsize", "large"]


def assert_std_smaller_than_the_table(text):
    """Before: the std was set {\\small ...} inside \\footnotesize tables, so it printed larger than the mean."""
    table = re.search(r"\\(" + "|".join(LATEX_SIZES) + r")\b", text).group(1)
    stds = re.findall(r"\$\\pm\$ \{\\([a-z]+) ", text)
    assert stds and all(LATEX_SIZES.index(s) < LATEX_SIZES.index(table) for s in stds), (
        table,
        set(stds),
    )


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
    df = aggregate_rows(
        _rows(
            {
                ("golf", "PM"): [8.0, 10.0],
                ("golf", "RVM"): [12.0, 14.0],
                ("golf", "NN1"): [6.0, 7.0],
            }
        )
    )
    text = latex_table(
        summarize(df),
        _paper(),
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
    acro = [ln for ln in lines if ln.startswith("Acrobatics")]
    assert (
        len(acro) == 1
        and "multicolumn{4}" in acro[0]
        and "data not on this machine; see the note" in acro[0]
    )
    assert any(ln.startswith("Navigate &") and "no data set of this source" in ln for ln in lines)
    # every one of the paper's Table I activities has a row
    assert [ln.split(" & ")[0] for ln in lines[1:] if not ln.startswith(r"\emph")] == [
        "Acrobatics",
        "Navigate",
        "Golf",
    ]


def test_latex_table_notes_skipped_sizes_and_states_the_frames():
    df = aggregate_rows(_rows({("golf", "PM"): [8.0, 10.0], ("golf", "NN1"): [6.0, 7.0]}))
    note = "N = 200 skipped: the 167 frames leave at most 0 test frames, fewer than min_test = 100"
    text = latex_table(
        summarize(df),
        _paper(),
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


def test_findings_count_where_the_claim_holds():
    df = aggregate_rows(
        _rows(
            {
                ("golf", "PM"): [8.0, 9.0],
                ("golf", "RVM"): [12.0, 13.0],
                ("golf", "NN1"): [7.0, 7.5],
                ("acrobatics", "PM"): [16.0, 17.0],
                ("acrobatics", "RVM"): [12.0, 13.0],
                ("acrobatics", "NN1"): [9.0, 9.5],
            }
        )
    )
    text = "\n".join(findings(df, _paper(), labels=LABELS))
    plain = re.sub(r"\\mbox\{([^}]*)\}", r"\1", text)
    assert (
        "At $N=30$, PM has a lower mean error than RVM for 1 of the 2 activities studied (Golf (hsc)), "
        "but not for Acrobatics (hsc)."
    ) in plain
    assert "a lower mean error than RVM in 1 of the 2 (activity, $N$) rows" in plain
    assert "(the references 1-NN included) in 0 of the 2 rows" in plain
    # 1-NN beats PM on both: the count says "none" and the sign is spelled out
    assert (
        "PM has a lower mean error than 1-NN for none of the 2 activities studied (Acrobatics (hsc), Golf (hsc)); "
        "PM's mean error minus 1-NN's, median over these activities, is +4.25 degrees "
        "(PM's error is higher)."
    ) in plain
    assert "on 2 of the 4 splits" in plain
    # ours / paper: PM golf 8.5/8.241, acrobatics 16.5/12.595 -> median of the two ratios, per source
    ratio = np.median([8.5 / 8.241, 16.5 / 12.595])
    assert (
        f"on the hsc data, RVM {np.median([12.5 / 14.514, 12.5 / 15.963]):.2f}, PM {ratio:.2f}."
        in plain
    )
    assert "holds" not in plain and "0 of 2 activities" not in plain


def test_the_paper_claim_is_counted_from_the_paper_table_not_asserted():
    """Before: the summary said "in the paper's Tables I and II, PM has the lowest error in every row", but the
    paper's own table has rows where SR beats PM (throw and catch football, N = 100 and 200)."""
    paper = _paper()
    extra = pd.DataFrame(
        [
            {
                "table": "II",
                "activity": "Throw and catch football",
                "n_train": 100,
                "method": "SR",
                "mean_deg": 9.09,
                "std_deg": 1.0,
            },
            {
                "table": "II",
                "activity": "Throw and catch football",
                "n_train": 100,
                "method": "PM",
                "mean_deg": 9.54,
                "std_deg": 1.0,
            },
            {
                "table": "II",
                "activity": "Throw and catch football",
                "n_train": 200,
                "method": "PM",
                "mean_deg": 7.0,
                "std_deg": 1.0,
            },  # PM alone: not a comparison, not counted
        ]
    )
    extra["key"] = extra["activity"].map(paper_key)
    paper = pd.concat([paper, extra], ignore_index=True)
    df = aggregate_rows(_rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]}))
    text = "\n".join(findings(df, paper, labels=LABELS))
    assert "every row" not in text
    assert "PM has a lower error than every other method in 2 of the 3 (activity, $N$) rows" in text
    assert "in 2 of the 2 (activity, $N$) rows" in "\n".join(findings(df, _paper(), labels=LABELS))
    assert "paper's Tables" not in "\n".join(findings(df, None, labels=LABELS))


def test_ratio_to_the_paper_and_coverage_are_given_per_source():
    rows = _rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]})
    mocap = [dict(r, source="mocap", error=r["error"] / 4) for r in rows]
    for r in rows + mocap:
        r["coverage_90"] = 0.5 if r["source"] == "hsc" else 0.9
    df = aggregate_rows(rows + mocap)
    text = "\n".join(findings(df, _paper(), labels=LABELS))
    hsc_pm, mocap_pm = 8.5 / 8.241, 8.5 / 4 / 8.241
    # methods in the configuration's order (that of the labels)
    assert (
        f"on the hsc data, RVM {12.5 / 14.514:.2f}, PM {hsc_pm:.2f}; "
        f"on the mocap data, RVM {12.5 / 4 / 14.514:.2f}, PM {mocap_pm:.2f}."
    ) in text
    assert r"on the hsc data, RVM 50\%, PM 50\%; on the mocap data, RVM 90\%, PM 90\%." in text


def test_findings_for_all_and_for_none():
    all_ok = aggregate_rows(
        _rows(
            {
                ("golf", "PM"): [1.0],
                ("golf", "RVM"): [2.0],
                ("acrobatics", "PM"): [1.0],
                ("acrobatics", "RVM"): [2.0],
            }
        )
    )
    text = "\n".join(findings(all_ok, None, labels=LABELS))
    assert "than RVM for both activities studied" in text and "all 2" not in text
    three = aggregate_rows(
        _rows(
            {
                (a, m): [1.0 if m == "PM" else 2.0]
                for a in ("golf", "acrobatics", "navigate")
                for m in ("PM", "RVM")
            }
        )
    )
    assert "than RVM for all 3 activities studied" in "\n".join(
        findings(three, None, labels=LABELS)
    )
    # one activity: PM better reads "for the activity studied"; PM worse used to read the same (the sentence
    # said PM had the lower error when it had the higher one)
    better = aggregate_rows(_rows({("golf", "PM"): [1.0], ("golf", "RVM"): [2.0]}))
    text = "\n".join(findings(better, None, labels=LABELS))
    assert "than RVM for the activity studied (\\mbox{Golf (hsc)})" in text
    worse = aggregate_rows(_rows({("golf", "PM"): [3.0], ("golf", "RVM"): [2.0]}))
    text = "\n".join(findings(worse, None, labels=LABELS))
    assert "than RVM for no activity: not for \\mbox{Golf (hsc)}, the only activity studied" in text
    assert "for the activity studied" not in text


def test_findings_without_a_method_named_pm_point_to_the_variants():
    rows = _rows({("golf", "PMK8"): [8.0, 9.0], ("golf", "NN1"): [7.0, 7.5]})
    text = findings(aggregate_rows(rows), None, labels={"PMK8": "PM K=8", "NN1": "1-NN"})
    assert text == [
        "No method named PM was run, so the paper's claims about it are not checked here; the PM "
        "variants run (PM K=8) are compared in the section ``Why PM trails the paper here''."
    ]
    text = findings(aggregate_rows(_rows({("golf", "NN1"): [7.0, 7.5]})), None, labels=LABELS)
    assert text == [
        "No method named PM was run, so the paper's claims about it are not checked here."
    ]


def test_findings_cover_every_protocol_run_and_the_section_is_never_an_empty_list(tmp_path):
    """Before: only the random and contiguous protocols had findings, so a cross-trial study got an empty
    itemize and LaTeX stopped ("perhaps a missing \\item"); the setup said CV used seed 0 when the study's
    splits start at seed 100."""
    rows = _rows(
        {("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0], ("golf", "NN1"): [7.0, 7.5]}
    )
    for r in rows:
        r.update(protocol="cross_trial", seed=r["seed"] + 100, cv="per_size")
    df = aggregate_rows(rows)
    text = "\n".join(findings(df, None, labels=LABELS))
    assert (
        "Cross-trial protocol, summary" in text and "At $N=30$ (cross-trial protocol), PM" in text
    )
    assert "_" not in text.replace(r"\_", "")
    out = tmp_path / "body.tex"
    write_generated(out, df, None, labels=LABELS)
    tex = out.read_text()
    assert "on the training frames of seed 100 (the study's first)" in tex and "seed 0" not in tex
    assert "2 splits (seeds) per size" in tex
    write_generated(out, aggregate_rows([r for r in rows if r["seed"] == 100]), None, labels=LABELS)
    assert "1 split (seed) per size" in out.read_text()
    only_pm = aggregate_rows([r for r in rows if r["method"] == "PM"])
    assert findings(only_pm, None, labels=LABELS) == []
    write_generated(out, only_pm, None, labels=LABELS)
    body = out.read_text().split(r"\section{Findings}")[1]
    assert body.count(r"\item ") == 1 and "No sentence applies" in body


DESIGN = {
    "protocols": ["random"],
    "pairs": [["hsc", "golf"]],
    "methods": ["PM", "RVM"],
    "n_train": [30],
    "seeds": [0, 1],
}


def test_an_aggregate_of_another_configuration_is_never_reported(tmp_path):
    df = aggregate_rows(_rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]}))
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

    df = aggregate_rows(_rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]}))
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


def test_missing_data_note_is_one_paragraph_per_source_with_copyable_commands():
    status = {
        "Golf": "golf",
        "Acrobatics": {
            "kind": "download",
            "activity": "acrobatics",
            "command": "snakemake --cores 2 results/features/mocap/acrobatics.npz",
        },
        "Run": {"kind": "here", "activity": "run"},
        "Navigate": {"kind": "none"},
    }
    note = missing_data_note("mocap", status)
    assert note.count(r"\paragraph") == 1
    # "--" stays two hyphens in the PDF (no en-dash ligature), "_" an underscore
    assert r"\texttt{snakemake -{}-{}cores 2 results/features/mocap/acrobatics.npz}" in note
    assert r"add \texttt{run} to the configuration key \texttt{study\_activities.mocap}" in note
    # activities without an entry are grouped with those of kind "none"
    assert (
        r"\mbox{Navigate}, \mbox{Throw and catch football}" in note and "no mocap data set" in note
    )
    assert "Golf" not in note
    assert missing_data_note("hsc", {pa: "x" for t in PAPER_TABLES.values() for pa in t}) == ""


def test_page_one_names_the_config_overrides_after_the_files():
    """Before: the header listed the configuration files only, so a study run with `--config n_train=[30,60]`
    claimed the files' N. Now the overrides follow the files, as a shell takes them (quoted where the shell
    needs it), in typewriter type with ASCII hyphens and upright quotes."""
    from bsrbench.reporting.report import build_header, config_provenance

    files = ["config/datasets.yaml", "config/config.yaml", "config/ci.yaml"]
    text = config_provenance(
        files, ["study=ci_n", "n_train=[30,60]", "report={subjective_methods: [SR]}"]
    )
    assert text.startswith(
        r"config/datasets.yaml, config/config.yaml, config/ci.yaml (in the order they apply), then "
    )
    q = r"\textquotesingle{}"
    assert text.endswith(
        r"\texttt{\frenchspacing -{}-{}config study=ci\_n "
        + q
        + "n\\_train=[30,60]"
        + q
        + " "
        + q
        + r"report=\{subjective\_methods: [SR]\}"
        + q
        + "}"
    ), text
    assert (
        config_provenance(files, [])
        == config_provenance(files)
        == ("config/datasets.yaml, config/config.yaml, config/ci.yaml (in the order they apply)")
    )
    assert (
        config_provenance([], ["job_server=False"])
        == r"none, then \texttt{\frenchspacing -{}-{}config job\_server=False}"
    )
    header = build_header(configfiles=files, overrides=["n_train=[30,60]"])
    row = [ln for ln in header.splitlines() if ln.startswith("Configuration & ")]
    assert len(row) == 1 and "n\\_train=[30,60]" in row[0]


def test_a_table_without_any_studied_activity_is_left_out_and_the_note_says_so(tmp_path):
    """Before: the quick study's mocap Table I was three rows of "data not on this machine" (it studies walk,
    of Table II, only). Now a table none of whose activities is studied on a source is not built, and the
    note under that source's tables says which table is left out and why."""
    from bsrbench.reporting.report import write_body
    from bsrbench.reporting.tables import tables_with_rows

    walk_only = {
        "Walk": "walk",
        "Acrobatics": {
            "kind": "download",
            "activity": "acrobatics",
            "command": "snakemake --cores 2 results/features/mocap/acrobatics.npz",
        },
    }
    assert tables_with_rows(walk_only) == ["II"]
    assert tables_with_rows({"Golf": "golf", "Run": "run"}) == ["I", "II"]
    assert tables_with_rows({"Run": {"kind": "here", "activity": "run"}}) == []
    note = missing_data_note("mocap", walk_only)
    lines = note.split("\\\\\n")
    assert re.sub(r".*\\small\n", "", lines[0], flags=re.S) == (
        r"Table I (\mbox{Acrobatics}, \mbox{Navigate} and \mbox{Golf}) is not shown for the mocap data: this "
        "study has none of its activities on that source, so every row would be empty."
    )
    assert (
        note.count("not shown") == 1
        and r"\mbox{Acrobatics}: the data are not on this machine" in note
    )
    both = missing_data_note("hsc", {"Laugh": "laugh"})
    assert (
        "Tables I and II (" in both
        and "are not shown for the hsc data" in both
        and "their activities" in both
    )
    assert "not shown" not in missing_data_note("hsc", {"Golf": "golf", "Run": "run"})
    # the note of a source left without any table still reaches the report, after the tables
    body = tmp_path / "body.tex"
    write_body(
        body,
        tables=["tables/tableI_hsc.tex"],
        figures=[],
        notes={"hsc": "HSC NOTE", "mocap": "MOCAP NOTE"},
    )
    text = body.read_text()
    assert (
        text.index(r"\input{tables/tableI_hsc}") < text.index("HSC NOTE") < text.index("MOCAP NOTE")
    )


def test_parameters_table_lists_configured_cv_chosen_and_default_values():
    rows = _rows({("golf", "PM"): [8.0, 9.0]})
    rows[0]["params"], rows[1]["params"] = {"a": 1, "k": 64}, {"a": 1, "k": 128}
    df = aggregate_rows(rows)
    used = parameters_used(df, defaults={"PM": {"a": 5, "k": 3, "thin": 10, "random_state": None}})
    assert used["PM"] == ({"a": [1], "k": [64, 128]}, {"thin": 10, "random_state": "per job"})
    table = parameters_table(df, labels=LABELS, defaults={"PM": {"thin": 10}})
    assert (
        r"a=1, k=64|\allowbreak{}128 (CV)" in table and "thin=10" in table and "tabularx" in table
    )


def test_latex_log_problems_flags_overfull_boxes_and_undefined_references():
    log = "\n".join(
        [
            r"Overfull \hbox (0.5pt too wide) in paragraph at lines 3--4",
            r"Overfull \hbox (12.3pt too wide) in paragraph at lines 9--10",
            r"Overfull \vbox (3.0pt too high) has occurred while \output is active",
            r"LaTeX Warning: Reference `tab:parameters' on page 1 undefined on input line 40.",
            r"Underfull \hbox (badness 10000) in paragraph at lines 1--2",
        ]
    )
    problems = latex_log_problems(log)
    assert (
        len(problems) == 3
        and "12.3pt" in problems[0]
        and "3.0pt" in problems[1]
        and "tab:parameters" in problems[2]
    )
    assert latex_log_problems("Overfull \\hbox (0.9pt too wide)") == []


def test_figures_fit_the_text_width_with_fonts_of_at_least_7_pt():
    """The report includes figures unscaled, so matplotlib's sizes are the printed sizes."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import (
        MIN_FONT_PT,
        TEXT_WIDTH,
        plot_calibration,
        plot_error_vs_ntrain,
    )

    rows = []
    for n in (30, 100):
        for r in _rows(
            {
                ("golf", "PM"): [8.0, 9.0],
                ("golf", "RVM"): [12.0, 13.0],
                ("acrobatics", "PM"): [5.0, 6.0],
                ("acrobatics", "RVM"): [7.0, 7.5],
            }
        ):
            rows.append(dict(r, n_train=n, coverage_50=0.4, coverage_90=0.8))
    df = aggregate_rows(rows)
    figs = [
        plot_error_vs_ntrain(df, _paper(), source="hsc", methods=["PM", "RVM"], labels=LABELS),
        plot_calibration(df, methods=["PM", "RVM"], labels=LABELS, source="hsc"),
    ]
    for fig in figs:
        fig.canvas.draw()
        bbox = fig.get_tightbbox(fig.canvas.get_renderer())
        assert bbox.width <= TEXT_WIDTH + 0.01
        sizes = [
            t.get_fontsize()
            for t in fig.findobj(plt.Text)
            if t.get_visible() and t.get_text().strip()
        ]
        assert sizes and min(sizes) >= MIN_FONT_PT
        ticks = [float(t.get_text()) for t in fig.axes[0].get_xticklabels() if t.get_text()]
        if ticks and fig is figs[0]:
            assert ticks == [30.0, 100.0]  # only the sizes studied
        plt.close(fig)


@pytest.mark.parametrize(
    "protocols, shown", [(("contiguous",), "contiguous"), (("contiguous", "random"), "random")]
)
def test_calibration_uses_the_random_protocol_else_the_one_run(protocols, shown):
    """A study without the random protocol (the ablation) still gets its calibration curves, titled by protocol."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import plot_calibration

    rows = []
    for protocol in protocols:
        cov = {"random": 0.4, "contiguous": 0.2}[protocol]
        for r in _rows({("golf", "PM"): [8.0, 9.0]}):
            rows.append(dict(r, protocol=protocol, coverage_50=cov, coverage_90=2 * cov))
    fig = plot_calibration(aggregate_rows(rows), methods=["PM"], labels=LABELS, source="hsc")
    ax = fig.axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_label() == LABELS["PM"]]
    assert len(lines) == 1
    np.testing.assert_allclose(
        lines[0].get_ydata(), [0.4, 0.8] if shown == "random" else [0.2, 0.4]
    )
    assert ax.get_title() == ("N = 30" if shown == "random" else "N = 30 (contiguous)")
    assert not [t for t in ax.texts if "no method" in t.get_text()]
    plt.close(fig)


@pytest.mark.parametrize(
    "protocols", [("contiguous",), ("random",), ("random", "contiguous"), ("cross_trial",)]
)
def test_error_figure_legend_names_only_the_protocols_run(protocols):
    """Before: the legend always had "this study (random)", also for a contiguous-only study; a cross-trial
    study's Fig. 1 drew no line at all."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import plot_error_vs_ntrain

    rows = [dict(r, protocol=p) for p in protocols for r in _rows({("golf", "PM"): [8.0, 9.0]})]
    fig = plot_error_vs_ntrain(
        aggregate_rows(rows), _paper(), source="hsc", methods=["PM"], labels=LABELS
    )
    names = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
    expected = [
        f"this study ({p.replace('_', '-')})"
        for p in ("random", "contiguous", "cross_trial")
        if p in protocols
    ]
    assert [n for n in names if n.startswith("this study")] == expected
    assert "PM" in names and "the paper" in names
    styles = {ln.get_linestyle() for ln in fig.axes[0].get_lines()} - {
        ":",
        "None",
    }  # the paper dotted; caps
    assert styles == {
        {"random": "-", "contiguous": "--", "cross_trial": "-."}[p] for p in protocols
    }
    plt.close(fig)


def test_error_figure_draws_the_paper_only_where_this_study_has_a_point():
    """Before: Fig. 1 drew the paper's point at every configured N, also at an N the study skipped for that
    activity (walk at N = 100 in the quick study: 167 frames leave 67 < min_test test frames), with no point of
    ours beside it and no word in the caption. Now the paper is drawn at the N the study ran for the activity,
    and paper_points_not_drawn names what is left out (for the caption)."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import paper_points_not_drawn, plot_error_vs_ntrain

    paper = pd.read_csv(
        io.StringIO(PAPER_CSV + "I,Golf,100,PM,5.0,1.0\nI,Acrobatics,100,PM,9.0,1.0\n")
    )
    paper["key"] = paper["activity"].map(paper_key)
    rows = [
        dict(r, n_train=30)
        for r in _rows({("golf", "PM"): [8.0, 9.0], ("acrobatics", "PM"): [12.0, 13.0]})
    ]
    rows += [
        dict(r, n_train=100) for r in _rows({("golf", "PM"): [6.0, 7.0]})
    ]  # acrobatics: N = 100 skipped
    df = aggregate_rows(rows)
    kw = dict(source="hsc", methods=["PM"], labels=LABELS, n_train=[30, 100])
    fig = plot_error_vs_ntrain(df, paper, **kw)
    panels = {ax.get_title(): ax for ax in fig.axes}
    for title, sizes in (("Golf", [30, 100]), ("Acrobatics", [30])):
        dotted = [ln for ln in panels[title].get_lines() if ln.get_linestyle() == ":"]
        assert len(dotted) == 1, title  # the paper's PM line
        np.testing.assert_allclose(dotted[0].get_xdata(), sizes, rtol=0.05, err_msg=title)
    plt.close(fig)
    assert paper_points_not_drawn(df, paper, **kw) == {"Acrobatics": [100]}
    # a method the figure does not draw, or a size the study does not configure, is no omission
    assert paper_points_not_drawn(df, paper, **{**kw, "methods": ["NN1"]}) == {}
    assert paper_points_not_drawn(df, paper, **{**kw, "n_train": [30]}) == {}


def _error_axis_labels(lo, hi):
    """Fig. 1 for errors from about ``lo`` (N = 100) to ``hi`` (N = 30) degrees: (y limits, {value: label} of the
    labelled y ticks inside them), read from the drawn canvas (major and minor ticks)."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import plot_error_vs_ntrain

    rows = []
    for n, err in ((30, hi), (100, lo)):
        for r in _rows(
            {("golf", "PM"): [err, err * 0.98], ("golf", "RVM"): [err * 0.99, err * 0.97]}
        ):
            rows.append(dict(r, n_train=n))
    fig = plot_error_vs_ntrain(
        aggregate_rows(rows), _paper()[:0], source="hsc", methods=["PM", "RVM"], labels=LABELS
    )
    fig.canvas.draw()
    ax = fig.axes[0]
    y0, y1 = ax.get_ylim()
    labels = {}
    for minor in (False, True):
        for t in ax.get_yticklabels(minor=minor):
            v = t.get_position()[1]
            if t.get_text() and y0 <= v <= y1:
                assert float(t.get_text()) == pytest.approx(v)  # the label is the tick's value
                labels[v] = t.get_text()
    plt.close(fig)
    return (y0, y1), labels


@pytest.mark.parametrize(
    "lo, hi", [(3.0, 25.0), (7.0, 18.0), (4.0, 17.0), (1.6, 17.0), (11.0, 60.0), (9.6, 10.4)]
)
def test_error_axis_is_labelled_across_its_whole_range(lo, hi):
    """Before: labels only at 1, 2, 3, 5 (or every integer) times a power of ten, so an axis from 7 to 18
    degrees was labelled 7, 8, 9, 10 and nothing above 10. Now every 10^k and 2, 3, 5 x 10^k of a range over a
    decade is labelled, and labels cover the whole range: at least four, none of the gaps between them (or
    between an end of the axis and the nearest label) wider than 40% of the axis in log scale."""
    (y0, y1), labels = _error_axis_labels(lo, hi)
    values = sorted(labels)
    assert len(values) >= 4, labels
    logs = np.log10([y0, *values, y1])
    assert np.diff(logs).max() <= 0.4 * (logs[-1] - logs[0]) + 1e-9, labels
    if y1 > 12:
        assert max(values) > 10, labels
    if y1 / y0 >= 10:
        nice = [m * 10.0**k for k in range(-1, 3) for m in (1, 2, 3, 5) if y0 <= m * 10.0**k <= y1]
        assert all(any(np.isclose(v, n) for v in values) for n in nice), (nice, labels)
    if (lo, hi) == (3.0, 25.0):
        assert [labels[v] for v in values] == ["3", "5", "10", "20"]


def test_hsc_stick_figures_show_the_input_histogram_and_the_authors_skeleton():
    """Features without images (the hsc source) get the input histogram in the silhouette's place, and the
    true and predicted poses as stick figures of the authors' skeleton, drawn at the same scale in a row."""
    import matplotlib.pyplot as plt
    from matplotlib.container import BarContainer

    from bsrbench.authors import hsc_stick_figure
    from bsrbench.reporting.plots import MIN_FONT_PT, TEXT_WIDTH, plot_subjective_sticks

    rng = np.random.default_rng(0)
    y_true = rng.uniform(-40, 40, 57)
    y_pred = y_true + rng.normal(0, 5, 57)
    true, parents = hsc_stick_figure(y_true)
    pnl = {
        "label": "Golf",
        "frame": 7,
        "x": rng.random(100),
        "parents": parents,
        "true": true,
        "preds": {"PM": hsc_stick_figure(y_pred)[0]},
        "errors": {"PM": 4.2},
    }
    fig = plot_subjective_sticks([pnl], labels=LABELS)
    hist, true_ax, pred_ax = fig.axes[:3]
    bars = [c for c in hist.containers if isinstance(c, BarContainer)]
    assert len(bars) == 1 and len(bars[0]) == 100
    assert "input histogram" in hist.get_title() and "test frame 7" in hist.get_title()
    assert true_ax.get_title() == "true pose" and pred_ax.get_title() == "PM (4.2 deg)"
    # one line per bone: the true pose alone, the prediction over the true pose in grey
    n_bones = int((parents >= 0).sum())
    assert len(true_ax.lines) == n_bones and len(pred_ax.lines) == 2 * n_bones
    assert true_ax.get_xlim() == pred_ax.get_xlim()
    fig.canvas.draw()
    assert fig.get_tightbbox(fig.canvas.get_renderer()).width <= TEXT_WIDTH + 0.01
    sizes = [
        t.get_fontsize() for t in fig.findobj(plt.Text) if t.get_visible() and t.get_text().strip()
    ]
    assert min(sizes) >= MIN_FONT_PT
    plt.close(fig)


def test_stick_figure_titles_of_long_method_labels_stay_over_their_panel():
    """Before: "PM K=16 5000 sw. text pred. (7.6 deg)" ran into the next panel's title (the paper-goal report)."""
    import matplotlib.pyplot as plt

    from bsrbench.authors import hsc_stick_figure
    from bsrbench.reporting.plots import plot_subjective_sticks

    rng = np.random.default_rng(1)
    true, parents = hsc_stick_figure(rng.uniform(-40, 40, 57))
    methods = ["PMK8", "PMK16s5000text", "NN1"]
    labels = {"PMK8": "PM K=8", "PMK16s5000text": "PM K=16 5000 sw. text pred.", "NN1": "1-NN"}
    pnl = {
        "label": "Golf",
        "frame": 7,
        "x": rng.random(100),
        "parents": parents,
        "true": true,
        "preds": {m: hsc_stick_figure(rng.uniform(-40, 40, 57))[0] for m in methods},
        "errors": {m: 7.6 for m in methods},
    }
    fig = plot_subjective_sticks([pnl], labels=labels)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    titles = [ax.title for ax in fig.axes[1:5]]
    assert titles[2].get_text().replace("\n", " ") == "PM K=16 5000 sw. text pred. (7.6 deg)"
    boxes = [t.get_window_extent(r) for t in titles]
    for left, right in zip(boxes, boxes[1:]):
        assert left.x1 < right.x0, (left, right)  # no title overlaps its neighbour
    plt.close(fig)


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
    df = aggregate_rows(_rows({("acrobatics", "PM"): [8.0, 9.0], ("golf", "PM"): [5.0, 6.0]}))
    path = tmp_path / "results.csv"
    df.to_csv(path, index=False)
    assert len(read_results(path)) == 4
    damage(df).to_csv(path, index=False)
    with pytest.raises(DataFileError, match=message):
        read_results(path)


# ------------------------------------------------------------------------ python -m bsrbench.reporting.published
PUBLISHED = Path(__file__).resolve().parents[1] / "reports" / "published" / "paper.csv"
PAPER_TABLES_CSV = Path(__file__).resolve().parents[1] / "resources" / "paper-tables.csv"


def _files(tmp_path):
    """Missing and garbled inputs: {name: path}."""
    out = {"missing": tmp_path / "nope" / "file.csv", "folder": tmp_path}
    for name, data in {
        "binary": b"\x00\xff\xfe garbage",
        "empty": b"",
        "cols": b"a,b\n1,2\n",
    }.items():
        out[name] = tmp_path / f"{name}.csv"
        out[name].write_bytes(data)
    bad = PAPER_TABLES_CSV.read_text().replace(
        "I,Acrobatics,30,RVM,15.963", "I,Acrobatics,30,RVM,abc", 1
    )
    out["paper-value"] = tmp_path / "paper-value.csv"
    out["paper-value"].write_text(bad)
    return out


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["readme", "{published}", "--update", "{missing}"],
            r"nope/file\.csv: cannot read the file to update \(No such file or directory\); expected an existing UTF-8",
        ),
        (
            ["readme", "{published}", "--update", "{folder}"],
            r"cannot read the file to update \(Is a directory\)",
        ),
        (
            ["readme", "{published}", "--update", "{binary}"],
            r"binary\.csv: cannot read the file to update \('utf-8'",
        ),
        (
            ["readme", "{published}", "--update", "{cols}"],
            r"cols\.csv: no markers '<!-- results-table:hsc -->'",
        ),
        (["readme", "{missing}"], r"file\.csv: cannot read the aggregate table"),
        (["readme", "{binary}"], r"binary\.csv: cannot read the aggregate table \('utf-8' codec"),
        (["readme", "{empty}"], r"empty\.csv: cannot read the aggregate table \(No columns"),
        (["readme", "{cols}"], r"cols\.csv: missing columns \['protocol'"),
        (
            ["readme", "{published}", "--paper", "{binary}"],
            r"binary\.csv: cannot read the paper's tables",
        ),
        (
            ["readme", "{published}", "--paper", "{empty}"],
            r"empty\.csv: cannot read the paper's tables",
        ),
        (
            ["readme", "{published}", "--paper", "{paper-value}"],
            r"paper-value\.csv: row 2, column 'mean_deg': 'abc'; expected a finite number >= 0",
        ),
        (["readme", "{published}", "--protocol", "sideways"], r"no rows of protocol 'sideways'"),
        (
            ["publish", "--study", "out", "{binary}", "{tmp}/out.csv"],
            r"binary\.csv: cannot read the aggregate table",
        ),
        (
            ["publish", "{published}", "{binary}/out.csv"],
            r"binary\.csv/out\.csv: cannot write the published table",
        ),
        (
            ["publish", "{published}", "{tmp}/nope/out.csv"],
            r"nope/out\.csv: cannot write the published table: its folder '.*/nope' does not exist; expected the path "
            r"of a table in an existing folder",
        ),
    ],
    ids=[
        "update-missing",
        "update-folder",
        "update-binary",
        "update-no-markers",
        "table-missing",
        "table-binary",
        "table-empty",
        "table-columns",
        "paper-binary",
        "paper-empty",
        "paper-value",
        "protocol",
        "publish-binary",
        "publish-unwritable",
        "publish-missing-folder",
    ],
)
def test_published_cli_missing_or_garbled_input_is_a_clear_error(tmp_path, capsys, args, message):
    """Before: `readme ... --update MISSING` (and a binary table, an empty or non-numeric paper table, an
    unwritable destination) ended in a FileNotFoundError/UnicodeDecodeError/ValueError traceback; now exit code 2
    and one line naming the file, with every input left unchanged."""
    from bsrbench.reporting.published import main

    paths = {k: str(v) for k, v in _files(tmp_path).items()}
    before = {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    argv = [a.format(published=PUBLISHED, tmp=tmp_path, **paths) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert re.search(message, err), err
    assert {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before
    assert not (
        tmp_path / "nope"
    ).exists()  # publish to a missing folder creates nothing (it used to create it)


def test_publish_refuses_another_studys_table(tmp_path, capsys):
    """Before: `publish results/quick/aggregate/results.csv reports/published/paper.csv` silently replaced the
    committed paper-protocol table with the quick study's results. Now the destination must be named after the study
    (the folder of results/<study>/aggregate/results.csv, or --study for a source outside results/): exit 2, one line
    naming both studies and the right command, the destination unchanged; the right command then works."""
    from bsrbench.reporting.published import main

    src = tmp_path / "results" / "quick" / "aggregate" / "results.csv"
    src.parent.mkdir(parents=True)
    src.write_bytes(PUBLISHED.read_bytes())
    dest = tmp_path / "reports" / "published" / "paper.csv"
    dest.parent.mkdir(parents=True)
    dest.write_text("the committed paper table\n")

    def fails(argv, *needles):
        assert main([str(a) for a in argv]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1, err
        for needle in needles:
            assert needle in err, (needle, err)
        assert dest.read_text() == "the committed paper table\n"
        assert not dest.with_name("quick.csv").exists()

    fails(
        ["publish", src, dest],
        "study 'quick'",
        "is study 'paper'",
        f"The right command: python -m bsrbench.reporting.published publish {src} {dest.with_name('quick.csv')}",
    )
    fails(
        ["publish", "--study", "paper", src, dest], "--study 'paper' contradicts", "study 'quick'"
    )
    outside = tmp_path / "elsewhere.csv"
    outside.write_bytes(PUBLISHED.read_bytes())
    fails(["publish", outside, dest], "cannot tell the study", "--study NAME")
    fails(
        ["publish", "--study", "quick", outside, dest],
        "is study 'paper'",
        f"--study quick {outside}",
    )

    assert main(["publish", str(src), str(dest.with_name("quick.csv"))]) == 0
    assert main(["publish", "--study", "paper", str(outside), str(dest)]) == 0
    assert (
        dest.read_bytes()
        == dest.with_name("quick.csv").read_bytes()
        != b"the committed paper table\n"
    )


# ------------------------------------------------------------------------------ paired comparisons in the report
def _paired(errors, n_test=570):
    """errors: {(activity, method): [error per seed]} -> aggregate with n_test."""
    rows = _rows(errors)
    for r in rows:
        r["n_test"] = n_test
    return aggregate_rows(rows)


def test_tables_do_not_import_the_report_module():
    """Before: tables imported NO_ROW from report, which imports tables (an import cycle)."""
    import subprocess
    import sys

    code = (
        "import sys, bsrbench.reporting.tables as t; "
        "assert 'bsrbench.reporting.report' not in sys.modules; print(t.NO_ROW['download'])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "data not on this machine"


def test_latex_table_marks_the_means_tied_with_the_best_and_says_so():
    from bsrbench.reporting.comparisons import comparisons, tied_with_best

    # PM ties NN1 (noise around the same level), RVM is worse by a constant 5 degrees: p = 0, never tied
    df = _paired(
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
    text = latex_table(summarize(df), _paper(), ties=ties, **kw)
    golf = next(ln for ln in text.splitlines() if ln.startswith("Golf & 30"))
    cells = golf[:-2].split(" & ")
    assert cells[2].startswith("11.50 $") and r"\dagger" not in cells[2]
    assert cells[3].startswith(r"6.63$^{\dagger}$ $\pm$")
    assert cells[4].startswith(r"\textbf{6.50}") and r"\dagger" not in cells[4]
    assert r"$^{\dagger}$: statistically indistinguishable from the best of its row" in text
    assert "Holm-adjusted" in text and r"$p \geq 0.05$" in text
    plain = latex_table(summarize(df), _paper(), **kw)
    assert r"\dagger" not in plain.split(r"\caption")[1].split("\n", 1)[1]
    assert "No paired comparisons were made" in plain
    # one split: no test, no mark, and the caption says so
    one = df[df["seed"] == 0]
    t1 = latex_table(summarize(one), _paper(), ties=tied_with_best(comparisons(one)), **kw)
    assert "no row was tested and none is marked" in t1


def test_findings_count_pm_against_the_best_and_1nn(tmp_path):
    from bsrbench.reporting.comparisons import comparisons

    base = np.array([5.0, 5.3, 4.8, 5.1, 5.2])
    rng = np.random.default_rng(1)
    errors = {
        # golf: PM worse than the best (SR) and than 1-NN by a constant: significant
        ("golf", "SR"): list(base),
        ("golf", "NN1"): list(base + 0.5),
        ("golf", "PM"): list(base + 2.0),
        # acrobatics: PM is the best; 1-NN ties with it (noise)
        ("acrobatics", "SR"): list(base + 3.0),
        ("acrobatics", "NN1"): list(base + rng.normal(0, 0.1, 5)),
        ("acrobatics", "PM"): list(base - 0.05),
    }
    df = _paired(errors)
    comp = comparisons(df)
    labels = {"NN1": "1-NN", "PM": "PM", "SR": "SR"}
    text = " ".join(findings(df, _paper(), labels=labels, comparisons=comp))
    assert (
        "PM is significantly worse, tied or better than the best method of the cell: worse in 1, tied in 0, "
        "better in 0, and PM is itself the best in 1 of the 2 cells; than 1-NN: worse in 1, tied in 1, better in 0 "
        "of the 2 cells. By the Wilcoxon signed-rank test alone (no allowance for the overlap of the splits or for "
        "the number of comparisons) PM is worse than the best method of the cell in 0 and than 1-NN in 0"
        in text
    )  # 5 splits: the smallest two-sided Wilcoxon p is 2/32 > 0.05
    out = tmp_path / "findings.tex"
    write_generated(out, df, _paper(), labels=labels, comparisons=comp)
    tex = out.read_text()
    assert r"\label{tab:pm-counts}" in tex
    assert "random & hsc & best method & 2 & 1 & 0 & 0 & 1 & 0 & 0" in tex
    assert "random & hsc & 1-NN & 2 & 1 & 1 & 0 &  & 0 & 0" in tex
    # without comparisons: neither the sentence nor the table
    write_generated(out, df, _paper(), labels=labels)
    assert "tab:pm-counts" not in out.read_text()


def test_readme_tables_mark_ties_and_count_pm(tmp_path, capsys):
    from bsrbench.reporting.comparisons import comparisons
    from bsrbench.reporting.published import TIE_LEGEND, main, readme_counts, readme_tables

    df = _paired(
        {
            ("golf", "NN1"): [6.0, 7.0, 6.5],
            ("golf", "PM"): [6.2, 6.9, 6.8],
            ("golf", "RVM"): [11.0, 12.0, 11.5],
        }
    )
    t = readme_tables(df, _paper())["hsc"]
    row = next(ln for ln in t.splitlines() if ln.startswith("| golf | 30 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert (
        cells[2].startswith("11.50±")
        and cells[3].startswith("6.63†±")
        and cells[4].startswith("**6.50**±")
    )
    assert t.endswith(TIE_LEGEND)
    counts = readme_counts(comparisons(df))
    assert "| random | hsc | best method | 1 | 0 | 1 | 0 | 0 | 0 | 0 |" in counts
    assert "| random | hsc | 1-NN | 1 | 0 | 1 | 0 |  | 0 | 0 |" in counts
    # --update fills the optional counts markers
    src = tmp_path / "paper.csv"
    df.to_csv(src, index=False)
    readme = tmp_path / "README.md"
    readme.write_text(
        "<!-- results-table:hsc -->\nSTALE\n<!-- /results-table:hsc -->\n"
        "<!-- results-counts -->\nSTALE\n<!-- /results-counts -->\n"
    )
    assert main(["readme", str(src), "--update", str(readme)]) == 0
    text = readme.read_text()
    assert "STALE" not in text and "6.63†" in text and "| random | hsc | 1-NN |" in text
    readme.write_text("<!-- results-table:hsc -->\nSTALE\n<!-- /results-table:hsc -->\n")
    assert main(["readme", str(src), "--update", str(readme)]) == 0
    assert "no markers '<!-- results-counts -->'" in capsys.readouterr().err


def test_published_comparisons_are_the_paper_table_s_and_have_exactly_the_columns(tmp_path, capsys):
    from bsrbench.reporting.comparisons import PUBLISHED_COLUMNS
    from bsrbench.reporting.published import main

    dest = tmp_path / "paper-comparisons.csv"
    assert main(["comparisons", str(PUBLISHED), str(dest)]) == 0
    got = pd.read_csv(dest)
    assert list(got.columns) == PUBLISHED_COLUMNS
    committed = pd.read_csv(PUBLISHED.with_name("paper-comparisons.csv"))
    pd.testing.assert_frame_equal(got, committed)
    # one cell by hand: SR against PM, hsc golf N = 30 (corrected t with the rows' n_test)
    paper = pd.read_csv(PUBLISHED)
    cell = paper[(paper.source == "hsc") & (paper.activity == "golf") & (paper.n_train == 30)]
    e = cell.pivot(index="seed", columns="method", values="error")
    d = (e["SR"] - e["PM"]).to_numpy()
    n_test = float(cell["n_test"].mean())
    se = np.sqrt((1 / d.size + n_test / 30) * d.var(ddof=1))
    from scipy import stats

    p = 2 * stats.t.sf(abs(d.mean() / se), d.size - 1)
    row = got[(got.source == "hsc") & (got.activity == "golf") & (got.n_train == 30)]
    row = row[(row.method == "SR") & (row.versus == "PM")].iloc[0]
    assert row.n_splits == 10 and row.mean_diff == pytest.approx(d.mean())
    assert row.p_corrected_t == pytest.approx(p)
    # the destination is named after the table
    assert main(["comparisons", str(PUBLISHED), str(tmp_path / "other.csv")]) == 2
    assert "go to 'paper-comparisons.csv'" in capsys.readouterr().err


def _chained(rhats, *, extra=None):
    """Rows of PMK16 and NN1 (golf, contiguous, N = 30), one per split, PMK16 with 4 chains and these R-hats of
    the log-likelihood and g_xy; ``extra``: {column: value per split} (tail ESS, MCSE)."""
    from bsrbench.reporting import convergence as conv

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
    from bsrbench.reporting import convergence as conv

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
    g = conv.goal_table(_chained([(1.001, 1.009), (1.02, 1.0)]), variants=["PMK16"]).iloc[0]
    assert (g["converged"], g["both"], g["converged_strict"], g["both_strict"]) == (1, 1, 0, 0)
    g = conv.goal_table(_chained([(1.001, 1.009), (1.002, 1.0)]), variants=["PMK16"]).iloc[0]
    assert (g["converged_strict"], g["both_strict"]) == (1, 1)
    tex = conv.goal_latex(_chained([(1.001, 1.009), (1.02, 1.0)]), variants=["PMK16"], labels={})
    assert "PMK16 & yes & 1 & 1 & 1 & 1 & 1.0 & 0 & 0" in tex and r"$\hat R < 1.01$" in tex
    text = conv.goal_sentence(
        _chained([(1.001, 1.009), (1.02, 1.0)]), variants=["PMK16"], labels={}
    )
    assert r"At $\hat R < 1.01$ every split converged in 0 of its cells" in text
