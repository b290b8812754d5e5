"""The result rows (bsrbench.results): a job's key columns, the aggregate table, its reading and design checks."""

import pytest

from bsrbench.errors import DataFileError, InputError
from bsrbench.results import (
    KEY_COLUMNS,
    aggregate_files,
    aggregate_rows,
    design_changes,
    read_results,
    row_key,
    write_csv,
)
from bsrbench.splits import JobSpec

DESIGN = {
    "protocols": ["random"],
    "pairs": [["hsc", "golf"]],
    "methods": ["PM", "NN1"],
    "n_train": [30],
    "seeds": [0, 1],
}


def _row(method, seed, error):
    spec = JobSpec("hsc", "golf", method, 30, seed, paper_activity="Golf")
    return {**row_key(spec), "error": error, "params": {"k": 1}}


def test_row_key_is_the_jobs_identity_in_the_rows_order():
    spec = JobSpec("hsc", "golf", "PM", "30", "1", protocol="contiguous", paper_activity="")
    key = row_key(spec)
    assert list(key) == [
        "source",
        "activity",
        "paper_activity",
        "method",
        "n_train",
        "seed",
        "protocol",
        "pose_transform",
    ]
    assert set(KEY_COLUMNS) <= set(key)
    assert (key["n_train"], key["seed"], key["protocol"]) == (30, 1, "contiguous")


def test_aggregate_sorts_flattens_and_refuses_duplicates(tmp_path):
    rows = [_row(m, k, 5.0 + k) for m in ("PM", "NN1") for k in (1, 0)]
    df = aggregate_rows(rows)
    assert list(df.columns[: len(KEY_COLUMNS) + 1]) == KEY_COLUMNS + ["error"]
    assert list(zip(df["method"], df["seed"])) == [("NN1", 0), ("NN1", 1), ("PM", 0), ("PM", 1)]
    assert df["params"].iloc[0] == '{"k": 1}'
    with pytest.raises(InputError, match="duplicate result rows"):
        aggregate_rows(rows + rows[:1])
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    with pytest.raises(DataFileError, match="cannot read result row"):
        aggregate_files([bad])


def test_read_results_checks_the_design_and_every_cells_seeds(tmp_path):
    path = tmp_path / "results.csv"
    write_csv(aggregate_rows([_row(m, k, 5.0) for m in ("PM", "NN1") for k in (0, 1)]), path)
    assert len(read_results(path, design=DESIGN)) == 4
    assert design_changes(read_results(path), {**DESIGN, "n_train": [30, 60]})[0] == 4
    with pytest.raises(
        DataFileError, match=r"0 configured job\(s\) without a row, 2 row\(s\) of jobs not"
    ):
        read_results(path, design={**DESIGN, "methods": ["PM"]})
    write_csv(aggregate_rows([_row("PM", 0, 5.0), _row("PM", 1, 5.0), _row("NN1", 0, 5.0)]), path)
    with pytest.raises(DataFileError, match=r"has seeds \[0\]; expected all of \[0, 1\]"):
        read_results(path)
