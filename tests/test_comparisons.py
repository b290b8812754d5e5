"""Paired comparisons per cell (corrected resampled t, Wilcoxon, Holm, Bayesian correlated t) and the ranking
across cells, each formula checked against a hand computation on a small example (and scipy where it has one)."""

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from bsrbench.errors import InputError
from bsrbench.reporting.comparisons import (
    NO_TEST,
    PUBLISHED_COLUMNS,
    bayes_correlated_t,
    cd_diagram,
    cd_ranks,
    cell_means,
    compare_pair,
    comparisons,
    corrected_t,
    holm,
    paired_t,
    pm_counts,
    published,
    tied_with_best,
    wilcoxon_p,
)


def t2_cdf(t):
    """CDF of Student's t with 2 degrees of freedom, in closed form."""
    return 0.5 + t / (2.0 * math.sqrt(2.0 + t * t))


def t2_ppf(q):
    """Quantile of Student's t with 2 degrees of freedom, in closed form."""
    return (2.0 * q - 1.0) / math.sqrt(2.0 * q * (1.0 - q))


def test_corrected_t_by_hand():
    # d = 1, 2, 3: mean 2, s^2 = 1, J = 3; n_test/n_train = 5/10: variance factor 1/3 + 1/2 = 5/6
    mean, lo, hi, p = corrected_t([1.0, 2.0, 3.0], n_train=10, n_test=5)
    se = math.sqrt(5.0 / 6.0)
    t = 2.0 / se
    assert mean == pytest.approx(2.0)
    assert p == pytest.approx(2.0 * (1.0 - t2_cdf(t)), rel=1e-12)
    h = t2_ppf(0.975) * se
    assert (lo, hi) == pytest.approx((2.0 - h, 2.0 + h), rel=1e-12)


def test_corrected_t_without_the_correction_is_scipy_ttest():
    d = np.array([0.3, -0.1, 0.8, 0.5, 0.2, 1.1])
    _, lo, hi, p = corrected_t(d, n_train=1.0, n_test=1e-15)
    ref = stats.ttest_1samp(d, 0.0)
    assert p == pytest.approx(ref.pvalue, rel=1e-9)
    ci = ref.confidence_interval(0.95)
    assert (lo, hi) == pytest.approx((ci.low, ci.high), rel=1e-9)


def test_paired_t_is_scipy_ttest_rel():
    a = np.array([5.1, 4.8, 6.0, 5.5, 5.2, 4.9])
    b = np.array([4.9, 4.9, 5.2, 5.0, 5.1, 4.2])
    mean, lo, hi, p = paired_t(a - b)
    ref = stats.ttest_rel(a, b)
    ci = ref.confidence_interval(0.95)
    assert mean == pytest.approx(float(np.mean(a - b)))
    assert p == pytest.approx(ref.pvalue, rel=1e-9)
    assert (lo, hi) == pytest.approx((ci.low, ci.high), rel=1e-9)
    with pytest.raises(InputError, match="paired t-test needs at least 2 paired splits; got 1"):
        paired_t([1.0])


def test_corrected_t_is_wider_than_the_plain_t():
    d = np.array([0.3, -0.1, 0.8, 0.5, 0.2, 1.1])
    _, lo, hi, p = corrected_t(d, n_train=30, n_test=570)
    ref = stats.ttest_1samp(d, 0.0)
    assert p > ref.pvalue
    # the half-width grows by sqrt((1/J + n_test/n_train) / (1/J))
    ci = ref.confidence_interval(0.95)
    ratio = (hi - lo) / (ci.high - ci.low)
    assert ratio == pytest.approx(math.sqrt((1 / 6 + 19) / (1 / 6)), rel=1e-9)


def test_bayes_correlated_t_by_hand():
    d = [1.0, 2.0, 3.0]
    pb, pr, pw = bayes_correlated_t(d, n_train=10, n_test=5, rope=0.5)
    rho = 5 / 15
    scale = math.sqrt((1 / 3 + rho / (1 - rho)) * 1.0)
    assert pb == pytest.approx(t2_cdf((-0.5 - 2.0) / scale), rel=1e-12)
    assert pw == pytest.approx(1.0 - t2_cdf((0.5 - 2.0) / scale), rel=1e-12)
    assert pr == pytest.approx(t2_cdf((0.5 - 2.0) / scale) - t2_cdf((-0.5 - 2.0) / scale), rel=1e-9)
    assert pb + pr + pw == pytest.approx(1.0)


