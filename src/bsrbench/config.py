"""The study's configuration: read, retyped, validated and cross-checked once, as one frozen :class:`Study`.

:func:`load_study` takes the merged configuration (``configfile:``, ``--configfile`` and ``--config``), and

1. reads the ``--config`` list and mapping values as YAML, like the configuration files (Snakemake keeps the
   scalars inside them strings: ``--config n_train='[100]'`` would be ``['100']``), and reads as numbers the
   strings YAML 1.1 leaves from YAML 1.2 floats (``1e-3``) wherever the schema allows a number;
2. validates it against the JSON schemas of ``workflow/schemas`` (filling in their defaults);
3. makes the cross-checks a schema cannot: data-set entries, methods and their parameter values, the studied
   activities, the cells skipped for too few test frames, the report's methods;
4. returns a :class:`Study`: the design, cells, seeds, skipped cells, methods, data sets and targets.

Every error names the key, its value and what was expected. Nothing here needs a running Snakemake workflow.
"""

import math
import re
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import yaml

from .datasets import motion_map
from .errors import InputError
from .methods import registry
from .paper import PAPER_ACTIVITIES
from .results import KEY_COLUMNS, design_changes, study_of  # noqa: F401 (names of the aggregate table's checks)
from .safeload import check_plain, read_yaml, yaml_text

#: The JSON schemas of the configuration (a source checkout; the Snakefile passes its own folder).
SCHEMAS = Path(__file__).resolve().parents[2] / "workflow" / "schemas"
MOTION_FORMATS = ("bvh", "amc")


# ------------------------------------------------------------------------------------------- command line


def option_args(argv, names):
    """The values a snakemake argument list ``argv`` gives the options ``names`` (each takes the following
    arguments up to the next option, as Snakemake's parser does, or ``--name=VALUE``)."""
    return [v for _, values in option_groups(argv, names) for v in values]


def option_groups(argv, names):
    """``(option, values)`` per occurrence in ``argv`` of an option of ``names``, in order: the values it takes
    (see :func:`option_args`; empty for an option followed by another option or by nothing)."""
    groups = []
    short = [n for n in names if len(n) == 2 and n[0] == "-" and n[1] != "-"]
    for arg in argv:
        arg = str(arg)
        name, eq, value = arg.partition("=")
        attached = next((n for n in short if arg.startswith(n) and len(arg) > 2), None)
        if name in names:
            groups.append((name, [value] if eq else []))
            taking = not eq
        elif attached:  # -Cfoo: argparse reads the value attached to a short option
            groups.append((attached, [arg[2:]]))
            taking = False
        elif arg.startswith("-"):
            taking = False
        elif groups and taking:
            groups[-1][1].append(arg)
    return groups


def configfile_args(argv):
    """The files ``argv`` names with ``--configfile``/``--configfiles``."""
    return option_args(argv, ("--configfile", "--configfiles"))


def config_arg_problem(entry):
    """What is wrong with one ``--config`` entry, one line (None if it is ``KEY=VALUE``). Snakemake answers
    anything else with a traceback before the Snakefile runs, so ``bin/study`` asks this first."""
    key, eq, _ = entry.partition("=")
    if not eq or not _CONFIG_KEY.match(key):
        return (
            f"--config {entry!r}: expected KEY=VALUE (KEY: at least two characters, letters, digits, _ or -, from "
            "a letter or _, ending in a letter, digit or _), for example --config study=mine "
            "'study_activities={hsc: [golf], mocap: []}' (config/README.md lists the keys)"
        )
    return None


#: What Snakemake's command line takes as a ``--config`` key (snakemake/cli.py, ``parse_config``).
_CONFIG_KEY = re.compile(r"[a-zA-Z_][\w-]*\w$")


def argv_problems(argv):
    """The problems of the ``--configfile`` files and ``--config`` entries of a snakemake argument list."""
    bad = [configfile_problem(f) for f in configfile_args(argv)]
    for _, values in option_groups(argv, ("--config", "-C")):
        # Snakemake takes --config with no entry (nargs="*") and runs the whole study with the defaults
        bad += [config_arg_problem(e) for e in values] or ["--config: no KEY=VALUE given"]
    return [m for m in bad if m]


def configfile_problem(path):
    """What is wrong with a ``--configfile`` file, one line (None if it exists, is readable and parses as a
    YAML mapping of ordinary size, :func:`bsrbench.safeload.read_yaml`). Snakemake reads these files before the
    Snakefile runs, answers a missing one with a traceback and evaluates the Python expressions of one that sets
    ``__use_yte__``, so ``bin/study`` asks this first."""
    p = Path(path)
    expected = "expected a YAML file such as config/paper.yaml"
    if not p.exists():
        return f"--configfile {path}: no such file; {expected}"
    if not p.is_file():
        return f"--configfile {path}: not a file; {expected}"
    try:
        data = read_yaml(p)
    except InputError as exc:
        return f"--configfile {exc}" + ("" if "; expected" in str(exc) else f"; {expected}")
    if data is None or data == {}:
        # Snakemake refuses an empty file with a WorkflowError; an empty mapping would override nothing
        return f"--configfile {path}: is empty (no configuration keys); {expected}"
    if not isinstance(data, dict):
        return (
            f"--configfile {path}: holds a {type(data).__name__}, not a mapping of configuration keys; "
            f"{expected}"
        )
    return None


def or_exit(check, *args, **kwargs):
    """``check(*args, **kwargs)``, or, on an InputError, its message on stderr and exit status 1: the
    Snakefile's configuration checks end in one line, without the traceback Snakemake prints for an
    exception raised while it reads the Snakefile."""
    import sys

    try:
        return check(*args, **kwargs)
    except InputError as exc:
        print(exc, file=sys.stderr)
        sys.exit(1)


