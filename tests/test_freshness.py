"""Fingerprints of result rows and the published tables' staleness check, verify, restamp and merge (issue 36)."""

import hashlib
import json
import math
import shutil
import subprocess
from pathlib import Path

import pandas as pd
import pytest

from bsrbench.reporting import freshness
from bsrbench.reporting.published import main
from bsrbench.results import (
    PROVENANCE_COLUMNS,
    code_digests,
    code_fingerprint,
    git_commit,
    row_provenance,
)
from bsrbench.sources import ROOT

NN1 = "bsrbench.models.reference:NearestNeighbourRegressor"
RIDGE = "bsrbench.models.reference:RidgeRegressor"


def test_the_code_fingerprint_is_the_hash_of_the_methods_files_by_relative_path():
    digests = code_digests(NN1)
    assert "bsrbench/models/reference.py" in digests and "bsrbench/runs.py" in digests
    assert "bsrbench/models/bsr.py" not in digests  # PM's module is not 1-NN's code
    for rel, digest in digests.items():
        assert digest == hashlib.sha256((ROOT / rel).read_bytes()).hexdigest()
    by_hand = hashlib.sha256(
        "".join(f"{p}\0{d}\n" for p, d in sorted(digests.items())).encode()
    ).hexdigest()
    assert code_fingerprint(digests) == by_hand
    edited = {**digests, "bsrbench/seeds.py": "0" * 64}
    assert code_fingerprint(edited) != by_hand
    assert code_fingerprint({**digests, "bsrbench/new.py": "0" * 64}) != by_hand


