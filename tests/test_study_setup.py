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
