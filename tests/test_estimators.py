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
    with pytest.raises(InputError, match="cannot find module 'bsrbench.models.nosuch'"):
        load_estimator_class("bsrbench.models.nosuch:X")
    with pytest.raises(InputError, match="no attribute 'Nope'"):
        load_estimator_class(f"{REF}:Nope")
    with pytest.raises(InputError, match=r"no parameter\(s\) \['alpah'\]"):
        make_estimator(f"{REF}:RidgeRegressor", {"alpah": 1.0})
    assert default_grid(f"{REF}:RidgeRegressor") == {"alpha": [0.1, 1.0, 10.0, 100.0, 1000.0]}


# ------------------------------------------------------------- the resolver runs no code it did not mean to
def _package(tmp_path, monkeypatch, name, init="", modules=None):
    """A package ``name`` in a directory on PYTHONPATH (and ``sys.path``) whose ``__init__`` is ``init`` and with
    the modules ``{name: source}``: a researcher's own package."""
    pkg = tmp_path / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text(init)
    for mod, src in (modules or {}).items():
        (pkg / f"{mod}.py").write_text(src)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    return pkg


ESTIMATOR_SOURCE = (
    "open({marker!r}, 'w').close()\n"
    "class Planted:\n"
    "    def fit(self, X, Y):\n        return self\n"
    "    def predict(self, X):\n        return X\n"
    "    def get_params(self, deep=True):\n        return {{}}\n"
)


def test_a_module_planted_in_the_working_directory_is_refused_and_never_runs(tmp_path, monkeypatch):
    """Python puts the working directory (or a script's) on the path without anyone installing it: a ``.py`` file
    there that a configuration names is refused before it is imported, naming the directory."""
    marker = tmp_path / "marker"
    (tmp_path / "planted_est.py").write_text(ESTIMATOR_SOURCE.format(marker=str(marker)))
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv("PYTHONPATH", raising=False)
    with pytest.raises(InputError) as err:
        load_estimator_class("planted_est:Planted")
    assert str(err.value).startswith(
        f"estimator 'planted_est:Planted': module 'planted_est' is found in {tmp_path}, which no installation "
        "put on the path"
    ), err.value
    assert not marker.exists()
    # the same file in a directory the user puts on PYTHONPATH is their own code: accepted
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    assert load_estimator_class("planted_est:Planted").__name__ == "Planted"
    assert marker.exists()


def test_a_relative_pythonpath_entry_does_not_vouch_for_the_working_directory(
    tmp_path, monkeypatch
):
    """Python resolved a relative PYTHONPATH entry against the directory it started in, which the check cannot
    know: ``PYTHONPATH=.`` does not make the working directory an installation."""
    marker = tmp_path / "marker"
    (tmp_path / "planted_rel.py").write_text(ESTIMATOR_SOURCE.format(marker=str(marker)))
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    for entry in (".", "./", "sub/.."):
        monkeypatch.setenv("PYTHONPATH", entry)
        with pytest.raises(InputError) as err:
            load_estimator_class("planted_rel:Planted")
        assert "which no installation put on the path" in str(err.value), err.value
        assert "a directory on PYTHONPATH (an absolute path)" in str(err.value)
    assert not marker.exists()


@pytest.mark.parametrize("user_site", [False, True])
def test_the_user_site_counts_only_where_this_interpreter_reads_it(
    tmp_path, monkeypatch, user_site
):
    """A ``.pth`` file of the user's site-packages adds its directories only where Python reads the user site (not
    in a virtual environment): where it does not, those directories are no installation."""
    from bsrbench import estimators

    marker = tmp_path / "marker"
    user = tmp_path / "user-site"
    code = tmp_path / "code"
    user.mkdir()
    code.mkdir()
    (user / "mine.pth").write_text(f"{code}\n")
    (code / "planted_user.py").write_text(ESTIMATOR_SOURCE.format(marker=str(marker)))
    monkeypatch.setattr(estimators.site, "ENABLE_USER_SITE", user_site)
    monkeypatch.setattr(estimators.site, "getusersitepackages", lambda: str(user))
    monkeypatch.syspath_prepend(str(code))
    monkeypatch.delenv("PYTHONPATH", raising=False)
    assert (code.resolve() in estimators.installed_roots()) is user_site
    if user_site:
        assert load_estimator_class("planted_user:Planted").__name__ == "Planted"
        assert marker.exists()
    else:
        with pytest.raises(InputError, match=f"is found in {code}, which no installation"):
            load_estimator_class("planted_user:Planted")
        assert not marker.exists()


