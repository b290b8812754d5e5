# Tables, figures, generated text and the PDF report, all from {RESULTS}/aggregate/results.csv.
# Every output is under reports/{study} (REPORTS): studies of different configurations never share a report file,
# so that each one's report (and `snakemake --report`) shows that study only, and two studies can run at once.
# include: put this file's folder first on Python's path: off before anything is imported (bsrbench.pythonpath)
import os
import sys

if os.path.realpath(sys.path[0]) == os.path.realpath(
    workflow.current_basedir.get_path_or_uri(secret_free=False)
):
    del sys.path[0]


from bsrbench.reporting.tables import error_tables, other_activities


# The HTML report's landing page (snakemake --report): titled with the study's name. Snakemake 9.27 fixes the
# browser tab's title ("Snakemake Report") in its template; no option changes it.
report: "../report/workflow.rst"


rule table:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        comparisons=f"{RESULTS}/aggregate/comparisons.csv",
        paper="resources/paper-tables.csv",
    output:
        report(
            f"{REPORTS}/tables/table{{table}}_{{source}}.tex",
            category="Tables",
            subcategory="{source}",
            caption="../report/tables.rst",
        ),
    log:
        f"{LOGS}/report/table{{table}}_{{source}}.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        methods=table_methods(),
        labels=method_labels(),
        groups=method_groups(),
        n_train=config["n_train"],
        protocols=config["protocols"],
        status=lambda w: data_status(w.source),
        skipped=lambda w: skipped_notes(w.source),
        frames=lambda w: {
            a: frame_protocol_text(w.source, a) for a in config["study_activities"][w.source]
        },
    script:
        "../scripts/tables.py"


# quick, like the other report rules: on the submit host under SLURM (the Snakefile's localrules)
localrules:
    table_activities,


rule table_activities:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        comparisons=f"{RESULTS}/aggregate/comparisons.csv",
    output:
        report(
            f"{REPORTS}/tables/activities_{{source}}.tex",
            category="Tables",
            subcategory="{source}",
            caption="../report/activities.rst",
        ),
    log:
        f"{LOGS}/report/activities_{{source}}.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        methods=table_methods(),
        labels=method_labels(),
        groups=method_groups(),
        n_train=config["n_train"],
        protocols=config["protocols"],
        activities=lambda w: other_activities(
            data_status(w.source), config["study_activities"][w.source]
        ),
        skipped=lambda w: skipped_notes(w.source),
        frames=lambda w: {
            a: frame_protocol_text(w.source, a) for a in config["study_activities"][w.source]
        },
    script:
        "../scripts/table_activities.py"


rule report_text:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        comparisons=f"{RESULTS}/aggregate/comparisons.csv",
        paper="resources/paper-tables.csv",
    output:
        findings=f"{REPORTS}/tables/findings.tex",
        body=f"{REPORTS}/tables/body.tex",
    log:
        f"{LOGS}/report/report_text.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        labels=method_labels(),
        figure_methods=table_methods(),
        study=config["study"],
        tables=error_tables(
            REPORTS,
            {s: (data_status(s), config["study_activities"][s]) for s in report_sources()},
        ),
        figures=figure_targets("pdf"),
        cd_figures=[f"{REPORTS}/figures/cd_{s}.pdf" for s in report_sources()],
        status={s: data_status(s) for s in report_sources()},
        stick_kinds={
            s: sorted({str(stick_kind(s, a)) for a in config["study_activities"][s]})
            for s in report_sources()
        },
        subjective_first=next(iter(subjective_methods()), ""),
    script:
        "../scripts/report_text.py"


rule plot_error_vs_ntrain:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        paper="resources/paper-tables.csv",
    output:
        pdf=f"{REPORTS}/figures/error_vs_ntrain_{{source}}.pdf",
        png=report(
            f"{REPORTS}/figures/error_vs_ntrain_{{source}}.png",
            category="Figures",
            subcategory="{source}",
            caption="../report/error_vs_ntrain.rst",
        ),
    log:
        f"{LOGS}/report/error_vs_ntrain_{{source}}.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        n_train=config["n_train"],
        methods=table_methods(),
        labels=method_labels(),
    script:
        "../scripts/plots_error.py"


rule plot_cd:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
    output:
        pdf=f"{REPORTS}/figures/cd_{{source}}.pdf",
        png=report(
            f"{REPORTS}/figures/cd_{{source}}.png",
            category="Figures",
            subcategory="{source}",
            caption="../report/cd.rst",
        ),
    log:
        f"{LOGS}/report/cd_{{source}}.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        protocols=config["protocols"],
        labels=method_labels(),
    script:
        "../scripts/plots_cd.py"


rule plot_calibration:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
    output:
        pdf=f"{REPORTS}/figures/calibration_{{source}}.pdf",
        png=report(
            f"{REPORTS}/figures/calibration_{{source}}.png",
            category="Figures",
            subcategory="{source}",
            caption="../report/calibration.rst",
        ),
    log:
        f"{LOGS}/report/calibration_{{source}}.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        methods=table_methods(),
        labels=method_labels(),
    script:
        "../scripts/plots_calibration.py"


rule plot_trace:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        predictions=trace_input,
    output:
        pdf=f"{REPORTS}/figures/trace.pdf",
        png=report(
            f"{REPORTS}/figures/trace.png",
            category="Figures",
            caption="../report/trace.rst",
        ),
    log:
        f"{LOGS}/report/trace.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        method=config["report"]["trace_method"],
        labels=method_labels(),
    script:
        "../scripts/plots_trace.py"


