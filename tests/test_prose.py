"""Numbers in prose generated from the published tables (bsrbench.reporting.prose): none is stale, a changed one
is found and restored, an unknown claim, a malformed marker or an unreadable table is refused in one line, and claims
agree with a hand computation."""

import pandas as pd
import pytest

from bsrbench.errors import DataFileError, InputError
from bsrbench.reporting import prose
from bsrbench.reporting.published import main

BOOK = prose.Book()
PUBLISHED = prose.ROOT / "reports" / "published"


def test_every_marked_number_is_its_claim_today():
    assert prose.check(book=BOOK) == []


def test_every_claim_is_used_by_some_marker():
    assert set(prose.CLAIMS) == prose.used()


def test_a_changed_number_is_reported_with_its_line_and_update_restores_it(tmp_path):
    src = prose.ROOT / "docs" / "results.md"
    text = src.read_text(encoding="utf-8")
    line, name, value = next(m for m in prose.markers(src) if m[1] == "paper.cells")
    marked = f"<!-- n:{name} -->{value}<!-- /n -->"
    assert text.count(marked) == 1
    changed = text.replace(marked, f"<!-- n:{name} -->28 (by hand)<!-- /n -->")
    copy = tmp_path / "results.md"
    copy.write_text(changed, encoding="utf-8")
    assert prose.check([copy], book=BOOK) == [(copy, line, name, "28 (by hand)", value)]
    assert prose.update([copy], book=BOOK) == [copy]
    assert copy.read_text(encoding="utf-8") == text
    assert prose.update([copy], book=BOOK) == []  # nothing left to rewrite


def test_update_refuses_a_symbolic_link_before_writing_any_file(tmp_path):
    """Before: the files before a symbolic link were rewritten and the link replaced by a regular file; now every
    file to rewrite is checked first and nothing is written."""
    stale = "<!-- n:paper.cells -->28 (by hand)<!-- /n --> cells\n"
    first, real = tmp_path / "a.md", tmp_path / "real.md"
    first.write_text(stale, encoding="utf-8")
    real.write_text(stale, encoding="utf-8")
    link = tmp_path / "link.md"
    link.symlink_to(real)
    with pytest.raises(DataFileError) as e:
        prose.update([first, link], book=BOOK)
    assert str(e.value) == (
        f"{link}: is a symbolic link (to '{real}'); expected a regular file (the update would replace the link "
        "by a copy): name the file it points to"
    )
    assert first.read_text(encoding="utf-8") == stale and link.is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.md", "link.md", "real.md"]


UNKNOWN = "<!-- n:paper.cells -->32<!-- /n --> cells.\nPM wins <!-- n:paper.pm_wins -->all<!-- /n --> cells.\n"


def _unknown(f):
    return (
        f"{f}:2: unknown claim 'paper.pm_wins'; expected a claim of bsrbench.reporting.prose.CLAIMS "
        f"({len(prose.CLAIMS)} defined)"
    )


def test_an_unknown_claim_is_refused_in_one_line_naming_its_path_and_line(tmp_path):
    f = tmp_path / "x.md"
    f.write_text(UNKNOWN, encoding="utf-8")
    for run in (prose.check, prose.update):
        with pytest.raises(InputError) as e:
            run([f], book=BOOK)
        assert str(e.value) == _unknown(f)
    assert f.read_text(encoding="utf-8") == UNKNOWN


def test_the_command_refuses_an_unknown_claim_in_one_line(tmp_path, monkeypatch, capsys):
    f = tmp_path / "x.md"
    f.write_text(UNKNOWN, encoding="utf-8")
    monkeypatch.setattr(prose, "files", lambda root=None: [f])
    assert main(["prose"]) == 2
    assert capsys.readouterr().err == f"error: {_unknown(f)}\n"


EXPECTED_TAG = (
    "expected exactly '<!-- n:CLAIM -->' or '<!-- /n -->' (CLAIM: letters, digits, '_', '.', '-')"
)


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "a\nPM beats 1-NN in <!-- n:paper.pm_beats_nn -->5 cells.\n",
            ":2: marker '<!-- n:paper.pm_beats_nn -->' is not closed; expected '<!-- /n -->' after its number",
        ),
        (
            "<!-- n:paper.cells -->32 cells,\n<!-- n:paper.motions -->4<!-- /n --> motions\n",
            ":1: marker '<!-- n:paper.cells -->' is not closed before the next one (line 2); expected "
            "'<!-- /n -->' after its number",
        ),
        (
            "a\n\n<!--n:paper.cells-->32<!--/n--> cells\n",
            f":3: malformed marker '<!--n:paper.cells-->'; {EXPECTED_TAG}",
        ),
        (
            "<!-- n:paper.cells-->32<!-- /n --> cells\n",
            f":1: malformed marker '<!-- n:paper.cells-->'; {EXPECTED_TAG}",
        ),
        (
            "<!-- n: paper.cells -->32<!-- /n -->\n",
            f":1: malformed marker '<!-- n: paper.cells -->'; {EXPECTED_TAG}",
        ),
        (
            "<!-- n:paper.cells -->32<!-- /n-->\n",
            f":1: malformed marker '<!-- /n-->'; {EXPECTED_TAG}",
        ),
        (
            "32<!-- /n --> cells\n",
            ":1: '<!-- /n -->' closes no marker; expected '<!-- n:CLAIM -->' before it",
        ),
    ],
    ids=[
        "unclosed",
        "unclosed-before-next",
        "no-spaces",
        "no-space-before-end",
        "space-after-colon",
        "closing-without-space",
        "closes-none",
    ],
)
def test_a_malformed_marker_is_refused_naming_its_path_and_line(
    tmp_path, monkeypatch, capsys, text, message
):
    """Before: a marker without its closing tag or without the spaces was skipped, its number unchecked (or taken
    with the next marker's); now check, update and the command refuse it in one line naming path:line."""
    f = tmp_path / "x.md"
    f.write_text(text, encoding="utf-8")
    for run in (prose.check, prose.update):
        with pytest.raises(InputError) as e:
            run([f], book=BOOK)
        assert str(e.value) == f"{f}{message}"
    assert f.read_text(encoding="utf-8") == text
    monkeypatch.setattr(prose, "files", lambda root=None: [f])
    assert main(["prose"]) == 2
    assert capsys.readouterr().err == f"error: {f}{message}\n"


