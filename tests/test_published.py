"""python -m bsrbench.reporting.published: bad inputs, another study's table, the README's tables and the published
comparisons."""

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from reportdata import paired_rows, paper_frame

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


def test_readme_tables_mark_ties_and_count_pm(tmp_path, capsys):
    from bsrbench.reporting.comparisons import comparisons
    from bsrbench.reporting.published import TIE_LEGEND, main, readme_counts, readme_tables

    df = paired_rows(
        {
            ("golf", "NN1"): [6.0, 7.0, 6.5],
            ("golf", "PM"): [6.2, 6.9, 6.8],
            ("golf", "RVM"): [11.0, 12.0, 11.5],
        }
    )
    t = readme_tables(df, paper_frame())["hsc"]
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


def test_a_part_published_with_its_studys_configfiles_is_checked_against_them(
    tmp_path, capsys, monkeypatch
):
    """A part of a study run with --config study=<part> (e.g. ablation-golf) has no config/<part>.yaml: publish
    records the study's files given by --configfiles, and the check reads the part under parts/."""
    import json

    from bsrbench.reporting import freshness
    from bsrbench.reporting.published import main

    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    src = tmp_path / "results" / "paper-hsc" / "aggregate" / "results.csv"
    src.parent.mkdir(parents=True)
    df = pd.read_csv(PUBLISHED)
    df[df["source"] == "hsc"].to_csv(src, index=False)
    dest = tmp_path / "published" / "parts" / "paper-hsc.csv"
    dest.parent.mkdir(parents=True)
    outside = tmp_path / "nope.yaml"
    outside.write_text("run: [NN1]\n")
    assert main(["publish", str(src), str(dest), "--configfiles", str(outside)]) == 2
    assert (
        f"configfiles entry '{outside}': expected a path relative to the checkout"
        in capsys.readouterr().err
    )
    assert main(["publish", str(src), str(dest), "--configfiles", "config/nope.yaml"]) == 2
    assert (
        "config/nope.yaml: no such file; expected a configuration file" in capsys.readouterr().err
    )
    assert not dest.exists()
    assert main(["publish", str(src), str(dest), "--configfiles", "config/ci.yaml"]) == 2
    assert "do not run the methods" in capsys.readouterr().err
    assert not dest.exists()
    assert main(["publish", str(src), str(dest), "--configfiles", "config/paper.yaml"]) == 0
    prov = json.loads(freshness.provenance_path(dest).read_text())
    assert prov["study"] == "paper-hsc" and prov["configfiles"] == ["config/paper.yaml"]
    assert freshness.published_tables(tmp_path / "published") == [dest]
    lines, _ = freshness.check_table(dest)
    methods = sorted(df.loc[df["source"] == "hsc", "method"].unique())
    assert sorted(line.split()[1].rstrip(":") for line in lines) == methods
    assert not any("unknown method" in line for line in lines)


@pytest.mark.parametrize("configfiles", [[], ["--configfiles", "config/paper.yaml"]])
def test_publish_with_an_unreadable_destination_provenance_writes_nothing(
    tmp_path, capsys, configfiles
):
    """The destination's old provenance is read (for its configuration files and restamp records) before the
    table is written: one that cannot be read is one line and exit 2, with the table and its provenance as
    they were."""
    from bsrbench.reporting import freshness
    from bsrbench.reporting.published import main

    src = tmp_path / "results" / "paper-hsc" / "aggregate" / "results.csv"
    src.parent.mkdir(parents=True)
    df = pd.read_csv(PUBLISHED)
    df[df["source"] == "hsc"].to_csv(src, index=False)
    dest = tmp_path / "published" / "paper-hsc.csv"
    dest.parent.mkdir()
    dest.write_text("the old table\n")
    prov = freshness.provenance_path(dest)
    prov.write_text('{"study": "paper-hsc", ')
    assert main(["publish", str(src), str(dest), *configfiles]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {prov}: cannot read the provenance") and err.count("\n") == 1
    assert dest.read_text() == "the old table\n" and prov.read_text() == '{"study": "paper-hsc", '
    assert sorted(p.name for p in dest.parent.iterdir()) == [dest.name, prov.name]


# ------------------------------------------------------------------------------------ --update FILE: the target
def _targets(tmp_path):
    """A regular file with the markers of every block, a symbolic link to it and a read-only copy of it."""
    text = "".join(
        f"<!-- {b} -->\nold\n<!-- /{b} -->\n"
        for b in ("results-table:hsc", "results-summary", "mechanisms", "reconcile", "paper-pmfair")
    )
    real = tmp_path / "real.md"
    real.write_text(text)
    link = tmp_path / "link.md"
    link.symlink_to(real)
    ro = tmp_path / "ro.md"
    ro.write_text(text)
    ro.chmod(0o444)
    return real, link, ro


def _refused(path):
    """The message refusing ``path`` as an --update target."""
    if path.is_symlink():
        return (
            f"{path}: is a symbolic link (to '{path.readlink()}'); expected a regular file (the update would "
            "replace the link by a copy): name the file it points to"
        )
    return (
        f"{path}: is read-only (mode 444); expected a writable file (the update would replace it): make it "
        "writable first"
    )


def _listing(folder):
    """{name: (is a link, mode, content)} of the files of ``folder``."""
    return {p.name: (p.is_symlink(), p.lstat().st_mode, p.read_bytes()) for p in folder.iterdir()}


@pytest.mark.parametrize(
    "args",
    [
        ["readme", str(PUBLISHED)],
        ["mechanisms", str(PUBLISHED.with_name("ablation-mechanisms.csv"))],
        ["reconcile", str(PUBLISHED.with_name("reconcile.csv"))],
        ["budget", str(PUBLISHED.with_name("paper-pmfair.csv"))],
    ],
    ids=["readme", "mechanisms", "reconcile", "budget"],
)
@pytest.mark.parametrize("target", ["link", "read-only"])
def test_update_refuses_a_symbolic_link_and_a_read_only_file(tmp_path, capsys, args, target):
    """Before: --update's atomic rename put a regular file in the place of a symbolic link, and replaced a
    read-only file; now exit 2, one line naming the path, and nothing written."""
    from bsrbench.reporting.published import main

    _, link, ro = _targets(tmp_path)
    path = link if target == "link" else ro
    before = _listing(tmp_path)
    assert main([*args, "--update", str(path)]) == 2
    assert capsys.readouterr().err == f"error: {_refused(path)}\n"
    assert _listing(tmp_path) == before


def test_the_writers_of_update_refuse_the_target_themselves(tmp_path):
    """The functions that write --update's file check it too, not only the command line."""
    from bsrbench.errors import DataFileError
    from bsrbench.reporting import headline
    from bsrbench.reporting.published import update_mechanisms, update_readme

    _, link, ro = _targets(tmp_path)
    before = _listing(tmp_path)
    for path in (link, ro):
        for write in (
            lambda p: update_readme(p, {"hsc": "new"}, summary="new"),
            lambda p: update_mechanisms(p, "new"),
            lambda p: headline.update_blocks(p, {"reconcile": "new"}),
            lambda p: headline.write_update(p, "new"),
        ):
            with pytest.raises(DataFileError) as e:
                write(path)
            assert str(e.value) == _refused(path)
    assert _listing(tmp_path) == before
