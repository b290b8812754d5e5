# Configuration validation, cross-checks and helpers of the study rules (fit, aggregate, report).

import importlib.util
import os
import sys
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from bsrbench.cli_config import config_validation_error

# a schema error as one line naming the key, its value and what was expected (bsrbench.cli_config), instead of
# Snakemake's message dumping the whole schema and configuration
try:
    validate(config, "../schemas/config.schema.yaml")
except WorkflowError as exc:
    raise config_validation_error(exc, "configuration") from None

#: Root of this study's results: every rule writes its fit, CV, aggregate and benchmark files under it (the
#: features and poses of results/features and results/mocap do not depend on the study and are shared).
RESULTS = f"results/{config['study']}"
#: Root of this study's logs.
LOGS = f"logs/{config['study']}"
#: Root of this study's report: tables, figures, the PDF (and, by `snakemake --report`, the HTML report); the
#: template reports/report.tex and the published tables of reports/published are shared.
REPORTS = f"reports/{config['study']}"


wildcard_constraints:
    protocol="random|contiguous|cross_trial",
    source="[a-z0-9_]+",
    activity="[a-z0-9_]+",
    method="[A-Za-z0-9]+",
    n_train="[0-9]+",
    seed="[0-9]+",
    chain="[0-9]+",
    table="I|II",


def _data_activities(source):
    """{activity: frames} of the data sets configured for ``source`` (config/datasets.yaml); {} if none.

    The frames a data set will have (``data_frames``): fewer than n_frames when its trials give fewer.
    """
    return {a: data_frames(s, a) for s, a in datasets_of(source) if s == source}


#: {(protocol, source, activity, n_train): why the cell is not run}, filled by _check_study_config.
SKIPPED_CELLS = {}


