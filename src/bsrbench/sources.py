"""The package's own import graph, read from its source files with :mod:`ast` (nothing is imported).

Every ``import`` and ``from ... import`` statement counts, at module level or inside a function, with relative
imports resolved. The study derives from it the source files whose edit reruns a method's jobs
(:meth:`bsrbench.config.Study.estimator_sources`) and the modules a job server preloads
(:data:`bsrbench.jobs.PRELOAD`, with the other packages' modules they import, :func:`external_imports`);
tests/test_architecture.py checks with it that the package has no import cycle
and that its layers import only downwards (docs/architecture.md).
"""

import ast
import functools
from pathlib import Path

#: The folder holding the ``bsrbench`` package.
ROOT = Path(__file__).resolve().parent.parent


def module_files(package="bsrbench", root=ROOT):
    """{dotted module name: source file} of every module of ``package`` under ``root`` (packages by their
    ``__init__.py``)."""
    out = {}
    for path in sorted((Path(root) / package).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imported(path, name, modules):
    """The modules of ``modules`` that the source file ``path`` of module ``name`` imports."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            # ``from pkg import mod`` imports the module pkg.mod when there is one
            targets = [
                f"{target}.{a.name}" if f"{target}.{a.name}" in modules else target
                for a in node.names
            ]
        else:
            continue
        for target in targets:
            # ``import a.b.c`` imports a, a.b and a.b.c; count the deepest module of the package
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def _external(path, package):
    """The absolute imports of the source file ``path`` outside ``package``: the dotted names of ``import a.b`` and
    ``from a.b import c`` (``a.b.c`` too, which is the module imported when ``c`` is a submodule)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names if a.name != "*"]
        else:
            continue
        found.update(n for n in names if n.partition(".")[0] != package)
    return found


def external_imports(names, package="bsrbench", root=ROOT):
    """The modules of other packages that the package's modules ``names`` import, at module level or inside a
    function (sorted dotted names), keeping those that are installed: a name whose top package is missing (an
    optional import) and a ``from a import c`` whose ``c`` is not a module of ``a`` are left out. Finding a
    dotted module imports its parent packages, so call this where importing them is wanted (a job server)."""
    import importlib.util

    files = module_files(package, root)
    wanted = set().union(*(_external(files[name], package) for name in names))
    out = []
    for name in sorted(wanted):
        try:
            if importlib.util.find_spec(name) is not None:
                out.append(name)
        except (ImportError, ValueError):  # a parent that is no package, or missing
            pass
    return out


@functools.cache
def import_graph(package="bsrbench", root=ROOT):
    """{module: sorted tuple of the package's modules it imports} of every module of ``package``."""
    files = module_files(package, root)
    return {name: tuple(sorted(_imported(path, name, files))) for name, path in files.items()}


def closure(names, graph=None):
    """The modules of ``names`` and every module of the package they import, directly or not (sorted)."""
    graph = import_graph() if graph is None else graph
    seen, todo = set(), list(names)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        if name not in graph:
            raise ValueError(
                f"{name!r} is not a module of the package; expected one of {sorted(graph)}"
            )
        seen.add(name)
        todo.extend(graph[name])
    return sorted(seen)


def cycles(graph=None):
    """The import cycles of ``graph``: one list ``[a, b, ..., a]`` per strongly connected group of modules that
    import each other (Tarjan's algorithm), the group's first module first; ``[]`` when there is none."""
    graph = import_graph() if graph is None else graph
    index, low, stack, on_stack, groups = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    out = []
    for group in sorted(groups):
        # the shortest path from the group's first module back to it, for the message
        start, members = group[0], set(group)
        paths, done = {start: [start]}, None
        while done is None:
            for head, path in list(paths.items()):
                for w in graph[head]:
                    if w == start:
                        done = path + [start]
                    elif w in members and w not in paths:
                        paths[w] = path + [w]
        out.append(done)
    return out
