"""Pose regressors sharing one scikit-learn contract: ``fit(X, Y)``, ``predict(X[, return_std])``.

- ``BayesianSR``: the paper's model (PM), Gibbs sampling with a correct Metropolis-Hastings step (``bsr``).
- ``RVM``, ``TGP``, ``SR``, ``DDL``: the paper's baselines.
- ``NearestNeighbourRegressor``, ``RidgeRegressor``: simple references.

- ``KernelRidgeRBF``, ``GaussianProcessARD``, ``RandomForest``, ``MLP``: today's baselines.

Classes are imported on first use, so importing one model does not load (or JIT-compile) the others. The classes
are those the model modules export in their ``__all__`` (read from the sources, :func:`bsrbench.methods.model_classes`).
"""

import importlib

from ..methods import model_classes

#: {class name: its module}
_WHERE = model_classes()

__all__ = sorted(_WHERE)


def __getattr__(name):
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return __all__
