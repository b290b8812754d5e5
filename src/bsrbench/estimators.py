"""Estimators named by dotted path (``"bsrbench.models.bsr:BayesianSR"``): import, build, parameters, grids.

Classes are imported only when used, so a missing model module fails only the jobs that need it.
"""

import importlib
import inspect

from .errors import InputError


def load_estimator_class(path):
    """Import ``"package.module:ClassName"`` and return the class; errors name the path."""
    if not isinstance(path, str) or path.count(":") != 1:
        raise InputError(f"estimator path must look like 'package.module:ClassName'; got {path!r}")
    module_name, class_name = path.split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise InputError(
            f"estimator {path!r}: cannot import module {module_name!r} ({exc})"
        ) from exc
    try:
        return getattr(module, class_name)
    except AttributeError:
        raise InputError(
            f"estimator {path!r}: module {module_name!r} has no attribute {class_name!r}"
        ) from None


def make_estimator(path, params, random_state=None):
    """Instantiate the estimator at ``path`` with ``params``; ``random_state`` is set if the class takes one."""
    cls = load_estimator_class(path)
    params = dict(params or {})
    accepted = set(inspect.signature(cls).parameters)
    unknown = sorted(set(params) - accepted)
    if unknown:
        raise InputError(
            f"estimator {path!r} has no parameter(s) {unknown}; it accepts {sorted(accepted)}"
        )
    if random_state is not None and "random_state" in accepted and "random_state" not in params:
        params["random_state"] = int(random_state)
    return cls(**params)


def estimator_parameters(path):
    """Names of the constructor parameters of the estimator at ``path``, or None if it takes ``**kwargs``.

    scikit-learn estimators (whose ``get_params`` reads the same signature) take exactly these keywords.
    Raises InputError (naming ``path``) if the class cannot be imported.
    """
    cls = load_estimator_class(path)
    sig = inspect.signature(cls)
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in sig.parameters.values()):
        return None
    return sorted(
        n for n, p in sig.parameters.items() if p.kind not in (inspect.Parameter.VAR_POSITIONAL,)
    )


def estimator_defaults(path):
    """``{parameter: default}`` of the estimator at ``path`` (``get_params()`` of a default instance)."""
    cls = load_estimator_class(path)
    try:
        return dict(cls().get_params(deep=False))
    except (TypeError, AttributeError):
        return {
            n: p.default
            for n, p in inspect.signature(cls).parameters.items()
            if p.default is not inspect.Parameter.empty
        }


def check_estimator_params(path, params, n_samples=None):
    """Build the estimator at ``path`` with ``params`` and run its own parameter validation, without data.

    The estimator's ``_check_params(n_samples=None)`` (the check its ``fit`` makes; bsrbench's estimators have
    one), else scikit-learn's ``_validate_params()`` (the ``_parameter_constraints`` of scikit-learn's own
    estimators); an estimator with neither is only built. ``n_samples``: the number of training rows it will be
    fitted on, for the checks that depend on it (e.g. ``n_neighbors <= N``); None skips those. Raises
    InputError with the estimator's message (naming the parameter, its value and what it expects).
    """
    try:
        est = make_estimator(path, params)
        check = getattr(est, "_check_params", None)
        if callable(check):
            if "n_samples" in inspect.signature(check).parameters:
                check(n_samples=n_samples)
            else:
                check()
        elif callable(getattr(est, "_validate_params", None)) and hasattr(
            est, "_parameter_constraints"
        ):
            est._validate_params()
    except InputError:
        raise
    except (
        ValueError,
        TypeError,
    ) as exc:  # scikit-learn's InvalidParameterError, or a constructor's own check
        raise InputError(str(exc).splitlines()[0] if str(exc) else repr(exc)) from None


def grid_points(grid):
    """The points of a CV grid ({param: [values]}), in scikit-learn's ParameterGrid order; [{}] for no grid."""
    if not grid:
        return [{}]
    from sklearn.model_selection import ParameterGrid

    return list(ParameterGrid(grid))


def default_grid(path):
    """The hyper-parameter grid a model module publishes as ``DEFAULT_GRID`` for the class at ``path``.

    A module may publish one grid (``{param: [values]}``) or one per class (``{ClassName: {param: [values]}}``).
    Returns ``{}`` if the module publishes none.
    """
    cls = load_estimator_class(path)
    grid = getattr(importlib.import_module(cls.__module__), "DEFAULT_GRID", None) or {}
    if cls.__name__ in grid and isinstance(grid[cls.__name__], dict):
        grid = grid[cls.__name__]
    if not all(isinstance(v, (list, tuple)) for v in grid.values()):
        raise InputError(
            f"{cls.__module__}.DEFAULT_GRID for {cls.__name__} is not a {{param: [values]}} dict"
        )
    return {k: list(v) for k, v in grid.items()}


def supports_std(estimator):
    try:
        return "return_std" in inspect.signature(estimator.predict).parameters
    except (TypeError, ValueError):
        return False
