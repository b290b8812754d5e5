"""The registry of a study's methods: who each method is, read from the configuration, and what the code derives.

A method is one entry of the configuration's ``methods`` (its estimator class, label and table block) and its place
in ``run`` (the order of the tables' columns). What is not configured is derived: the modules its jobs run (the
import graph of its estimator's module and of the job logic, :mod:`bsrbench.sources`) and the paper's name of it
(the ``paper_name`` of its estimator class: the column of the paper's Tables I-II that it reproduces). Adding a
method is one estimator class and one configuration entry (docs/architecture.md).
"""

import ast
import importlib.util
from dataclasses import dataclass
from pathlib import Path

from . import sources

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
        an edit of one reruns the method's jobs. Raises ValueError naming the method when its module is missing."""
        spec = importlib.util.find_spec(self.module)
        if spec is None or spec.origin is None:
            raise ValueError(
                f"config key 'methods.{self.name}.estimator': module {self.module!r} not found"
            )
        files = sources.module_files()
        out = [str(files[m]) for m in self.modules()]
        return out if self.module in files else [str(Path(spec.origin)), *out]


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
    module, _, cls = estimator.partition(":")
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        return None
    return _class_constants(spec.origin, cls).get("paper_name")


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


def configured(study=None, folder=CONFIG):
    """The registry of the methods run by ``config/config.yaml``, or by ``config/<study>.yaml`` read over it (as
    ``--configfile`` does): the methods of a published study, for tables made without its workflow."""
    import yaml

    methods, run = {}, []
    for path in [Path(folder) / "config.yaml", Path(folder) / f"{study}.yaml"][: 2 if study else 1]:
        if not path.is_file():
            continue
        data = yaml.safe_load(path.read_text()) or {}
        for name, entry in (data.get("methods") or {}).items():
            methods[name] = {**methods.get(name, {}), **(entry or {})}
        run = data.get("run", run)
    return registry(methods, run)
