"""The protocol reconciliation (bsrbench.reporting.reconcile): variants read from the configuration, ratios and
within-std counts checked by hand, the nearest variant."""

import pandas as pd
import pytest

from bsrbench.errors import InputError
from bsrbench.reporting import reconcile as rc

NN1 = "bsrbench.models.reference:NearestNeighbourRegressor"
RVM = "bsrbench.models.rvm:RVM"
CONFIG = {
    "methods": {
        "NN1": {"estimator": NN1, "params": {"n_neighbors": 1}, "grid": None},
        "RVM": {"estimator": RVM, "params": {}, "grid": "default"},
        "RVMd": {"estimator": RVM, "params": {}, "grid": None},
        "RVMr": {"estimator": RVM, "params": {}, "grid": "default", "pose_transform": "none"},
    }
}
DATASETS = {
    "hsc": {
        "golf": {"n_frames": 600, "first_frame": 0, "frame_step": 1},
        "golf_late": {"n_frames": 600, "first_frame": 100, "frame_step": 1},
    }
}
PAPER = pd.DataFrame(
    [
        ("I", "Golf", 30, "RVM", 10.0, 2.0),
        ("I", "Golf", 30, "TGP", 8.0, 1.0),
        ("I", "Golf", 30, "SR", 9.0, 1.0),
        ("I", "Golf", 30, "DDL", 12.0, 1.0),
    ],
    columns=["table", "activity", "n_train", "method", "mean_deg", "std_deg"],
).assign(key="golf")


def _rows(method, estimator, activity, protocol, errors, unwrapped=None):
    return [
        dict(
            protocol=protocol,
            source="hsc",
            activity=activity,
            paper_activity="Golf",
            method=method,
            estimator=estimator,
            n_train=30,
            seed=s,
            error=e,
            error_unwrapped=(unwrapped or errors)[s],
        )
        for s, e in enumerate(errors)
    ]


def _table():
    rows = []
    rows += _rows("NN1", NN1, "golf", "random", [4.0, 6.0])
    rows += _rows("RVM", RVM, "golf", "random", [5.0, 7.0], unwrapped=[9.0, 9.0])
    rows += _rows("RVMd", RVM, "golf", "random", [11.0, 11.0])
    rows += _rows("RVMr", RVM, "golf", "random", [6.0, 6.0])
    rows += _rows("NN1", NN1, "golf", "blocked", [8.0, 8.0])
    rows += _rows("RVM", RVM, "golf", "blocked", [10.5, 11.5])
    rows += _rows("NN1", NN1, "golf_late", "random", [5.0, 5.0])
    rows += _rows("RVM", RVM, "golf_late", "random", [6.0, 6.0])
    return pd.DataFrame(rows)


def test_variants_come_from_the_configuration_and_ratios_are_by_hand():
    c = rc.cells(_table(), CONFIG, DATASETS, PAPER)
    key = ["splits", "frames", "setting", "metric", "method"]
    c = c.set_index(key)
    base = ("random", "rows 0-599", "tuned", "wrapped")
    # RVM: mean 6 against the paper's 10 (std 2): ratio 0.6, not within
    r = c.loc[(*base, "RVM")]
    assert r["ratio"] == pytest.approx(0.6) and not r["within"] and r["paper_method"] == "RVM"
    # 1-NN against the best of the paper's four baselines in the cell: TGP's 8 (std 1)
    r = c.loc[(*base, "1-NN")]
    assert r["paper_method"] == "TGP" and r["ratio"] == pytest.approx(5.0 / 8.0) and not r["within"]
    assert c.loc[("random", "rows 0-599", "tuned", "unwrapped", "RVM"), "ratio"] == pytest.approx(
        0.9
    )
    assert c.loc[(*base[:2], "defaults", "wrapped", "RVM"), "within"]  # 11 within 10 +- 2
    assert c.loc[(*base[:2], "no heading transform", "wrapped", "RVM"), "ratio"] == pytest.approx(
        0.6
    )
    assert c.loc[("blocked", "rows 0-599", "tuned", "wrapped", "RVM"), "ratio"] == pytest.approx(
        1.1
    )
    assert c.loc[("random", "rows 100-699", "tuned", "wrapped", "RVM"), "ratio"] == pytest.approx(
        0.6
    )
    # 1-NN is the same fit under every setting of the baselines
    assert c.loc[(*base[:2], "defaults", "wrapped", "1-NN"), "ratio"] == pytest.approx(5.0 / 8.0)


