"""The report's figures (bsrbench.reporting.plots): sizes and fonts, protocols drawn, the paper's points, axes and
stick figures."""

import io

import numpy as np
import pandas as pd
import pytest
from reportdata import (
    LABELS,
    PAPER_CSV,
    paper_frame,
    result_rows,
)

from bsrbench.reporting.tables import (
    aggregate_rows,
    paper_key,
)


def test_figures_fit_the_text_width_with_fonts_of_at_least_7_pt():
    """The report includes figures unscaled, so matplotlib's sizes are the printed sizes."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import (
        MIN_FONT_PT,
        TEXT_WIDTH,
        plot_calibration,
        plot_error_vs_ntrain,
    )

    rows = []
    for n in (30, 100):
        for r in result_rows(
            {
                ("golf", "PM"): [8.0, 9.0],
                ("golf", "RVM"): [12.0, 13.0],
                ("acrobatics", "PM"): [5.0, 6.0],
                ("acrobatics", "RVM"): [7.0, 7.5],
            }
        ):
            rows.append(dict(r, n_train=n, coverage_50=0.4, coverage_90=0.8))
    df = aggregate_rows(rows)
    figs = [
        plot_error_vs_ntrain(df, paper_frame(), source="hsc", methods=["PM", "RVM"], labels=LABELS),
        plot_calibration(df, methods=["PM", "RVM"], labels=LABELS, source="hsc"),
    ]
    for fig in figs:
        fig.canvas.draw()
        bbox = fig.get_tightbbox(fig.canvas.get_renderer())
        assert bbox.width <= TEXT_WIDTH + 0.01
        sizes = [
            t.get_fontsize()
            for t in fig.findobj(plt.Text)
            if t.get_visible() and t.get_text().strip()
        ]
        assert sizes and min(sizes) >= MIN_FONT_PT
        ticks = [float(t.get_text()) for t in fig.axes[0].get_xticklabels() if t.get_text()]
        if ticks and fig is figs[0]:
            assert ticks == [30.0, 100.0]  # only the sizes studied
        plt.close(fig)


@pytest.mark.parametrize(
    "protocols, shown", [(("contiguous",), "contiguous"), (("contiguous", "random"), "random")]
)
def test_calibration_uses_the_random_protocol_else_the_one_run(protocols, shown):
    """A study without the random protocol (the ablation) still gets its calibration curves, titled by protocol."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import plot_calibration

    rows = []
    for protocol in protocols:
        cov = {"random": 0.4, "contiguous": 0.2}[protocol]
        for r in result_rows({("golf", "PM"): [8.0, 9.0]}):
            rows.append(dict(r, protocol=protocol, coverage_50=cov, coverage_90=2 * cov))
    fig = plot_calibration(aggregate_rows(rows), methods=["PM"], labels=LABELS, source="hsc")
    ax = fig.axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_label() == LABELS["PM"]]
    assert len(lines) == 1
    np.testing.assert_allclose(
        lines[0].get_ydata(), [0.4, 0.8] if shown == "random" else [0.2, 0.4]
    )
    assert ax.get_title() == ("N = 30" if shown == "random" else "N = 30 (contiguous)")
    assert not [t for t in ax.texts if "no method" in t.get_text()]
    plt.close(fig)


