"""Command-line configuration: ``snakemake --config key=value`` values read as YAML, like configuration files.

Snakemake reads a ``--config`` value with ``int``, ``float``, a boolean parser and then YAML's *BaseLoader*,
which keeps every scalar inside a list or mapping a string: ``--config n_train='[100]'`` becomes ``['100']``
and fails validation ("'100' is not of type 'integer'"). :func:`retype_cli_config` reads those list and
mapping values again with ``yaml.safe_load`` and merges them into the configuration, so that every key can be
overridden from the command line with the YAML flow syntax of the configuration files::

    snakemake --cores 2 --config n_train='[30,60]' protocols='[random,contiguous]'
    snakemake --cores 2 --config study_activities='{hsc: [golf], mocap: []}' report='{subjective_methods: [SR]}'

Mappings are merged into the configuration's, lists and scalars replace it (as with ``--configfile``).

Numbers in exponent notation: YAML 1.1, which PyYAML and so Snakemake's loader follow, reads ``1e-3``, ``1E3``
and ``1.0e3`` (an exponent without a decimal point or without a sign) as STRINGS, while YAML 1.2 and JSON read
them as numbers. :func:`retype_yaml_numbers` reads such strings as floats (``1e-3`` -> 0.001) wherever the
configuration schema allows a number: keys of type number (or integer, when the value is whole: ``1e2`` -> 100),
and the values the schema leaves open (``methods.<M>.params``, ``cv_params``, the values of a ``grid``). Keys the
schema types as strings (names, labels, paths) are never touched; a quoted ``'1e-3'`` in such a place cannot be
told from an unquoted one after loading, so a string parameter spelled like a number is read as the number.
The Snakefile calls both functions right after the configuration is loaded, before any validation, so
``--configfile`` files, ``configfile:`` files and ``--config`` values are read alike.
"""

import re
from pathlib import Path

import yaml
from snakemake.utils import update_config

from .errors import InputError


def retype_cli_config(config, config_args, parsed):
    """Merge the ``--config`` list and mapping values of ``config_args`` into ``config``, read with YAML's
    safe loader (in place; returns ``config``).

    ``config_args``: the raw ``key=value`` strings (``workflow.config_settings.config_args``); ``parsed``:
    Snakemake's reading of them (``workflow.config_settings.config``). Scalars keep Snakemake's reading.
    Raises InputError naming the key when a value is not valid YAML.
    """
    if not config_args or isinstance(config_args, (str, bytes)):
        return config
    for arg in config_args:
        key, sep, text = str(arg).partition("=")
        if not sep or not isinstance(parsed.get(key), (list, dict)):
            continue
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise InputError(
                f"--config {key}: {text!r} is not valid YAML ({str(exc).splitlines()[0]}); expected e.g. "
                f"{key}='[30, 100]' or {key}='{{name: value}}'"
            ) from None
        update_config(config, {key: value})
    return config


#: A float of YAML 1.2's core schema that YAML 1.1 reads as a string: exponent without a decimal point or sign.
_EXPONENT_FLOAT = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)[eE][-+]?[0-9]+")


def load_schema(*paths):
    """The configuration schema: the union of the JSON schemas at ``paths`` (their top-level ``properties`` and
    ``$defs``; a later file's entries replace an earlier one's, so the data-set schema's precise ``datasets``
    replaces the study schema's placeholder)."""
    out = {"type": "object", "properties": {}, "$defs": {}}
    for path in paths:
        schema = yaml.safe_load(Path(path).read_text())
        out["properties"].update(schema.get("properties") or {})
        out["$defs"].update(schema.get("$defs") or {})
    return out


def _resolve(node, root):
    while (
        isinstance(node, dict)
        and isinstance(node.get("$ref"), str)
        and node["$ref"].startswith("#/")
    ):
        target = root
        for part in node["$ref"][2:].split("/"):
            target = target.get(part, {})
        node = target
    return node if isinstance(node, dict) else {}


def _branches(node, root):
    """The subschemas a value may match: the node itself and its oneOf/anyOf alternatives (resolved)."""
    node = _resolve(node, root)
    alts = [_resolve(a, root) for key in ("oneOf", "anyOf") for a in node.get(key) or []]
    return [node, *alts]


def _types(node, root):
    """The JSON types a node allows (empty set: no constraint)."""
    out = set()
    for b in _branches(node, root):
        t = b.get("type")
        out |= {t} if isinstance(t, str) else set(t or [])
    return out


def _child(node, root, container, key=None):
    """The subschema of an item (``container`` "array") or of the property ``key`` (``container`` "object");
    None if the schema forbids it; {} (no constraint) if it says nothing."""
    for b in _branches(node, root):
        t = b.get("type")
        kinds = {t} if isinstance(t, str) else set(t or [])
        if kinds and container not in kinds:
            continue
        if container == "array":
            if "items" in b:
                return b["items"]
            continue
        if key in (b.get("properties") or {}):
            return b["properties"][key]
        extra = b.get("additionalProperties", None)
        if isinstance(extra, dict):
            return extra
        if extra is False and (b.get("properties") or kinds):
            return None
    return {}


