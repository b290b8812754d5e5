"""Reading data that anyone may have written (a configuration, a provenance, a published row's JSON column):
bounded in size, nesting and alias expansion, and never a way to run code.

YAML is read with PyYAML's safe loader, which builds only plain values, and a document is refused when it would
expand past :data:`MAX_NODES` nodes (an alias counts once per use, so a "billion laughs" of a few kB is refused
before anything walks it) or nest deeper than :data:`MAX_DEPTH`. A configuration that sets ``__use_yte__`` is
refused: Snakemake reads ``--configfile`` files with YTE, which evaluates the Python expressions of such a file.
JSON is read with the standard parser, its nesting bounded the same way. Every refusal is one
:class:`~bsrbench.errors.InputError` naming the file or value and what was expected.
"""

import json
from pathlib import Path

from .errors import DataFileError, InputError

#: Largest YAML or JSON text read (bytes): the project's largest configuration is a few kB.
MAX_BYTES = 1 << 20
#: Most nodes a document may expand to (mappings, lists and scalars, an alias counted at each use).
MAX_NODES = 100_000
#: Deepest nesting of mappings and lists.
MAX_DEPTH = 32
#: The key by which a YAML file asks Snakemake's YTE to evaluate its Python expressions.
YTE_KEY = "__use_yte__"


def check_plain(data, what, *, max_nodes=MAX_NODES, max_depth=MAX_DEPTH):
    """``data`` if it expands to at most ``max_nodes`` nodes nested at most ``max_depth`` deep and holds no cycle;
    InputError naming ``what`` otherwise. Linear in the distinct nodes: a shared (aliased) node is measured once."""
    sizes, open_ = {}, set()

    def size(node, depth):
        if not isinstance(node, (dict, list, tuple)):
            return 1
        if depth > max_depth:
            raise InputError(
                f"{what}: nested more than {max_depth} levels deep; expected a plain configuration"
            )
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in open_:
            raise InputError(f"{what}: holds a value that contains itself (a recursive YAML alias)")
        open_.add(key)
        total = 1
        for child in node.values() if isinstance(node, dict) else node:
            total += (1 if isinstance(node, dict) else 0) + size(child, depth + 1)
            if total > max_nodes:
                raise InputError(
                    f"{what}: expands to more than {max_nodes} values (YAML anchors and aliases counted at each "
                    "use); expected a configuration of ordinary size"
                )
        open_.discard(key)
        sizes[key] = total
        return total

    size(data, 0)
    return data


def _text(path):
    path = Path(path)
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except OSError as exc:
        raise DataFileError(path, f"cannot be read ({exc.strerror})") from None
    if len(raw) > MAX_BYTES:
        raise DataFileError(
            path, f"larger than {MAX_BYTES} bytes; expected a configuration of ordinary size"
        )
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DataFileError(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def yaml_text(text, what):
    """The plain value of the YAML document ``text`` (safe loader, :func:`check_plain`); InputError naming
    ``what`` (and the line) when it is not valid YAML, too large or too deep, or sets :data:`YTE_KEY`."""
    import yaml

    if len(text) > MAX_BYTES:
        raise InputError(
            f"{what}: larger than {MAX_BYTES} characters; expected a configuration of ordinary size"
        )
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark is not None else ""
        raise InputError(f"{what}: not valid YAML{line} ({str(exc).splitlines()[0]})") from None
    except RecursionError:
        raise InputError(
            f"{what}: nested too deeply for YAML's parser; expected a plain configuration"
        ) from None
    check_plain(data, what)
    if isinstance(data, dict) and YTE_KEY in data:
        raise InputError(
            f"{what}: key {YTE_KEY!r} asks Snakemake to evaluate the file's Python expressions (YTE templates); "
            "expected a plain YAML configuration"
        )
    return data


def read_yaml(path):
    """:func:`yaml_text` of the file ``path``; DataFileError naming it."""
    text = _text(path)
    try:
        return yaml_text(text, str(path))
    except DataFileError:
        raise
    except InputError as exc:
        raise DataFileError(path, str(exc).removeprefix(f"{path}: ")) from None


def json_text(text, what, *, max_depth=MAX_DEPTH):
    """The value of the JSON ``text``, nested at most ``max_depth`` deep; InputError naming ``what`` when it is not
    JSON, too large or too deep."""
    if not isinstance(text, (str, bytes)):
        raise InputError(f"{what}: {text!r} of type {type(text).__name__}; expected JSON text")
    if len(text) > MAX_BYTES:
        raise InputError(
            f"{what}: larger than {MAX_BYTES} characters; expected JSON of ordinary size"
        )
    try:
        data = json.loads(text)
    except RecursionError:
        raise InputError(
            f"{what}: JSON nested too deeply; expected at most {max_depth} levels"
        ) from None
    except (ValueError, UnicodeDecodeError) as exc:
        shown = text if len(text) <= 40 else text[:37] + "..."
        raise InputError(f"{what}: {shown!r} is not JSON ({exc})") from None
    return check_plain(data, what, max_depth=max_depth, max_nodes=MAX_BYTES)


def read_json_file(path, *, max_depth=MAX_DEPTH):
    """:func:`json_text` of the file ``path``; DataFileError naming it."""
    text = _text(path)
    try:
        return json_text(text, str(path), max_depth=max_depth)
    except InputError as exc:
        raise DataFileError(path, str(exc).removeprefix(f"{path}: ")) from None
