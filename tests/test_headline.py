"""The README's generated statements (verdict table, findings, NLPD notes) are computed from the published tables:
the committed README and docs/results.md hold exactly what the code computes from reports/published/paper.csv,
and each statement follows its table on small examples."""

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from reportdata import estimator_of

from bsrbench.methods import configured
from bsrbench.reporting import comparisons as cmp
from bsrbench.reporting import headline
from bsrbench.reporting.verdict import COLUMNS, read_verdict, verdict

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "reports" / "published"


def _block(path, name):
    text = path.read_text(encoding="utf-8")
    m = re.search(rf"<!-- {name} -->\n(.*?)\n<!-- /{name} -->", text, re.S)
    assert m, f"{path} has no markers <!-- {name} -->"
    return m.group(1)


@pytest.fixture(scope="module")
def paper():
    df = pd.read_csv(PUBLISHED / "paper.csv")
    labels = {m: r.label for m, r in configured("paper").items()}
    return df, headline.blocks(df, cmp.comparisons(df), verdict(df), labels=labels)


def test_readme_and_results_blocks_are_computed_from_the_published_table(paper):
    _, blocks = paper
    for name in ("verdict", "findings"):
        assert _block(ROOT / "README.md", name) == blocks[name], name
    assert _block(ROOT / "docs" / "results.md", "notes") == blocks["notes"]


def test_published_verdict_is_the_paper_tables(paper):
    df, _ = paper
    committed = read_verdict(PUBLISHED / "paper-verdict.csv")
    assert list(committed.columns) == COLUMNS
    fresh = verdict(df)
    num = [c for c in COLUMNS if c not in ("protocol", "unit", "scope", "method", "versus", "note")]
    np.testing.assert_allclose(
        committed[num].to_numpy(float), fresh[num].to_numpy(float), rtol=1e-12, equal_nan=True
    )


def _rows(cells, mpjpe=None):
    """Results rows from {(source, activity, n): {method: error}}, two seeds each."""
    rows = []
    for (s, a, n), errs in cells.items():
        for m, e in errs.items():
            for seed in (0, 1):
                rows.append(
                    dict(
                        protocol="random",
                        source=s,
                        activity=a,
                        n_train=n,
                        method=m,
                        estimator=estimator_of(m),
                        seed=seed,
                        error=e + 0.1 * seed,
                        n_test=500,
                        mpjpe_mm=(mpjpe or {}).get(m, np.nan),
                    )
                )
    return pd.DataFrame(rows)


def test_findings_name_the_cells_where_pm_beats_a_paper_baseline():
    cells = {
        ("hsc", "golf", 30): {"PM": 5.0, "RVM": 6.0, "TGP": 4.0, "NN1": 5.5},
        ("hsc", "golf", 60): {"PM": 5.0, "RVM": 4.0, "TGP": 3.0, "NN1": 4.5},
        ("hsc", "run", 30): {"PM": 7.0, "RVM": 6.0, "TGP": 5.0, "NN1": 6.5},
    }
    mpjpe = {"PM": 50.0, "RVM": 60.0, "TGP": 40.0, "NN1": 45.0}
    df = _rows(cells, mpjpe)
    labels = {"NN1": "1-NN"}
    text = headline.findings_markdown(df, cmp.comparisons(df), verdict(df), labels=labels)
    assert (
        "lower mean error than all of RVM, TGP at once in 0 of the 3 cells, and than at least one of them "
        "in 1: hsc golf N = 30 (than RVM)" in text
    )
    assert "It beats 1-NN in 1 cells (N = 30)" in text
    assert (
        "the second highest on hsc (50.0 mm; the others 40.0-60.0 mm; above it: RVM 60.0)" in text
    )


def test_notes_name_the_split_that_dominates_a_mean_nlpd():
    df = _rows({("hsc", "run", 30): {"RVM": 5.0}, ("hsc", "run", 60): {"RVM": 4.0}})
    df["nlpd"] = [2.0, 3.0, 1e6, 2.5]
    text = headline.notes_markdown(df, labels={})
    assert text.startswith(
        "- RVM's mean NLPD on hsc (2.5e+05) comes from one split: hsc run, N = 60, seed 0"
    )
    assert "(NLPD 1.0e+06, 100.00% of the sum over its 4 splits)" in text
    df["nlpd"] = [2.0, 3.0, 4.0, 2.5]
    assert headline.notes_markdown(df, labels={}) == "- No mean NLPD is dominated by one split."


@pytest.mark.parametrize(
    "p, text", [(0.5, "0.500"), (0.001, "0.001"), (3.0598e-4, "3e-04"), (float("nan"), "no test")]
)
def test_p_text(p, text):
    assert headline.p_text(p) == text


def test_findings_with_one_cell_say_no_test_across_cells():
    df = _rows({("hsc", "golf", 30): {"PM": 5.0, "RVM": 6.0, "TGP": 4.0}})
    text = headline.findings_markdown(df, cmp.comparisons(df), verdict(df), labels={})
    assert text.startswith(
        "- With 1 complete (source, activity, N) cells, no test across the cells is possible "
        "(fewer than 2 complete blocks: no test)."
    )
