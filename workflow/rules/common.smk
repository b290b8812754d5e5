# Configuration validation, cross-checks and helpers of the study rules (fit, aggregate, report).

import importlib.util
from pathlib import Path

from snakemake.utils import validate


validate(config, "../schemas/config.schema.yaml")

#: Root of this study's results: every rule writes its fit, CV, aggregate and benchmark files under it (the
#: features and poses of results/features and results/mocap do not depend on the study and are shared).
RESULTS = f"results/{config['study']}"
#: Root of this study's logs.
LOGS = f"logs/{config['study']}"


wildcard_constraints:
    protocol="random|contiguous",
    source="[a-z0-9_]+",
    activity="[a-z0-9_]+",
    method="[A-Za-z0-9]+",
    n_train="[0-9]+",
    seed="[0-9]+",
    table="I|II",


def _data_activities(source):
    """{activity: frames} of the data sets configured for ``source`` (config/datasets.yaml); {} if none."""
    return {
        a: int(dataset(s, a)["n_frames"]) for s, a in datasets_of(source) if s == source
    }


def _check_study_config():
    """Cross-checks the JSON schema cannot make; raise ValueError naming the key before any job runs."""
    from bsrbench.study import max_n_train

    methods = config["methods"]
    for m in config["run"]:
        if m not in methods:
            raise ValueError(
                f"config key 'run': unknown method {m!r}; defined under 'methods': {sorted(methods)}"
            )
    for key in ("trace_method",):
        m = config["report"].get(key)
        if m is not None and m not in methods:
            raise ValueError(
                f"config key 'report.{key}': unknown method {m!r}; defined under 'methods': {sorted(methods)}"
            )
    for m in config["report"]["subjective_methods"]:
        if m not in methods:
            raise ValueError(
                f"config key 'report.subjective_methods': unknown method {m!r}; defined: {sorted(methods)}"
            )
    if not any(config["study_activities"].values()):
        raise ValueError("config key 'study_activities': no activity to study (every source has an empty list)")
    for source, acts in config["study_activities"].items():
        known = _data_activities(source)
        if not known:
            raise ValueError(
                f"config key 'study_activities': unknown data source {source!r}; "
                f"config/datasets.yaml defines {sorted(config.get('datasets') or {})}"
            )
        for a in acts:
            if a not in known:
                raise ValueError(
                    f"config key 'study_activities.{source}': unknown activity {a!r}; "
                    f"source {source!r} has {sorted(known)}"
                )
            for protocol in config["protocols"]:
                limit = max_n_train(
                    known[a],
                    protocol=protocol,
                    min_test=config["min_test"],
                    gap=config["gap"],
                )
                for n in config["n_train"]:
                    if n > limit:
                        raise ValueError(
                            f"config key 'n_train': {n} is too large for {source}/{a} ({known[a]} frames) with "
                            f"protocol {protocol!r}, min_test={config['min_test']}, gap={config['gap']}: "
                            f"at most {limit}"
                        )


_check_study_config()


def run_methods():
    return list(config["run"])


def method_setting(method):
    return config["methods"][method]


def method_labels():
    """{method: label} for every method run, in table order (JSON for the report scripts)."""
    return {m: method_setting(m).get("label", m) for m in run_methods()}


def seeds():
    return list(range(config["n_seeds"]))


def study_pairs():
    """[(source, activity)] in configuration order."""
    return [(s, a) for s, acts in config["study_activities"].items() for a in acts]


def fit_targets(ext="json"):
    return [
        f"{RESULTS}/fit/{p}/{s}/{a}/{m}/n{n}/seed{k}.{ext}"
        for p in config["protocols"]
        for s, a in study_pairs()
        for m in run_methods()
        for n in config["n_train"]
        for k in seeds()
    ]


def estimator_sources(wildcards):
    """Source files of a method's estimator and of the job logic: editing a model reruns its jobs.

    The estimator's module, the module's private helpers (e.g. _bsr_kernels.py for bsr.py), bsrbench.study.
    """
    modname = method_setting(wildcards.method)["estimator"].split(":")[0]
    spec = importlib.util.find_spec(modname)
    if spec is None or spec.origin is None:
        raise ValueError(
            f"config key 'methods.{wildcards.method}.estimator': module {modname!r} not found"
        )
    origin = Path(spec.origin)
    helpers = sorted(origin.parent.glob(f"_{origin.stem}_*.py"))
    study = Path(importlib.util.find_spec("bsrbench.study").origin)
    return [str(p) for p in [origin, *helpers, study]]


