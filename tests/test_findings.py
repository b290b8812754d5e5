"""The report's findings (bsrbench.reporting.findings): where the paper's claims hold, counted from the tables."""

import re

import numpy as np
import pandas as pd
from reportdata import LABELS, paired_rows, paper_frame, result_rows

from bsrbench.reporting.findings import (
    findings,
    write_generated,
)
from bsrbench.reporting.tables import (
    aggregate_rows,
    paper_key,
)


def test_findings_count_where_the_claim_holds():
    df = aggregate_rows(
        result_rows(
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
    text = "\n".join(findings(df, paper_frame(), labels=LABELS))
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
    paper = paper_frame()
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
    df = aggregate_rows(result_rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]}))
    text = "\n".join(findings(df, paper, labels=LABELS))
    assert "every row" not in text
    assert "PM has a lower error than every other method in 2 of the 3 (activity, $N$) rows" in text
    assert "in 2 of the 2 (activity, $N$) rows" in "\n".join(
        findings(df, paper_frame(), labels=LABELS)
    )
    assert "paper's Tables" not in "\n".join(findings(df, None, labels=LABELS))


def test_ratio_to_the_paper_and_coverage_are_given_per_source():
    rows = result_rows({("golf", "PM"): [8.0, 9.0], ("golf", "RVM"): [12.0, 13.0]})
    mocap = [dict(r, source="mocap", error=r["error"] / 4) for r in rows]
    for r in rows + mocap:
        r["coverage_90"] = 0.5 if r["source"] == "hsc" else 0.9
    df = aggregate_rows(rows + mocap)
    text = "\n".join(findings(df, paper_frame(), labels=LABELS))
    hsc_pm, mocap_pm = 8.5 / 8.241, 8.5 / 4 / 8.241
    # methods in the configuration's order (that of the labels)
    assert (
        f"on the hsc data, RVM {12.5 / 14.514:.2f}, PM {hsc_pm:.2f}; "
        f"on the mocap data, RVM {12.5 / 4 / 14.514:.2f}, PM {mocap_pm:.2f}."
    ) in text
    assert r"on the hsc data, RVM 50\%, PM 50\%; on the mocap data, RVM 90\%, PM 90\%." in text


def test_findings_for_all_and_for_none():
    all_ok = aggregate_rows(
        result_rows(
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
        result_rows(
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
    better = aggregate_rows(result_rows({("golf", "PM"): [1.0], ("golf", "RVM"): [2.0]}))
    text = "\n".join(findings(better, None, labels=LABELS))
    assert "than RVM for the activity studied (\\mbox{Golf (hsc)})" in text
    worse = aggregate_rows(result_rows({("golf", "PM"): [3.0], ("golf", "RVM"): [2.0]}))
    text = "\n".join(findings(worse, None, labels=LABELS))
    assert "than RVM for no activity: not for \\mbox{Golf (hsc)}, the only activity studied" in text
    assert "for the activity studied" not in text


def test_findings_without_a_method_named_pm_point_to_the_variants():
    rows = result_rows({("golf", "PMK8"): [8.0, 9.0], ("golf", "NN1"): [7.0, 7.5]})
    text = findings(aggregate_rows(rows), None, labels={"PMK8": "PM K=8", "NN1": "1-NN"})
    assert text == [
        "No method named PM was run, so the paper's claims about it are not checked here; the PM "
        r"variants run (PM K=8) are compared in Section~\ref{sec:why-pm}."
    ]
    text = findings(aggregate_rows(result_rows({("golf", "NN1"): [7.0, 7.5]})), None, labels=LABELS)
    assert text == [
        "No method named PM was run, so the paper's claims about it are not checked here."
    ]


def test_findings_cover_every_protocol_run_and_the_section_is_never_an_empty_list(tmp_path):
    """Before: only the random and contiguous protocols had findings, so a cross-trial study got an empty
    itemize and LaTeX stopped ("perhaps a missing \\item"); the setup said CV used seed 0 when the study's
    splits start at seed 100."""
    rows = result_rows(
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
    df = paired_rows(errors)
    comp = comparisons(df)
    labels = {"NN1": "1-NN", "PM": "PM", "SR": "SR"}
    text = " ".join(findings(df, paper_frame(), labels=labels, comparisons=comp))
    assert (
        "PM is significantly worse, tied or better than the best method of the cell: worse in 1, tied in 0, "
        "better in 0, and PM is itself the best in 1 of the 2 cells; than 1-NN: worse in 1, tied in 1, better in 0 "
        "of the 2 cells. By the corrected resampled $t$-test (Nadeau and Bengio 2003), which asks about a new data "
        "set of independent frames, PM is worse than the best method of the cell in 1 and than 1-NN in 1"
        in text
    )  # golf: constant gaps, no variance: p = 0 by either test
    out = tmp_path / "findings.tex"
    write_generated(out, df, paper_frame(), labels=labels, comparisons=comp)
    tex = out.read_text()
    assert r"\label{tab:pm-counts}" in tex
    assert "random & hsc & best method & 2 & 1 & 0 & 0 & 1 & 0 & 1" in tex
    assert "random & hsc & 1-NN & 2 & 1 & 1 & 0 &  & 0 & 1" in tex
    # without comparisons: neither the sentence nor the table
    write_generated(out, df, paper_frame(), labels=labels)
    assert "tab:pm-counts" not in out.read_text()