def test_git_commit_names_head_and_a_dirty_work_tree(tmp_path):
    assert git_commit(tmp_path) == "unknown"

    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), *args], check=True, capture_output=True)

    git("init", "-q")
    (tmp_path / "a.txt").write_text("a")
    git("add", "a.txt")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "a")
    head = subprocess.run(
        ["git", "-C", str(tmp_path), "rev-parse", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    assert git_commit(tmp_path) == head
    (tmp_path / "a.txt").write_text("b")
    assert git_commit(tmp_path) == head + "+dirty"


@pytest.fixture
def study(published_ci_table):
    return published_ci_table


def _write_part(df, path, files=("config/ci.yaml",)):
    """Write rows ``df`` as a part of the study ``files`` (a table and its provenance) to ``path``."""
    df.to_csv(path, index=False)
    freshness.write_table_provenance(path, df, list(files))
    return path


def test_a_row_carries_its_methods_fingerprint_and_the_commit(study):
    df = pd.read_csv(study)
    assert (
        df.loc[df["method"] == "NN1", "code_fingerprint"] == code_fingerprint(code_digests(NN1))
    ).all()
    assert set(df["git_commit"]) == {git_commit()}
    assert set(row_provenance(NN1)) == set(PROVENANCE_COLUMNS) <= set(df.columns)


def test_check_says_fresh_then_names_the_file_that_changed(study, capsys):
    assert main(["check", str(study)]) == 0
    assert capsys.readouterr().out.splitlines() == [f"{study} NN1: fresh", f"{study} Ridge: fresh"]
    # a table made by other code: the provenance's digest of seeds.py differs from today's
    prov = json.loads(freshness.provenance_path(study).read_text())
    prov["methods"]["NN1"]["files"]["bsrbench/seeds.py"] = "0" * 64
    freshness.provenance_path(study).write_text(json.dumps(prov))
    df = pd.read_csv(study)
    df.loc[df["method"] == "NN1", "code_fingerprint"] = "old"
    df.to_csv(study, index=False)
    assert main(["check", str(study)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0] == (
        f"{study} NN1: stale: 4 of 4 rows of other code (1 fingerprint(s)); changed: bsrbench/seeds.py"
    )
    assert out[1] == f"{study} Ridge: fresh"
    # knowingly historical: reported, not a failure
    prov["historical"] = "made before the change of X"
    freshness.provenance_path(study).write_text(json.dumps(prov))
    assert main(["check", str(study)]) == 0
    assert capsys.readouterr().out.strip() == f"{study}: historical: made before the change of X"


def test_check_names_a_table_without_fingerprints_and_unknown_methods(study, capsys):
    df = pd.read_csv(study)
    df.loc[0, "method"] = "Nobody"
    df.drop(columns=["code_fingerprint"]).to_csv(study, index=False)
    assert main(["check", str(study)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"{study} Nobody: unknown method (not run by config/ci.yaml)")
    assert out[1].startswith(f"{study}: stale: no code fingerprints")
    assert len(out) == 2


@pytest.mark.parametrize("content", [None, b"\x00\xff garbage", b"a,b\n1,2\n"])
def test_verify_of_a_missing_or_corrupt_table_is_one_line_and_exit_2(tmp_path, capsys, content):
    table = tmp_path / "ci.csv"
    if content is not None:
        table.write_bytes(content)
    assert main(["verify", str(table), "--rows", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(table) in err


def test_verify_reruns_rows_equal_and_finds_a_changed_one(study, capsys):
    feats = study.parent.parent / "features"
    assert freshness.verify(study, 2, seed=1, features_folder=feats)
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and all("equal within" in line for line in out)
    df = pd.read_csv(study)
    df["error"] *= 1.01  # one percent off: beyond rtol 1e-4
    df.to_csv(study, index=False)
    assert not freshness.verify(study, 5, features_folder=feats)
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 5 and all("DIFFERENT: error (|diff|" in line for line in out)


@pytest.mark.parametrize("command", ["verify", "restamp"])
def test_verify_and_restamp_refuse_rows_of_a_method_the_study_does_not_run(study, capsys, command):
    df = pd.read_csv(study)
    df.loc[0, "method"] = "Nobody"
    df.to_csv(study, index=False)
    assert main([command, str(study)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"{study}: methods ['Nobody'] are not run by config/ci.yaml" in err
    assert "such rows cannot be rerun" in err


def test_restamp_stamps_only_the_methods_whose_rows_rerun_equal(study, capsys):
    feats = study.parent.parent / "features"
    df = pd.read_csv(study)
    df["code_fingerprint"] = "old"
    df.loc[df["method"] == "Ridge", "error"] += 1.0  # Ridge's number changed: must stay stale
    df.to_csv(study, index=False)
    out = freshness.restamp(study, 3, features_folder=feats)
    assert out["NN1"][0] and not out["Ridge"][0]
    after = pd.read_csv(study)
    assert (
        after.loc[after["method"] == "NN1", "code_fingerprint"]
        == code_fingerprint(code_digests(NN1))
    ).all()
    assert (after.loc[after["method"] == "Ridge", "code_fingerprint"] == "old").all()
    prov = json.loads(freshness.provenance_path(study).read_text())
    rerun = prov["methods"]["NN1"]["restamped"]["rows_rerun"]
    assert len(rerun) == 3 and {r["method"] for r in rerun} == {"NN1"}
    assert prov["methods"]["Ridge"].get("restamped") is None
    capsys.readouterr()
    assert main(["check", str(study)]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"{study} NN1: fresh" and lines[1].startswith(f"{study} Ridge: stale")


def test_merge_keeps_the_newest_row_and_refuses_equal_age_conflicts(study, tmp_path, capsys):
    df = pd.read_csv(study)
    a, b = df.iloc[:3].copy(), df.iloc[2:].copy()
    b.loc[b.index[0], "error"] = 99.0
    b.loc[b.index[0], "written_at"] = "2100-01-01T00:00:00+00:00"  # newer than a's row of that job
    pa, pb, dest = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "published" / "ci.csv"
    _write_part(a, pa)
    _write_part(b, pb)
    assert main(["merge", str(pa), str(pb), str(dest)]) == 0
    merged = pd.read_csv(dest)
    assert len(merged) == len(df) and merged["error"].tolist().count(99.0) == 1
    # the same job twice, equal age, different numbers: refused, naming the job and the parts
    b.loc[b.index[0], "written_at"] = a.loc[a.index[2], "written_at"]
    b.to_csv(pb, index=False)
    assert main(["merge", str(pa), str(pb), str(dest)]) == 2
    err = capsys.readouterr().err
    assert "different rows of equal age" in err and "a.csv" in err and "b.csv" in err
    # identical rows in two parts are one row
    a.to_csv(pb, index=False)
    fresh = tmp_path / "published" / "ci-a.csv"
    assert main(["merge", str(pa), str(pb), str(fresh)]) == 0
    assert len(pd.read_csv(fresh)) == 3


def test_check_reads_every_published_table_of_the_project(capsys):
    """The committed tables: each reported by name, one line per table or method, no traceback."""
    tables = freshness.published_tables(
        Path(__file__).resolve().parents[1] / "reports" / "published"
    )
    assert tables and not any(freshness.is_derived(t) for t in tables)
    for t in tables:
        lines, _ = freshness.check_table(t)
        assert lines and all(line.startswith(str(t)) for line in lines)


def test_merging_a_new_part_into_a_restamped_table_keeps_its_restamp_record(study, tmp_path):
    feats = study.parent.parent / "features"
    df = pd.read_csv(study)
    df["code_fingerprint"] = "old"
    df.drop(columns=["written_at"]).to_csv(study, index=False)  # a table from before written_at
    assert freshness.restamp(study, 3, features_folder=feats)["NN1"][0]
    part = tmp_path / "part.csv"
    new = pd.read_csv(study).iloc[:1].assign(activity="run", written_at="2100-01-01T00:00:00+00:00")
    _write_part(new, part)
    assert main(["merge", str(study), str(part), str(study)]) == 0
    assert len(pd.read_csv(study)) == len(df) + 1
    prov = json.loads(freshness.provenance_path(study).read_text())
    assert len(prov["methods"]["NN1"]["restamped"]["rows_rerun"]) == 3
    assert freshness.check_table(study)[1] is False


@pytest.mark.parametrize("content", [None, b"", b"\x00\x01\x02binary"])
def test_check_of_a_missing_or_corrupt_table_is_one_line_and_exit_2(tmp_path, capsys, content):
    from bsrbench.reporting.published import main

    table = tmp_path / "paper.csv"
    if content is not None:
        table.write_bytes(content)
    assert main(["check", str(table)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1 and err[0].startswith(f"error: {table}: ") and err[0].count(str(table)) == 1
    )


def test_merge_into_a_folder_is_one_line_and_exit_2(tmp_path, capsys):
    from bsrbench.reporting.published import main

    part = tmp_path / "part.csv"
    published = ROOT.parent / "reports" / "published" / "ablation-crosstrial.csv"
    pd.read_csv(published).head(3).to_csv(part, index=False)
    shutil.copy(freshness.provenance_path(published), freshness.provenance_path(part))
    (tmp_path / "dest.csv").mkdir()
    assert main(["merge", str(part), str(tmp_path / "dest.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot write the merged table" in err[0]


def test_cell_shifts_are_changes_of_the_mean_in_standard_errors_of_the_old_mean():
    key = dict(protocol="random", source="hsc", activity="golf", method="NN1", n_train=30)
    old = pd.DataFrame([dict(key, seed=s, error=e) for s, e in enumerate([1.0, 2.0, 3.0, 6.0])])
    new = old.assign(error=[2.0, 3.0, 4.0, 7.0])  # every seed one degree worse
    other = dict(key, method="Ridge")
    old = pd.concat([old, pd.DataFrame([dict(other, seed=0, error=5.0)])])  # only in the old table
    out = freshness.cell_shifts(old, new)
    assert len(out) == 1
    # by hand: old mean 3, sample std sqrt(((-2)^2 + (-1)^2 + 0 + 3^2) / 3) = sqrt(14/3), SE = that / 2
    se = math.sqrt(14 / 3) / 2
    assert out["se_old"].iloc[0] == pytest.approx(se)
    assert out["z"].iloc[0] == pytest.approx(1.0 / se)


def test_a_rerun_row_runs_blas_on_one_thread_as_the_fit_jobs_do(monkeypatch):
    from threadpoolctl import threadpool_info

    monkeypatch.setattr(freshness, "row_settings", lambda row, config, where: {})
    monkeypatch.setattr(freshness, "_rerun_row", lambda settings, folder: threadpool_info())
    inside = freshness.rerun_row({}, {})
    blas = [p for p in inside if p["user_api"] == "blas"]
    assert blas and all(p["num_threads"] == 1 for p in blas)


def test_shift_names_cells_with_missing_or_nan_seeds_and_refuses_tables_without_common_cells(
    study, tmp_path, capsys
):
    new = tmp_path / "new.csv"
    df = pd.read_csv(study)
    df.loc[df["method"] == "Ridge", "error"] = float(
        "nan"
    )  # a failed regeneration must not look unchanged
    df.to_csv(new, index=False)
    assert main(["shift", str(study), str(new)]) == 1
    out = capsys.readouterr().out
    assert "WARNING: 1 cell(s) have no z" in out and "method=Ridge" in out
    other = tmp_path / "other.csv"
    df.assign(activity="walk").to_csv(other, index=False)
    assert main(["shift", str(study), str(other)]) == 2
    assert "have no cell in common" in capsys.readouterr().err
    assert main(["shift", str(study), str(study), "--column", "method"]) == 2
    assert "is not numeric" in capsys.readouterr().err
    assert main(["shift", str(study), str(study)]) == 1  # Ridge has one seed: no standard error
    assert "WARNING: 1 cell(s) have no z" in capsys.readouterr().out
    nn = tmp_path / "nn.csv"
    pd.read_csv(study).query("method == 'NN1'").to_csv(nn, index=False)
    assert main(["shift", str(nn), str(nn)]) == 0
    assert "largest |z| 0.00" in capsys.readouterr().out


def _prov(table):
    return json.loads(freshness.provenance_path(table).read_text())


def _one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_merge_refuses_a_historical_part_and_writes_nothing(study, tmp_path, capsys):
    prov = _prov(study)
    prov["historical"] = "made before the change of X"
    freshness.provenance_path(study).write_text(json.dumps(prov))
    part = _write_part(pd.read_csv(study).assign(activity="run"), tmp_path / "part.csv")
    dest = tmp_path / "published" / "merged.csv"
    assert main(["merge", str(part), str(study), str(dest)]) == 2
    err = _one_error_line(capsys)
    assert err.startswith(f"error: {study}: historical") and "a merge needs current parts" in err
    assert not dest.exists() and not freshness.provenance_path(dest).exists()


def test_merge_refuses_parts_of_different_studies_or_without_provenance(study, tmp_path, capsys):
    df = pd.read_csv(study)
    pa = _write_part(df.iloc[:2], tmp_path / "a.csv")
    pb = _write_part(df.iloc[2:], tmp_path / "b.csv", files=["config/ablation.yaml"])
    dest = tmp_path / "published" / "merged.csv"
    assert main(["merge", str(pa), str(pb), str(dest)]) == 2
    err = _one_error_line(capsys)
    assert f"{pa} and {pb} are parts of different studies" in err
    assert "['config/ci.yaml']" in err and "['config/ablation.yaml']" in err
    freshness.provenance_path(pb).unlink()
    assert main(["merge", str(pa), str(pb), str(dest)]) == 2
    assert _one_error_line(capsys).startswith(
        f"error: {tmp_path / 'b.provenance.json'}: no such file"
    )
    assert not dest.exists()


def test_merge_refuses_a_part_without_fingerprints(study, tmp_path, capsys):
    df = pd.read_csv(study)
    part = _write_part(df.iloc[2:].drop(columns=["code_fingerprint"]), tmp_path / "b.csv")
    dest = tmp_path / "published" / "merged.csv"
    assert main(["merge", str(study), str(part), str(dest)]) == 2
    err = _one_error_line(capsys)
    assert err.startswith(f"error: {part}: no column 'code_fingerprint'")
    assert not dest.exists()


def test_merge_refuses_a_header_only_part_and_rows_its_provenance_does_not_list(
    study, tmp_path, capsys
):
    df = pd.read_csv(study)
    dest = tmp_path / "published" / "merged.csv"
    empty = _write_part(df.iloc[:0], tmp_path / "empty.csv")
    assert main(["merge", str(study), str(empty), str(dest)]) == 2
    assert _one_error_line(capsys) == (
        f"error: {empty}: has no rows (only a header); expected a published table of result rows"
    )
    part = _write_part(df.iloc[2:], tmp_path / "b.csv")
    edited = pd.read_csv(part)
    edited.loc[edited["method"] == "Ridge", "code_fingerprint"] = (
        "f" * 64
    )  # rows changed after publishing
    edited.to_csv(part, index=False)
    assert main(["merge", str(study), str(part), str(dest)]) == 2
    err = _one_error_line(capsys)
    assert err.startswith(
        f"error: {part}: the rows of Ridge have code fingerprints ['ffffffffffff'], its "
    )
    assert "expected a part and its provenance written together" in err
    assert not dest.exists() and not freshness.provenance_path(dest).exists()


def test_merge_refuses_a_part_twice_and_a_destination_not_csv(study, tmp_path, capsys):
    df = pd.read_csv(study)
    pa = _write_part(df.iloc[:2], tmp_path / "a.csv")
    pb = _write_part(df.iloc[2:], tmp_path / "b.csv")
    before = {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    assert main(["merge", str(pa), str(pa), str(pb), str(tmp_path / "m.csv")]) == 2
    assert (
        _one_error_line(capsys)
        == f"error: {pa}: given twice (also as {pa}); expected each part once"
    )
    assert main(["merge", str(pa), str(pb), str(freshness.provenance_path(pb))]) == 2
    assert "expected a path ending in .csv" in _one_error_line(capsys)
    assert {
        p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()
    } == before  # nothing written


def test_merge_carries_a_parts_restamp_record_while_the_merged_rows_have_its_fingerprint(
    study, tmp_path
):
    feats = study.parent.parent / "features"
    df = pd.read_csv(study)
    df["code_fingerprint"] = "old"
    df.to_csv(study, index=False)
    assert all(ok for ok, _ in freshness.restamp(study, 3, features_folder=feats).values())
    record = _prov(study)["methods"]
    new = pd.read_csv(study).assign(activity="run", written_at="2100-01-01T00:00:00+00:00")
    part = _write_part(new, tmp_path / "part.csv")
    dest = tmp_path / "merged" / "ci.csv"
    dest.parent.mkdir()
    assert main(["merge", str(study), str(part), str(dest)]) == 0
    merged = _prov(dest)["methods"]
    for m in ("NN1", "Ridge"):
        assert merged[m]["restamped"] == record[m]["restamped"]
        assert merged[m]["code_fingerprint"] == record[m]["code_fingerprint"]
    # a part whose Ridge rows are of other code: the merged Ridge rows no longer have the record's fingerprint
    new.loc[new["method"] == "Ridge", "code_fingerprint"] = "other"
    _write_part(new, part)
    assert main(["merge", str(study), str(part), str(dest)]) == 0
    merged = _prov(dest)["methods"]
    assert merged["NN1"]["restamped"] == record["NN1"]["restamped"]
    assert "restamped" not in merged["Ridge"]


def test_merge_with_an_unreadable_destination_provenance_writes_nothing(study, tmp_path, capsys):
    dest = tmp_path / "merged" / "ci.csv"
    dest.parent.mkdir()
    freshness.provenance_path(dest).write_text("{not json")
    assert main(["merge", str(study), str(dest)]) == 2
    err = _one_error_line(capsys)
    assert err.startswith(f"error: {freshness.provenance_path(dest)}: cannot read the provenance")
    assert not dest.exists()
    assert freshness.provenance_path(dest).read_text() == "{not json"


def test_a_table_and_its_provenance_are_written_both_or_neither(study, tmp_path):
    before = study.read_bytes(), freshness.provenance_path(study).read_bytes()
    df = pd.read_csv(study).assign(error=0.0)
    with pytest.raises(TypeError):  # the provenance cannot be written: a set is no JSON
        freshness.write_table(df, study, "the table", {"methods": {"NN1"}})
    assert (study.read_bytes(), freshness.provenance_path(study).read_bytes()) == before
    assert sorted(p.name for p in study.parent.iterdir()) == ["ci.csv", "ci.provenance.json"]
    freshness.write_table(df, study, "the table", {"study": "ci"})
    assert (pd.read_csv(study)["error"] == 0.0).all() and _prov(study) == {"study": "ci"}


@pytest.mark.parametrize(
    "key, value, words",
    [
        (
            "configfiles",
            5,
            "key 'configfiles' is 5 of type int; expected a list of configuration files",
        ),
        (
            "configfiles",
            "config/ablation.yaml",
            "key 'configfiles' is 'config/ablation.yaml' of type str; expected a list of configuration files",
        ),
        (
            "methods",
            ["TGP"],
            "key 'methods' is ['TGP'] of type list; expected a mapping of method name",
        ),
        ("methods", {"TGP": "x"}, "key 'methods.TGP' is 'x' of type str; expected a mapping"),
        (
            "methods",
            {"TGP": {"code_fingerprint": 7}},
            "key 'methods.TGP.code_fingerprint' is 7 of type int; expected a string or a list of strings",
        ),
        ("historical", True, "key 'historical' is True of type bool; expected a string"),
    ],
)
@pytest.mark.parametrize("command", ["check", "verify"])
def test_a_provenance_of_the_wrong_shape_is_one_line_and_exit_2(
    study, capsys, command, key, value, words
):
    prov = _prov(study)
    prov[key] = value
    freshness.provenance_path(study).write_text(json.dumps(prov))
    assert main([command, str(study)]) == 2
    assert _one_error_line(capsys).startswith(f"error: {freshness.provenance_path(study)}: {words}")


@pytest.mark.parametrize("command", ["check", "verify"])
def test_check_and_verify_name_a_missing_provenance(study, capsys, command):
    freshness.provenance_path(study).unlink()
    assert main([command, str(study)]) == 2
    err = _one_error_line(capsys)
    assert err.startswith(f"error: {freshness.provenance_path(study)}: no such file")


def test_shift_names_the_file_without_rows_or_without_a_numeric_column(study, tmp_path, capsys):
    empty = tmp_path / "empty.csv"
    pd.read_csv(study).head(0).to_csv(empty, index=False)
    assert main(["shift", str(study), str(empty)]) == 2
    assert _one_error_line(capsys).startswith(f"error: {empty}: has no rows")
    assert main(["shift", str(empty), str(study)]) == 2
    assert _one_error_line(capsys).startswith(f"error: {empty}: has no rows")
    assert main(["shift", str(study), str(study), "--column", "nosuch"]) == 2
    assert _one_error_line(capsys).startswith(f"error: {study}: no column 'nosuch'")
    assert main(["shift", str(study), str(study), "--column", "params"]) == 2
    assert _one_error_line(capsys).startswith(f"error: {study}: column 'params' is not numeric")


# ------------------------------------------------------------------- a published row never names code
def _edit_row(table, line, **values):
    """Set columns of the row on CSV line ``line`` (the header is line 1) of ``table``."""
    df = pd.read_csv(table)
    for col, v in values.items():
        df[col] = df[col].astype(object) if col in df.columns else None
        df.loc[line - 2, col] = v
    df.to_csv(table, index=False)


@pytest.mark.parametrize("command", [["verify", "--rows", "5"], ["restamp"]])
def test_a_row_naming_a_foreign_estimator_is_refused_and_never_run(
    study, tmp_path, capsys, command
):
    """verify and restamp take the estimator from the study's configuration: a row naming another callable is
    refused before any row is rerun, and its payload never runs."""
    marker = tmp_path / "marker"
    payload = json.dumps({"args": ["sh", "-c", f"touch {marker}"]})
    _edit_row(study, 3, estimator="subprocess:Popen", params=payload)
    before = study.read_bytes()
    assert main([*command[:1], str(study), *command[1:]]) == 2
    assert _one_error_line(capsys) == (
        f"error: {study} line 3: column 'estimator' is 'subprocess:Popen'; expected "
        "'bsrbench.models.reference:NearestNeighbourRegressor', the estimator of method NN1 in the configuration"
    )
    assert not marker.exists() and study.read_bytes() == before


@pytest.mark.parametrize(
    "values, words",
    [
        (
            {"params": '{"n_neighbors": 3}'},
            "line 2: column 'params': n_neighbors: 3 is not what method NN1 is configured with; expected 1",
        ),
        (
            {"params": '{"n_neighbors": 1, "metric": "pyfunc"}'},
            "line 2: column 'params': metric: 'pyfunc' is not what method NN1 is configured with; "
            "expected no such key",
        ),
        ({"params": "{oops"}, "line 2: column 'params': '{oops' is not JSON"),
        ({"params": "[" * 100000}, "line 2: column 'params': JSON nested too deeply"),
        (
            {"n_train": "abc"},
            "line 2: column 'n_train' is 'abc'; expected a whole number from 1 to 1000000",
        ),
        (
            {"seed": None},
            "line 2: column 'seed' is nan; expected a whole number from 0 to 2147483647",
        ),
        (
            {"source": "../../etc"},
            "line 2: column 'source' is '../../etc'; expected a data set name",
        ),
        (
            {"n_chains": 10**9},
            "line 2: column 'n_chains' is 1000000000.0; expected a whole number from 1 to 1024",
        ),
        ({"method": None}, "line 2: column 'method' is empty; expected a method of config/ci.yaml"),
    ],
    ids=[
        "params-value",
        "params-key",
        "params-not-json",
        "params-nested",
        "n_train",
        "seed",
        "source",
        "chains",
        "method",
    ],
)
def test_verify_checks_every_rows_columns_against_the_configuration(study, capsys, values, words):
    _edit_row(study, 2, **values)
    assert main(["verify", str(study)]) == 2
    err = _one_error_line(capsys)
    assert err.startswith(f"error: {study} {words}"), err


def test_an_empty_method_beside_an_unknown_one_and_a_bad_versions_value_are_one_line(study, capsys):
    _edit_row(study, 2, method=None)
    _edit_row(study, 3, method="XGB")
    for command in ("check", "verify", "restamp"):
        assert main([command, str(study)]) == 2
        assert _one_error_line(capsys).startswith(
            f"error: {study} line 2: column 'method' is empty"
        )
    _edit_row(study, 2, method="NN1")
    _edit_row(study, 3, method="NN1", versions=5)
    assert main(["check", str(study)]) == 2
    assert _one_error_line(capsys) == (
        f"error: {study} line 3: column 'versions' is '5'; expected a JSON object of package versions"
    )


def _config_folder(tmp_path, monkeypatch, text):
    """A checkout's config folder in ``tmp_path`` (the real config.yaml and ``evil.yaml`` holding ``text``) that
    the published tools read instead of the checkout's."""
    from bsrbench import methods

    folder = tmp_path / "checkout" / "config"
    folder.mkdir(parents=True)
    shutil.copy(methods.CONFIG / "config.yaml", folder / "config.yaml")
    (folder / "evil.yaml").write_text(text)
    monkeypatch.setattr(methods, "CONFIG", folder)
    return folder


def _use_configfiles(table, files):
    prov = _prov(table)
    prov["configfiles"] = files
    freshness.provenance_path(table).write_text(json.dumps(prov))


@pytest.mark.parametrize(
    "text, words",
    [
        ("methods: [NN1]\n", "key 'methods' is a list; expected a mapping"),
        ("methods: {NN1: [x]}\n", "key 'methods.NN1' is a list; expected a mapping"),
        ("run: 5\n", "key 'run' is 5; expected a list of method names"),
        (
            "run: [NN1]\nmethods: {NN1: {estimator: 5}}\n",
            "key 'methods.NN1.estimator': estimator 5 (of type int); expected 'package.module:ClassName'",
        ),
    ],
    ids=["methods-list", "method-list", "run-number", "estimator-number"],
)
def test_a_referenced_configuration_of_the_wrong_shape_is_one_line(
    study, tmp_path, capsys, monkeypatch, text, words
):
    _config_folder(tmp_path, monkeypatch, text)
    _use_configfiles(study, ["config/evil.yaml"])
    for command in ("check", "verify", "restamp"):
        assert main([command, str(study)]) == 2
        err = _one_error_line(capsys)
        assert words in err and "evil.yaml" in err, err


@pytest.mark.parametrize("estimator", ["this.x:Y", "antigravity:Y", "no_such_package_q.mod:Y"])
def test_check_imports_no_module_a_referenced_configuration_names(
    study, tmp_path, capsys, monkeypatch, estimator
):
    """The staleness check finds an estimator's source file through the import system's finders: it imports
    nothing, so a module with side effects on import (``this`` prints, ``antigravity`` opens a browser) stays
    unimported."""
    import sys

    _config_folder(
        tmp_path, monkeypatch, f"run: [NN1]\nmethods: {{NN1: {{estimator: '{estimator}'}}}}\n"
    )
    _use_configfiles(study, ["config/evil.yaml"])
    top = estimator.split(".")[0].split(":")[0]
    assert top not in sys.modules
    assert main(["check", str(study)]) == 2
    out = capsys.readouterr()
    assert top not in sys.modules
    assert "Beautiful is better" not in out.out + out.err
    err = out.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"error: config key 'methods.NN1.estimator': estimator '{estimator}': "
    ), err


@pytest.mark.parametrize(
    "files",
    [
        ["/etc/passwd"],
        ["../outside.yaml"],
        ["config/../../outside.yaml"],
        ["config\\ci.yaml"],
        ["README.md"],
    ],
)
@pytest.mark.parametrize("command", ["check", "verify", "merge"])
def test_configfiles_must_be_yaml_files_inside_the_checkout(
    study, tmp_path, capsys, command, files
):
    _use_configfiles(study, files)
    args = [str(study), str(tmp_path / "merged.csv")] if command == "merge" else [str(study)]
    assert main([command, *args]) == 2
    err = _one_error_line(capsys)
    assert err.startswith(
        f"error: {freshness.provenance_path(study)}: key 'configfiles': configfiles entry"
    ), err
    assert not (tmp_path / "merged.csv").exists()


def test_a_deeply_nested_provenance_is_one_line(study, capsys):
    freshness.provenance_path(study).write_text('{"methods": ' + "[" * 100000 + "]" * 100000 + "}")
    for command in ("check", "verify", "restamp"):
        assert main([command, str(study)]) == 2
        assert _one_error_line(capsys).startswith(
            f"error: {freshness.provenance_path(study)}: cannot read the provenance (JSON nested too deeply"
        )


# ------------------------------------------------------------------- break test D6-D8: header only, columns, types
@pytest.mark.parametrize("command", ["check", "verify", "restamp"])
def test_a_table_with_a_header_but_no_rows_is_refused_in_one_line(study, capsys, command):
    """A table emptied to its header passed check and verify silently (merge and shift already refused it)."""
    pd.read_csv(study).head(0).to_csv(study, index=False)
    assert (
        len(study.read_text().splitlines()) == 1
    )  # the header, still with its provenance beside it
    assert main([command, str(study)]) == 2
    assert _one_error_line(capsys) == (
        f"error: {study}: has no rows (only a header); expected a published table of result rows"
    )


@pytest.mark.parametrize(
    "values, words",
    [
        (
            {"n_chains": 3},
            "line 2: column 'n_chains' is 3; expected 1, the chains of method NN1 in the configuration",
        ),
        (
            {"paper_activity": "Run"},
            "line 2: column 'paper_activity' is 'Run'; expected 'Golf', the paper_activity of data set "
            "hsc/golf in the configuration (datasets.hsc.golf.paper_activity)",
        ),
        (
            {"params": '{"n_neighbors": 1.0}'},
            "line 2: column 'params': n_neighbors: 1.0 is of type float; expected 1 of type int, what method "
            "NN1 is configured with (methods.NN1.params and grid)",
        ),
        (
            {"params": '{"n_neighbors": true}'},
            "line 2: column 'params': n_neighbors: True is of type bool; expected 1 of type int, what method "
            "NN1 is configured with (methods.NN1.params and grid)",
        ),
    ],
    ids=["n_chains", "paper_activity", "params-float-for-int", "params-bool-for-int"],
)
def test_verify_checks_chains_paper_activity_and_the_type_of_params(study, capsys, values, words):
    _edit_row(study, 2, **values)
    assert main(["verify", str(study)]) == 2
    assert _one_error_line(capsys) == f"error: {study} {words}"


def test_the_row_check_skips_a_column_the_row_lacks_and_compares_one_it_has(study):
    """Rows written before a column existed lack it: not compared. A column present is compared, an empty
    ``n_chains`` cell being one chain (what a single-chain fit writes)."""
    config = freshness.study_config(["config/ci.yaml"])
    datasets = freshness._study_datasets(["config/ci.yaml"])
    assert datasets["hsc"]["golf"]["paper_activity"] == "Golf"
    row = pd.read_csv(study).iloc[0].to_dict()  # NN1: its rows have no n_chains column
    assert "n_chains" not in row
    config["methods"]["NN1"]["chains"] = 2
    assert freshness.row_settings(row, config, "T line 2", datasets)["n_chains"] == 1
    for cell, ok in [(2.0, True), (float("nan"), False), (4.0, False)]:
        if ok:
            out = freshness.row_settings({**row, "n_chains": cell}, config, "T line 2", datasets)
            assert out["n_chains"] == 2
            continue
        with pytest.raises(freshness.InputError) as exc:
            freshness.row_settings({**row, "n_chains": cell}, config, "T line 2", datasets)
        shown = "empty (one chain)" if cell != cell else int(cell)
        assert str(exc.value) == (
            f"T line 2: column 'n_chains' is {shown}; expected 2, the chains of method NN1 in the configuration"
        )
    config["methods"]["NN1"]["chains"] = 1
    for label, ok in [("Golf", True), (float("nan"), True), ("Walk", False)]:
        edited = {**row, "paper_activity": label}
        if ok:
            out = freshness.row_settings(edited, config, "T line 2", datasets)
            assert out["spec"].paper_activity == (label if isinstance(label, str) else "")
            continue
        with pytest.raises(freshness.InputError) as exc:
            freshness.row_settings(edited, config, "T line 2", datasets)
        assert str(exc.value).startswith(
            "T line 2: column 'paper_activity' is 'Walk'; expected 'Golf'"
        )
    del row["paper_activity"]
    assert freshness.row_settings(row, config, "T line 2", datasets)["spec"].paper_activity == ""


def test_a_grid_value_of_another_type_is_refused_naming_the_grid():
    config = freshness.study_config(["config/ci.yaml"])
    row = {
        "method": "KNN",
        "estimator": config["methods"]["KNN"]["estimator"],
        "source": "hsc",
        "activity": "golf",
        "params": json.dumps({"n_neighbors": 5.0, "weights": "distance"}),
    }
    with pytest.raises(freshness.InputError) as exc:
        freshness.row_settings(row, config, "T line 9")
    assert str(exc.value) == (
        "T line 9: column 'params': n_neighbors: 5.0 is of type float; expected the grid's [3, 5] of type int, "
        "what method KNN is configured with (methods.KNN.params and grid)"
    )


@pytest.mark.parametrize("command", ["check", "verify", "restamp", "shift"])
def test_a_table_that_is_a_link_to_a_file_of_another_kind_is_one_line(tmp_path, capsys, command):
    """A link to /etc/passwd: the CSV parser's message ended in a newline, so the error took two lines."""
    target = tmp_path / "passwd"
    target.write_text(
        "root:x:0:0:root:/root:/bin/bash\nbin:x:1:1:bin:/bin:/sbin/nologin\n"
        "u:x:1000:1000:A User,Room 1,,:/home/u:/bin/sh\n"
    )
    table = tmp_path / "paper.csv"
    table.symlink_to(target)
    args = [str(table)] * (2 if command == "shift" else 1)
    assert main([command, *args]) == 2
    assert _one_error_line(capsys) == (
        f"error: {table}: cannot read the published table (Error tokenizing data. C error: Expected 1 fields in "
        "line 3, saw 4); expected a CSV table of result rows"
    )


@pytest.mark.parametrize(
    "datasets, words",
    [
        (
            "datasets: [hsc]\n",
            "key 'datasets' is a list; expected a mapping {source: {activity: entry}}",
        ),
        (
            "datasets: {hsc: [golf]}\n",
            "key 'datasets.hsc' is a list; expected a mapping {activity: entry}",
        ),
    ],
)
def test_verify_names_a_referenced_datasets_section_of_the_wrong_shape(
    study, tmp_path, capsys, monkeypatch, datasets, words
):
    """The rows' paper_activity is compared with the study's data sets: a configuration file whose ``datasets``
    has another shape is one line naming it, not an AttributeError."""
    text = (ROOT.parent / "config" / "ci.yaml").read_text() + datasets
    folder = _config_folder(tmp_path, monkeypatch, text)
    _use_configfiles(study, ["config/evil.yaml"])
    assert main(["verify", str(study)]) == 2
    assert _one_error_line(capsys) == f"error: {folder / 'evil.yaml'}: {words}"


def _files(folder):
    """{name: (bytes, mode, is a link)} of the files of ``folder``: what a refused merge must leave as it is."""
    return {
        p.name: (p.read_bytes(), p.lstat().st_mode, p.is_symlink())
        for p in sorted(folder.iterdir())
        if p.is_file() or p.is_symlink()
    }


def test_merge_refuses_a_destination_of_another_study_before_writing(tmp_path, capsys):
    """The break test's case: a part of the fair-budget study merged onto the headline table paper.csv."""
    published = ROOT.parent / "reports" / "published"
    part = tmp_path / "parts" / "paper-pmfair-mocap.csv"
    part.parent.mkdir()
    dest = tmp_path / "paper.csv"
    for src, dst in ((published / "parts" / part.name, part), (published / "paper.csv", dest)):
        shutil.copy(src, dst)
        shutil.copy(freshness.provenance_path(src), freshness.provenance_path(dst))
    before = _files(tmp_path)
    assert main(["merge", str(part), str(dest)]) == 2
    assert _one_error_line(capsys) == (
        f"error: {dest}: is a table of another study (configfiles ['config/paper.yaml']), the parts are of "
        "configfiles ['config/paper.yaml', 'config/paper-pmfair.yaml']; expected a new destination or a table "
        "of the parts' study (the merge would replace its rows by the parts')"
    )
    assert _files(tmp_path) == before


def test_merge_refuses_a_destination_without_provenance_of_another_study(study, tmp_path, capsys):
    dest = tmp_path / "other.csv"  # no provenance: its study is config/other.yaml
    pd.read_csv(study).to_csv(dest, index=False)
    before = _files(tmp_path)
    assert main(["merge", str(study), str(dest)]) == 2
    assert _one_error_line(capsys).startswith(
        f"error: {dest}: is a table of another study (configfiles ['config/other.yaml']), the parts are of "
        "configfiles ['config/ci.yaml']; "
    )
    assert _files(tmp_path) == before


@pytest.mark.parametrize("which", ["table", "provenance"])
def test_merge_refuses_a_symlinked_destination_before_writing(study, tmp_path, capsys, which):
    part = _write_part(pd.read_csv(study).assign(activity="run"), tmp_path / "part.csv")
    dest = study
    target = dest if which == "table" else freshness.provenance_path(dest)
    real = tmp_path / ("real" + target.suffix)
    shutil.move(target, real)
    target.symlink_to(real)
    before, outside = _files(study.parent), _files(tmp_path)
    assert main(["merge", str(study), str(part), str(dest)]) == 2
    assert _one_error_line(capsys) == (
        f"error: {target}: is a symbolic link (to {str(real)!r}); expected a regular file (the merge would "
        "replace the link by a copy): name the file it points to"
    )
    assert target.is_symlink() and _files(study.parent) == before and _files(tmp_path) == outside


@pytest.mark.parametrize("which", ["table", "provenance"])
def test_merge_refuses_a_read_only_destination_before_writing(study, tmp_path, capsys, which):
    part = _write_part(pd.read_csv(study).assign(activity="run"), tmp_path / "part.csv")
    target = study if which == "table" else freshness.provenance_path(study)
    target.chmod(0o444)
    before = _files(study.parent)
    try:
        assert main(["merge", str(study), str(part), str(study)]) == 2
        assert _one_error_line(capsys) == (
            f"error: {target}: is read-only (mode 444); expected a writable file (the merge would replace "
            "it): make it writable first"
        )
        assert _files(study.parent) == before
    finally:
        target.chmod(0o644)


@pytest.mark.parametrize(
    "column, value, shown, expected",
    [
        (
            "error",
            float("nan"),
            "nan",
            "a finite number in [0, 180] (the mean wrapped angle error in degrees)",
        ),
        (
            "error",
            -1.5,
            "-1.5",
            "a finite number in [0, 180] (the mean wrapped angle error in degrees)",
        ),
        (
            "error",
            1e300,
            "1e+300",
            "a finite number in [0, 180] (the mean wrapped angle error in degrees)",
        ),
        (
            "error",
            "abc",
            "'abc'",
            "a finite number in [0, 180] (the mean wrapped angle error in degrees)",
        ),
        (
            "written_at",
            "yesterday",
            "'yesterday'",
            "an ISO 8601 date-time (e.g. 2024-05-01T12:00:00+00:00: when the row was written)",
        ),
        (  # pandas reads 'now' and 'today' as dates: such a row would be the newest at every merge
            "written_at",
            "now",
            "'now'",
            "an ISO 8601 date-time (e.g. 2024-05-01T12:00:00+00:00: when the row was written)",
        ),
        (
            "written_at",
            "today",
            "'today'",
            "an ISO 8601 date-time (e.g. 2024-05-01T12:00:00+00:00: when the row was written)",
        ),
    ],
)
def test_merge_refuses_a_part_row_with_a_bad_error_or_written_at(
    study, tmp_path, capsys, column, value, shown, expected
):
    df = pd.read_csv(study)
    if column == "error" and isinstance(value, str):
        df["error"] = df["error"].astype(object)
    df.loc[df.index[2], column] = value
    part = _write_part(df, tmp_path / "part.csv")
    dest = tmp_path / "published" / "merged.csv"
    assert main(["merge", str(part), str(dest)]) == 2
    assert (
        _one_error_line(capsys)
        == f"error: {part} line 4: column {column!r} is {shown}; expected {expected}"
    )
    assert not dest.exists() and not freshness.provenance_path(dest).exists()


def test_merge_takes_errors_of_0_and_180_degrees_and_a_missing_written_at(study, tmp_path):
    df = pd.read_csv(study)
    df.loc[df.index[0], "error"] = 0.0
    df.loc[df.index[1], "error"] = 180.0
    df.loc[df.index[2], "written_at"] = None
    part = _write_part(df, tmp_path / "part.csv")
    dest = tmp_path / "merged.csv"
    assert main(["merge", str(part), str(dest)]) == 0
    assert len(pd.read_csv(dest)) == len(df)


def test_merge_refuses_to_drop_the_jobs_of_an_existing_destination(study, tmp_path, capsys):
    """Merging one part onto an existing table of the same study that is not among the parts would replace its rows
    by the part's: refused, naming the table and a job it would lose; with the table among the parts it grows, and
    parts holding all its jobs (a regeneration) replace it."""
    df = pd.read_csv(study)
    whole = _write_part(df, tmp_path / "whole.csv")
    part = _write_part(df.iloc[:3], tmp_path / "part.csv")
    before = whole.read_bytes()
    assert main(["merge", str(part), str(whole)]) == 2
    line = _one_error_line(capsys)
    assert line.startswith(
        f"error: {whole}: {len(df) - 3} of its {len(df)} rows are jobs that no part holds (e.g. "
    )
    assert line.endswith(
        f"and the merge would drop them; expected {whole} among the parts (a table grows by a new part) or parts "
        "that hold all its jobs (a regeneration)"
    )
    assert whole.read_bytes() == before
    assert main(["merge", str(part), str(whole), str(whole)]) == 0  # grows (here: by rows it holds)
    assert len(pd.read_csv(whole)) == len(df)
    rest = _write_part(df.iloc[3:], tmp_path / "rest.csv")
    assert main(["merge", str(part), str(rest), str(whole)]) == 0  # a regeneration in parts
    assert len(pd.read_csv(whole)) == len(df)
    # the same jobs with N written as a float are the same jobs
    floats = pd.read_csv(whole)
    floats["n_train"] = floats["n_train"].astype(float)
    floats.to_csv(whole, index=False)
    assert main(["merge", str(part), str(rest), str(whole)]) == 0
    # a destination without a key column cannot be compared: refused, naming it
    pd.read_csv(whole).drop(columns=["seed"]).to_csv(whole, index=False)
    capsys.readouterr()
    assert main(["merge", str(part), str(rest), str(whole)]) == 2
    assert _one_error_line(capsys) == (
        f"error: {whole}: missing columns ['seed']; expected a table of result rows"
    )