@pytest.mark.parametrize(
    "protocols", [("contiguous",), ("random",), ("random", "contiguous"), ("cross_trial",)]
)
def test_error_figure_legend_names_only_the_protocols_run(protocols):
    """Before: the legend always had "this study (random)", also for a contiguous-only study; a cross-trial
    study's Fig. 1 drew no line at all."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import plot_error_vs_ntrain

    rows = [
        dict(r, protocol=p) for p in protocols for r in result_rows({("golf", "PM"): [8.0, 9.0]})
    ]
    fig = plot_error_vs_ntrain(
        aggregate_rows(rows), paper_frame(), source="hsc", methods=["PM"], labels=LABELS
    )
    names = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
    expected = [
        f"this study ({p.replace('_', '-')})"
        for p in ("random", "contiguous", "cross_trial")
        if p in protocols
    ]
    assert [n for n in names if n.startswith("this study")] == expected
    assert "PM" in names and "the paper" in names
    styles = {ln.get_linestyle() for ln in fig.axes[0].get_lines()} - {
        ":",
        "None",
    }  # the paper dotted; caps
    assert styles == {
        {"random": "-", "contiguous": "--", "cross_trial": "-."}[p] for p in protocols
    }
    plt.close(fig)


def test_error_figure_draws_the_paper_only_where_this_study_has_a_point():
    """Before: Fig. 1 drew the paper's point at every configured N, also at an N the study skipped for that
    activity (walk at N = 100 in the quick study: 167 frames leave 67 < min_test test frames), with no point of
    ours beside it and no word in the caption. Now the paper is drawn at the N the study ran for the activity,
    and paper_points_not_drawn names what is left out (for the caption)."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import paper_points_not_drawn, plot_error_vs_ntrain

    paper = pd.read_csv(
        io.StringIO(PAPER_CSV + "I,Golf,100,PM,5.0,1.0\nI,Acrobatics,100,PM,9.0,1.0\n")
    )
    paper["key"] = paper["activity"].map(paper_key)
    rows = [
        dict(r, n_train=30)
        for r in result_rows({("golf", "PM"): [8.0, 9.0], ("acrobatics", "PM"): [12.0, 13.0]})
    ]
    rows += [
        dict(r, n_train=100) for r in result_rows({("golf", "PM"): [6.0, 7.0]})
    ]  # acrobatics: N = 100 skipped
    df = aggregate_rows(rows)
    kw = dict(source="hsc", methods=["PM"], labels=LABELS, n_train=[30, 100])
    fig = plot_error_vs_ntrain(df, paper, **kw)
    panels = {ax.get_title(): ax for ax in fig.axes}
    for title, sizes in (("Golf", [30, 100]), ("Acrobatics", [30])):
        dotted = [ln for ln in panels[title].get_lines() if ln.get_linestyle() == ":"]
        assert len(dotted) == 1, title  # the paper's PM line
        np.testing.assert_allclose(dotted[0].get_xdata(), sizes, rtol=0.05, err_msg=title)
    plt.close(fig)
    assert paper_points_not_drawn(df, paper, **kw) == {"Acrobatics": [100]}
    # a method the figure does not draw, or a size the study does not configure, is no omission
    assert paper_points_not_drawn(df, paper, **{**kw, "methods": ["NN1"]}) == {}
    assert paper_points_not_drawn(df, paper, **{**kw, "n_train": [30]}) == {}


