# The study's configuration and the rules' input functions.
# include: put this file's folder first on Python's path: off before anything is imported (bsrbench.pythonpath)
import os
import sys

if os.path.realpath(sys.path[0]) == os.path.realpath(
    workflow.current_basedir.get_path_or_uri(secret_free=False)
):
    del sys.path[0]
import os
import sys
from pathlib import Path
from types import SimpleNamespace

from snakemake.logging import logger

from bsrbench.config import load_study, or_exit
from bsrbench.splits import PROTOCOLS
from bsrbench.results import check_report_is_current, design_change_message, report_arg

# A bad configuration stops here with its one-line message (or_exit), before any job runs.
STUDY = or_exit(
    load_study,
    DATA,
    schema_dir=Path(str(workflow.current_basedir)).parent / "schemas",
    cwd=os.getcwd(),
    validate=not workflow.modifier.skip_validation,
)
#: This study's results, logs and report folders.
RESULTS, LOGS, REPORTS = STUDY.results, STUDY.logs, STUDY.reports

# `--report`: refuse a table of another design.
try:
    check_report_is_current(STUDY, sys.argv)
# an aggregate table of another design, an HTML file in another study's folder
except ValueError as exc:
    print(exc, file=sys.stderr)
    sys.exit(1)
# Warn when the design changed under the same study name.
if workflow.is_main_process and report_arg(sys.argv) is None:
    if message := design_change_message(STUDY):
        logger.warning(f"Warning: {message}")


wildcard_constraints:
    protocol="|".join(PROTOCOLS),
    source="[a-z0-9_]+",
    activity="[a-z0-9_]+",
    method="[A-Za-z0-9]+",
    n_train="[0-9]+",
    seed="[0-9]+",
    chain="[0-9]+",
    table="I|II",


method_setting = STUDY.method
method_labels = STUDY.method_labels
method_groups = STUDY.method_groups
method_regex = STUDY.method_regex
skipped_notes = STUDY.skipped_notes
fit_targets = STUDY.fit_targets
pm_variants = STUDY.pm_variants
table_methods = STUDY.table_methods
report_sources = STUDY.report_sources
subjective_methods = STUDY.subjective_methods
activity_labels = STUDY.activity_labels
data_status = STUDY.data_status


def study_design():
    return STUDY.design


def chain_inputs(wildcards):
    """The chain files of a split, one per chain of the method."""
    w = wildcards
    split = (
        f"{RESULTS}/fit/{w.protocol}/{w.source}/{w.activity}/{w.method}/n{w.n_train}/seed{w.seed}"
    )
    return [f"{split}/chain{c}.npz" for c in range(STUDY.n_chains(w.method))]


def seed_files(pattern, seeds):
    """``pattern``'s files of ``seeds`` (one per seed, in order), its other wildcards kept."""
    return expand(pattern, seed=seeds, allow_missing=True)


def block_name(seeds):
    """The block's name in its rule, log and benchmark: seed3 (one seed) or seeds0to9."""
    return f"seed{seeds[0]}" if len(seeds) == 1 else f"seeds{seeds[0]}to{seeds[-1]}"


def with_seed(wildcards, seed):
    """A block job's wildcards with the wildcard ``seed`` of one of its seeds."""
    return SimpleNamespace(**dict(wildcards.items()), seed=str(seed))


def block_cv_inputs(seeds):
    """The CV results a block's fits read (each once)."""

    def inputs(wildcards):
        files = (cv_input(with_seed(wildcards, s)) for s in seeds)
        return sorted({f for f in files if f})

    return inputs


def estimator_sources(wildcards):
    """Source files of the estimator and the job logic: editing a model reruns its jobs."""
    return STUDY.estimator_sources(wildcards.method)


def conformal(wildcards):
    """The method's split-conformal settings ({"level", "params"}), or None."""
    return STUDY.conformal(wildcards.method)


def pose_transform(wildcards):
    """The method's pose transform: its own, else the study's."""
    return method_setting(wildcards.method).get("pose_transform") or config["pose_transform"]


