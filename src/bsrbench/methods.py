"""The registry of a study's methods: who each method is, read from the configuration, and what the code derives.

A method is one entry of the configuration's ``methods`` (its estimator class, label and table block) and its place
in ``run`` (the order of the tables' columns). What is not configured is derived: the modules its jobs run (the
import graph of its estimator's module and of the job logic, :mod:`bsrbench.sources`) and the paper's name of it
(the ``paper_name`` of its estimator class: the column of the paper's Tables I-II that it reproduces). Adding a
method is one estimator class and one configuration entry (docs/architecture.md).
"""

import ast
from dataclasses import dataclass
from pathlib import Path

from . import sources
from .errors import InputError

#: The module of the jobs' bodies: its imports, direct or not, are the job logic of every method.
JOB_ENTRY = "bsrbench.jobs"
#: The package of the model classes.
MODELS = "bsrbench.models"


@dataclass(frozen=True)
class Method:
    """One configured method: ``name`` (its key), ``label`` (column label), ``group`` (table block, "paper" or
    "today"), ``order`` (its place in ``run``, 0 first) and ``estimator`` ("package.module:ClassName")."""

    name: str
    label: str
    group: str
    order: int
    estimator: str

    @property
    def module(self):
        """The module of the estimator class."""
        return self.estimator.split(":")[0]

    @property
    def paper_name(self):
        """The paper's name of the method (a column of Tables I-II: "RVM", ..., "PM"): the ``paper_name`` of its
        estimator class, read from the source; None for a method the paper does not compare."""
        return paper_name(self.estimator)

    def modules(self):
        """The package's modules whose code the method's jobs run: its estimator's module, the job logic
        (:data:`JOB_ENTRY`) and everything they import (an estimator module outside the package counts alone)."""
        graph = sources.import_graph()
        own = [self.module] if self.module in graph else []
        return sources.closure([*own, JOB_ENTRY], graph)

    def source_files(self):
        """The source files of :meth:`modules` (and of the estimator's module when it is outside the package):
        an edit of one reruns the method's jobs. Found without importing anything
        (:func:`bsrbench.estimators.locate_estimator`); InputError naming the method when its module is missing."""
        from .estimators import locate_estimator

        try:
            origin = locate_estimator(self.estimator)
        except InputError as exc:
            raise InputError(f"config key 'methods.{self.name}.estimator': {exc}") from None
        files = sources.module_files()
        out = [str(files[m]) for m in self.modules()]
        return out if self.module in files else [str(origin), *out]


def registry(methods, run):
    """{name: :class:`Method`} of the methods ``run`` (names, in the tables' order), from the configuration's
    ``methods`` mapping (entries with ``estimator`` and optionally ``label`` and ``group``)."""
    return {
        name: Method(
            name=name,
            label=methods[name].get("label", name),
            group=methods[name].get("group") or "paper",
            order=k,
            estimator=methods[name]["estimator"],
        )
        for k, name in enumerate(run)
    }


def _class_constants(path, class_name):
    """{name: value} of the literal constants assigned in the body of class ``class_name`` of the file ``path``."""
    for node in ast.parse(Path(path).read_text()).body:
        if isinstance(node, ast.ClassDef) and node.name == class_name:
            out = {}
            for item in node.body:
                if isinstance(item, ast.Assign) and isinstance(item.value, ast.Constant):
                    out.update(
                        {t.id: item.value.value for t in item.targets if isinstance(t, ast.Name)}
                    )
            return out
    return {}


def paper_name(estimator):
    """The ``paper_name`` of the estimator class at ``estimator`` ("module:Class"), read from its source without
    importing it; None when it has none or the class is not found."""
    from .estimators import locate_estimator

    try:
        origin = locate_estimator(estimator)
    except InputError:
        return None
    return _class_constants(origin, estimator.partition(":")[2]).get("paper_name")


def model_classes():
    """{class name: module name} of the estimator classes the model modules export (their ``__all__``)."""
    out = {}
    for name, path in sources.module_files().items():
        if not name.startswith(MODELS + ".") or name.rpartition(".")[2].startswith("_"):
            continue
        for node in ast.parse(path.read_text()).body:
            if (
                isinstance(node, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)
                and isinstance(node.value, (ast.List, ast.Tuple))
            ):
                out.update({ast.literal_eval(e): name for e in node.value.elts})
    return out


def job_preload():
    """The package's modules a job server imports before forking jobs: the job logic and every model module that
    exports an estimator."""
    models = sorted(set(model_classes().values()))
    return sources.closure([JOB_ENTRY, *models])


#: The configuration files of a source checkout.
CONFIG = Path(__file__).resolve().parents[2] / "config"