def _error_axis_labels(lo, hi):
    """Fig. 1 for errors from about ``lo`` (N = 100) to ``hi`` (N = 30) degrees: (y limits, {value: label} of the
    labelled y ticks inside them), read from the drawn canvas (major and minor ticks)."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import plot_error_vs_ntrain

    rows = []
    for n, err in ((30, hi), (100, lo)):
        for r in result_rows(
            {("golf", "PM"): [err, err * 0.98], ("golf", "RVM"): [err * 0.99, err * 0.97]}
        ):
            rows.append(dict(r, n_train=n))
    fig = plot_error_vs_ntrain(
        aggregate_rows(rows), paper_frame()[:0], source="hsc", methods=["PM", "RVM"], labels=LABELS
    )
    fig.canvas.draw()
    ax = fig.axes[0]
    y0, y1 = ax.get_ylim()
    labels = {}
    for minor in (False, True):
        for t in ax.get_yticklabels(minor=minor):
            v = t.get_position()[1]
            if t.get_text() and y0 <= v <= y1:
                assert float(t.get_text()) == pytest.approx(v)  # the label is the tick's value
                labels[v] = t.get_text()
    plt.close(fig)
    return (y0, y1), labels


@pytest.mark.parametrize(
    "lo, hi", [(3.0, 25.0), (7.0, 18.0), (4.0, 17.0), (1.6, 17.0), (11.0, 60.0), (9.6, 10.4)]
)
def test_error_axis_is_labelled_across_its_whole_range(lo, hi):
    """Before: labels only at 1, 2, 3, 5 (or every integer) times a power of ten, so an axis from 7 to 18
    degrees was labelled 7, 8, 9, 10 and nothing above 10. Now every 10^k and 2, 3, 5 x 10^k of a range over a
    decade is labelled, and labels cover the whole range: at least four, none of the gaps between them (or
    between an end of the axis and the nearest label) wider than 40% of the axis in log scale."""
    (y0, y1), labels = _error_axis_labels(lo, hi)
    values = sorted(labels)
    assert len(values) >= 4, labels
    logs = np.log10([y0, *values, y1])
    assert np.diff(logs).max() <= 0.4 * (logs[-1] - logs[0]) + 1e-9, labels
    if y1 > 12:
        assert max(values) > 10, labels
    if y1 / y0 >= 10:
        nice = [m * 10.0**k for k in range(-1, 3) for m in (1, 2, 3, 5) if y0 <= m * 10.0**k <= y1]
        assert all(any(np.isclose(v, n) for v in values) for n in nice), (nice, labels)
    if (lo, hi) == (3.0, 25.0):
        assert [labels[v] for v in values] == ["3", "5", "10", "20"]


def test_hsc_stick_figures_show_the_input_histogram_and_the_authors_skeleton():
    """Features without images (the hsc source) get the input histogram in the silhouette's place, and the
    true and predicted poses as stick figures of the authors' skeleton, drawn at the same scale in a row."""
    import matplotlib.pyplot as plt
    from matplotlib.container import BarContainer

    from bsrbench.authors import hsc_stick_figure
    from bsrbench.reporting.plots import MIN_FONT_PT, TEXT_WIDTH, plot_subjective_sticks

    rng = np.random.default_rng(0)
    y_true = rng.uniform(-40, 40, 57)
    y_pred = y_true + rng.normal(0, 5, 57)
    true, parents = hsc_stick_figure(y_true)
    pnl = {
        "label": "Golf",
        "frame": 7,
        "x": rng.random(100),
        "parents": parents,
        "true": true,
        "preds": {"PM": hsc_stick_figure(y_pred)[0]},
        "errors": {"PM": 4.2},
    }
    fig = plot_subjective_sticks([pnl], labels=LABELS)
    hist, true_ax, pred_ax = fig.axes[:3]
    bars = [c for c in hist.containers if isinstance(c, BarContainer)]
    assert len(bars) == 1 and len(bars[0]) == 100
    assert "input histogram" in hist.get_title() and "test frame 7" in hist.get_title()
    assert true_ax.get_title() == "true pose" and pred_ax.get_title() == "PM (4.2 deg)"
    # one line per bone: the true pose alone, the prediction over the true pose in grey
    n_bones = int((parents >= 0).sum())
    assert len(true_ax.lines) == n_bones and len(pred_ax.lines) == 2 * n_bones
    assert true_ax.get_xlim() == pred_ax.get_xlim()
    fig.canvas.draw()
    assert fig.get_tightbbox(fig.canvas.get_renderer()).width <= TEXT_WIDTH + 0.01
    sizes = [
        t.get_fontsize() for t in fig.findobj(plt.Text) if t.get_visible() and t.get_text().strip()
    ]
    assert min(sizes) >= MIN_FONT_PT
    plt.close(fig)


def test_stick_figure_titles_of_long_method_labels_stay_over_their_panel():
    """Before: "PM K=16 5000 sw. text pred. (7.6 deg)" ran into the next panel's title (the paper-goal report)."""
    import matplotlib.pyplot as plt

    from bsrbench.authors import hsc_stick_figure
    from bsrbench.reporting.plots import plot_subjective_sticks

    rng = np.random.default_rng(1)
    true, parents = hsc_stick_figure(rng.uniform(-40, 40, 57))
    methods = ["PMK8", "PMK16s5000text", "NN1"]
    labels = {"PMK8": "PM K=8", "PMK16s5000text": "PM K=16 5000 sw. text pred.", "NN1": "1-NN"}
    pnl = {
        "label": "Golf",
        "frame": 7,
        "x": rng.random(100),
        "parents": parents,
        "true": true,
        "preds": {m: hsc_stick_figure(rng.uniform(-40, 40, 57))[0] for m in methods},
        "errors": {m: 7.6 for m in methods},
    }
    fig = plot_subjective_sticks([pnl], labels=labels)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    titles = [ax.title for ax in fig.axes[1:5]]
    assert titles[2].get_text().replace("\n", " ") == "PM K=16 5000 sw. text pred. (7.6 deg)"
    boxes = [t.get_window_extent(r) for t in titles]
    for left, right in zip(boxes, boxes[1:]):
        assert left.x1 < right.x0, (left, right)  # no title overlaps its neighbour
    plt.close(fig)