def method_grid(wildcards):
    return STUDY.grid(wildcards.method)


def cv_input(wildcards):
    """The CV result a fit job reads (none with cv.mode none or without a grid)."""
    seed = STUDY.cv_seed(wildcards.method, wildcards.seed)
    if seed is None:
        return []
    w = wildcards
    return (
        f"{RESULTS}/cv/{w.protocol}/{w.source}/{w.activity}/{w.method}/n{w.n_train}/seed{seed}.json"
    )


def table_targets():
    """The paper's tables per studied source with at least one studied activity."""
    from bsrbench.reporting.tables import tables_with_rows

    return [
        f"{REPORTS}/tables/table{t}_{s}.tex"
        for s in report_sources()
        for t in tables_with_rows(data_status(s))
    ]


def figure_targets(ext):
    kinds = ("error_vs_ntrain", "subjective", "calibration")
    return [f"{REPORTS}/figures/{k}_{s}.{ext}" for k in kinds for s in report_sources()]


def why_pm_figures(ext):
    """Chain traces and the g_xy mechanism of the section "Why PM trails the paper here"."""
    out = []
    if STUDY.trace_method in STUDY.run:
        out.append(f"{REPORTS}/figures/trace.{ext}")
    if config["report"].get("gxy_methods"):
        out.append(f"{REPORTS}/figures/gxy.{ext}")
    return out


def _first_fit(source, activity, method, n):
    p = STUDY.protocols[0]
    return f"{RESULTS}/fit/{p}/{source}/{activity}/{method}/n{n}/seed{STUDY.first_seed}.npz"


def subjective_inputs(wildcards):
    """Predictions of the largest N run per activity, first seed and protocol, of the methods drawn."""
    s, p = wildcards.source, STUDY.protocols[0]
    acts = config["study_activities"][s]
    return {
        "poses": [f"results/mocap/{s}/{a}.npz" for a in acts if is_motion(s, a)],
        "features": [f"results/features/{s}/{a}.npz" for a in acts],
        "predictions": [
            _first_fit(s, a, m, STUDY.largest_run_n(p, s, a))
            for a in acts
            for m in subjective_methods()
        ],
    }


def subjective_motion(wildcards):
    """Poses file, trial files and render settings of the motion-capture activities (stick figures)."""
    s = wildcards.source
    return {
        a: {
            "poses": f"results/mocap/{s}/{a}.npz",
            "files": list(dataset(s, a)["files"]),
            "asf": dataset(s, a).get("asf"),
            "render": render_params(),
        }
        for a in config["study_activities"][s]
        if is_motion(s, a)
    }


def pit_inputs():
    """(predictions file, (source, method)) of the PIT figure: every table method's fits at the largest N run
    per activity, all seeds, first protocol (methods without a predictive distribution have no PIT values).
    """
    p = STUDY.protocols[0]
    out = []
    for s, a in STUDY.pairs:
        n = STUDY.largest_run_n(p, s, a)
        for m in table_methods():
            for seed in STUDY.seeds:
                out.append((f"{RESULTS}/fit/{p}/{s}/{a}/{m}/n{n}/seed{seed}.npz", (s, m)))
    return out


def trace_input(wildcards):
    """The fit of the trace method: first studied activity, largest N, first seed."""
    s, a = STUDY.pairs[0]
    n = STUDY.largest_run_n(STUDY.protocols[0], s, a)
    return _first_fit(s, a, config["report"]["trace_method"], n)


def gxy_inputs(wildcards):
    """The fits of the g_xy figure's methods: first studied activity, smallest N, first seed."""
    s, a = STUDY.pairs[0]
    n = min(config["n_train"])
    return [_first_fit(s, a, m, n) for m in config["report"].get("gxy_methods") or []]


def config_overrides():
    """This run's `--config KEY=VALUE` strings that configure the study (all but job_server and seeds_per_job,
    which change where and in which jobs the fits run, not their results, like --cores)."""
    return [
        str(a)
        for a in workflow.config_settings.config_args or []
        if str(a).partition("=")[0].strip() not in ("job_server", "seeds_per_job")
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
