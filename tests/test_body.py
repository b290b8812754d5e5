"""The report's sections Tables and Figures (bsrbench.reporting.body): the notes on missing data and the tables
left out."""

import re

from bsrbench.reporting.body import missing_data_note, write_body
from bsrbench.reporting.tables import (
    PAPER_TABLES,
)


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


def test_a_table_without_any_studied_activity_is_left_out_and_the_note_says_so(tmp_path):
    """Before: the quick study's mocap Table I was three rows of "data not on this machine" (it studies walk,
    of Table II, only). Now a table none of whose activities is studied on a source is not built, and the
    note under that source's tables says which table is left out and why."""
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