def test_frame_errors_wrap_the_angle_differences():
    from bsrbench.reporting.plots import frame_errors

    truth = np.array([[350.0, 10.0], [0.0, -170.0]])
    pred = np.array([[10.0, 10.0], [90.0, 170.0]])
    # 350 -> 10 is 20 degrees, not 340; -170 -> 170 is 20 degrees
    np.testing.assert_allclose(frame_errors(truth, pred), [(20 + 0) / 2, (90 + 20) / 2])


def test_figures_with_nothing_to_draw_say_so_in_one_line():
    """Before: a study without a method with a predictive distribution failed in rule plot_pit (matplotlib's
    "Number of rows must be a positive integer, not 0"); one without a subjective method drew empty axes."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import plot_subjective
    from bsrbench.reporting.today import plot_pit

    for fig, words in (
        (plot_pit({}, labels={}), "no method with a predictive"),
        (plot_subjective([], labels={}), "no method of report.subjective_methods was run"),
    ):
        texts = [t.get_text() for ax in fig.axes for t in ax.texts]
        assert len(texts) == 1 and words in texts[0], texts
        plt.close(fig)


def test_error_figure_draws_the_paper_methods_and_the_others_in_panels_of_their_own():
    """Before: 12 methods and the paper's dotted lines in one panel per activity. Now the paper's methods (with
    the paper's lines) and the references and today's baselines (beside PM, in the same colour) have a row of
    panels each, with the same y range per activity."""
    import matplotlib.pyplot as plt

    from bsrbench.reporting.plots import figure_blocks, plot_error_vs_ntrain

    labels = {**LABELS, "KNN": "k-NN"}
    names = {"PM": "PM", "RVM": "RVM", "NN1": None, "KNN": None}
    assert figure_blocks(["PM", "RVM", "NN1", "KNN"], names) == [
        ("the paper's methods", ["PM", "RVM"]),
        ("references and today's baselines", ["PM", "NN1", "KNN"]),
    ]
    assert figure_blocks(["PM", "RVM"], names) == [(None, ["PM", "RVM"])]
    df = aggregate_rows(
        result_rows(
            {
                ("golf", "PM"): [8.0, 9.0],
                ("golf", "RVM"): [12.0, 13.0],
                ("golf", "NN1"): [7.0, 7.5],
                ("golf", "KNN"): [3.0, 3.5],
            }
        )
    )
    fig = plot_error_vs_ntrain(
        df, paper_frame(), source="hsc", methods=["PM", "RVM", "NN1", "KNN"], labels=labels
    )
    assert len(fig.subfigs) == 2 and len(fig.axes) == 2
    legends = [[t.get_text() for t in sub.legends[0].get_texts()] for sub in fig.subfigs]
    assert legends[0][:2] == ["PM", "RVM"] and "the paper" in legends[0]
    assert legends[1][:3] == ["PM", "1-NN", "k-NN"] and "the paper" not in legends[1]
    top, bottom = fig.axes
    assert top.get_ylim() == bottom.get_ylim()
    pm_colour = {
        tuple(ln.get_color()) if not isinstance(ln.get_color(), str) else ln.get_color()
        for ax in fig.axes
        for ln in ax.get_lines()
        if ln.get_marker() == "o"
    }
    assert len(pm_colour) == 1  # PM (first method, marker "o") in one colour in both blocks
    plt.close(fig)