def test_wilcoxon_by_hand():
    # all 5 differences positive: W- = 0, P(W- <= 0) = 1/32 under H0, two-sided 2/32
    assert wilcoxon_p([1.0, 2.0, 3.0, 4.0, 5.0]) == pytest.approx(2 / 32)
    # one negative of rank 1: W- = 1, P(W- <= 1) = 2/32, two-sided 4/32
    assert wilcoxon_p([-1.0, 2.0, 3.0, 4.0, 5.0]) == pytest.approx(4 / 32)
    assert wilcoxon_p([0.0, 0.0, 0.0]) == 1.0


def test_holm_by_hand():
    # sorted 0.01, 0.03, 0.04: 3 * 0.01 = 0.03, 2 * 0.03 = 0.06, max(0.06, 1 * 0.04) = 0.06
    assert holm([0.01, 0.04, 0.03, math.nan]) == pytest.approx(
        [0.03, 0.06, 0.06, math.nan], nan_ok=True
    )


def test_holm_equals_statsmodels():
    from statsmodels.stats.multitest import multipletests

    rng = np.random.default_rng(3)
    for m in (1, 2, 7, 21):
        p = rng.uniform(0, 0.2, m)
        p[: m // 3] = p[0]  # ties
        assert holm(p) == pytest.approx(multipletests(p, method="holm")[1], rel=1e-12)


def test_identical_errors_give_p_one_and_a_zero_interval():
    e = [3.0, 4.0, 5.0, 6.0]
    r = compare_pair(e, e, n_train=30, n_test=570)
    assert r["n_splits"] == 4
    assert (r["mean_diff"], r["ci_low"], r["ci_high"]) == (0.0, 0.0, 0.0)
    assert r["p_corrected_t"] == 1.0 and r["p_wilcoxon"] == 1.0
    assert (r["p_better"], r["p_rope"], r["p_worse"]) == (0.0, 1.0, 0.0)
    # a constant shift: no variance, certainly different
    r = compare_pair([4.0, 5.0, 6.0], [3.0, 4.0, 5.0], n_train=30, n_test=570)
    assert r["p_corrected_t"] == 0.0 and (r["ci_low"], r["ci_high"]) == (1.0, 1.0)
    assert (r["p_better"], r["p_rope"], r["p_worse"]) == (0.0, 0.0, 1.0)


def test_fewer_than_two_splits_get_no_test():
    r = compare_pair([3.0], [4.0], n_train=30, n_test=570)
    assert r["n_splits"] == 1 and r["note"] == NO_TEST
    assert (
        r["mean_diff"] == -1.0
        and math.isnan(r["p_corrected_t"])
        and math.isnan(r["p_holm"] if "p_holm" in r else math.nan)
    )
    with pytest.raises(InputError, match="at least 2 paired splits; got 1"):
        corrected_t([1.0], n_train=30, n_test=570)


def _results(errors, *, n_train=30, n_test=570, protocol="random", source="hsc", activity="golf"):
    """errors: {method: [error per seed]} (None: no row for that seed)."""
    rows = []
    for m, errs in errors.items():
        for seed, e in enumerate(errs):
            if e is None:
                continue
            nt = n_test[seed] if isinstance(n_test, list) else n_test
            rows.append(
                dict(
                    protocol=protocol,
                    source=source,
                    activity=activity,
                    n_train=n_train,
                    method=m,
                    seed=seed,
                    error=e,
                    n_test=nt,
                )
            )
    return pd.DataFrame(rows)


def test_cell_compares_with_pm_and_the_best_with_holm_over_the_cell():
    pm = [5.0, 5.5, 6.0, 5.2, 5.8]
    a = [4.0, 4.1, 4.6, 4.3, 4.2]  # the best
    b = [4.5, 5.0, 5.1, 4.4, 5.2]
    c = comparisons(_results({"PM": pm, "A": a, "B": b}, n_train=30, n_test=60))
    assert list(c.columns[: len(PUBLISHED_COLUMNS)]) == PUBLISHED_COLUMNS
    got = {(r.method, r.versus) for r in c.itertuples()}
    assert got == {("A", "PM"), ("B", "PM"), ("PM", "A"), ("B", "A")}
    assert set(c["best"]) == {"A"}
    # each row by hand
    e = {"PM": np.array(pm), "A": np.array(a), "B": np.array(b)}
    raw, raw_plain = {}, {}
    for r in c.itertuples():
        d = e[r.method] - e[r.versus]
        mean, lo, hi, p = corrected_t(d, n_train=30, n_test=60)
        assert (r.mean_diff, r.ci_low, r.ci_high, r.p_corrected_t) == pytest.approx(
            (mean, lo, hi, p)
        )
        assert r.p_wilcoxon == pytest.approx(stats.wilcoxon(d).pvalue)
        assert r.p_paired_t == pytest.approx(stats.ttest_1samp(d, 0.0).pvalue)
        raw[frozenset((r.method, r.versus))] = p
        raw_plain[frozenset((r.method, r.versus))] = r.p_paired_t

    # Holm over the 3 distinct pairs {A, PM}, {B, PM}, {A, B}: sorted p times 3, 2, 1, running maximum
    def by_hand(raw):
        adj, run = {}, 0.0
        for i, k in enumerate(sorted(raw, key=raw.get)):
            run = max(run, min(1.0, (3 - i) * raw[k]))
            adj[k] = run
        return adj

    adj, adj_plain = by_hand(raw), by_hand(raw_plain)
    for r in c.itertuples():
        assert r.p_holm == pytest.approx(adj[frozenset((r.method, r.versus))])
        assert r.p_holm_paired == pytest.approx(adj_plain[frozenset((r.method, r.versus))])
    pa = c[(c.method == "PM") & (c.versus == "A")].iloc[0]
    ap = c[(c.method == "A") & (c.versus == "PM")].iloc[0]
    assert pa.p_holm == ap.p_holm and pa.mean_diff == -ap.mean_diff
    assert (pa.p_better, pa.p_worse) == pytest.approx((ap.p_worse, ap.p_better))


def test_best_is_pm_gives_one_set_of_rows():
    c = comparisons(_results({"PM": [1.0, 1.2, 1.1], "A": [2.0, 2.5, 2.1], "B": [3.0, 3.1, 3.3]}))
    assert sorted(zip(c.method, c.versus)) == [("A", "PM"), ("B", "PM")]
    assert set(c.best) == {"PM"}


def test_missing_splits_pair_on_the_common_ones():
    pm = [5.0, 5.5, 6.0, 5.2, 5.8]
    a = [4.0, None, 4.6, None, 4.2]
    c = comparisons(_results({"PM": pm, "A": a}, n_test=[500, 510, 520, 530, 540]))
    r = c[(c.method == "A") & (c.versus == "PM")].iloc[0]
    assert r.n_splits == 3
    d = np.array([4.0 - 5.0, 4.6 - 6.0, 4.2 - 5.8])
    # n_test: the mean over the common splits 0, 2, 4
    mean, lo, hi, p = corrected_t(d, n_train=30, n_test=(500 + 520 + 540) / 3)
    assert (r.mean_diff, r.ci_low, r.ci_high, r.p_corrected_t) == pytest.approx((mean, lo, hi, p))


def test_one_common_split_is_said_in_the_table():
    c = comparisons(_results({"PM": [5.0, 5.5, None], "A": [None, 4.0, 4.1]}))
    r = c.iloc[0]
    assert r.n_splits == 1 and r.note == NO_TEST and math.isnan(r.p_holm)
    assert tied_with_best(c) == {}


def test_published_has_exactly_the_columns():
    c = comparisons(_results({"PM": [5.0, 5.5, 6.0], "A": [4.0, 4.1, 4.6]}))
    assert list(published(c).columns) == PUBLISHED_COLUMNS


def test_bad_input_names_the_column_and_value():
    df = _results({"PM": [5.0, 5.5], "A": [4.0, 4.1]})
    with pytest.raises(InputError, match=r"lacks columns \['n_test'\]"):
        comparisons(df.drop(columns="n_test"))
    df.loc[1, "n_test"] = 0
    with pytest.raises(InputError, match=r"n_test = 0.*expected a finite number > 0"):
        comparisons(df)


def test_ties_and_counts():
    rng = np.random.default_rng(0)
    base = rng.normal(5.0, 0.3, 10)
    frames = [
        # PM far worse than A and NN1: a constant shift, p = 0 -> worse
        _results({"PM": base + 3.0, "A": base, "NN1": base + 0.5}, activity="walk"),
        # PM the same as the best up to noise -> tied; the best is A
        _results(
            {"PM": base + rng.normal(0, 0.05, 10), "A": base - 0.2, "NN1": base + 10.0},
            activity="run",
        ),
    ]
    c = comparisons(pd.concat(frames, ignore_index=True))
    ties = tied_with_best(c, test="corrected")
    assert "PM" not in ties[("random", "hsc", "walk", 30)]
    assert ties[("random", "hsc", "run", 30)] == {"A", "PM"}
    # on these frames PM's 0.2 deg gap to A is consistent over the splits: worse by the plain paired test
    assert tied_with_best(c)[("random", "hsc", "run", 30)] == {"A"}
    plain = pm_counts(c).set_index("versus")
    assert plain.loc["best", ["cells", "worse", "tied", "better"]].tolist() == [2, 2, 0, 0]
    with pytest.raises(InputError, match="unknown per-cell test 'plain'"):
        pm_counts(c, test="plain")
    t = pm_counts(c, test="corrected").set_index("versus")
    assert t.loc["best", ["cells", "worse", "tied", "better"]].tolist() == [2, 1, 1, 0]
    assert t.loc["NN1", ["cells", "worse", "better"]].tolist() == [2, 1, 1]
    # the corrected counts ride along with either test
    assert t.loc["best", ["worse_corrected", "tied_corrected"]].tolist() == [1, 1]
    assert plain.loc["best", ["worse_corrected", "tied_corrected"]].tolist() == [1, 1]


def test_cd_ranks_by_hand():
    means = pd.DataFrame(
        {
            "A": [1.0, 2.0, 3.0, 1.0, 2.0, 1.5],
            "B": [2.0, 1.0, 4.0, 3.0, 3.0, 2.5],
            "C": [3.0, 3.0, 5.0, 2.0, 1.0, 3.5],
        }
    )
    ranks, p = cd_ranks(means)
    # ranks per row: A 1 2 1 1 2 1, B 2 1 2 3 3 2, C 3 3 3 2 1 3
    assert ranks.to_dict() == pytest.approx({"A": 8 / 6, "B": 13 / 6, "C": 15 / 6})
    raw = {
        ("A", "B"): stats.wilcoxon(means["A"], means["B"]).pvalue,
        ("A", "C"): stats.wilcoxon(means["A"], means["C"]).pvalue,
        ("B", "C"): stats.wilcoxon(means["B"], means["C"]).pvalue,
    }
    adj = dict(zip(raw, holm(list(raw.values()))))
    for (x, y), v in adj.items():
        assert p.loc[x, y] == pytest.approx(v) and p.loc[y, x] == pytest.approx(v)
    assert p.loc["A", "A"] == 1.0
    with pytest.raises(InputError, match="at least 2 cells"):
        cd_ranks(means.iloc[:1])


def test_cd_diagram_draws(tmp_path):
    frames = [
        _results(
            {
                "PM": [5.0 + k, 5.5 + k],
                "A": [4.0 + 0.7 * k, 4.1 + k],
                "B": [4.5 + 1.3 * k, 6.0 + k],
            },
            n_train=n,
        )
        for k, n in enumerate((30, 60, 100))
    ]
    df = pd.concat(frames, ignore_index=True)
    assert cell_means(df, protocol="random", source="hsc").shape == (3, 3)
    fig = cd_diagram(df, protocols=["random"], source="hsc", labels={"A": "Alpha"})
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert any("Alpha" in t for t in texts)
    fig.savefig(tmp_path / "cd.png")
    one = cd_diagram(df[df.n_train == 30], protocols=["random"], source="hsc")
    assert any("no ranking test" in t.get_text() for t in one.axes[0].texts)