def test_the_nearest_variant_has_every_method_and_the_smallest_distance():
    s = rc.summary(rc.cells(_table(), CONFIG, DATASETS, PAPER))
    best, dist = rc.nearest(s)
    # blocked: RVM 11/10, 1-NN 8/8: distance (|log 1.1| + 0) / 2
    assert best == {
        "splits": "blocked",
        "frames": "rows 0-599",
        "setting": "tuned",
        "metric": "wrapped",
    }
    import math

    assert dist == pytest.approx(math.log(1.1) / 2)
    text = rc.markdown(rc.cells(_table(), CONFIG, DATASETS, PAPER))
    assert "Nearest the paper: splits blocked, rows 0-599, tuned, wrapped error" in text
    assert text.splitlines()[2].startswith("| random | rows 0-599 | tuned | wrapped |")


def test_results_without_the_baselines_or_the_unwrapped_error_are_refused():
    from bsrbench.errors import InputError

    df = _table()
    with pytest.raises(InputError, match="neither 1-NN nor one of the paper's baselines"):
        rc.cells(
            df.assign(method="X", estimator="bsrbench.models.bsr:BayesianSR"),
            CONFIG,
            DATASETS,
            PAPER,
        )
    with pytest.raises(InputError, match=r"lack columns \['error_unwrapped'\]"):
        rc.cells(df.drop(columns="error_unwrapped"), CONFIG, DATASETS, PAPER)


def test_pm_under_the_nearest_variant_is_tested_against_each_baseline_by_hand():
    from scipy import stats

    BSR = "bsrbench.models.bsr:BayesianSR"
    config = {
        "methods": {
            **CONFIG["methods"],
            "PM": {"estimator": BSR, "label": "PM", "params": {"n_atoms": 8}, "grid": None},
        }
    }
    pm = [5.0, 5.1, 4.9, 5.2, 4.8]
    rvm = [7.0, 7.2, 6.9, 7.1, 7.3]
    nn = [5.05, 5.0, 5.1, 4.95, 5.0]
    rows = _rows("PM", BSR, "golf", "blocked", pm)
    rows += _rows("RVMd", RVM, "golf", "blocked", rvm)
    rows += _rows("NN1", NN1, "golf", "blocked", nn)
    rows += _rows("PM", BSR, "golf", "random", [1.0] * 5)  # another variant: not counted
    df = pd.DataFrame(rows).assign(r_hat_test_error=1.0)
    df.loc[df["method"] == "PM", "r_hat_test_error"] = [1.0, 1.02, 1.01, 1.0, 1.04] + [9.0] * 5
    paper = pd.concat(
        [PAPER, PAPER.iloc[:1].assign(method="PM", mean_deg=6.0, std_deg=1.0)], ignore_index=True
    )
    variant = {
        "splits": "blocked",
        "frames": "rows 0-599",
        "setting": "defaults",
        "metric": "wrapped",
    }
    got, names = rc.pm_rows(df, config, DATASETS, variant)
    assert names == ["PM"] and set(got["name"]) == {"PM", "RVM", "1-NN"}
    (s,) = rc.pm_summary(got, names, paper)
    assert (
        s["cells"] == 1 and s["ratios"] == [pytest.approx(sum(pm) / 5 / 6.0)] and s["within"] == 1
    )
    assert sorted(s["r_hat"]) == [1.0, 1.0, 1.01, 1.02, 1.04]
    # by hand: paired t-tests over the seeds, Holm over PM's two comparisons of the cell
    p_rvm, p_nn = stats.ttest_rel(pm, rvm).pvalue, stats.ttest_rel(pm, nn).pvalue
    lo, hi = sorted([p_rvm, p_nn])
    holm = {lo: 2 * lo, hi: max(2 * lo, hi)}
    assert holm[p_rvm] < 0.05 <= holm[p_nn]
    assert s["counts"] == {"1-NN": [0, 1, 0], "RVM": [1, 0, 0]}
    text = rc.pm_markdown([s], variant)
    assert "| PM | 1 | 5.00 / nan | 0.83 (1/1) | 1.010, 1.040 | 0/1/0 | 1/0/0 |" in text


@pytest.mark.parametrize(
    "change, words",
    [
        (lambda d: d.drop(columns="estimator"), r"lack columns \['estimator'\]"),
        (lambda d: d.drop(columns="paper_activity"), r"lack columns \['paper_activity'\]"),
        (
            lambda d: d.assign(error_unwrapped=[float("nan")] + [1.0] * (len(d) - 1)),
            "'error_unwrapped' is empty",
        ),
        (
            lambda d: d.assign(activity="golf_half"),
            "data set hsc/golf_half .* not in the study's configuration",
        ),
    ],
)
def test_rows_it_cannot_reconcile_are_refused_in_one_line(change, words):
    with pytest.raises(InputError, match=words):
        rc.cells(change(_table()), CONFIG, DATASETS, PAPER)