def retype_cli_config(config, config_args, parsed):
    """Merge the ``--config`` list and mapping values of ``config_args`` into ``config``, read with YAML's
    safe loader (in place; returns ``config``).

    ``config_args``: the raw ``key=value`` strings (``workflow.config_settings.config_args``); ``parsed``:
    Snakemake's reading of them (``workflow.config_settings.config``). Scalars keep Snakemake's reading, but for
    ``null`` and ``~``, which become None.
    Raises InputError naming the key when a value is not valid YAML.
    """
    from snakemake.utils import update_config

    if not config_args or isinstance(config_args, (str, bytes)):
        return config
    for arg in config_args:
        key, sep, text = str(arg).partition("=")
        if (
            sep
            and text.strip() in ("null", "~", "Null", "NULL")
            and parsed.get(key) == text.strip()
        ):
            config[key] = None  # YAML's null, as in a file (Snakemake keeps the string)
            continue
        if not sep or not isinstance(parsed.get(key), (list, dict)):
            continue
        try:
            value = yaml_text(text, f"--config {key}={text!r}")
        except InputError as exc:
            raise InputError(
                f"{exc}; expected e.g. {key}='[30, 100]' or {key}='{{name: value}}'"
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
    return _clip(repr(value), limit)


def _clip(text, limit=160):
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
                f"{what}: unknown key {key!r} (value {_short(error.instance[extra[0]])}): {_clip(error.message)}; "
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
    return head + f"{_clip(error.message)}; expected {validator}: {_short(expected_value)}{desc}"


def config_validation_error(exc, what="configuration"):
    """The InputError (:func:`schema_error_message`) for Snakemake's ``WorkflowError`` of ``snakemake.utils.validate``
    (raised while handling jsonschema's ``ValidationError``, its ``__context__``); ``exc`` itself if it has none."""
    from jsonschema.exceptions import ValidationError

    cause = exc.__cause__ or exc.__context__
    if isinstance(cause, ValidationError):
        return InputError(schema_error_message(cause, what))
    return exc


def validate_config(config, schema_path, what):
    """Validate ``config`` against the schema at ``schema_path`` and fill in its defaults (in place).

    Raises InputError with :func:`schema_error_message`'s one line naming the key, its value and what was
    expected (instead of Snakemake's dump of the whole schema and configuration)."""
    from snakemake.exceptions import WorkflowError
    from snakemake.utils import validate

    try:
        validate(config, str(schema_path))
    except WorkflowError as exc:
        raise config_validation_error(exc, what) from None


# ---------------------------------------------------------------------------------------------- methods
def check_method_names(methods):
    """Refuse, before the schema's "'estimator' is a required property", an entry of ``methods`` without an
    estimator: a method the configuration files do not define (a misspelt name given params or a label by
    ``--config`` or an override file). Raises InputError naming the key, the known methods and the closest one."""
    import difflib

    if not isinstance(methods, dict):
        return
    known = sorted(m for m, s in methods.items() if isinstance(s, dict) and "estimator" in s)
    for name, setting in methods.items():
        if isinstance(setting, dict) and "estimator" not in setting:
            close = difflib.get_close_matches(str(name), known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise InputError(
                f"config key 'methods.{name}': unknown method {name!r}{hint}; known methods: {known}; a new "
                f"method needs an 'estimator' ('package.module:ClassName')"
            )


def method_cv(config, name):
    """The CV of method ``name``: its own ``methods.<M>.cv`` ({mode, folds}) over the study's ``cv``."""
    own = (config["methods"][name] or {}).get("cv") or {}
    return {**config["cv"], **own}


def check_method_settings(methods, run, *, n_train=None, cv=None):
    """Check, before any job runs, that every method in ``run`` can be built and fitted as configured.

    ``methods``: the configuration's ``methods`` mapping ({name: {estimator, params, cv_params, grid, ...}});
    ``run``: the names of the methods to run. For each method run, its estimator class must import and every
    key of ``params``, ``cv_params`` and ``grid`` (the module's ``DEFAULT_GRID`` for ``grid: default``) must be
    a constructor parameter of it. Then the VALUES are checked by the estimator's own validation
    (:func:`bsrbench.estimators.check_estimator_params`): ``params`` alone; with ``n_train`` (the training-set
    sizes) and ``cv`` (``{"mode", "folds"}``), every setting a job will fit: ``params`` updated with each grid
    point on the smallest N, and, when CV runs, ``params`` + ``cv_params`` + each grid point on the smallest
    training fold (KFold: N - ceil(N / folds) rows); ``cv.folds`` must not exceed the smallest N. A method's
    own ``cv`` (:func:`method_cv`) replaces ``cv`` for it, and needs a grid unless its mode is none.
    Raises InputError naming the configuration key, the method, the value and what was expected.
    """
    from .estimators import default_grid, estimator_parameters, load_estimator_class

    for name in run:
        if name not in methods:
            raise InputError(
                f"config key 'run': unknown method {name!r}; defined under 'methods': {sorted(methods)}"
            )
        setting = methods[name] or {}
        path = setting.get("estimator")
        try:
            accepted = estimator_parameters(path)
        except InputError as exc:
            raise InputError(f"config key 'methods.{name}.estimator': {exc}") from None
        grid = setting.get("grid", "default")
        where_grid = f"methods.{name}.grid"
        if grid == "default":
            grid = default_grid(path)
            where_grid += f" (default: {load_estimator_class(path).__module__}.DEFAULT_GRID)"
        parts = [
            (f"methods.{name}.params", setting.get("params") or {}),
            (f"methods.{name}.cv_params", setting.get("cv_params") or {}),
            (where_grid, grid or {}),
        ]
        for key, values in parts:
            if not isinstance(values, dict):
                raise InputError(
                    f"config key '{key}': expected a mapping {{parameter: value}}; got {values!r}"
                )
            if accepted is None:
                continue
            for p, v in values.items():
                if p not in accepted:
                    raise InputError(
                        f"config key '{key}': {p}: {v!r} is not a parameter of {path}; "
                        f"expected one of {accepted}"
                    )
        for p, v in (grid or {}).items():
            if not isinstance(v, (list, tuple)) or not v:
                raise InputError(
                    f"config key '{where_grid}': {p}: {v!r}; expected a non-empty list of values"
                )
        chains = setting.get("chains", 1)
        if (
            accepted is not None
            and isinstance(chains, int)
            and chains > 1
            and "random_state" not in accepted
        ):
            # chain c differs from chain 0 by its seed alone (runs.chain_seed)
            raise InputError(
                f"config key 'methods.{name}.chains': {chains}, but {path} takes no random_state, so its chains "
                "would be identical; expected chains: 1, or an estimator that samples (an MCMC sampler such as "
                "bsrbench.models.bsr:BayesianSR)"
            )
        own_cv = setting.get("cv") or {}
        if own_cv and own_cv.get("mode") != "none" and not grid:
            raise InputError(
                f"config key 'methods.{name}.cv': {own_cv!r} asks for CV, but the method has no grid "
                f"(methods.{name}.grid is {setting.get('grid', 'default')!r}); expected a grid "
                f"{{parameter: [values]}} or 'default' with a DEFAULT_GRID, or no cv"
            )
        method_cv = None if cv is None else {**cv, **own_cv}
        _check_method_values(
            name, setting, path, grid or {}, where_grid, n_train=n_train, cv=method_cv
        )


def _check_method_values(name, setting, path, grid, where_grid, *, n_train, cv):
    """The value checks of :func:`check_method_settings` for one method (keys already known to be valid)."""
    from .estimators import check_estimator_params, grid_points

    params = dict(setting.get("params") or {})
    cv_params = dict(setting.get("cv_params") or {})
    cv_runs = bool(cv) and cv.get("mode", "none") != "none" and bool(grid)
    points = grid_points(grid) if cv_runs else [{}]
    sizes = sorted({int(n) for n in n_train}) if n_train else []

    def fail(key, exc, what):
        raise InputError(f"config key '{key}' (method {name}, {path}): {what}: {exc}") from None

    def shown(d):
        return "{" + ", ".join(f"{k}: {v!r}" for k, v in d.items()) + "}"

    try:
        check_estimator_params(path, params)
    except InputError as exc:
        fail(f"methods.{name}.params", exc, f"params {shown(params)}")
    if cv_params and (cv is None or cv_runs):  # cv_params act in CV fits only
        try:
            check_estimator_params(path, {**params, **cv_params})
        except InputError as exc:
            fail(
                f"methods.{name}.cv_params",
                exc,
                f"cv_params {shown(cv_params)} over params {shown(params)}",
            )
    for point in points:
        if point:
            try:
                check_estimator_params(path, {**params, **point})
            except InputError as exc:
                fail(where_grid, exc, f"grid point {shown(point)} over params {shown(params)}")
    if not sizes:
        return
    n_min = sizes[0]
    for point in points:
        try:
            check_estimator_params(path, {**params, **point}, n_samples=n_min)
        except InputError as exc:
            key = where_grid if point else f"methods.{name}.params"
            what = (
                f"grid point {shown(point)} over params {shown(params)}"
                if point
                else f"params {shown(params)}"
            )
            fail(key, exc, f"{what}, fitted on the smallest n_train N = {n_min}")
    if not cv_runs:
        return
    folds = int(cv.get("folds", 5))
    where_cv = f"methods.{name}.cv" if "folds" in (setting.get("cv") or {}) else "cv"
    if folds > n_min:
        raise InputError(
            f"config key '{where_cv}.folds': {folds} folds of the smallest n_train N = {n_min} (method {name} is "
            f"tuned by CV, mode {cv.get('mode')!r}) would leave empty folds; expected folds <= {n_min}"
        )
    n_fold = n_min - math.ceil(n_min / folds)
    for point in points:
        try:
            check_estimator_params(path, {**params, **cv_params, **point}, n_samples=n_fold)
        except InputError as exc:
            key = f"methods.{name}.cv_params" if cv_params and not point else where_grid
            fail(
                key,
                exc,
                f"the CV fits of grid point {shown(point)} over params {shown({**params, **cv_params})} "
                f"on training folds of {n_fold} frames (N = {n_min}, {where_cv}.folds = {folds})",
            )


# --------------------------------------------------------------------------------------------- data sets
def dataset_defaults(schema_dir=SCHEMAS):
    """Defaults of a data-set entry, read from the data-set schema (the one place they are written)."""
    schema = yaml.safe_load((Path(schema_dir) / "datasets.schema.yaml").read_text())
    props = schema["$defs"]["dataset"]["properties"]
    return {k: v["default"] for k, v in props.items() if "default" in v}


def cmu_split(trial_id):
    """'09_12' -> ('09', '12')."""
    s, t = trial_id.split("_")
    return f"{int(s):02d}", f"{int(t):02d}"


def resolve_datasets(config, defaults):
    """{(source, activity): entry} with the schema's defaults filled in and the input files resolved (CMU
    trials to paths in the download folder, the ASF skeleton of an AMC trial)."""
    folder = config["download"]["dir"].rstrip("/")
    out = {}
    for source, acts in config["datasets"].items():
        for activity, entry in acts.items():
            d = {**defaults, **entry}
            d["source"], d["activity"] = source, activity
            if d["cmu_trials"]:
                d["files"] = [
                    "{0}/{1}/{1}_{2}.amc".format(folder, *cmu_split(t)) for t in d["cmu_trials"]
                ]
                if d["asf"] is None:
                    s = cmu_split(d["cmu_trials"][0])[0]
                    d["asf"] = f"{folder}/{s}/{s}.asf"
            elif d["format"] == "amc" and d["asf"] is None and d["files"]:
                f = Path(d["files"][0])
                d["asf"] = str(f.with_name(f.stem.split("_")[0] + ".asf"))
            out[(source, activity)] = MappingProxyType(d)
    return out


def check_datasets(datasets, codebook_files):
    """Checks of the data-set entries the schema cannot express; errors name the key and what was expected."""
    for (s, a), d in datasets.items():
        where = f"config datasets.{s}.{a}"
        if not d["files"]:
            raise InputError(
                f"{where}: give `files` (a list of paths) or `cmu_trials` (CMU ids 'SS_TT')"
            )
        if d["cmu_trials"] and d["format"] != "amc":
            raise InputError(
                f"{where}: cmu_trials are downloaded as .amc; expected format: amc, got {d['format']!r}"
            )
        if d["format"] == "mat" and len(d["files"]) != 1:
            raise InputError(f"{where}: format mat takes exactly one file; got {len(d['files'])}")
        for f in d["files"]:
            suffix = Path(f).suffix.lower().lstrip(".")
            if suffix != d["format"]:
                raise InputError(
                    f"{where}: file {f!r} does not end in .{d['format']} (format: {d['format']})"
                )
        if d["fewer_frames"] == "use_all" and d["frame_selection"] != "first":
            raise InputError(
                f"{where}: fewer_frames: use_all needs frame_selection: first; got {d['frame_selection']!r}"
            )
        if d["first_frame"] != 0 and d["format"] in MOTION_FORMATS:
            raise InputError(
                f"{where}: first_frame applies to format mat; got {d['first_frame']} for format "
                f"{d['format']} (use skip_frames for motion capture trials)"
            )
        if d["joint_map"] is not None and len(d["joint_map"]) == 0:
            raise InputError(f"{where}: joint_map is an empty list; expected joint names or null")
    motion = {s for (s, _), d in datasets.items() if d["format"] in MOTION_FORMATS}
    mat = {s for (s, _), d in datasets.items() if d["format"] not in MOTION_FORMATS}
    if motion & mat:
        raise InputError(
            f"config datasets: source(s) {sorted(motion & mat)} mix format mat with bvh/amc entries; "
            f"a source holds one kind (put them under different source names)"
        )
    enabled_motion = any(d["enabled"] and d["format"] in MOTION_FORMATS for d in datasets.values())
    if enabled_motion and not codebook_files:
        raise InputError(
            "config features.codebook.files is empty; the bvh/amc data sets need codebook trials"
        )


def data_frames(entry):
    """Frames a data set will have: n_frames, or (motion capture with fewer_frames: use_all) what its trials
    give, counted from the BVH headers or the AMC frame lines; n_frames when that cannot be counted before the
    files exist."""
    from .datasets import count_mat_rows, count_motion_frames

    n = int(entry["n_frames"])
    if entry["fewer_frames"] != "use_all":
        return n
    if entry["format"] in MOTION_FORMATS:
        have = count_motion_frames(entry["files"], entry["skip_frames"], entry["frame_step"])
    else:
        rows = count_mat_rows(entry["files"][0], entry["x_key"]) if entry["files"] else None
        have = None if rows is None else len(range(entry["first_frame"], rows, entry["frame_step"]))
    return n if have is None else min(n, have)


def check_data_files(entry):
    """Check, before any job runs, that the input files of a data set are here and pass their checksums
    (``checksums`` of the entry); files a download rule fetches (``cmu_trials``) may be absent. Raises
    InputError naming the data-set key, the file and what was expected."""
    from .datasets import verify_checksum
    from .errors import DataFileError

    where = f"config datasets.{entry['source']}.{entry['activity']} (config/datasets.yaml)"
    files = list(entry["files"])
    if entry["format"] == "amc" and entry.get("asf"):
        files.append(entry["asf"])
    for f in files:
        if not Path(f).is_file():
            if entry["cmu_trials"]:
                continue  # downloaded by rule download_cmu_amc / download_cmu_asf
            raise InputError(
                f"{where}: data file {f} does not exist; expected the file its `files` names (correct the "
                f"path, or remove {entry['activity']!r} from study_activities.{entry['source']})"
            )
        checksums = entry["checksums"] if f in entry["files"] else None
        try:
            verify_checksum(f, checksums)
        except DataFileError as exc:
            raise InputError(f"{where}: {exc}") from None


def check_mat_rows(entry):
    """Check, before any job runs, that the .mat file of a data set of format mat has the rows its frames ask for:
    ``first_frame + (n_frames - 1) * frame_step`` must be a row of the file (unless ``fewer_frames: use_all`` with
    ``frame_selection: first``, which keeps what there is, and at least ``first_frame`` is). The rows are read from
    the file's header (:func:`bsrbench.datasets.count_mat_rows`, scipy's ``whosmat``: no data is loaded); a file
    that is missing or whose header cannot be read is left to the features job. Raises InputError naming the
    data-set key, its frame settings, the file and its rows."""
    from .datasets import count_mat_rows

    if entry["format"] in MOTION_FORMATS or not entry["files"]:
        return
    path, x_key = entry["files"][0], entry["x_key"]
    rows = count_mat_rows(path, x_key) if Path(path).is_file() else None
    if rows is None:
        return
    where = f"config datasets.{entry['source']}.{entry['activity']} (config/datasets.yaml)"
    first, step, n = int(entry["first_frame"]), int(entry["frame_step"]), int(entry["n_frames"])
    usable = len(range(first, rows, step))
    if usable == 0:
        raise InputError(
            f"{where}: first_frame {first} is not a row of {path}, which has {rows} rows ({x_key}); expected "
            f"first_frame below {rows}"
        )
    keeps_fewer = entry["fewer_frames"] == "use_all" and entry["frame_selection"] == "first"
    if usable < n and not keeps_fewer:
        raise InputError(
            f"{where}: first_frame {first}, frame_step {step} and n_frames {n} need row "
            f"{first + (n - 1) * step}, but {path} has {rows} rows ({x_key}), {usable} of them from first_frame "
            f"every frame_step; expected first_frame + (n_frames - 1) x frame_step below {rows} (lower "
            "n_frames, first_frame or frame_step, or set fewer_frames: use_all with frame_selection: first)"
        )


def check_codebook_files(codebook):
    """Check that the codebook trials (``features.codebook``), which the motion-capture features are encoded
    over, are here and pass their checksums. Raises InputError naming the key, the file and what was expected."""
    from .datasets import verify_checksum
    from .errors import DataFileError

    where = "config features.codebook.files (config/datasets.yaml)"
    for f in codebook["files"]:
        if not Path(f).is_file():
            raise InputError(
                f"{where}: codebook trial {f} does not exist; expected the BVH/AMC trials the shape-context "
                f"codebook of the motion-capture features is built from"
            )
        try:
            verify_checksum(f, codebook.get("checksums"))
        except DataFileError as exc:
            raise InputError(f"{where}: {exc}") from None


def features_path(source, activity):
    return f"results/features/{source}/{activity}.npz"


# ------------------------------------------------------------------------------------------------ study
def skipped_cells(frames, pairs, protocols, n_train, min_test, gap):
    """{(protocol, source, activity, n_train): why the cell is not run}: the cells whose split would leave
    fewer than ``min_test`` test frames. ``frames``: {(source, activity): frames of the data set}."""
    from .splits import max_n_train

    out = {}
    for s, a in pairs:
        for protocol in protocols:
            limit = max_n_train(frames[(s, a)], protocol=protocol, min_test=min_test, gap=gap)
            for n in n_train:
                if n > limit:
                    after_gap = {
                        "contiguous": f" (fewer after the gap of {gap})",
                        "blocked": f" (fewer after the gaps of {gap} around its runs)",
                    }.get(protocol, "")
                    out[(protocol, s, a, int(n))] = (
                        f"N = {n} skipped: the {frames[(s, a)]} frames leave at most "
                        f"{max(frames[(s, a)] - n, 0)} test frames{after_gap}, fewer than min_test = {min_test}"
                    )
    return out


def _check_study(config, datasets, cwd):
    """The cross-checks of the study keys; returns the skipped cells. Raises InputError naming the key."""
    methods = config["methods"]
    check_method_settings(methods, config["run"], n_train=config["n_train"], cv=config["cv"])
    level = config.get("conformal_level")
    if level is not None:
        from .scores import min_calibration_frames

        # a finite split-conformal radius at this level needs this many calibration frames, and one to fit
        need = min_calibration_frames(level) + 1
        if min(config["n_train"]) < need:
            raise InputError(
                f"config key 'conformal_level': {level!r} needs at least {need} training frames (a finite "
                f"split-conformal radius needs ceil(level / (1 - level)) = {need - 1} calibration frames), but "
                f"n_train has {min(config['n_train'])}; lower conformal_level (at most "
                f"{(min(config['n_train']) - 1) / min(config['n_train']):.4g}) or set it to null"
            )
    report = config["report"]
    m = report.get("trace_method")
    if m is not None and m not in methods:
        raise InputError(
            f"config key 'report.trace_method': unknown method {m!r}; defined under 'methods': {sorted(methods)}"
        )
    for m in report.get("gxy_methods") or []:
        if m not in config["run"]:
            raise InputError(
                f"config key 'report.gxy_methods': method {m!r} is not run; 'run' lists {config['run']}"
            )
    for m in report["subjective_methods"]:
        if m not in methods:
            raise InputError(
                f"config key 'report.subjective_methods': unknown method {m!r}; defined: {sorted(methods)}"
            )
    if not any(config["study_activities"].values()):
        raise InputError(
            "config key 'study_activities': no activity to study (every source has an empty list)"
        )
    frames = {}
    for source, acts in config["study_activities"].items():
        known = [a for s, a in datasets if s == source]
        if not config.get("datasets"):
            raise InputError(
                f"config key 'datasets': empty, so config/datasets.yaml was not loaded from the working directory "
                f"{cwd}; run snakemake in the repository (the folder of the Snakefile) or point "
                f"--directory at it"
            )
        if not known:
            raise InputError(
                f"config key 'study_activities': unknown data source {source!r}; "
                f"config/datasets.yaml defines {sorted(config.get('datasets') or {})}"
            )
        for a in acts:
            if a not in known:
                raise InputError(
                    f"config key 'study_activities.{source}': unknown activity {a!r}; "
                    f"source {source!r} has {sorted(known)}"
                )
            d = datasets[(source, a)]
            if "cross_trial" in config["protocols"] and (
                d["format"] not in MOTION_FORMATS or len(d["files"]) < 2
            ):
                raise InputError(
                    f"config key 'protocols': cross_trial needs a motion-capture data set of several trials; "
                    f"{source}/{a} is format {d['format']!r} with "
                    f"{len(d['files'])} file(s) (study it with random or contiguous)"
                )
            if d["enabled"]:
                check_data_files(d)
            check_mat_rows(d)
            frames[(source, a)] = data_frames(d)
    pairs = [(s, a) for s, acts in config["study_activities"].items() for a in acts]
    if any(datasets[p]["enabled"] and datasets[p]["format"] in MOTION_FORMATS for p in pairs):
        check_codebook_files(config["features"]["codebook"])
    n_train, min_test, gap = config["n_train"], config["min_test"], config["gap"]
    skipped = skipped_cells(frames, pairs, config["protocols"], n_train, min_test, gap)
    for protocol in config["protocols"]:
        for s, a in pairs:
            if all((protocol, s, a, int(n)) in skipped for n in n_train):
                raise InputError(
                    f"config key 'study_activities.{s}': {a} has {frames[(s, a)]} frames, and every "
                    f"n_train {n_train} leaves fewer than min_test={min_test} test frames "
                    f"with protocol {protocol!r}; remove it, add a smaller n_train or lower min_test"
                )
        for n in n_train:
            if pairs and all((protocol, s, a, int(n)) in skipped for s, a in pairs):
                where = ", ".join(f"{s}/{a} ({frames[(s, a)]} frames)" for s, a in pairs)
                raise InputError(
                    f"config key 'n_train': {n} is too large for {where} with protocol {protocol!r}, "
                    f"min_test={min_test}, gap={gap}: no studied activity can use it"
                )
    return skipped


@dataclass(frozen=True)
class DataSets:
    """The checked data sets (config/datasets.yaml) and the feature settings. ``config``: the validated
    configuration; ``entries``: {(source, activity): entry, defaults filled in, input files resolved}."""

    config: MappingProxyType
    entries: MappingProxyType

    def download_dir(self):
        return self.config["download"]["dir"].rstrip("/")

    def codebook_files(self):
        return list(self.config["features"]["codebook"]["files"])

    def download_checksum(self, name):
        """Known SHA-256 of a downloaded file name, or None."""
        return self.config["download"]["checksums"].get(name)

    def dataset(self, source, activity):
        """A data-set entry with the schema's defaults filled in and its input files resolved."""
        try:
            return self.entries[(source, activity)]
        except KeyError:
            configured = [f"{s}/{a}" for s, a in self.entries]
            raise InputError(
                f"config datasets: no data set {source}/{activity}; configured: {configured}"
            ) from None

    def datasets_of(self, source=None, enabled_only=False):
        """[(source, activity)] of the configured data sets."""
        return [
            (s, a)
            for (s, a), d in self.entries.items()
            if (source is None or s == source) and (not enabled_only or d["enabled"])
        ]

    def is_motion(self, source, activity):
        return self.dataset(source, activity)["format"] in MOTION_FORMATS

    def sources(self, motion):
        """The sources of motion-capture (``motion``) or of .mat data sets."""
        return sorted({s for s, a in self.entries if self.is_motion(s, a) == motion})

    def source_regex(self, motion):
        """A wildcard regex matching exactly those sources (or nothing when there are none)."""
        names = self.sources(motion)
        return "|".join(re.escape(n) for n in names) if names else "(?!x)x"

    def feature_targets(self, include_disabled=False):
        """The features file of every enabled data set (every data set if asked)."""
        return [features_path(s, a) for s, a in self.datasets_of(enabled_only=not include_disabled)]

    def preview_targets(self):
        return [
            f"results/features/{s}/{a}.preview.png"
            for s, a in self.datasets_of(enabled_only=True)
            if self.is_motion(s, a)
        ]

    def data_frames(self, source, activity):
        """Frames the data set will have (:func:`data_frames`)."""
        return data_frames(self.dataset(source, activity))

    def motion_params(self, source, activity):
        """Keyword arguments of bsrbench.datasets.prepare_motion for one data set."""
        d = self.dataset(source, activity)
        return {
            "n_frames": d["n_frames"],
            "frame_selection": d["frame_selection"],
            "skeleton_kind": None if d["skeleton"] == "auto" else d["skeleton"],
            "joint_map": d["joint_map"],
            "skip_frames": d["skip_frames"],
            "frame_step": d["frame_step"],
            "fewer_frames": d["fewer_frames"],
            "checksums": d["checksums"],
        }

    def motions(self):
        """{"source/activity": motion} of every data set (:func:`motion_map`; a rule param, so string keys)."""
        return {f"{s}/{a}": m for (s, a), m in motion_map(self.entries).items()}

    def features_meta(self, source, activity):
        d = self.dataset(source, activity)
        return {"source": source, "activity": activity, "paper_activity": d["paper_activity"] or ""}

    def mat_params(self, source, activity):
        """Keyword arguments of bsrbench.datasets.build_mat_features for one data set."""
        d = self.dataset(source, activity)
        keys = (
            "n_frames",
            "frame_selection",
            "drop_y_columns",
            "x_key",
            "y_key",
            "checksums",
            "first_frame",
            "frame_step",
            "fewer_frames",
        )
        return {**{k: d[k] for k in keys}, "meta": self.features_meta(source, activity)}

    def render_params(self):
        """Keyword arguments of bsrbench.render.render_silhouettes."""
        r = self.config["features"]["render"]
        return {
            k: r[k] for k in ("image_size", "view_azimuth_deg", "view_elevation_deg", "body_scale")
        }

    def frame_protocol_text(self, source, activity):
        """How the data set's frames are chosen, as one sentence for the tables."""
        from .datasets import frame_protocol, motion_frame_time

        d = self.dataset(source, activity)
        if d["format"] not in MOTION_FORMATS:
            name = Path(d["files"][0]).name
            first, step = int(d["first_frame"]), int(d["frame_step"])
            if first or step > 1:
                every = f"every {step}th " if step > 1 else ""
                name = f"{every}row of {name} from row {first}"
                n = data_frames(d)
                if d["frame_selection"] == "first":
                    return f"{name}, first {n}"
                return f"{name}, {n} spread evenly"
            if d["frame_selection"] == "first":
                return f"rows of {name}, first {d['n_frames']}"
            return f"{d['n_frames']} rows of {name} spread evenly"
        frame_time = motion_frame_time(d["files"][0])
        text = frame_protocol(
            d["frame_selection"], int(d["frame_step"]), int(d["n_frames"]), frame_time
        )
        n = self.data_frames(source, activity)
        if n < int(d["n_frames"]):
            text += f" (the trials here give {n})"
        return text

    def stick_kind(self, source, activity):
        """How the subjective figure draws an activity's poses: "bvh" (silhouette and stick figures of the
        trial's skeleton), "authors" (input histogram and stick figures of the authors' skeleton) or None
        (angle profiles)."""
        d = self.dataset(source, activity)
        if self.is_motion(source, activity):
            return "bvh"
        if d.get("pose_convention") == "authors":
            return "authors"
        return None

    def data_availability(self):
        """For each of the paper's 8 activities and each source: is the data here, and if not how to get it.

        A list of dicts: table, paper_activity, source, activity (None if the source has no entry for it),
        enabled, available (all input files present), missing (files), target (features file) and command (a
        snakemake command that downloads and builds it, or None when no rule can fetch it).
        """
        rows = []
        for table, pa in PAPER_ACTIVITIES:
            for s in self.config["datasets"]:
                match = [
                    a
                    for a in self.config["datasets"][s]
                    if self.dataset(s, a)["paper_activity"] == pa
                ]
                if not match:
                    rows.append(
                        {
                            "table": table,
                            "paper_activity": pa,
                            "source": s,
                            "activity": None,
                            "enabled": False,
                            "available": False,
                            "missing": [],
                            "target": None,
                            "command": None,
                        }
                    )
                    continue
                for a in match:
                    d = self.dataset(s, a)
                    files = list(d["files"]) + (
                        [d["asf"]] if d["format"] == "amc" and d["asf"] else []
                    )
                    missing = [f for f in files if not Path(f).is_file()]
                    target = features_path(s, a)
                    if not missing:
                        command = f"snakemake --cores 2 {target}"
                    elif d["cmu_trials"]:
                        command = f"snakemake --cores 1 {' '.join(missing)} && snakemake --cores 2 {target}"
                    else:
                        command = None
                    rows.append(
                        {
                            "table": table,
                            "paper_activity": pa,
                            "source": s,
                            "activity": a,
                            "enabled": d["enabled"],
                            "available": not missing,
                            "missing": missing,
                            "target": target,
                            "command": command,
                        }
                    )
        return rows


@dataclass(frozen=True)
class Study:
    """The checked configuration of one study. ``config``: the validated configuration, defaults filled in."""

    config: MappingProxyType
    data: DataSets
    skipped: MappingProxyType  # {(protocol, source, activity, n_train): note}

    # ----------------------------------------------------------------------------------- design
    @property
    def name(self):
        return self.config["study"]

    @property
    def results(self):
        """Root of the fit, CV, aggregate and benchmark files (features and poses are shared)."""
        return f"results/{self.name}"

    @property
    def logs(self):
        return f"logs/{self.name}"

    @property
    def reports(self):
        """Root of the report: tables, figures, the PDF and the HTML report."""
        return f"reports/{self.name}"

    @property
    def protocols(self):
        return list(self.config["protocols"])

    @property
    def pairs(self):
        """[(source, activity)] in configuration order."""
        return [(s, a) for s, acts in self.config["study_activities"].items() for a in acts]

    @property
    def run(self):
        return list(self.config["run"])

    @property
    def n_train(self):
        return [int(n) for n in self.config["n_train"]]

    @property
    def first_seed(self):
        """The first split seed (config key seed_start; 0 in the paper protocol)."""
        return int(self.config.get("seed_start", 0))

    @property
    def seeds(self):
        """Split seeds seed_start .. seed_start + n_seeds - 1."""
        return list(range(self.first_seed, self.first_seed + self.config["n_seeds"]))

    @property
    def seed_blocks(self):
        """The seeds in consecutive blocks of ``seeds_per_job`` (all in one block when null), one fit job each."""
        size = self.config.get("seeds_per_job") or len(self.seeds)
        return [self.seeds[i : i + size] for i in range(0, len(self.seeds), size)]

    def cv_blocks(self):
        """{tuple of seeds: [method, ...]}: the blocks of seeds whose CV one cv job runs, and the methods whose CV
        they are (every configured method with a CV): the seed blocks for a per_job CV, the first seed alone for
        a per_size CV."""
        out = {}
        for name in self.config["methods"]:
            if self.cv_seed(name, self.first_seed) is None:
                continue
            if self.method_cv(name)["mode"] == "per_size":
                blocks = [[self.first_seed]]
            else:
                blocks = self.seed_blocks
            for block in blocks:
                out.setdefault(tuple(block), []).append(name)
        return out

    def runs_cell(self, protocol, source, activity, n_train):
        """False for the cells skipped because too few test frames would remain."""
        return (protocol, source, activity, int(n_train)) not in self.skipped

    @property
    def cells(self):
        """[(protocol, source, activity, n_train)] of the cells run, in configuration order."""
        return [
            (p, s, a, n)
            for p in self.protocols
            for s, a in self.pairs
            for n in self.n_train
            if self.runs_cell(p, s, a, n)
        ]

    @property
    def design(self):
        """The configured jobs, as the report rules check the aggregate table against (:func:`bsrbench.results.check_design`)."""
        return {
            "protocols": self.protocols,
            "pairs": [[s, a] for s, a in self.pairs],
            "methods": self.run,
            "n_train": self.n_train,
            "seeds": self.seeds,
            "skipped": [[p, s, a, int(n)] for p, s, a, n in sorted(self.skipped)],
        }

    def skipped_notes(self, source):
        """{protocol: {activity: [note, ...]}} of the skipped cells of ``source`` (for the tables)."""
        out = {}
        for (p, s, a, _n), note in sorted(self.skipped.items()):
            if s == source:
                out.setdefault(p, {}).setdefault(a, []).append(note)
        return out

    def largest_run_n(self, protocol, source, activity):
        """The largest N run for an activity (None if every N is skipped)."""
        ok = [n for n in self.n_train if self.runs_cell(protocol, source, activity, n)]
        return max(ok) if ok else None

    def fit_targets(self, ext="json"):
        """The result files of every fit job of the study."""
        return [
            f"{self.results}/fit/{p}/{s}/{a}/{m}/n{n}/seed{k}.{ext}"
            for p in self.protocols
            for s, a in self.pairs
            for m in self.run
            for n in self.n_train
            for k in self.seeds
            if self.runs_cell(p, s, a, n)
        ]

    # ---------------------------------------------------------------------------------- methods
    def method(self, name):
        """The configuration of method ``name`` (estimator, label, params, cv_params, grid, chains)."""
        return self.config["methods"][name]

    def registry(self):
        """{name: :class:`bsrbench.methods.Method`} of every configured method (run ones first, in table order)."""
        names = self.run + [m for m in self.config["methods"] if m not in self.run]
        return registry(self.config["methods"], names)

    def method_labels(self):
        """{method: label} for every method run, in table order."""
        methods = self.registry()
        return {m: methods[m].label for m in self.run}

    def conformal(self, name):
        """The split-conformal settings of a method's fits, ``{"level", "params"}``, or None (``conformal_level``
        null, or the method's ``conformal: false``). ``params``: the method's ``cv_params``, which the refit
        on 75% of the training frames uses too (e.g. fewer MCMC sweeps): the interval's guarantee holds for any
        point predictor."""
        level = self.config.get("conformal_level")
        if level is None or not self.method(name).get("conformal", True):
            return None
        return {"level": float(level), "params": dict(self.method(name).get("cv_params") or {})}

    def paper_names(self):
        """{method: the paper's name of it (a column of Tables I-II) or None} for every method run."""
        methods = self.registry()
        return {m: methods[m].paper_name for m in self.run}

    def method_groups(self):
        """{method: its table block, "paper" or "today"} for every method run (methods.<M>.group)."""
        methods = self.registry()
        return {m: methods[m].group for m in self.run}

    def n_chains(self, name):
        """MCMC chains per split of a method (methods.<M>.chains, default 1)."""
        return int(self.method(name).get("chains", 1))

    def chain_groups(self):
        """{C: [method, ...]}: the study's methods (``run``) with C > 1 chains per split, by C (a rule's outputs are
        fixed, so the job that runs a split's chains is one rule per C)."""
        out = {}
        for name in self.run:
            if self.n_chains(name) > 1:
                out.setdefault(self.n_chains(name), []).append(name)
        return dict(sorted(out.items()))

    def method_regex(self, chained):
        """Wildcard regex of the method names run with several chains (chained=True) or with one."""
        names = [m for m in self.config["methods"] if (self.n_chains(m) > 1) == chained]
        return "|".join(names) if names else "(?!x)x"

    def grid(self, name):
        """The CV grid of a method: its `grid` ({} for null), or the module's DEFAULT_GRID for "default"."""
        grid = self.method(name).get("grid", "default")
        if grid is None:
            return {}
        if grid == "default":
            from .estimators import default_grid

            return default_grid(self.method(name)["estimator"])
        return grid

    def method_cv(self, name):
        """The CV of a method, ``{"mode", "folds"}``: its ``methods.<M>.cv`` over the study's ``cv``."""
        return method_cv(self.config, name)

    def cv_seed(self, name, seed):
        """The seed of the CV result a fit job reads; None when it reads none (the method's CV mode none, no
        grid)."""
        mode = self.method_cv(name)["mode"]
        if mode == "none" or self.grid(name) == {}:
            return None
        return self.first_seed if mode == "per_size" else seed

    def estimator_sources(self, name):
        """Source files whose edit reruns a method's jobs: its estimator's module, the job logic and every module
        of the package they import (:meth:`bsrbench.methods.Method.source_files`)."""
        return self.registry()[name].source_files()

    @property
    def trace_method(self):
        return self.config["report"].get("trace_method")

    def pm_variants(self):
        """Run methods with the estimator of report.trace_method (else of PM)."""
        ref = self.trace_method or "PM"
        if ref not in self.config["methods"]:
            return []
        est = self.method(ref)["estimator"]
        return [m for m in self.run if self.method(m)["estimator"] == est]

    def table_methods(self):
        """The methods of Tables I-II and of the error and calibration figures: every run method but the PM
        variants other than the reference variant (the variants have the ablation table)."""
        variants = self.pm_variants()
        ref = self.trace_method or "PM"
        keep = ref if ref in self.run else (variants[0] if variants else None)
        return [m for m in self.run if m not in variants or m == keep]

    def subjective_methods(self):
        """The methods of report.subjective_methods that are run."""
        return [m for m in self.config["report"]["subjective_methods"] if m in self.run]

    # -------------------------------------------------------------------------------- data sets
    def activity_labels(self, source):
        """{activity: the paper's name of it (or "")} for the studied activities of ``source``."""
        return {
            a: self.data.dataset(source, a)["paper_activity"] or ""
            for a in self.config["study_activities"].get(source, [])
        }

    def report_sources(self):
        """Data sources with at least one studied activity."""
        return [s for s, acts in self.config["study_activities"].items() if acts]

    def data_status(self, source):
        """{paper activity: the studied activity id, or why there is no row: {"kind", "activity", "command",
        "missing"}}.

        kind "none": no data set of ``source`` for it; "here": data here, activity not studied; "download":
        data not here, ``command`` downloads and builds them; "missing": input files missing.
        """
        studied = {a: pa for a, pa in self.activity_labels(source).items() if pa}
        rank = (
            "none",
            "missing",
            "download",
            "here",
        )  # several data sets may serve one paper activity
        out = {}
        for row in self.data.data_availability():
            if row["source"] != source:
                continue
            pa, a = row["paper_activity"], row["activity"]
            if isinstance(out.get(pa), str):  # already a studied activity
                continue
            if a is not None and a in studied:
                out[pa] = a
                continue
            if a is None:
                kind = "none"
            else:
                kind = "here" if row["available"] else "download" if row["command"] else "missing"
            if pa in out and rank.index(out[pa]["kind"]) >= rank.index(kind):
                continue
            out[pa] = {
                "kind": kind,
                "activity": a or "",
                "command": f"snakemake --cores 2 {row['target']}" if kind == "download" else "",
                "missing": list(row["missing"]),
            }
        return out


def load_datasets(config, *, schema_dir=SCHEMAS, config_args=None, parsed_args=None, validate=True):
    """The :class:`DataSets` of the merged configuration ``config``, which is retyped, validated and given its
    defaults in place (the workflow's rules read it too).

    ``config_args``/``parsed_args``: the raw ``--config`` strings and Snakemake's reading of them
    (:func:`retype_cli_config`). Raises InputError naming the key, its value and what was expected.
    """
    schema_dir = Path(schema_dir)
    # before anything walks it: Snakemake has read the files' YAML aliases as shared values, which expand on walking
    check_plain(config, "configuration")
    retype_cli_config(config, config_args, parsed_args or {})
    retype_yaml_numbers(
        config, load_schema(schema_dir / "config.schema.yaml", schema_dir / "datasets.schema.yaml")
    )
    if validate:
        validate_config(
            config, schema_dir / "datasets.schema.yaml", "data sets (config/datasets.yaml)"
        )
    entries = resolve_datasets(config, dataset_defaults(schema_dir))
    check_datasets(entries, list(config["features"]["codebook"]["files"]))
    return DataSets(config=config, entries=MappingProxyType(entries))


def load_study(data, *, schema_dir=SCHEMAS, cwd=".", validate=True):
    """The :class:`Study` of the configuration of ``data`` (:func:`load_datasets`), validated against the study
    schema (defaults filled in, in place) and cross-checked. ``cwd``: the working directory, named when
    config/datasets.yaml was not found. Raises InputError naming the key, its value and what
    was expected.
    """
    config = data.config
    check_method_names(config.get("methods"))
    if validate:
        validate_config(config, Path(schema_dir) / "config.schema.yaml", "configuration")
    skipped = _check_study(config, data.entries, cwd)
    return Study(config=config, data=data, skipped=MappingProxyType(skipped))
