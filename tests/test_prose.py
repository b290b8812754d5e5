"""Numbers in prose generated from the published tables (bsrbench.reporting.prose): none is stale, a changed one
is found and restored, an unknown claim is refused, and claims agree with a hand computation."""

import pandas as pd
import pytest

from bsrbench.errors import InputError
from bsrbench.reporting import prose
from bsrbench.reporting.published import main

BOOK = prose.Book()


def test_every_marked_number_is_its_claim_today():
    assert prose.check(book=BOOK) == []


def test_every_claim_is_used_by_some_marker():
    assert set(prose.CLAIMS) == prose.used()


def test_a_changed_number_is_reported_with_its_line_and_update_restores_it(tmp_path):
    src = prose.ROOT / "docs" / "results.md"
    text = src.read_text(encoding="utf-8")
    line, name, value = next(m for m in prose.markers(src) if m[1] == "paper.cells")
    marked = f"<!-- n:{name} -->{value}<!-- /n -->"
    changed = text.replace(marked, f"<!-- n:{name} -->28 (by hand)<!-- /n -->")
    assert changed != text
    copy = tmp_path / "results.md"
    copy.write_text(changed, encoding="utf-8")
    assert prose.check([copy], book=BOOK) == [(copy, line, name, "28 (by hand)", value)]
    assert prose.update([copy], book=BOOK) == [copy]
    assert copy.read_text(encoding="utf-8") == text


def test_an_unknown_claim_is_refused_in_one_line(tmp_path, capsys):
    f = tmp_path / "x.md"
    f.write_text("PM wins <!-- n:paper.pm_wins -->all<!-- /n --> cells.\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"unknown claims \['paper.pm_wins'\]"):
        prose.check([f], book=BOOK)


def test_claims_agree_with_a_hand_computation():
    df = pd.read_csv(prose.ROOT / "reports" / "published" / "paper.csv")
    df = df[df["protocol"] == "random"]
    cells = df.groupby(["source", "activity", "n_train", "method"])["error"].mean().unstack()
    assert prose.CLAIMS["paper.cells"](BOOK) == str(len(cells))
    assert prose.CLAIMS["paper.pm_beats_nn"](BOOK) == str(int((cells["PM"] < cells["NN1"]).sum()))
    pm = df[(df["source"] == "mocap") & (df["method"] == "PM")]["coverage_90"].mean()
    assert prose.CLAIMS["paper.coverage.PM.mocap"](BOOK) == f"{100 * pm:.0f}%"
    rc = pd.read_csv(prose.ROOT / "reports" / "published" / "reconcile.csv")
    assert prose.CLAIMS["reconcile.rows"](BOOK) == f"{len(rc):,}"


def test_the_command_exits_0_when_fresh(capsys):
    assert main(["prose"]) == 0
    assert "0 differ" in capsys.readouterr().err
