"""The package's import graph: no cycle, and the layers of docs/architecture.md import only downwards."""

import re
from pathlib import Path

import pytest

from bsrbench import sources

DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"


def read_layers(text):
    """{layer: (rank, [module prefix, ...])} from the table between ``<!-- layers -->`` and ``<!-- /layers -->``."""
    block = re.search(r"<!-- layers -->(.*?)<!-- /layers -->", text, re.S)
    assert block, f"{DOC}: no <!-- layers --> ... <!-- /layers --> block"
    out = {}
    for line in block.group(1).splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[1].isdigit():
            out[cells[0]] = (int(cells[1]), cells[2].replace("`", "").split())
    return out


def layer_of(module, layers):
    """The layer of a module of the package: the layer listing the longest prefix of its name (after
    ``bsrbench.``); None for a module no layer lists."""
    name = module.removeprefix("bsrbench.")
    best = None
    for layer, (_rank, prefixes) in layers.items():
        for p in prefixes:
            if (name == p or name.startswith(p + ".")) and (best is None or len(p) > best[1]):
                best = (layer, len(p))
    return best and best[0]


def violations(graph, layers):
    """The imports ``(module, its layer, imported module, its layer)`` that go up or sideways between layers."""
    out = []
    for module, deps in sorted(graph.items()):
        if module == "bsrbench":
            continue
        a = layer_of(module, layers)
        for dep in deps:
            b = layer_of(dep, layers)
            if a != b and layers[b][0] >= layers[a][0]:
                out.append((module, a, dep, b))
    return out


def test_the_package_has_no_import_cycle():
    """Every import counts, also inside functions; a cycle is printed as the path that closes it."""
    found = sources.cycles()
    assert not found, "import cycles:\n" + "\n".join(" -> ".join(c) for c in found)


def test_a_cycle_is_found_and_printed():
    graph = {"p.a": ("p.b",), "p.b": ("p.c",), "p.c": ("p.a",), "p.d": ("p.a",)}
    assert sources.cycles(graph) == [["p.a", "p.b", "p.c", "p.a"]]
    assert sources.cycles({"p.a": ("p.b",), "p.b": ()}) == []


def test_the_graph_counts_function_local_and_relative_imports(tmp_path):
    pkg = tmp_path / "toy"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    from .sub import b\n    import toy.c\n")
    (pkg / "sub" / "b.py").write_text("from ..c import x\nfrom . import d\n")
    (pkg / "c.py").write_text("x = 1\n")
    (pkg / "sub" / "d.py").write_text("import numpy\n")
    graph = sources.import_graph("toy", tmp_path)
    assert graph["toy.a"] == ("toy.c", "toy.sub.b")
    assert graph["toy.sub.b"] == ("toy.c", "toy.sub.d")
    assert graph["toy.sub.d"] == ()
    assert sources.closure(["toy.a"], graph) == ["toy.a", "toy.c", "toy.sub.b", "toy.sub.d"]


def test_every_module_has_one_layer_of_the_doc():
    layers = read_layers(DOC.read_text())
    assert {"data", "models", "results", "jobs", "reporting", "workflow"} <= set(layers)
    unplaced = [m for m in sources.import_graph() if m != "bsrbench" and not layer_of(m, layers)]
    assert not unplaced, f"modules in no layer of {DOC}: {unplaced}"


def test_layers_import_only_downwards():
    """The import rules of docs/architecture.md hold: a module imports its own layer and lower-ranked ones."""
    layers = read_layers(DOC.read_text())
    bad = violations(sources.import_graph(), layers)
    assert not bad, "imports against the layers of docs/architecture.md:\n" + "\n".join(
        f"{m} ({a}) imports {d} ({b})" for m, a, d, b in bad
    )


@pytest.mark.parametrize(
    "module, dep",
    [
        ("bsrbench.metrics", "bsrbench.runs"),  # data imports jobs
        ("bsrbench.results", "bsrbench.reporting.tables"),  # results imports reporting
        ("bsrbench.config", "bsrbench.reporting.tables"),  # workflow and reporting are apart
        ("bsrbench.reporting.tables", "bsrbench.config"),
    ],
)
def test_the_layer_check_fails_on_an_upward_import(module, dep):
    layers = read_layers(DOC.read_text())
    graph = dict(sources.import_graph())
    graph[module] = (*graph[module], dep)
    assert (module, layer_of(module, layers), dep, layer_of(dep, layers)) in violations(
        graph, layers
    )
