"""Estimators named by dotted path: loading errors name the path and parameter (bsrbench.estimators)."""

import pytest

from bsrbench.errors import InputError
from bsrbench.estimators import (
    default_grid,
    load_estimator_class,
    make_estimator,
)

REF = "bsrbench.models.reference"


def test_estimator_loading_errors_name_the_path_and_parameter():
    assert load_estimator_class(f"{REF}:RidgeRegressor").__name__ == "RidgeRegressor"
    with pytest.raises(InputError, match="package.module:ClassName"):
        load_estimator_class("bsrbench.models.reference.RidgeRegressor")
    with pytest.raises(InputError, match="cannot import module 'bsrbench.models.nosuch'"):
        load_estimator_class("bsrbench.models.nosuch:X")
    with pytest.raises(InputError, match="no attribute 'Nope'"):
        load_estimator_class(f"{REF}:Nope")
    with pytest.raises(InputError, match=r"no parameter\(s\) \['alpah'\]"):
        make_estimator(f"{REF}:RidgeRegressor", {"alpah": 1.0})
    assert default_grid(f"{REF}:RidgeRegressor") == {"alpha": [0.1, 1.0, 10.0, 100.0, 1000.0]}