rule plot_gxy:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        predictions=gxy_inputs,
    output:
        pdf=f"{REPORTS}/figures/gxy.pdf",
        png=report(
            f"{REPORTS}/figures/gxy.png",
            category="Figures",
            caption="../report/gxy.rst",
        ),
    log:
        f"{LOGS}/report/gxy.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        labels=method_labels(),
    script:
        "../scripts/plots_gxy.py"


rule report_why_pm:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        paper="resources/paper-tables.csv",
    output:
        section=f"{REPORTS}/tables/why_pm.tex",
        convergence=report(
            f"{REPORTS}/tables/convergence.csv",
            category="Tables",
            caption="../report/convergence.rst",
        ),
    log:
        f"{LOGS}/report/why_pm.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        variants=pm_variants(),
        base=config["report"].get("trace_method") or "PM",
        nn="NN1",
        labels=method_labels(),
        figures=why_pm_figures("pdf"),
    script:
        "../scripts/report_why_pm.py"


rule report_mechanisms:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        comparisons=f"{RESULTS}/aggregate/comparisons.csv",
    output:
        section=f"{REPORTS}/tables/mechanisms.tex",
        table=report(
            f"{REPORTS}/tables/mechanisms.csv",
            category="Tables",
            caption="../report/mechanisms.rst",
        ),
    log:
        f"{LOGS}/report/mechanisms.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        # the paper's PM, as the section "Why PM trails the paper here" takes it; the variants are the
        # configuration's methods that differ from it in mechanism options only (reporting.mechanisms)
        base=config["report"].get("trace_method") or "PM",
        labels=method_labels(),
    script:
        "../scripts/report_mechanisms.py"


rule plot_pit:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        predictions=lambda w: [f for f, _ in pit_inputs()],
    output:
        pdf=f"{REPORTS}/figures/pit.pdf",
        png=report(
            f"{REPORTS}/figures/pit.png",
            category="Figures",
            caption="../report/pit.rst",
        ),
    log:
        f"{LOGS}/report/pit.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        panels=[k for _, k in pit_inputs()],
        labels=method_labels(),
    script:
        "../scripts/plots_pit.py"


rule report_today:
    input:
        results=f"{RESULTS}/aggregate/results.csv",
        comparisons=f"{RESULTS}/aggregate/comparisons.csv",
    output:
        section=f"{REPORTS}/tables/today.tex",
        table=report(
            f"{REPORTS}/tables/uncertainty.csv",
            category="Tables",
            caption="../report/uncertainty.rst",
        ),
    log:
        f"{LOGS}/report/today.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        methods=table_methods(),
        groups=method_groups(),
        labels=method_labels(),
        pit_figure="figures/pit.pdf",
    script:
        "../scripts/report_today.py"


rule plot_subjective:
    input:
        unpack(subjective_inputs),
        results=f"{RESULTS}/aggregate/results.csv",
    output:
        pdf=f"{REPORTS}/figures/subjective_{{source}}.pdf",
        png=report(
            f"{REPORTS}/figures/subjective_{{source}}.png",
            category="Figures",
            subcategory="{source}",
            caption="../report/subjective.rst",
        ),
    log:
        f"{LOGS}/report/subjective_{{source}}.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        design=study_design(),
        methods=subjective_methods(),
        activities=lambda w: config["study_activities"][w.source],
        labels_activity=lambda w: {
            a: pa or a.replace("_", " ").capitalize()
            for a, pa in activity_labels(w.source).items()
        },
        labels=method_labels(),
        motion=subjective_motion,
        sticks=lambda w: {a: stick_kind(w.source, a) for a in config["study_activities"][w.source]},
    script:
        "../scripts/plots_subjective.py"


rule report_verdict:
    input:
        f"{RESULTS}/aggregate/verdict.csv",
    output:
        f"{REPORTS}/tables/verdict.tex",
    log:
        f"{LOGS}/report/verdict.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        labels=method_labels(),
    script:
        "../scripts/report_verdict.py"


rule report_pdf:
    input:
        template="reports/report.tex",
        text=rules.report_text.output,
        tables=error_tables(
            REPORTS,
            {s: (data_status(s), config["study_activities"][s]) for s in report_sources()},
        ),
        figures=figure_targets("pdf"),
        cd_figures=[f"{REPORTS}/figures/cd_{s}.pdf" for s in report_sources()],
        why_pm=rules.report_why_pm.output.section,
        why_pm_figures=why_pm_figures("pdf"),
        mechanisms=rules.report_mechanisms.output.section,
        today=rules.report_today.output.section,
        verdict=rules.report_verdict.output[0],
        pit=rules.plot_pit.output.pdf,
    output:
        report(f"{REPORTS}/report.pdf", category="Report", caption="../report/report.rst"),
    log:
        f"{LOGS}/report/report_pdf.log",
    conda:
        "../envs/bsrbench.yaml"
    threads: 1
    params:
        # named on page 1 of the report (with the date, the git commit and the machine), in the order they apply
        configfiles=[
            os.path.relpath(f)
            for f in [
                *[f for f in workflow.configfiles if f not in workflow.overwrite_configfiles],
                *workflow.overwrite_configfiles,
            ]
        ],
        # and the --config KEY=VALUE overrides (command line or profile), which apply after them
        overrides=config_overrides(),
    script:
        "../scripts/report_pdf.py"