@pytest.mark.parametrize(
    "path", ["own_prog.__main__:Planted", "own_prog.__init__:Planted", "PIL.__main__:X"]
)
def test_a_packages_program_is_refused_and_never_runs(tmp_path, monkeypatch, path):
    """A package's ``__main__`` is its program (``python -m``), which many run unguarded when imported."""
    marker = tmp_path / "marker"
    _package(
        tmp_path,
        monkeypatch,
        "own_prog",
        modules={"__main__": ESTIMATOR_SOURCE.format(marker=str(marker))},
    )
    with pytest.raises(InputError) as err:
        load_estimator_class(path)
    dunder = path.split(":")[0].split(".")[-1]
    assert f"module name part {dunder!r} is a dunder module" in str(err.value), err.value
    assert not marker.exists()


@pytest.mark.parametrize(
    "path, words",
    [
        ("os:system", "module 'os' is of Python's standard library, which has no estimator"),
        ("subprocess:Popen", "module 'subprocess' is of Python's standard library"),
        ("sklearn.linear_model:ridge_regression", "'ridge_regression' is a function, not a class"),
        ("bsrbench.models.reference:np", "'np' is a module, not a class"),
        ("numpy:ndarray", "class 'ndarray' has no fit, predict, get_params"),
        ("sklearn.preprocessing:StandardScaler", "class 'StandardScaler' has no predict"),
        ("bsrbench.models.reference:", "expected 'package.module:ClassName'"),
        ("a b:C", "expected 'package.module:ClassName'"),
    ],
)
def test_the_resolver_accepts_only_estimator_classes(path, words):
    with pytest.raises(InputError) as err:
        make_estimator(path, {})
    assert str(err.value).startswith("estimator ") and words in str(err.value), err.value


def test_a_missing_module_is_refused_without_importing_its_parent_package(tmp_path, monkeypatch):
    marker = tmp_path / "marker"
    _package(tmp_path, monkeypatch, "sidefx_pkg", f"open({str(marker)!r}, 'w').close()\n")
    with pytest.raises(InputError, match="package 'sidefx_pkg' has no module 'nosuch'"):
        load_estimator_class("sidefx_pkg.nosuch:X")
    assert not marker.exists()
    # a module of the package that holds no such class is imported (the configuration names it), then refused
    with pytest.raises(InputError, match="module 'sidefx_pkg' has no attribute 'X'"):
        load_estimator_class("sidefx_pkg:X")
    assert marker.exists()


def test_a_module_getattr_is_never_asked_for_the_class(tmp_path, monkeypatch):
    """The class is taken from the module's namespace: a module ``__getattr__`` (PEP 562) would run code."""
    marker = tmp_path / "marker"
    _package(
        tmp_path,
        monkeypatch,
        "lazy_pkg",
        f"def __getattr__(name):\n    open({str(marker)!r}, 'w').close()\n    raise AttributeError(name)\n",
    )
    with pytest.raises(InputError, match="module 'lazy_pkg' has no attribute 'Model'"):
        load_estimator_class("lazy_pkg:Model")
    assert not marker.exists()


def test_an_estimator_class_of_another_package_is_accepted(tmp_path, monkeypatch):
    """A researcher's own regressor in their own package: found, imported, checked and built."""
    _package(
        tmp_path,
        monkeypatch,
        "own_models",
        modules={
            "mean": "from sklearn.base import BaseEstimator, RegressorMixin\n"
            "class MeanPose(RegressorMixin, BaseEstimator):\n"
            "    def __init__(self, shrink=0.0):\n        self.shrink = shrink\n"
            "    def fit(self, X, Y):\n        self.mean_ = Y.mean(0)\n        return self\n"
            "    def predict(self, X):\n        import numpy as np\n"
            "        return np.tile(self.mean_ * (1 - self.shrink), (len(X), 1))\n"
        },
    )
    est = make_estimator("own_models.mean:MeanPose", {"shrink": 0.5})
    assert type(est).__name__ == "MeanPose" and est.shrink == 0.5
