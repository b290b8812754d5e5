"""Estimators named by dotted path (``"bsrbench.models.bsr:BayesianSR"``): the one resolver, build, parameters,
grids.

A path is data (a configuration value, a published row's column), so it is resolved in steps that run no code until
the named thing is known to be an estimator class: :func:`parse_estimator_path` checks its form,
:func:`locate_estimator` finds the module's source file through the import system's finders without importing
anything (refused: a module of Python's standard library, which holds no regressor and some of whose modules act
when imported; a ``__main__`` or other dunder module, a package's program; and a module found in a directory
that no installation put on the path, such as the working directory, where a planted ``.py`` file would run),
and :func:`load_estimator_class` imports that one module, takes the name from the
module's own namespace (no module ``__getattr__``) and accepts it only if it is a class with ``fit``, ``predict``
and ``get_params`` (a scikit-learn-style regressor). Only then do :func:`make_estimator` and the helpers below
instantiate it. Classes are imported only when used, so a missing model module fails only the jobs that need it.
"""

import importlib
import importlib.machinery
import inspect
import os
import re
import site
import sys
import sysconfig
from pathlib import Path

from .errors import InputError

#: ``package.module:ClassName``: dotted identifiers, one colon, a class name.
_PATH = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*")
#: What a class must have to be used as an estimator.
PROTOCOL = ("fit", "predict", "get_params")
_EXPECTED = "'package.module:ClassName' naming a scikit-learn-style regressor class (fit, predict, get_params)"


def parse_estimator_path(path):
    """``(module, class_name)`` of ``"package.module:ClassName"``; InputError naming the value otherwise."""
    if not isinstance(path, str) or not _PATH.fullmatch(path):
        shown = repr(path) if len(repr(path)) <= 80 else repr(path)[:77] + "..."
        raise InputError(f"estimator {shown} (of type {type(path).__name__}); expected {_EXPECTED}")
    module, _, name = path.partition(":")
    return module, name


def _find_spec(name, search):
    """``(spec, finder)`` of module ``name`` from the import system's finders (``sys.meta_path``, as ``import``
    asks them), with ``search`` the parent package's ``__path__`` (None: top level); ``(None, None)`` if none has
    it. Finders read the file system; no module code runs. A module imported already answers from
    ``sys.modules`` (finder None)."""
    loaded = sys.modules.get(name)
    if loaded is not None:
        return getattr(loaded, "__spec__", None), None
    for finder in sys.meta_path:
        find = getattr(finder, "find_spec", None)
        if find is None:
            continue
        spec = find(name, search)
        if spec is not None:
            return spec, finder
    return None, None


def _resolved(path):
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError):
        return None


def installed_roots():
    """The directories a top-level estimator module may come from: the interpreter's site-packages (and the user's
    when this interpreter reads it: not in a virtual environment), the directories their ``.pth`` files add
    (editable installs such as bsrbench's own ``src/``), the absolute entries of ``PYTHONPATH`` (the user's explicit
    choice; a relative one was resolved against the directory Python started in, which may not be this one) and
    the directory bsrbench itself was imported from. Not the working directory or a script's directory, which
    Python puts on the path without anyone installing them."""
    sites = [*site.getsitepackages(), site.getusersitepackages() if site.ENABLE_USER_SITE else None]
    sites += [sysconfig.get_path(k) for k in ("purelib", "platlib")]
    roots = {Path(__file__).resolve().parents[1]}
    for d in filter(None, sites):
        base = _resolved(d)
        if base is None or not base.is_dir():
            continue
        roots.add(base)
        for pth in sorted(base.glob("*.pth")):
            try:
                lines = pth.read_text(errors="replace").splitlines()
            except OSError:
                continue
            for line in lines:
                line = line.strip()
                if line and not line.startswith(("#", "import ", "import\t")):
                    entry = _resolved(base / line)
                    if entry is not None:
                        roots.add(entry)
    for entry in os.environ.get("PYTHONPATH", "").split(os.pathsep):
        if os.path.isabs(entry) and _resolved(entry) is not None:
            roots.add(_resolved(entry))
    return roots