def configured(study=None, folder=None):
    """The registry of the methods run by ``config/config.yaml``, or by ``config/<study>.yaml`` read over it (as
    ``--configfile`` does): the methods of a published study, for tables made without its workflow."""
    folder = Path(folder or CONFIG)
    own = Path(folder) / f"{study}.yaml"
    files = [f"{Path(folder).name}/{own.name}"] if study and own.is_file() else []
    return study_registry(study_config(files, folder), " + ".join(files) or "config/config.yaml")


def repository_file(name, folder=None):
    """The file ``name`` of a study's ``configfiles`` (relative to the checkout, the parent of ``folder``), refused
    unless it is a relative path inside the checkout: the list comes from a published table's provenance."""
    folder = Path(folder or CONFIG)
    root = Path(folder).resolve().parent
    where = f"configfiles entry {name!r}"
    if not isinstance(name, str) or not name or Path(name).is_absolute() or "\\" in name:
        raise InputError(
            f"{where}: expected a path relative to the checkout, such as config/ablation.yaml"
        )
    path = (root / name).resolve()
    if not path.is_relative_to(root):
        raise InputError(
            f"{where}: leads outside the checkout ({root}); expected a file of the checkout, such as "
            "config/ablation.yaml"
        )
    if path.suffix not in (".yaml", ".yml"):
        raise InputError(
            f"{where}: expected a YAML configuration file (.yaml), such as config/ablation.yaml"
        )
    return path


def study_config(files, folder=None):
    """The configuration of a study: ``config/config.yaml`` with ``files`` (paths relative to the checkout, inside
    it) read over it in order (top-level keys replaced, ``methods`` entries merged key by key), as ``--configfile``
    reads them. Each file is read as untrusted YAML (:func:`bsrbench.safeload.read_yaml`). DataFileError naming a
    file that is missing, not a YAML mapping, or whose ``methods``, a method entry or ``run`` has another shape."""
    folder = Path(folder or CONFIG)
    from .errors import DataFileError
    from .safeload import read_yaml

    out = {}
    for path in [Path(folder) / "config.yaml", *(repository_file(f, folder) for f in files)]:
        if not path.is_file():
            raise DataFileError(path, "no such file; expected a configuration file of the study")
        data = read_yaml(path)
        data = {} if data is None else data
        if not isinstance(data, dict):
            raise DataFileError(
                path,
                f"holds a {type(data).__name__}; expected a YAML mapping of configuration keys",
            )
        for k, v in data.items():
            if k == "methods":
                if not isinstance(v, (dict, type(None))):
                    raise DataFileError(
                        path,
                        f"key 'methods' is a {type(v).__name__}; expected a mapping "
                        "{method: {estimator, params, ...}}",
                    )
                methods = dict(out.get("methods") or {})
                for name, entry in (v or {}).items():
                    if not isinstance(entry, (dict, type(None))):
                        raise DataFileError(
                            path,
                            f"key 'methods.{name}' is a {type(entry).__name__}; expected a "
                            "mapping {estimator, params, ...}",
                        )
                    methods[name] = {**methods.get(name, {}), **(entry or {})}
                out["methods"] = methods
            elif k == "run" and not (isinstance(v, list) and all(isinstance(m, str) for m in v)):
                raise DataFileError(path, f"key 'run' is {v!r}; expected a list of method names")
            else:
                out[k] = v
    return out


def study_datasets(files, folder=None):
    """The data sets of a study: config/datasets.yaml's ``datasets`` with the ``datasets`` of ``files``
    (:func:`study_config`'s files) merged over them entry by entry, as Snakemake merges the configuration files."""
    from .safeload import read_yaml

    folder = Path(folder or CONFIG)
    out = {}
    sources = [read_yaml(folder / "datasets.yaml") or {}]
    sources += [read_yaml(repository_file(f, folder)) or {} for f in files]
    for data in sources:
        for source, acts in (
            (data.get("datasets") if isinstance(data, dict) else None) or {}
        ).items():
            for activity, entry in (acts or {}).items():
                if isinstance(entry, dict):
                    merged = out.setdefault(source, {}).setdefault(activity, {})
                    merged.update(entry)
    return out


def study_registry(config, path="the configuration"):
    """The method registry (:func:`registry`) of a :func:`study_config`; InputError naming ``path`` and a run method
    without an entry or with an estimator that is not of the form ``package.module:ClassName``."""
    from .estimators import parse_estimator_path

    methods, run = config.get("methods") or {}, config.get("run") or []
    missing = [m for m in run if m not in methods or "estimator" not in (methods[m] or {})]
    if missing:
        raise InputError(f"{path}: run names {missing} without a methods entry with an estimator")
    for m in run:
        try:
            parse_estimator_path(methods[m]["estimator"])
        except InputError as exc:
            raise InputError(f"{path}: key 'methods.{m}.estimator': {exc}") from None
    return registry(methods, run)