def retype_yaml_numbers(config, schema):
    """Read as numbers the strings YAML 1.1 left from YAML 1.2 floats (``1e-3``), where ``schema`` allows a
    number (in place; returns the dotted keys changed).

    ``schema``: the configuration's JSON schema (:func:`load_schema`). A string matching YAML 1.2's float syntax
    with an exponent becomes a float where the schema allows ``number`` or sets no type (free-form values such as
    estimator parameters), an int where it allows only ``integer`` and the value is whole; elsewhere (a string key)
    it is left alone for the schema to judge. A whole float where only an integer is allowed becomes an int
    (Snakemake reads ``--config n_seeds=1e1`` as 10.0). ``"true"``/``"false"`` (any case) become booleans where the
    schema allows a boolean (Snakemake reads ``--config job_server=false`` as the string).
    """
    changed = []

    def walk(value, node, where):
        if node is None:
            return value
        if isinstance(value, dict):
            for k in list(value):
                value[k] = walk(
                    value[k], _child(node, schema, "object", k), f"{where}.{k}" if where else str(k)
                )
            return value
        if isinstance(value, list):
            item = _child(node, schema, "array")
            for i, v in enumerate(value):
                value[i] = walk(v, item, f"{where}[{i}]")
            return value
        if (
            isinstance(value, float)
            and value.is_integer()
            and _types(node, schema) & {"integer", "number"} == {"integer"}
        ):  # `--config n_seeds=1e1`: Snakemake reads 10.0
            changed.append(where)
            return int(value)
        if (
            isinstance(value, str)
            and value.strip().lower() in ("true", "false")
            and "boolean" in _types(node, schema)
        ):
            # `--config job_server=false`: Snakemake parses only Python's True/False, not YAML's true/false
            changed.append(where)
            return value.strip().lower() == "true"
        if isinstance(value, str) and _EXPONENT_FLOAT.fullmatch(value.strip()):
            types = _types(node, schema)
            number = float(value)
            if not types or "number" in types:
                changed.append(where)
                return number
            if "integer" in types and number.is_integer():
                changed.append(where)
                return int(number)
        return value

    walk(config, schema, "")
    return changed


def _key_path(parts):
    """'methods.PM.params' / 'protocols[0]' from a jsonschema path."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def _short(value, limit=80):
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def schema_error_message(error, what="configuration"):
    """One line for a jsonschema ``ValidationError`` of the configuration: the key path, the offending value and what
    was expected (the allowed keys of a misspelled key, the allowed values of an enum, the key's schema
    description for a forbidden value), instead of Snakemake's dump of the whole schema and configuration.

    ``what`` names the configuration checked (e.g. ``'config/datasets.yaml'``)."""
    parts = list(error.absolute_path)
    schema = error.schema if isinstance(error.schema, dict) else {}
    validator, expected_value = error.validator, error.validator_value
    if validator == "additionalProperties" and isinstance(error.instance, dict):
        known = set(schema.get("properties") or {})
        patterns = [re.compile(p) for p in schema.get("patternProperties") or {}]
        extra = [
            k
            for k in error.instance
            if k not in known and not any(p.search(str(k)) for p in patterns)
        ]
        if extra and known:
            key = _key_path([*parts, extra[0]])
            return (
                f"{what}: unknown key {key!r} (value {_short(error.instance[extra[0]])}): {error.message}; "
                f"expected one of the keys {sorted(known)}"
            )
    where = f"key {_key_path(parts)!r}" if parts else "top level"
    if "propertyNames" in error.schema_path:
        where = f"a name under {where}"
    head = f"{what}: {where}, value {_short(error.instance)}: "
    if validator == "enum":
        return head + f"not one of the allowed values; expected one of {list(expected_value)}"
    if validator == "not" and schema.get("description"):
        return head + f"not allowed here; {schema['description']}"
    desc = f" ({schema['description']})" if schema.get("description") else ""
    return head + f"{error.message}; expected {validator}: {_short(expected_value)}{desc}"


def config_validation_error(exc, what="configuration"):
    """The InputError (:func:`schema_error_message`) for Snakemake's ``WorkflowError`` of ``snakemake.utils.validate``
    (raised while handling jsonschema's ``ValidationError``, its ``__context__``); ``exc`` itself if it has none."""
    from jsonschema.exceptions import ValidationError

    cause = exc.__cause__ or exc.__context__
    if isinstance(cause, ValidationError):
        return InputError(schema_error_message(cause, what))
    return exc