def _top_level_dirs(spec):
    """The directories holding the top-level module or package of ``spec`` (several for a namespace package)."""
    if spec.submodule_search_locations is not None:
        return [Path(p).parent for p in spec.submodule_search_locations]
    return [Path(spec.origin).parent] if spec.has_location and spec.origin else []


def _check_installed(path, name, spec):
    """InputError unless the top-level module ``name`` lies in :func:`installed_roots` (a path entry's module;
    a meta-path finder other than the path finder was put there by an installed package and is trusted)."""
    dirs = _top_level_dirs(spec)
    roots = installed_roots()
    outside = [d for d in dirs if _resolved(d) not in roots]
    if dirs and not outside:
        return
    where = str(outside[0]) if outside else "nowhere on disk"
    raise InputError(
        f"estimator {path!r}: module {name!r} is found in {where}, which no installation put on the path (the "
        f"working directory or a script's directory); expected {_EXPECTED} of an installed package, of a "
        f"directory on PYTHONPATH (an absolute path) or of bsrbench.models"
    )


def locate_estimator(path):
    """The source file of the module of the estimator at ``path``, found without importing anything (not even its
    parent packages). InputError naming the path when it is malformed, of the standard library, or not found."""
    module, _ = parse_estimator_path(path)
    parts = module.split(".")
    if parts[0] in sys.stdlib_module_names or parts[0] in sys.builtin_module_names:
        raise InputError(
            f"estimator {path!r}: module {parts[0]!r} is of Python's standard library, which has no estimator; "
            f"expected {_EXPECTED} of an installed package or of bsrbench.models"
        )
    dunder = next((p for p in parts if p.startswith("__") and p.endswith("__")), None)
    if dunder is not None:
        raise InputError(
            f"estimator {path!r}: module name part {dunder!r} is a dunder module (a package's __main__ is its "
            f"program and runs when imported); expected {_EXPECTED}"
        )
    search, spec = None, None
    for k in range(len(parts)):
        name = ".".join(parts[: k + 1])
        spec, finder = _find_spec(name, search)
        if k == 0 and spec is not None and finder in (None, importlib.machinery.PathFinder):
            _check_installed(path, name, spec)
        if spec is None:
            where = (
                "" if k == 0 else f" (package {'.'.join(parts[:k])!r} has no module {parts[k]!r})"
            )
            raise InputError(
                f"estimator {path!r}: cannot find module {module!r}{where}; expected {_EXPECTED}"
            )
        search = spec.submodule_search_locations
        if search is None and k < len(parts) - 1:
            raise InputError(
                f"estimator {path!r}: {name!r} is a module, not a package, so it has no module {parts[k + 1]!r}; "
                f"expected {_EXPECTED}"
            )
    if not spec.has_location or not spec.origin:
        raise InputError(
            f"estimator {path!r}: module {module!r} has no source file; expected {_EXPECTED}"
        )
    return Path(spec.origin)


def load_estimator_class(path):
    """The estimator class at ``"package.module:ClassName"``, after :func:`locate_estimator`: its module imported,
    the name taken from the module's namespace, and accepted only if it is a class with :data:`PROTOCOL`.
    InputError naming the path and what it found otherwise; nothing is called."""
    module_name, class_name = parse_estimator_path(path)
    locate_estimator(path)
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise InputError(
            f"estimator {path!r}: cannot import module {module_name!r} ({exc})"
        ) from None
    if class_name not in vars(module):
        raise InputError(
            f"estimator {path!r}: module {module_name!r} has no attribute {class_name!r}; expected {_EXPECTED}"
        )
    cls = vars(module)[class_name]
    if not inspect.isclass(cls):
        raise InputError(
            f"estimator {path!r}: {class_name!r} is a {type(cls).__name__}, not a class; expected {_EXPECTED}"
        )
    missing = [a for a in PROTOCOL if not callable(inspect.getattr_static(cls, a, None))]
    if missing:
        raise InputError(
            f"estimator {path!r}: class {class_name!r} has no {', '.join(missing)}; expected {_EXPECTED}"
        )
    return cls


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
