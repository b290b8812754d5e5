"""The figure captions (bsrbench.reporting.captions): each says what its figure draws for the study at hand."""

import io
from pathlib import Path

import pandas as pd
import pytest
from reportdata import LABELS, PAPER_CSV, result_rows

from bsrbench.reporting import captions
from bsrbench.reporting.tables import aggregate_rows, paper_key


def _study(protocols=("random",), **kw):
    """PM on golf (N = 30, 100) and acrobatics (N = 30 only) per protocol; the paper has both at N = 30, 100."""
    rows = []
    for protocol in protocols:
        for n, errors in (
            (30, {("golf", "PM"): [8.0, 9.0], ("acrobatics", "PM"): [12.0, 13.0]}),
            (100, {("golf", "PM"): [6.0, 7.0]}),
        ):
            rows += [dict(r, n_train=n, protocol=protocol) for r in result_rows(errors)]
    paper = pd.read_csv(
        io.StringIO(PAPER_CSV + "I,Golf,100,PM,5.0,1.0\nI,Acrobatics,100,PM,9.0,1.0\n")
    )
    paper["key"] = paper["activity"].map(paper_key)
    args = dict(
        df=aggregate_rows(rows),
        paper=paper,
        labels=LABELS,
        figure_methods=["PM"],
        n_train=[30, 100],
        stick_kinds={"hsc": ["authors"], "mocap": ["skeleton"], "other": ["None"]},
        subjective_first="NN1",
        seed0=7,
    )
    return captions.Study(**{**args, **kw})


@pytest.mark.parametrize(
    "protocols, lines",
    [
        (("random",), "solid lines: random protocol"),
        (
            ("contiguous", "random"),
            "solid lines: random protocol; dashed lines: contiguous protocol",
        ),
        (("cross_trial",), "dash-dotted lines: cross-trial protocol"),
    ],
)
def test_fig1_names_the_line_style_of_each_protocol_run(protocols, lines):
    assert captions.study_lines(protocols) == lines
    text = captions.caption("error_vs_ntrain", "hsc", _study(protocols))
    assert f"Filled markers: this study ({lines});" in text


def test_fig1_names_the_paper_points_it_leaves_out():
    study = _study()
    text = captions.caption("error_vs_ntrain", "hsc", study)
    # acrobatics was not run at N = 100, where the paper has a point
    assert text.endswith(
        " Not drawn: the paper's points at the sizes this study skipped for an activity (too few test frames "
        "would remain; see the tables): Acrobatics at $N = 100$."
    )
    # a size the study does not configure is no omission: nothing is said
    assert "Not drawn" not in captions.caption("error_vs_ntrain", "hsc", _study(n_train=[30]))


def test_calibration_names_the_protocol_drawn():
    assert captions.calibration_protocol(["contiguous", "random"]) == "random protocol"
    assert captions.calibration_protocol([]) == "random protocol"
    assert captions.calibration_protocol(["cross_trial", "contiguous"]).startswith(
        r"contiguous protocol, as named in the panel titles; this study did not run the random one"
    )
    text = captions.caption("calibration", "hsc", _study(("cross_trial",)))
    assert text.startswith(r"Calibration on the hsc data (cross\_trial protocol, as named")


def test_subjective_caption_follows_the_stick_figures_drawn():
    study = _study()
    authors = captions.caption("subjective", "hsc", study)
    rendered = captions.caption("subjective", "mocap", study)
    none = captions.caption("subjective", "other", study)
    assert "authors' 19-joint skeleton" in authors and "rendered silhouette" not in authors
    assert "the rendered silhouette (the input)" in rendered
    assert "no stick figure is drawn" in none
    # the frame drawn: the first seed and the median-error frame of the first subjective method, by its label
    for text in (authors, rendered, none):
        assert "seed 7; the test frame with the median error of 1-NN" in text
    # none of report.subjective_methods run: one sentence says so (the figure has one line)
    assert captions.caption("subjective", "hsc", _study(subjective_first="")) == (
        "Subjective comparison on the hsc data: none of the methods of the configuration key "
        r"report.subjective\_methods was run, so no frame is drawn."
    )


def test_figure_captions_in_order_with_paths_from_the_report_folder(tmp_path):
    root = tmp_path / "reports" / "s"
    figures = [root / "figures" / f"{k}_hsc.pdf" for k in captions.KINDS]
    out = captions.figure_captions(figures, [root / "figures" / "cd_hsc.pdf"], _study(), root=root)
    assert [p for p, _ in out] == [Path("figures") / f.name for f in figures] + [
        Path("figures/cd_hsc.pdf")
    ]
    assert [c.split(" ", 1)[0] for _, c in out] == [
        "Error",
        "Subjective",
        "Calibration",
        "Critical-difference",
    ]
    assert all(" hsc data" in c for _, c in out)
    with pytest.raises(
        ValueError, match=r"figure .*pit_hsc.pdf: its name should begin with one of"
    ):
        captions.figure_captions([root / "figures" / "pit_hsc.pdf"], [], _study(), root=root)
    with pytest.raises(ValueError, match="no caption for figure kind 'pit'"):
        captions.caption("pit", "hsc", _study())


def test_why_pm_captions_describe_the_trace_and_the_gxy_panels(tmp_path):
    df = pd.DataFrame(
        [dict(method="PMK16", protocol="random", n_train=30, params='{"n_atoms": 16}')]
    )
    root = tmp_path / "reports" / "s"
    kw = dict(gxy_methods=["PMK16"], protocol="random", n_train=30, labels={}, root=root)
    out = captions.why_pm_captions(df, [root / "figures/trace.pdf", root / "figures/gxy.pdf"], **kw)
    assert out[0] == ("figures/trace.pdf", captions.TRACE)
    assert out[1][0] == "figures/gxy.pdf" and "PMK16: $K = 16 < N = 30$" in out[1][1]
    with pytest.raises(ValueError, match="expected trace or gxy"):
        captions.why_pm_captions(df, [root / "figures/pit.pdf"], **kw)


def test_error_caption_names_the_two_rows_of_panels_when_there_are_two():
    one = captions.caption("error_vs_ntrain", "hsc", _study())  # PM alone: one row
    assert "Top:" not in one
    two = captions.caption("error_vs_ntrain", "hsc", _study(figure_methods=["PM", "RVM", "NN1"]))
    assert (
        "Top: the paper's methods, with the paper's numbers; below: the references and today's baselines "
        "beside PM, on the same error axis." in two
    )
