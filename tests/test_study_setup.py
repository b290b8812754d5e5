"""The report's section Setup (bsrbench.reporting.study_setup): the parameter table."""

from reportdata import LABELS, result_rows

from bsrbench.reporting.study_setup import (
    parameters_table,
    parameters_used,
)
from bsrbench.reporting.tables import (
    aggregate_rows,
)


def test_parameters_table_lists_configured_cv_chosen_and_default_values():
    rows = result_rows({("golf", "PM"): [8.0, 9.0]})
    rows[0]["params"], rows[1]["params"] = {"a": 1, "k": 64}, {"a": 1, "k": 128}
    df = aggregate_rows(rows)
    used = parameters_used(df, defaults={"PM": {"a": 5, "k": 3, "thin": 10, "random_state": None}})
    assert used["PM"] == ({"a": [1], "k": [64, 128]}, {"thin": 10, "random_state": "per job"})
    table = parameters_table(df, labels=LABELS, defaults={"PM": {"thin": 10}})
    assert (
        r"a=1, k=64|\allowbreak{}128 (CV)" in table and "thin=10" in table and "tabularx" in table
    )


def test_a_tall_parameter_table_floats_and_a_short_one_stays_in_place():
    """Before: the quick study's 35-line table was placed here ([H]), so it went to page 2 and left page 1 half
    empty. A short one stays in place, so that Table 1 does not float past Table 2."""
    import pandas as pd

    from bsrbench.reporting.study_setup import parameters_table

    df = pd.DataFrame({"method": ["NN1"], "params": ['{"n_neighbors": 1}'], "estimator": ["m:C"]})
    assert r"\begin{table}[H]" in parameters_table(df, labels={}, defaults={"NN1": {"w": "x"}})
    many = {f"p{i}": "a_long_default_value" for i in range(12)}
    methods = [f"M{i}" for i in range(6)]
    tall = pd.DataFrame({"method": methods, "params": ["{}"] * 6, "estimator": ["m:C"] * 6})
    text = parameters_table(tall, labels={}, defaults={m: many for m in methods})
    assert (
        r"\begin{table}[tbp]" in text and r"\ttfamily" not in text
    )  # roman type in the parameter columns