def test_a_missing_table_is_named_in_one_line(tmp_path):
    f = tmp_path / "x.md"
    f.write_text("<!-- n:paper.cells -->32<!-- /n --> cells\n", encoding="utf-8")
    with pytest.raises(DataFileError, match="paper.csv") as e:
        prose.check([f], book=prose.Book(tmp_path))
    assert "\n" not in str(e.value)


def test_a_claim_that_cannot_be_computed_is_named(tmp_path, monkeypatch):
    monkeypatch.setitem(prose.CLAIMS, "paper.broken", lambda book: book.cells()["no such method"])
    f = tmp_path / "x.md"
    f.write_text("<!-- n:paper.broken -->1<!-- /n -->\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"claim 'paper.broken' cannot be computed .*KeyError"):
        prose.check([f], book=BOOK)


def test_claims_agree_with_a_hand_computation():
    df = pd.read_csv(PUBLISHED / "paper.csv")
    df = df[df["protocol"] == "random"]
    cells = df.groupby(["source", "activity", "n_train", "method"])["error"].mean().unstack()
    assert prose.CLAIMS["paper.cells"](BOOK) == str(len(cells))
    assert prose.CLAIMS["paper.pm_beats_nn"](BOOK) == str(int((cells["PM"] < cells["NN1"]).sum()))
    pm = df[(df["source"] == "mocap") & (df["method"] == "PM")]["coverage_90"].mean()
    assert prose.CLAIMS["paper.coverage.PM.mocap"](BOOK) == f"{100 * pm:.0f}%"
    rc = pd.read_csv(PUBLISHED / "reconcile.csv")
    assert prose.CLAIMS["reconcile.rows"](BOOK) == f"{len(rc):,}"


def test_ablation_claims_agree_with_a_hand_computation():
    a = pd.read_csv(PUBLISHED / "ablation.csv")
    k8 = a[a["method"] == "PMK8"]
    ok = (k8["r_hat_log_likelihood"] < 1.05) & (k8["r_hat_g_xy"] < 1.05)
    assert prose.CLAIMS["ablation.converged.PMK8"](BOOK) == f"{100 * ok.mean():.0f}%"
    cells = a.groupby(["activity", "n_train", "method"])["error"].mean().unstack()
    variants = [m for m in cells.columns if m.startswith("PM")]
    best = cells[variants].min(axis=1)
    assert prose.CLAIMS["ablation.best_beats_nn"](BOOK) == str(int((best < cells["NN1"]).sum()))
    g = pd.read_csv(PUBLISHED / "paper-goal.csv")
    g = g.groupby(["activity", "n_train", "method"])["error"].mean().unstack()
    assert prose.CLAIMS["goal.below.PMK8"](BOOK) == str(int((g["PMK8"] < g["NN1"]).sum()))


def test_fair_budget_claims_agree_with_a_hand_computation():
    import json

    f = pd.read_csv(PUBLISHED / "paper-pmfair.csv")
    p = pd.read_csv(PUBLISHED / "paper.csv")
    for source in ("hsc", "mocap"):
        fs = f[f["source"] == source]
        assert (
            prose.CLAIMS[f"paper_pmfair.{source}.error.fair"](BOOK) == f"{fs['error'].mean():.2f}"
        )
        pm = p[(p["source"] == source) & (p["method"] == "PM") & (p["protocol"] == "random")]
        assert prose.CLAIMS[f"paper_pmfair.{source}.error.PM"](BOOK) == f"{pm['error'].mean():.2f}"
        ok = int((fs["r_hat_test_error"] <= 1.01).sum())
        assert prose.CLAIMS[f"paper_pmfair.{source}.converged"](BOOK) == f"{ok} of the {len(fs)}"
        first = fs.sort_values("seed").groupby(["activity", "n_train"])["params"].first()
        b1 = sum(json.loads(x)["b_xy"] == 1 for x in first)
        assert prose.CLAIMS[f"paper_pmfair.{source}.b1"](BOOK) == f"{b1} of the {len(first)}"
    # the motions are the activities' names here: hsc and mocap share run and michael_jackson
    assert prose.CLAIMS["paper_pmfair.motions"](BOOK) == str(f["activity"].nunique())


def test_the_command_exits_0_when_fresh(capsys):
    assert main(["prose"]) == 0
    assert "; 0 differ" in capsys.readouterr().err