def _check_study_config():
    """Cross-checks the JSON schema cannot make; raise ValueError naming the key before any job runs."""
    from bsrbench.study import check_method_settings, max_n_train

    methods = config["methods"]
    # every method run must be buildable: its estimator imports, takes every configured parameter, and its own
    # validation accepts every value and grid point on the smallest N (and CV training fold) it will be fitted on
    check_method_settings(methods, config["run"], n_train=config["n_train"], cv=config["cv"])
    for key in ("trace_method",):
        m = config["report"].get(key)
        if m is not None and m not in methods:
            raise ValueError(
                f"config key 'report.{key}': unknown method {m!r}; defined under 'methods': {sorted(methods)}"
            )
    for m in config["report"].get("gxy_methods") or []:
        if m not in config["run"]:
            raise ValueError(
                f"config key 'report.gxy_methods': method {m!r} is not run; 'run' lists {config['run']}"
            )
    for m in config["report"]["subjective_methods"]:
        if m not in methods:
            raise ValueError(
                f"config key 'report.subjective_methods': unknown method {m!r}; defined: {sorted(methods)}"
            )
    if not any(config["study_activities"].values()):
        raise ValueError(
            "config key 'study_activities': no activity to study (every source has an empty list)"
        )
    for source, acts in config["study_activities"].items():
        known = _data_activities(source)
        if not config.get("datasets"):
            raise ValueError(
                f"config key 'datasets': empty, so config/datasets.yaml was not loaded from the working directory "
                f"{os.getcwd()}; run snakemake in the repository (the folder of the Snakefile) or point "
                f"--directory at it"
            )
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
            if "cross_trial" in config["protocols"] and (
                not is_motion(source, a) or len(dataset(source, a)["files"]) < 2
            ):
                raise ValueError(
                    f"config key 'protocols': cross_trial needs a motion-capture data set of several trials; "
                    f"{source}/{a} is format {dataset(source, a)['format']!r} with "
                    f"{len(dataset(source, a)['files'])} file(s) (study it with random or contiguous)"
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
                        SKIPPED_CELLS[(protocol, source, a, int(n))] = (
                            f"N = {n} skipped: the {known[a]} frames leave at most {max(known[a] - n, 0)} test "
                            + "frames"
                            + (
                                f" (fewer after the gap of {config['gap']})"
                                if protocol == "contiguous"
                                else ""
                            )
                            + f", fewer than min_test = {config['min_test']}"
                        )
    pairs = [(s, a) for s, acts in config["study_activities"].items() for a in acts]
    for protocol in config["protocols"]:
        for s, a in pairs:
            if all((protocol, s, a, int(n)) in SKIPPED_CELLS for n in config["n_train"]):
                raise ValueError(
                    f"config key 'study_activities.{s}': {a} has {_data_activities(s)[a]} frames, and every "
                    f"n_train {config['n_train']} leaves fewer than min_test={config['min_test']} test frames "
                    f"with protocol {protocol!r}; remove it, add a smaller n_train or lower min_test"
                )
        for n in config["n_train"]:
            if pairs and all((protocol, s, a, int(n)) in SKIPPED_CELLS for s, a in pairs):
                where = ", ".join(f"{s}/{a} ({_data_activities(s)[a]} frames)" for s, a in pairs)
                raise ValueError(
                    f"config key 'n_train': {n} is too large for {where} with protocol {protocol!r}, "
                    f"min_test={config['min_test']}, gap={config['gap']}: no studied activity can use it"
                )


_check_study_config()


def run_methods():
    return list(config["run"])


def method_setting(method):
    return config["methods"][method]


def method_labels():
    """{method: label} for every method run, in table order (JSON for the report scripts)."""
    return {m: method_setting(m).get("label", m) for m in run_methods()}


def first_seed():
    """The first split seed (config key seed_start; 0 in the paper protocol)."""
    return int(config.get("seed_start", 0))


def seeds():
    """Split seeds seed_start .. seed_start + n_seeds - 1."""
    return list(range(first_seed(), first_seed() + config["n_seeds"]))


def n_chains(method):
    """MCMC chains per split of a method (config key methods.<M>.chains, default 1)."""
    return int(method_setting(method).get("chains", 1))


def chained_methods():
    """Methods run with several chains per split (rules fit_chain and pool_chains instead of fit)."""
    return [m for m in config["methods"] if n_chains(m) > 1]


def method_regex(chained):
    """Wildcard regex of the method names run with several chains (chained=True) or with one."""
    names = [m for m in config["methods"] if (n_chains(m) > 1) == chained]
    return "|".join(names) if names else "(?!x)x"


def chain_inputs(wildcards):
    """The chain files of a split, one per chain of the method."""
    w = wildcards
    return [
        f"{RESULTS}/fit/{w.protocol}/{w.source}/{w.activity}/{w.method}/n{w.n_train}/seed{w.seed}/chain{c}.npz"
        for c in range(n_chains(w.method))
    ]


def study_pairs():
    """[(source, activity)] in configuration order."""
    return [(s, a) for s, acts in config["study_activities"].items() for a in acts]


def run_cell(protocol, source, activity, n_train):
    """False for the (protocol, activity, N) cells skipped because too few test frames would remain."""
    return (protocol, source, activity, int(n_train)) not in SKIPPED_CELLS


def skipped_notes(source):
    """{protocol: {activity: [note, ...]}} of the skipped cells of ``source`` (for the tables)."""
    out = {}
    for (p, s, a, n), note in sorted(SKIPPED_CELLS.items()):
        if s == source:
            out.setdefault(p, {}).setdefault(a, []).append(note)
    return out


def largest_run_n(protocol, source, activity):
    """The largest N run for an activity (None if every N is skipped)."""
    ok = [int(n) for n in config["n_train"] if run_cell(protocol, source, activity, n)]
    return max(ok) if ok else None


def study_design():
    """The configured study (protocols, [source, activity] pairs, methods, sizes, seeds): the report rules check
    that the aggregate table holds exactly these jobs (bsrbench.reporting.tables.check_design)."""
    return {
        "protocols": list(config["protocols"]),
        "pairs": [[s, a] for s, a in study_pairs()],
        "methods": run_methods(),
        "n_train": [int(n) for n in config["n_train"]],
        "seeds": seeds(),
        "skipped": [[p, s, a, int(n)] for p, s, a, n in sorted(SKIPPED_CELLS)],
    }


def fit_targets(ext="json"):
    return [
        f"{RESULTS}/fit/{p}/{s}/{a}/{m}/n{n}/seed{k}.{ext}"
        for p in config["protocols"]
        for s, a in study_pairs()
        for m in run_methods()
        for n in config["n_train"]
        for k in seeds()
        if run_cell(p, s, a, n)
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
    seed = first_seed() if mode == "per_size" else wildcards.seed
    w = wildcards
    return (
        f"{RESULTS}/cv/{w.protocol}/{w.source}/{w.activity}/{w.method}/n{w.n_train}/seed{seed}.json"
    )


def method_grid(wildcards):
    """The CV grid of a method: its config `grid` ({} for null), or the module's DEFAULT_GRID for "default"."""
    grid = method_setting(wildcards.method).get("grid", "default")
    if grid is None:
        return {}
    if grid == "default":
        from bsrbench.study import default_grid

        grid = default_grid(method_setting(wildcards.method)["estimator"])
    return grid


def pm_variants():
    """The PM variants of the study: run methods with the estimator of report.trace_method (else of PM)."""
    ref = config["report"].get("trace_method") or "PM"
    if ref not in config["methods"]:
        return []
    est = method_setting(ref)["estimator"]
    return [m for m in run_methods() if method_setting(m)["estimator"] == est]


def table_methods():
    """The methods of Tables I-II and of the error and calibration figures: every run method but the PM variants
    other than the reference variant (report.trace_method); the variants have the ablation table of the section
    "Why PM trails the paper here" (23 columns would not fit a page)."""
    variants = pm_variants()
    ref = config["report"].get("trace_method") or "PM"
    keep = ref if ref in run_methods() else (variants[0] if variants else None)
    return [m for m in run_methods() if m not in variants or m == keep]


def report_sources():
    """Data sources with at least one studied activity."""
    return [s for s, acts in config["study_activities"].items() if acts]


def table_targets():
    """The paper's tables per studied source, but none whose activities are all unstudied on that source (a block
    of "no data" rows; the note under the source's tables says it is left out)."""
    from bsrbench.reporting.tables import tables_with_rows

    return [
        f"{REPORTS}/tables/table{t}_{s}.tex"
        for s in report_sources()
        for t in tables_with_rows(data_status(s))
    ]


def figure_targets(ext):
    out = [f"{REPORTS}/figures/error_vs_ntrain_{s}.{ext}" for s in report_sources()]
    out += [f"{REPORTS}/figures/subjective_{s}.{ext}" for s in report_sources()]
    out += [f"{REPORTS}/figures/calibration_{s}.{ext}" for s in report_sources()]
    return out


def why_pm_figures(ext):
    """Figures of the section "Why PM trails the paper here": chain traces and the g_xy mechanism."""
    out = []
    if config["report"].get("trace_method") in run_methods():
        out.append(f"{REPORTS}/figures/trace.{ext}")
    if config["report"].get("gxy_methods"):
        out.append(f"{REPORTS}/figures/gxy.{ext}")
    return out


def subjective_methods():
    """The methods drawn in the subjective comparison: those of report.subjective_methods that are run."""
    return [m for m in config["report"]["subjective_methods"] if m in run_methods()]


def stick_kind(source, activity):
    """How the subjective figure draws an activity's poses: "bvh" (a BVH motion: silhouette and stick figures of
    the trial's skeleton), "authors" (features file in the authors' skeleton convention: input histogram and
    stick figures of their skeleton) or None (angle profiles)."""
    entry = dataset(source, activity)
    if is_motion(source, activity) and all(str(f).endswith(".bvh") for f in entry["files"]):
        return "bvh"
    if entry.get("pose_convention") == "authors":
        return "authors"
    return None


def subjective_inputs(wildcards):
    """Predictions of the largest n_train run for each activity, seed 0, first protocol, of the methods drawn."""
    p = config["protocols"][0]
    shown = subjective_methods()
    acts = config["study_activities"][wildcards.source]
    return {
        "poses": [
            f"results/mocap/{wildcards.source}/{a}.npz"
            for a in acts
            if is_motion(wildcards.source, a)
        ],
        "features": [f"results/features/{wildcards.source}/{a}.npz" for a in acts],
        "predictions": [
            f"{RESULTS}/fit/{p}/{wildcards.source}/{a}/{m}/n{largest_run_n(p, wildcards.source, a)}/seed{first_seed()}.npz"
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
    """The saved trace(s) of the trace method: first study activity, largest n_train, first seed."""
    s, a = study_pairs()[0]
    p = config["protocols"][0]
    n = largest_run_n(p, s, a)
    return (
        f"{RESULTS}/fit/{p}/{s}/{a}/{config['report']['trace_method']}/n{n}/seed{first_seed()}.npz"
    )


def gxy_inputs(wildcards):
    """Saved traces of the g_xy figure's methods: first study activity, smallest n_train, first seed."""
    s, a = study_pairs()[0]
    n = min(config["n_train"])
    p = config["protocols"][0]
    return [
        f"{RESULTS}/fit/{p}/{s}/{a}/{m}/n{n}/seed{first_seed()}.npz"
        for m in config["report"].get("gxy_methods") or []
    ]


def activity_labels(source):
    """{activity: the paper's name of it (or "")} for the studied activities of ``source``."""
    return {
        a: dataset(source, a)["paper_activity"] or ""
        for a in config["study_activities"].get(source, [])
    }


def data_status(source):
    """{paper activity: the studied activity id, or why there is no row: {"kind", "activity", "command", "missing"}}.

    kind "none": no data set of ``source`` for it; "here": data here, activity not studied; "download": data
    not here, ``command`` downloads (by the download rules) and builds them; "missing": input files missing.
    The report explains them once per source, under the tables.
    """
    studied = {a: pa for a, pa in activity_labels(source).items() if pa}
    out = {}
    for row in data_availability():
        if row["source"] != source:
            continue
        pa, a = row["paper_activity"], row["activity"]
        if isinstance(out.get(pa), str):  # already a studied activity
            continue
        if a is not None and a in studied:
            out[pa] = a
            continue
        kind = (
            "none"
            if a is None
            else "here" if row["available"] else "download" if row["command"] else "missing"
        )
        rank = (
            "none",
            "missing",
            "download",
            "here",
        )  # several data sets may serve one paper activity
        if pa in out and rank.index(out[pa]["kind"]) >= rank.index(kind):
            continue
        out[pa] = {
            "kind": kind,
            "activity": a or "",
            "command": f"snakemake --cores 2 {row['target']}" if kind == "download" else "",
            "missing": list(row["missing"]),
        }
    return out


def config_overrides():
    """The `--config KEY=VALUE` strings of this run (command line or profile), as given, that configure the study:
    all but job_server, an execution setting like --cores (switching it reruns nothing, the report included; the
    SLURM profile sets it)."""
    return [
        str(a)
        for a in workflow.config_settings.config_args or []
        if str(a).partition("=")[0].strip() != "job_server"
    ]


def study_targets():
    return [
        f"{RESULTS}/aggregate/results.csv",
        *table_targets(),
        *figure_targets("pdf"),
        *why_pm_figures("pdf"),
        f"{REPORTS}/tables/why_pm.tex",
        f"{REPORTS}/report.pdf",
    ]


def _report_arg(argv):
    """The file of `--report FILE` / `--report=FILE` in ``argv``: None without --report, Snakemake's default
    report.html when no file follows."""
    for k, a in enumerate(argv):
        if a.startswith("--report="):
            return a.split("=", 1)[1]
        if a == "--report":
            nxt = argv[k + 1] if k + 1 < len(argv) else ""
            return nxt if nxt and not nxt.startswith("-") else "report.html"
    return None


def _check_report_is_current():
    """`snakemake --report` embeds the outputs as they are on disk, without checking that they are current, and
    Snakefiles get no flag saying that a report is being built: so, on that command line, refuse an aggregate
    table of another configuration (the one check that matters: the HTML report would show another study), and
    an HTML file in another study's report folder (reports/{other}/, or the shared reports/ itself).
    """
    html = _report_arg(sys.argv)
    if html is None:
        return
    target, reports = Path(html).resolve(), Path("reports").resolve()
    if target.is_relative_to(reports) and not target.is_relative_to(Path(REPORTS).resolve()):
        raise ValueError(
            f"--report {html}: the HTML report of study {config['study']!r} goes to its report folder {REPORTS}/ "
            f"(e.g. --report {REPORTS}/report.html), not to a folder of reports/ shared with or owned by another "
            f"study"
        )
    aggregate = Path(f"{RESULTS}/aggregate/results.csv")
    if aggregate.exists():
        from bsrbench.reporting.tables import read_results

        read_results(aggregate, design=study_design())


_check_report_is_current()


def design_change_message():
    """When results/{study}/aggregate/results.csv exists but holds another design than the configured one (a
    method, size, seed, protocol or activity added or removed under the same study name): a message naming what
    changed and what to do; None otherwise, or when the table cannot be read (the aggregate rule rebuilds it, and
    the report rules name the problem). The table's key columns are the record of the design it was built for.
    """
    from bsrbench.reporting.tables import KEY_COLUMNS, design_changes

    aggregate = Path(f"{RESULTS}/aggregate/results.csv")
    if not aggregate.is_file():
        return None
    import pandas as pd

    try:
        missing, extra, differ = design_changes(
            pd.read_csv(aggregate, usecols=KEY_COLUMNS), study_design()
        )
    except (OSError, UnicodeDecodeError, ValueError, TypeError):
        # unreadable or damaged (pandas' parser errors are ValueErrors): not a design change; the aggregate and
        # report rules handle it
        return None
    if not (missing or extra):
        return None
    study, changes = config["study"], "; ".join(differ)
    return (
        f"study {study!r}: the configuration differs from the design of its results in {RESULTS}/ ({aggregate}: "
        f"{changes}; {missing} job(s) to add, {extra} no longer configured). Snakemake reruns what "
        f"this needs and rebuilds the aggregate table and the report of study {study!r} for the configuration as "
        f"it is now, replacing the old report (fits no longer configured stay unused in {RESULTS}/fit/). To keep "
        f"the old study's table and report instead, run this design under a study name of its own (--config "
        f"study=NAME, or the key 'study' of your configuration file); to start study {study!r} afresh, delete "
        f"{RESULTS}/ and {REPORTS}/."
    )


def _warn_if_design_changed():
    """Say at the start of the run (dry runs too), before any job, that the study's design changed under the same
    name. Not under `--report` (_check_report_is_current refuses the stale table) nor in the jobs Snakemake
    spawns (cluster jobs parse the Snakefile again)."""
    if not workflow.is_main_process or _report_arg(sys.argv) is not None:
        return
    message = design_change_message()
    if message:
        from snakemake.logging import logger

        logger.warning(f"Warning: {message}")


_warn_if_design_changed()