def cv_input(wildcards):
    """The CV result a fit job reads (none with cv.mode none)."""
    mode = config["cv"]["mode"]
    if mode == "none" or method_grid(wildcards) == {}:
        return []
    seed = 0 if mode == "per_size" else wildcards.seed
    w = wildcards
    return f"{RESULTS}/cv/{w.protocol}/{w.source}/{w.activity}/{w.method}/n{w.n_train}/seed{seed}.json"


def method_grid(wildcards):
    """The CV grid of a method: its config `grid` ({} for null), or the module's DEFAULT_GRID for "default"."""
    grid = method_setting(wildcards.method).get("grid", "default")
    if grid is None:
        return {}
    if grid == "default":
        from bsrbench.study import default_grid

        grid = default_grid(method_setting(wildcards.method)["estimator"])
    return grid


def report_sources():
    """Data sources with at least one studied activity."""
    return [s for s, acts in config["study_activities"].items() if acts]


def table_targets():
    return [
        f"reports/tables/table{t}_{s}.tex" for s in report_sources() for t in ("I", "II")
    ]


def figure_targets(ext):
    out = [f"reports/figures/error_vs_ntrain_{s}.{ext}" for s in report_sources()]
    out += [f"reports/figures/subjective_{s}.{ext}" for s in report_sources()]
    out.append(f"reports/figures/calibration.{ext}")
    if config["report"].get("trace_method") in run_methods():
        out.append(f"reports/figures/trace.{ext}")
    return out


def subjective_inputs(wildcards):
    """Predictions of the largest n_train, seed 0, first protocol, of the methods drawn in the comparison."""
    n = max(config["n_train"])
    p = config["protocols"][0]
    shown = [m for m in config["report"]["subjective_methods"] if m in run_methods()]
    acts = config["study_activities"][wildcards.source]
    return {
        "poses": [
            f"results/mocap/{wildcards.source}/{a}.npz"
            for a in acts
            if is_motion(wildcards.source, a)
        ],
        "features": [f"results/features/{wildcards.source}/{a}.npz" for a in acts],
        "predictions": [
            f"{RESULTS}/fit/{p}/{wildcards.source}/{a}/{m}/n{n}/seed0.npz"
            for a in acts
            for m in shown
        ],
    }


def subjective_motion(wildcards):
    """For motion-capture activities: poses file, trial files and render settings (for stick figures)."""
    return {
        a: {
            "poses": f"results/mocap/{wildcards.source}/{a}.npz",
            "files": list(dataset(wildcards.source, a)["files"]),
            "render": render_params(),
        }
        for a in config["study_activities"][wildcards.source]
        if is_motion(wildcards.source, a)
    }


def trace_input(wildcards):
    """The saved trace of the trace method: first study activity, largest n_train, seed 0."""
    s, a = study_pairs()[0]
    n = max(config["n_train"])
    p = config["protocols"][0]
    return f"{RESULTS}/fit/{p}/{s}/{a}/{config['report']['trace_method']}/n{n}/seed0.npz"


def activity_labels(source):
    """{activity: the paper's name of it (or "")} for the studied activities of ``source``."""
    return {
        a: dataset(source, a)["paper_activity"] or ""
        for a in config["study_activities"].get(source, [])
    }


def data_status(source):
    """{paper activity: the studied activity id, or why there is no row and how to get the data}."""
    studied = {a: pa for a, pa in activity_labels(source).items() if pa}
    out = {}
    for row in data_availability():
        if row["source"] != source:
            continue
        pa, a = row["paper_activity"], row["activity"]
        if pa in out and out[pa] in studied:
            continue
        if a is not None and a in studied:
            out[pa] = a
        elif a is None:
            out[pa] = f"no {source} data set for this activity (config/datasets.yaml)"
        elif row["available"]:
            out[pa] = (
                f"data here but not in this study: add {a} to study_activities.{source}"
            )
        elif row["command"]:
            out[pa] = f"data not on this machine; get it with: {row['command']}"
        else:
            out[pa] = f"data not on this machine (missing {', '.join(row['missing'])})"
    return out


def study_targets():
    return [
        f"{RESULTS}/aggregate/results.csv",
        *table_targets(),
        *figure_targets("pdf"),
        "reports/report.pdf",
    ]
