"""Pose regressors sharing one scikit-learn contract: ``fit(X, Y)``, ``predict(X[, return_std])``.

- ``BayesianSR``: the paper's model (PM), Gibbs sampling with a correct Metropolis-Hastings step (``bsr``).
- ``RVM``, ``TGP``, ``SR``, ``DDL``: the paper's baselines.
- ``NearestNeighbourRegressor``, ``RidgeRegressor``: simple references.

Classes are imported on first use, so importing one model does not load (or JIT-compile) the others.
"""

import importlib

_WHERE = {
    "BayesianSR": "bsr",
    "RVM": "rvm",
    "TGP": "tgp",
    "SR": "sr",
    "DDL": "ddl",
    "NearestNeighbourRegressor": "reference",
    "RidgeRegressor": "reference",
}

__all__ = sorted(_WHERE)


def __getattr__(name):
    if name in _WHERE:
        return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return __all__
