"""bsrbench.reporting.mechanisms against hand computations on small synthetic tables: which methods are mechanism
variants, the paired differences to PM, the verdict counts, the pooled interval per N, the training-error table
and the section's and README paragraph's text."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy import stats

from bsrbench.errors import InputError
from bsrbench.reporting import comparisons as cmp
from bsrbench.reporting import mechanisms as mech
from bsrbench.reporting.published import main as published_main
from bsrbench.reporting.published import update_mechanisms

ROOT = Path(__file__).resolve().parents[1]
BSR = "bsrbench.models.bsr:BayesianSR"
BASE = {"n_atoms": 64, "n_neighbors": 3, "n_iter": 1200}
PARAMS = {
    "PM": BASE,
    "PMsame": {**BASE, "logit_kernel": "identity"},  # errors identical to PM's
    "PMshift": {**BASE, "eta_scale": 10.0},  # errors PM's + 0.7
    "PMnoisy": {**BASE, "n_predict_samples": 1},  # errors PM's + 0.3 + noise
    "PMK16": {**BASE, "n_atoms": 16},  # another parameter: not a mechanism variant
}
N_TEST, SEEDS = 120, [100, 101, 102, 103, 104]
NOISE = np.array([0.5, -0.2, 0.1, -0.4, 0.3])


def _table(train_error=True):
    rng = np.random.default_rng(3)
    rows = []
    for act in ("golf", "run"):
        for n in (30, 60):
            pm = rng.uniform(5, 9, size=len(SEEDS))
            err = {
                "PM": pm,
                "PMsame": pm.copy(),
                "PMshift": pm + 0.7,
                "PMnoisy": pm + 0.3 + NOISE * (n / 30),
                "PMK16": pm - 1.0,
                "NN1": pm + 2.0,
            }
            for m, e in err.items():
                for k, s in enumerate(SEEDS):
                    r = {
                        "protocol": "random",
                        "source": "hsc",
                        "activity": act,
                        "paper_activity": act.capitalize(),
                        "n_train": n,
                        "method": m,
                        "seed": s,
                        "error": float(e[k]),
                        "n_test": N_TEST,
                        "estimator": BSR
                        if m != "NN1"
                        else "bsrbench.models.reference:NearestNeighbourRegressor",
                        "params": json.dumps(PARAMS.get(m, {"n_neighbors": 1})),
                    }
                    if train_error:
                        r["train_error"] = (
                            float(e[k]) - 3.0 if m in ("PM", "PMnoisy") else float("nan")
                        )
                    rows.append(r)
    return pd.DataFrame(rows)


DEFAULTS = {"logit_kernel": "pose", "eta_scale": 1.0, "n_predict_samples": None, "n_atoms": 128}
VARIANTS = {
    "PMsame": {"logit_kernel": "identity"},
    "PMshift": {"eta_scale": 10.0},
    "PMnoisy": {"n_predict_samples": 1},
}


# ------------------------------------------------------------------------------------- which methods
def test_variants_are_the_methods_differing_in_mechanism_options_only():
    assert mech.variants_from_results(_table(), base="PM", defaults=DEFAULTS) == VARIANTS
    # an option written out at its default value is no difference
    assert mech.differing_options(BASE, {**BASE, "logit_kernel": "pose"}, DEFAULTS) == {}
    assert mech.differing_options(BASE, {**BASE, "eta_scale": 1}, DEFAULTS) == {}
    assert mech.differing_options(BASE, {**BASE, "n_atoms": 16, "eta_scale": 10}, DEFAULTS) is None


def test_variants_of_the_study_configuration():
    """config/ablation-mechanisms.yaml: its 5 PM variants, read from the file (the estimator's own defaults)."""
    cfg = yaml.safe_load((ROOT / "config" / "ablation-mechanisms.yaml").read_text())
    got = mech.variants_from_config(cfg["methods"], cfg["run"], base="PM")
    assert got == {
        "PMinput": {"logit_kernel": "input"},
        "PMidentity": {"logit_kernel": "identity"},
        "PMeta01": {"eta_scale": 0.1},
        "PMeta10": {"eta_scale": 10.0},
        "PMone": {"n_predict_samples": 1},
    }
    # the 23-variant ablation varies other parameters: no mechanism variant, so no section
    abl = yaml.safe_load((ROOT / "config" / "ablation.yaml").read_text())
    base = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["methods"]
    methods = {m: {**base.get(m, {}), **v} for m, v in abl["methods"].items()}
    assert mech.variants_from_config(methods, abl["run"], base="PM") == {}


# --------------------------------------------------------------------------------------- the numbers
def _hand_corrected_t(d, n_train):
    J = len(d)
    se = math.sqrt((1 / J + N_TEST / n_train) * np.var(d, ddof=1))
    h = stats.t.ppf(0.975, J - 1) * se
    p = 2 * stats.t.sf(abs(np.mean(d)) / se, J - 1)
    return np.mean(d), np.mean(d) - h, np.mean(d) + h, p


def test_identical_variant_is_equal_and_shifted_variant_gives_the_shift():
    df = _table()
    t = mech.mechanism_table(df, cmp.comparisons(df), base="PM", variants=VARIANTS)
    assert len(t) == 3 * 4 and list(t.columns) == mech.TABLE_COLUMNS
    same = t[t["method"] == "PMsame"]
    assert (
        (same["mean_diff"] == 0).all()
        and (same["ci_low"] == 0).all()
        and (same["ci_high"] == 0).all()
    )
    assert (same["verdict"] == "tied").all() and (same["p_holm"] == 1).all()
    shift = t[t["method"] == "PMshift"]
    np.testing.assert_allclose(shift["mean_diff"], 0.7, atol=1e-12)
    np.testing.assert_allclose(shift["ci_low"], 0.7, atol=1e-12)
    assert (shift["verdict"] == "worse").all()
    # the mean errors: the variant's and PM's over the cell's splits
    pm = df[(df["method"] == "PM") & (df["activity"] == "golf") & (df["n_train"] == 30)]["error"]
    row = shift[(shift["activity"] == "golf") & (shift["n_train"] == 30)].iloc[0]
    assert row["base_error"] == pytest.approx(pm.mean()) and row["error"] == pytest.approx(
        pm.mean() + 0.7
    )


def test_noisy_variant_interval_and_holm_p_by_hand():
    df = _table()
    comp = cmp.comparisons(df)
    t = mech.mechanism_table(df, comp, base="PM", variants=VARIANTS)
    for n in (30, 60):
        d = 0.3 + NOISE * (n / 30)
        mean, lo, hi, p = _hand_corrected_t(d, n)
        r = t[(t["method"] == "PMnoisy") & (t["activity"] == "run") & (t["n_train"] == n)].iloc[0]
        assert (r["mean_diff"], r["ci_low"], r["ci_high"]) == pytest.approx((mean, lo, hi))
        # Holm by hand over the cell's 9 distinct pairs (5 methods against PM, the best, PMK16, against the 4
        # others but PM): the step-down maximum of (m - j + 1) p_(j)
        cell = comp[(comp["activity"] == "run") & (comp["n_train"] == n)]
        raw = {
            frozenset((a, b)): q
            for a, b, q in cell[["method", "versus", "p_corrected_t"]].itertuples(index=False)
        }
        assert len(raw) == 9
        ps = sorted(raw.values())
        adj, run = [], 0.0
        for j, q in enumerate(ps):
            run = max(run, min(1.0, (len(ps) - j) * q))
            adj.append(run)
        assert r["p_holm"] == pytest.approx(
            adj[ps.index(p)] if p in ps else adj[int(np.argmin(np.abs(np.array(ps) - p)))]
        )
        assert r["verdict"] == ("worse" if r["p_holm"] < 0.05 else "tied")


def test_verdict_counts():
    df = _table()
    t = mech.mechanism_table(df, None, base="PM", variants=VARIANTS)
    c = mech.verdict_counts(t).set_index("method")
    assert c.loc["PMsame", ["cells", "worse", "tied", "better"]].tolist() == [4, 0, 4, 0]
    assert c.loc["PMshift", ["cells", "worse", "tied", "better"]].tolist() == [4, 4, 0, 0]
    assert c.loc["PMshift", "reason"] == "pose" and c.loc["PMnoisy", "reason"] == "averaging"


def test_pooled_interval_by_hand():
    """Two cells with J = 5 and 4 splits: se from each interval, sum of variances over k^2, Welch-Satterthwaite."""
    se1, se2 = 0.4, 0.25
    q1, q2 = stats.t.ppf(0.975, 4), stats.t.ppf(0.975, 3)
    d = [1.0, -0.2]
    hi = [1.0 + q1 * se1, -0.2 + q2 * se2]
    mean, lo, up, k = mech.pooled(d, hi, [5, 4])
    var = (se1**2 + se2**2) / 4
    nu = (se1**2 + se2**2) ** 2 / (se1**4 / 4 + se2**4 / 3)
    h = stats.t.ppf(0.975, nu) * math.sqrt(var)
    assert k == 2 and mean == pytest.approx(0.4)
    assert (lo, up) == pytest.approx((0.4 - h, 0.4 + h))
    # a cell without a test is left out; zero variances give a point interval
    assert mech.pooled([0.5, 9.0], [0.5, float("nan")], [5, 1]) == (0.5, 0.5, 0.5, 1)
    assert math.isnan(mech.pooled([1.0], [float("nan")], [1])[0])


def test_pooled_by_n_of_the_shift_is_the_shift():
    df = _table()
    p = mech.pooled_by_n(mech.mechanism_table(df, None, base="PM", variants=VARIANTS))
    s = p[p["method"] == "PMshift"]
    assert s["n_train"].tolist() == [30, 60] and (s["activities"] == 2).all()
    np.testing.assert_allclose(s[["mean_diff", "ci_low", "ci_high"]].to_numpy(), 0.7, atol=1e-12)


def test_fit_table_and_not_recorded():
    df = _table()
    ft = mech.fit_table(df, base="PM", variants=VARIANTS)
    assert ft["method"].tolist() == ["PM", "PMnoisy", "PM", "PMnoisy"]
    pm30 = df[(df["method"] == "PM") & (df["n_train"] == 30)]["error"]
    r = ft[(ft["method"] == "PM") & (ft["n_train"] == 30)].iloc[0]
    assert r["test_error"] == pytest.approx(pm30.mean()) and r["train_error"] == pytest.approx(
        pm30.mean() - 3
    )
    no = _table(train_error=False)
    assert mech.fit_table(no, base="PM", variants=VARIANTS) is None
    text = " ".join(mech.fit_sentences(no, labels={}, base="PM", variants=VARIANTS))
    assert "not recorded" in text


# ----------------------------------------------------------------------------------------- the text
def test_section_sentences_are_drawn_from_the_numbers():
    df = _table()
    tex = mech.section_latex(
        df, None, base="PM", variants=VARIANTS, labels={"PMsame": "PM Sigma_w = I"}
    )
    assert r"\section{Do the paper's reasons hold?}" in tex
    assert (
        r"PM Sigma\_w = I, removing the pose information ($\Sigma_w = I$): the error against PM changes by "
        r"+0.00 degrees (95\% CI +0.00 to +0.00) at $N = 30$ (mean over 2 activities)"
    ) in tex
    assert "worse in 0, equal in 4, better in 0 of the 4 (activity, $N$) cells" in tex
    assert "+0.70 degrees (95\\% CI +0.70 to +0.70) at $N = 60$" in tex
    # the pose reason: PMsame (no difference) and PMshift (+0.7 in every cell) over 2 N each
    assert (
        "(PM Sigma\\_w = I, PMshift against PM; 5 splits per cell): significantly worse in 4, better in 0 of 8"
        in tex
    )
    assert (
        "lies above zero (worse) at 2 and below zero (better) at 0 of the 4 (variant, $N$) pairs"
        in tex
    )
    assert "PMK16" not in tex and "NN1" not in tex
    assert r"\label{tab:mech-fit}" in tex
    # no variants: no section
    assert mech.section_latex(df, None, base="PM", variants={}, labels={}) == ""


def test_mechanism_table_names_missing_methods():
    with pytest.raises(InputError, match="PMgone"):
        mech.mechanism_table(_table(), None, base="PM", variants={"PMgone": {"eta_scale": 2.0}})


def test_readme_paragraph_between_markers(tmp_path):
    df = _table()
    src = tmp_path / "ablation-mechanisms.csv"
    df.to_csv(src, index=False)
    readme = tmp_path / "README.md"
    readme.write_text("intro\n<!-- mechanisms -->\nOLD PARAGRAPH\n<!-- /mechanisms -->\nend\n")
    assert published_main(["mechanisms", str(src), "--update", str(readme)]) == 0
    text = readme.read_text()
    assert "OLD PARAGRAPH" not in text and text.startswith("intro\n") and text.endswith("end\n")
    assert (
        "PMsame, removing the pose information (Sigma_w = I): PM's error changes by +0.00 deg"
        in text
    )
    assert "+0.70 deg (95% CI +0.70 to +0.70) at N = 30" in text
    assert "significantly worse in 4, equal in 0 and better in 0 of 4 cells" in text
    # the training-vs-test table: PM's row at N = 30 (its training error is the test error - 3 here)
    pm30 = df[(df["method"] == "PM") & (df["n_train"] == 30)]["error"].mean()
    assert f"| 30 | {pm30 - 3:.2f} / {pm30:.2f} | " in text
    # a file without the markers, and a table without variants: clear errors, the file unchanged
    other = tmp_path / "OTHER.md"
    other.write_text("no markers\n")
    assert published_main(["mechanisms", str(src), "--update", str(other)]) == 2
    assert other.read_text() == "no markers\n"
    plain = tmp_path / "plain.csv"
    df[df["method"].isin(["PM", "NN1"])].to_csv(plain, index=False)
    assert published_main(["mechanisms", str(plain)]) == 2
    with pytest.raises(Exception, match="mechanisms"):
        update_mechanisms(other, "x")


def test_published_mechanisms_refuses_a_variant_missing_cells(tmp_path, capsys):
    df = _table()
    gap = df[~((df["method"] == "PMshift") & (df["n_train"] == 60))]
    src = tmp_path / "gap.csv"
    gap.to_csv(src, index=False)
    readme = tmp_path / "README.md"
    readme.write_text("<!-- mechanisms -->\nOLD\n<!-- /mechanisms -->\n")
    assert published_main(["mechanisms", str(src), "--update", str(readme)]) == 2
    err = capsys.readouterr().err
    assert str(src) in err and "variant 'PMshift'" in err and "2 of the 4 cells" in err
    assert "golf/60" in err and "run/60" in err
    assert readme.read_text() == "<!-- mechanisms -->\nOLD\n<!-- /mechanisms -->\n"
    assert published_main(["mechanisms", str(tmp_path / "x.csv")]) == 2  # a missing file: exit 2
    # the base missing a cell its variants have, and the base missing altogether
    df[~((df["method"] == "PM") & (df["n_train"] == 60) & (df["activity"] == "run"))].to_csv(
        src, index=False
    )
    assert published_main(["mechanisms", str(src), "--update", str(readme)]) == 2
    assert "base 'PM' has no rows in 1 of the 4 cells" in capsys.readouterr().err
    df[df["method"] != "PM"].to_csv(src, index=False)
    assert published_main(["mechanisms", str(src), "--update", str(readme)]) == 2
    assert "no rows of the base method 'PM'" in capsys.readouterr().err
    assert readme.read_text() == "<!-- mechanisms -->\nOLD\n<!-- /mechanisms -->\n"
    # the full table passes the same check
    df.to_csv(src, index=False)
    assert published_main(["mechanisms", str(src), "--update", str(readme)]) == 0


def test_published_mechanisms_no_variant_names_the_table(tmp_path, capsys):
    plain = tmp_path / "plain.csv"
    _table().query("method in ['PM', 'NN1']").to_csv(plain, index=False)
    assert published_main(["mechanisms", str(plain)]) == 2
    err = capsys.readouterr().err
    assert f"{plain}: no mechanism variant of 'PM'" in err


def test_section_and_table_find_the_variants_in_the_configuration():
    """The section and table of a configuration with variants; a configuration without any has no section and an
    empty table with the table's columns."""
    df = _table()
    comp = cmp.comparisons(df)
    methods = {m: {"estimator": BSR, "params": p} for m, p in PARAMS.items()}
    methods["NN1"] = {"estimator": "bsrbench.models.reference:NearestNeighbourRegressor"}
    run = list(methods)
    text, table, variants = mech.section_and_table(
        df, comp, methods=methods, run=run, base="PM", labels={}
    )
    assert variants == mech.variants_from_config(methods, run, base="PM")
    assert set(variants) == set(VARIANTS)  # PMK16 changes another parameter: no variant
    assert text == mech.section_latex(df, comp, base="PM", variants=variants, labels={})
    pd.testing.assert_frame_equal(
        table, mech.mechanism_table(df, comp, base="PM", variants=variants)
    )
    text, table, variants = mech.section_and_table(
        df, comp, methods=methods, run=["PM", "NN1"], base="PM", labels={}
    )
    assert (text, variants) == ("", {}) and table.empty
    assert list(table.columns) == mech.TABLE_COLUMNS
