"""bsrbench.reporting.compare: two result tables within a tolerance."""

import numpy as np
import pandas as pd
import pytest

from bsrbench.errors import DataFileError, InputError
from bsrbench.reporting.compare import compare_tables, main


def _table(path, changes=None):
    rows = [
        dict(protocol="random", source="hsc", activity="golf", method=m, n_train=30, seed=s,
             error=1.0 + s + (m == "PM"), coverage=np.nan if m == "SR" else 0.9,
             params="{'alpha': 1.0}", fit_seconds=0.1 * s)
        for m in ("PM", "SR") for s in range(3)
    ]  # fmt: skip
    df = pd.DataFrame(rows)
    for (m, s, col), v in (changes or {}).items():
        df.loc[(df.method == m) & (df.seed == s), col] = v
    df.to_csv(path, index=False)
    return path


def test_equal_tables_and_ignored_timings(tmp_path):
    a = _table(tmp_path / "a.csv")
    b = _table(tmp_path / "b.csv", {("SR", 1, "fit_seconds"): 99.0})
    res = compare_tables(a, b)
    assert res.equal and res.n_rows == 6
    assert main([str(a), str(b)]) == 0


def test_a_difference_is_found_only_beyond_the_tolerance(tmp_path, capsys):
    a = _table(tmp_path / "a.csv")
    b = _table(tmp_path / "b.csv", {("PM", 2, "error"): 4.0 + 3e-7})
    res = compare_tables(a, b, atol=1e-9)
    n, d, key = res.columns["error"]
    assert n == 1 and d == pytest.approx(3e-7, rel=1e-6) and key[3] == "PM" and key[5] == 2
    assert compare_tables(a, b, atol=1e-6).equal
    assert compare_tables(a, b, rtol=1e-7).equal  # 3e-7 <= 1e-7 * 4.0000003
    assert main([str(a), str(b)]) == 1
    assert "error: 1 rows differ" in capsys.readouterr().out


def test_nan_on_both_sides_is_equal_on_one_side_a_difference(tmp_path):
    a = _table(tmp_path / "a.csv")
    b = _table(tmp_path / "b.csv", {("PM", 0, "coverage"): np.nan})
    assert list(compare_tables(a, b).columns) == ["coverage"]
    assert compare_tables(a, a).equal  # SR's coverage is NaN in both


def test_text_columns_and_missing_rows(tmp_path):
    a = _table(tmp_path / "a.csv")
    b = _table(tmp_path / "b.csv", {("SR", 2, "params"): "{'alpha': 0.1}"})
    assert compare_tables(a, b).columns["params"][0] == 1
    df = pd.read_csv(a)
    df[df.seed < 2].to_csv(tmp_path / "c.csv", index=False)
    res = compare_tables(a, tmp_path / "c.csv")
    assert len(res.only_a) == 2 and not res.only_b and not res.columns and not res.equal


def test_bad_tables_name_the_file_and_what_is_wrong(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("protocol,source\nrandom,hsc\n")
    with pytest.raises(DataFileError, match=r"bad\.csv: has no column\(s\) \['activity'"):
        compare_tables(bad, bad)
    a = _table(tmp_path / "a.csv")
    df = pd.read_csv(a)
    pd.concat([df, df.iloc[[3]]]).to_csv(tmp_path / "dup.csv", index=False)
    with pytest.raises(DataFileError, match=r"dup\.csv: has two rows for the job .*line 8"):
        compare_tables(a, tmp_path / "dup.csv")
    with pytest.raises(InputError, match=r"--columns \['eror'\]"):
        compare_tables(a, a, columns=["eror"])
    assert main([str(a), str(tmp_path / "missing.csv")]) == 2


def test_number_lists_are_compared_within_the_tolerance_and_provenance_is_ignored(tmp_path):
    a = _table(tmp_path / "a.csv", {("PM", 0, "per_angle_rms"): "[1.0, 2.0]"})
    df = pd.read_csv(a)
    df["per_angle_rms"] = df["per_angle_rms"].fillna("[1.0, 2.0]")
    df["code_fingerprint"] = "abc"
    df.to_csv(a, index=False)
    b = tmp_path / "b.csv"
    df.assign(per_angle_rms="[1.0, 2.00001]", code_fingerprint="def").to_csv(b, index=False)
    assert compare_tables(a, b, atol=1e-4).equal
    res = compare_tables(a, b, atol=1e-6)
    assert list(res.columns) == ["per_angle_rms"]
    n, d, _ = res.columns["per_angle_rms"]
    assert n == 6 and d == pytest.approx(1e-5)
